"""The virtual rig (trackerd/sim/rig.py, trackerd/sim/netns.py): loops, addresses, namespaces."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from trackerd.config.models import RigConfig
from trackerd.errors import TrackerdError
from trackerd.sim import netns
from trackerd.sim.rig import VirtualRig, loop_truth, render_loop

NETNS_MISSING = netns.netns_missing_reason()
needs_netns = pytest.mark.skipif(NETNS_MISSING is not None, reason=f"needs network namespaces: {NETNS_MISSING}")
PREFIX = "trkds"
SUBNET = "10.213.201.0/24"


def test_each_camera_gets_its_own_slash_30() -> None:
    nets = netns.plan(3, "trkd", "10.213.0.0/24")
    assert [(n.host_address, n.camera_address) for n in nets] == [
        ("10.213.0.1", "10.213.0.2"),
        ("10.213.0.5", "10.213.0.6"),
        ("10.213.0.9", "10.213.0.10"),
    ]
    assert [n.namespace for n in nets] == ["trkd-cam0", "trkd-cam1", "trkd-cam2"]
    assert all(len(n.host_link) <= 15 for n in nets)  # Linux interface names


def test_a_plan_that_does_not_fit_is_refused() -> None:
    with pytest.raises(ValueError, match="no room for 3"):
        netns.plan(3, "trkd", "10.213.0.0/29")
    with pytest.raises(ValueError, match="prefix"):
        netns.plan(2, "Trk-1", "10.213.0.0/24")


def test_loop_truth_gives_true_ends_and_wall_hits(simulated_rig: RigConfig) -> None:
    truth = loop_truth(simulated_rig, "sweep", period_s=1.0, content_fps=4.0)
    assert [t["motion_time_s"] for t in truth] == [0.0, 0.25, 0.5, 0.75]
    for record in truth:
        front, back = np.array(record["front_m"]), np.array(record["back_m"])
        assert np.linalg.norm(front - back) == pytest.approx(simulated_rig.pointer.length_m)
        assert record["on_wall"] and len(record["wall_xy_m"]) == 2
    gone = [t for t in loop_truth(simulated_rig, "leave", 1.0, 20.0) if not t["present"]]
    assert gone and all("front_m" not in t for t in gone)


def test_a_rendered_loop_is_cached_by_rig_and_motion(simulated_rig: RigConfig, tmp_path: Path) -> None:
    first = render_loop(simulated_rig, "still", period_s=0.5, content_fps=2.0, cache_dir=tmp_path)
    again = render_loop(simulated_rig, "still", period_s=0.5, content_fps=2.0, cache_dir=tmp_path)
    other = render_loop(simulated_rig, "sweep", period_s=0.5, content_fps=2.0, cache_dir=tmp_path)
    assert first.rendered_s > 0 and again.rendered_s == 0.0
    assert again.directory == first.directory != other.directory
    frames = np.load(first.frame_paths[1], mmap_mode="r")
    assert frames.shape == (1, 1080, 1920) and frames.dtype == np.uint8
    truth = first.truth()[0]
    # The renderer's view of each ball lands near the projection of the true centre.
    assert set(truth["centroid_px"]) == {"left", "right"}
    assert len(json.loads(first.truth_path.read_text())["frames"]) == first.n_frames
    assert not list(tmp_path.glob(".partial-*"))


def test_without_namespaces_software_triggering_is_refused(simulated_rig: RigConfig) -> None:
    rig = simulated_rig.model_copy(
        update={"acquisition": simulated_rig.acquisition.model_copy(update={"trigger": "software"})}
    )
    with pytest.raises(TrackerdError, match="software triggering needs network namespaces"):
        VirtualRig(rig, network="loopback", synthetic=True)


def test_the_daemon_opens_the_simulated_cameras_by_address(simulated_rig: RigConfig, tmp_path: Path) -> None:
    loopback = VirtualRig(simulated_rig, network="loopback", synthetic=True, out_dir=tmp_path).daemon_rig
    assert [(c.address, c.device_id) for c in loopback.cameras] == [("127.0.0.1", None), (None, "Fake_1")]
    if NETNS_MISSING is None:
        rig = VirtualRig(simulated_rig, network="netns", synthetic=True, prefix=PREFIX, subnet=SUBNET, mtu=9000)
        daemon = rig.daemon_rig
        assert [c.address for c in daemon.cameras] == ["10.213.201.2", "10.213.201.6"]
        assert [c.serial for c in daemon.cameras] == ["SIM-LEFT", "SIM-RIGHT"]
        assert daemon.cameras[0].acquisition.packet_size_bytes == 8000


def _namespaces() -> set[str]:
    out = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    return {line.split()[0] for line in out.splitlines() if line.strip()}


@needs_netns
@pytest.mark.root
def test_namespaces_are_made_torn_down_and_stale_ones_cleared() -> None:
    nets = netns.plan(2, PREFIX, SUBNET)
    lock = netns.PrefixLock(PREFIX)
    lock.acquire()
    try:
        for net in nets:
            netns.create(net, mtu=9000)
        assert {n.namespace for n in nets} <= _namespaces()
        inside = subprocess.run(
            ["ip", "-n", nets[1].namespace, "-j", "addr", "show", nets[1].camera_link],
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        addresses = [a["local"] for link in json.loads(inside) for a in link["addr_info"] if a["family"] == "inet"]
        assert addresses == [nets[1].camera_address]
        route = subprocess.run(["ip", "-j", "route", "get", nets[1].camera_address], capture_output=True, text=True)
        assert json.loads(route.stdout)[0]["dev"] == nets[1].host_link
        # A second user of the prefix is turned away while the lock is held.
        with pytest.raises(netns.NetnsError, match="another virtual rig"):
            netns.PrefixLock(PREFIX).acquire()
        # As after a crash: the namespaces are still there; the next run clears them.
        removed = netns.remove_stale(PREFIX)
        assert {n.namespace for n in nets} <= set(removed)
        assert not {n.namespace for n in nets} & _namespaces()
    finally:
        for net in nets:
            netns.remove(net)
        lock.release()


def _simrig(*args: str, **kwargs) -> subprocess.Popen[str]:
    import sys

    command = [sys.executable, "-m", "trackerd", "simrig", *args]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kwargs)


def test_simrig_refuses_a_bad_rig_file_with_exit_2(tmp_path: Path) -> None:
    bad = tmp_path / "rig.toml"
    bad.write_text("version = 1\n[[cameras]]\nid = 'left'\n")
    _out, err = _simrig("--config", str(bad)).communicate(timeout=60)
    assert err.startswith(f"trackerd simrig: {bad}: ")
    assert "Traceback" not in err


@needs_netns
@pytest.mark.root
@pytest.mark.aravis
def test_simrig_measures_a_run_and_cleans_up_on_sigterm(tmp_path: Path) -> None:
    import signal

    repo = Path(__file__).resolve().parents[2]
    common = [
        "--config",
        str(repo / "config" / "simulated.toml"),
        "--synthetic",
        "--prefix",
        PREFIX,
        "--subnet",
        SUBNET,
        "--out",
        str(tmp_path / "out"),
    ]
    measured = _simrig(*common, "--seconds", "2", "--measure", "--json", "--trigger", "software")
    out, err = measured.communicate(timeout=120)
    assert measured.returncode == 0, err
    figures = json.loads(out)
    assert figures["trigger"] == "software" and figures["pairing"] == "trigger count"
    assert figures["pairs"] > 0 and figures["frame_drop_rate"] is not None
    assert {"skew_p50_us", "skew_p99_us", "true_skew_p99_us"} <= set(figures)

    serving = _simrig(*common)  # until stopped
    try:
        assert "ground truth" in "".join(serving.stdout.readline() for _ in range(5))
        assert {f"{PREFIX}-cam0", f"{PREFIX}-cam1"} <= _namespaces()
    finally:
        serving.send_signal(signal.SIGTERM)
        serving.communicate(timeout=60)
    assert serving.returncode == 130
    assert not {f"{PREFIX}-cam0", f"{PREFIX}-cam1"} & _namespaces()


def _running(pid: int) -> bool:
    """Whether the process exists and has not exited (a zombie waits only to be reaped)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def _camera_processes(parent: int) -> list[int]:
    """The simulated camera processes started by ``parent``."""
    children = Path(f"/proc/{parent}/task/{parent}/children").read_text().split()
    return [int(pid) for pid in children if b"trackerd.sim.gvcamera" in Path(f"/proc/{pid}/cmdline").read_bytes()]


@needs_netns
@pytest.mark.root
@pytest.mark.aravis
def test_the_cameras_leave_ctrl_c_to_the_rig_and_never_outlive_it(tmp_path: Path) -> None:
    """A terminal's Ctrl-C goes to its foreground process group. The cameras are outside it, so the
    daemon stops before its cameras vanish (they used to die first: 'acquisition thread did not
    stop in time'); and a rig killed outright still takes its cameras with it."""
    import os
    import signal
    import time

    repo = Path(__file__).resolve().parents[2]
    args = [
        "--config",
        str(repo / "config" / "simulated.toml"),
        "--synthetic",
        "--prefix",
        PREFIX,
        "--subnet",
        SUBNET,
        "--out",
        str(tmp_path / "out"),
    ]
    serving = _simrig(*args, start_new_session=True)  # its own process group, as in a terminal
    try:
        assert "ground truth" in "".join(serving.stdout.readline() for _ in range(5))
        cameras = _camera_processes(serving.pid)
        assert len(cameras) == 2
        assert all(os.getpgid(pid) != os.getpgid(serving.pid) for pid in cameras)
        serving.kill()
        serving.communicate(timeout=10)
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and any(_running(pid) for pid in cameras):
            time.sleep(0.1)
        assert not [pid for pid in cameras if _running(pid)]
    finally:
        if serving.poll() is None:
            serving.send_signal(signal.SIGTERM)
            serving.communicate(timeout=60)
        netns.remove_stale(PREFIX)  # killed outright, the rig could not remove its namespaces
    assert not {f"{PREFIX}-cam0", f"{PREFIX}-cam1"} & _namespaces()


@needs_netns
@pytest.mark.root
@pytest.mark.aravis
def test_a_second_rig_with_the_same_prefix_is_turned_away_and_the_first_keeps_its_namespaces(
    simulated_rig: RigConfig, tmp_path: Path
) -> None:
    from trackerd.acquisition.arv import aravis_missing_reason
    from trackerd.acquisition.gvcp import probe

    if aravis_missing_reason() is not None:
        pytest.skip(f"needs Aravis: {aravis_missing_reason()}")
    repo = Path(__file__).resolve().parents[2]
    ours = {f"{PREFIX}-cam0", f"{PREFIX}-cam1"}
    out = tmp_path / "out"  # shared, as two `trackerd simrig` runs share simrig-out/ by default
    with VirtualRig(simulated_rig, network="netns", synthetic=True, prefix=PREFIX, subnet=SUBNET, out_dir=out) as first:
        with first.truth_path(0).open("a") as truth:
            truth.write('{"served by": "the first rig"}\n')
        # A rendered (not synthetic) second rig: it must be turned away before rendering anything.
        cache = tmp_path / "cache"
        second = VirtualRig(
            simulated_rig,
            network="netns",
            prefix=PREFIX,
            subnet="10.213.202.0/24",
            out_dir=out,
            cache_dir=cache,
            period_s=0.5,
            content_fps=2.0,
        )
        with pytest.raises(netns.NetnsError, match="another virtual rig uses the namespace prefix"):
            second.start()
        second.stop()  # as `with` would: must not touch the first rig's names either
        assert ours <= _namespaces()
        assert not cache.exists()  # no loop rendered for a rig that cannot run
        assert "the first rig" in first.truth_path(0).read_text()  # its ground truth not truncated
        assert probe(first.nets[1].camera_address, 1.0) is not None  # its cameras still answer

        # The same through the command line: one line, exit 1, and the first rig unharmed.
        refused = subprocess.run(
            [
                sys.executable,
                "-m",
                "trackerd",
                "simrig",
                "--config",
                str(repo / "config" / "simulated.toml"),
                "--synthetic",
                "--prefix",
                PREFIX,
                "--subnet",
                "10.213.202.0/24",
                "--seconds",
                "2",
                "--out",
                str(tmp_path / "out2"),
            ],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert refused.returncode == 1, refused.stderr
        assert refused.stderr.startswith("trackerd simrig: another virtual rig uses the namespace prefix")
        assert len(refused.stderr.strip().splitlines()) == 1 and "Traceback" not in refused.stderr
        assert ours <= _namespaces()
        assert probe(first.nets[0].camera_address, 1.0) is not None
    assert not ours & _namespaces()


def test_the_cache_keeps_the_most_recently_used_loops(simulated_rig: RigConfig, tmp_path: Path) -> None:
    import os

    from trackerd.sim.loops import prune_loops

    for name in ("a", "b", "c"):
        (tmp_path / name).mkdir()
    os.utime(tmp_path / "a", (1, 1))  # the oldest
    prune_loops(tmp_path, keep=2)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b", "c"]
