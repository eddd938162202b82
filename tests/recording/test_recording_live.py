"""Recording from the virtual GigE Vision rig: the daemon records on demand, a recorder is killed mid-write.

The simulated cameras run in their own network namespaces (root) and serve the
rendered figure eight with exact ground truth per frame. The daemon, the
recorder and the replays are real processes; this one subscribes.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import zmq
from rec_helpers import interaction_events, replay_and_listen, trackerd, unsmoothed_xy

from trackerd.acquisition.arv import aravis_missing_reason
from trackerd.config.loader import dump_rig
from trackerd.config.recording import RecordingConfig
from trackerd.recording.format import FILE_HEADER, INDEX_ENTRY
from trackerd.recording.reader import Recording
from trackerd.sim.netns import netns_missing_reason

pytestmark = [
    pytest.mark.skipif(aravis_missing_reason() is not None, reason=f"needs Aravis: {aravis_missing_reason()}"),
    pytest.mark.skipif(
        netns_missing_reason() is not None, reason=f"needs network namespaces (root): {netns_missing_reason()}"
    ),
    pytest.mark.root,
    pytest.mark.aravis,
]

PREFIX, SUBNET = "trkdrec", "10.213.220.0/24"


@pytest.fixture(scope="module")
def virtual(simulated_rig, tmp_path_factory):
    from trackerd.sim.rig import VirtualRig

    with VirtualRig(
        simulated_rig, motion="figure8", prefix=PREFIX, subnet=SUBNET, out_dir=tmp_path_factory.mktemp("simrig")
    ) as rig:
        yield rig


def _rig_file(virtual, path: Path, endpoint: str, recording: RecordingConfig) -> Path:
    zmq_cfg = virtual.daemon_rig.outputs.zmq.model_copy(update={"endpoints": (endpoint,), "status_interval_ms": 250.0})
    rig = virtual.daemon_rig.model_copy(
        update={
            "outputs": virtual.daemon_rig.outputs.model_copy(update={"zmq": zmq_cfg}),
            "recording": recording,
        }
    )
    path.write_text(dump_rig(rig))
    return path


def _truth_by_device_time(virtual) -> dict[int, dict[str, Any]]:
    out = {}
    for index in range(len(virtual.rig.cameras)):
        for line in virtual.truth_path(index).read_text().splitlines():
            record = json.loads(line)
            out[record["device_timestamp_ns"]] = record
    return out


def _errors_to_truth_mm(virtual, recording_path: Path, hits: list[dict[str, Any]]) -> np.ndarray:
    """Each hit against the true hit, for pairs whose two frames show the same rendered scene (at
    60 fps and 30 loop frames a second, with the cameras' phases apart, the two frames of some
    pairs straddle a loop frame: those views disagree, and no true hit fits them)."""
    truth = _truth_by_device_time(virtual)
    with Recording.open(recording_path) as recording:
        shown = {}
        for i, entry in enumerate(recording.entries):
            views = [truth[f.device_timestamp_ns] for f in recording.header(i).frames]
            if len({v["loop_index"] for v in views}) == 1:
                shown[entry.sequence] = views[0]["wall_xy_m"]
    errors = [
        1000 * np.hypot(*np.subtract(unsmoothed_xy(h), shown[h["sequence"]])) for h in hits if h["sequence"] in shown
    ]
    assert len(errors) > 0.25 * len(hits)
    return np.array(errors)


def _interaction(messages: list[tuple[str, dict[str, Any]]], sequences: set[int]) -> list[tuple[str, int, str]]:
    return sorted(interaction_events([(t, m) for t, m in messages if m.get("sequence") in sequences]))


@pytest.mark.parametrize("mode", ["raw", "windowed"])
def test_the_daemon_records_on_demand_and_its_replay_publishes_what_it_published_live(virtual, tmp_path, mode) -> None:
    """Raw, and windowed (only the tracker's windows over keyframes): the replay publishes the live hits."""
    directory = tmp_path / "recordings"
    endpoint = f"ipc://{tmp_path}/live.sock"
    # A long queue: this machine's disk sometimes stalls for over half a second (32 pairs), and
    # the comparison with the live run below needs every pair recorded.
    queue = {"directory": directory, "queue_pairs": 160, "mode": mode}
    rig_file = _rig_file(virtual, tmp_path / "rig.toml", endpoint, RecordingConfig(**queue))
    ctx = zmq.Context()
    sub = ctx.socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"")
    sub.connect(endpoint)
    live: list[tuple[str, dict[str, Any]]] = []

    def collect(seconds: float, until: str | None = None) -> None:
        """Messages for ``seconds``, or until a status says the recording is ``until`` (the daemon
        takes its SIGHUP handler only once started, and a slow disk may delay a recording's end)."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if sub.poll(50):
                topic, payload = sub.recv_multipart()
                live.append((topic.decode(), json.loads(payload)))
                if (
                    until is not None
                    and live[-1][0] == "status"
                    and (live[-1][1].get("recording") or {}).get("state") == until
                ):
                    return

    daemon = subprocess.Popen(
        [sys.executable, "-m", "trackerd", "run", "--config", str(rig_file)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        collect(30.0, until="idle")
        collect(1.0)  # live hits before the recording, too
        _rig_file(virtual, rig_file, endpoint, RecordingConfig(**queue, enabled=True))
        daemon.send_signal(signal.SIGHUP)
        collect(20.0, until="recording")
        collect(3.0)
        _rig_file(virtual, rig_file, endpoint, RecordingConfig(**queue, enabled=False))
        daemon.send_signal(signal.SIGHUP)
        collect(20.0, until="stopped")
        collect(0.2)
        daemon.send_signal(signal.SIGTERM)
        code = daemon.wait(timeout=10)
        collect(0.3)
    finally:
        if daemon.poll() is None:
            daemon.kill()
        _, err = daemon.communicate()
        sub.close(0)
        ctx.term()
    assert code == 0 and "Traceback" not in err, err
    states = [m["recording"]["state"] for t, m in live if t == "status" and m.get("recording")]
    assert states[0] == "idle" and "recording" in states and states[-1] == "stopped"
    (path,) = directory.glob("*.trec")
    check = trackerd("recording", "check", path, "--json")
    report = json.loads(check.stdout)
    assert check.returncode == 0 and report["intact"] and report["dropped_by_recorder"] == 0, check.stdout
    assert report["pairs"] > 40 and report["mode"] == mode
    if mode == "windowed":  # windows for most pairs: keyframes at the first pair and once a second
        assert report["keyframes"] < report["pairs"] / 3, report
    with Recording.open(path) as recording:
        # What the daemon knew of its cameras and its rig file (they were null in recordings on demand).
        assert all(c.serial == f"SIM-{c.id.upper()}" and c.vendor and c.model for c in recording.cameras)
        assert recording.metadata.rig_file == str(rig_file.resolve())

    replayed_run, replayed = replay_and_listen(path, "--speed", "max", endpoint=f"ipc://{tmp_path}/replay.sock")
    assert replayed_run.returncode == 0, replayed_run.stderr
    with Recording.open(path) as recording:
        recorded = {e.sequence for e in recording.entries}
    live_pointers = {m["sequence"]: m for t, m in live if t == "pointer" and m["sequence"] in recorded}
    replay_pointers = {m["sequence"]: m for t, m in replayed if t == "pointer"}
    assert len(live_pointers) > 30 and set(replay_pointers) == set(live_pointers)
    for sequence, live_pointer in live_pointers.items():
        again = replay_pointers[sequence]
        # Capture times too: the recording keeps the daemon's clock offset (a gesture's start_ns
        # and end_ns differed by the microsecond between the recorder's reading and the daemon's).
        assert again["capture_ns"] == live_pointer["capture_ns"]
        strip = ("publish_ns",)
        assert {k: v for k, v in again.items() if k not in strip} == {
            k: v for k, v in live_pointer.items() if k not in strip
        }
    live_hits = {m["sequence"]: unsmoothed_xy(m) for t, m in live if t == "hit" and m["sequence"] in recorded}
    replay_hits = [m for t, m in replayed if t == "hit"]
    assert {m["sequence"]: unsmoothed_xy(m) for m in replay_hits} == live_hits  # the same hits, bit for bit
    # And the same interaction: the recording started mid-session (by a reload), and the stage
    # started afresh with it, so smoothing, enter/leave and gestures replay as they were published.
    # cursor_id counts sessions since the daemon started; the replay's last messages end its session.
    last_pair = max(i for i, (t, _) in enumerate(replayed) if t in ("pointer", "hit"))
    assert _interaction(replayed[: last_pair + 1], recorded) == _interaction(live, recorded)
    assert any(t == "enter" for t, _ in replayed)
    errors = _errors_to_truth_mm(virtual, path, replay_hits)
    assert np.median(errors) < 5.0 and np.percentile(errors, 95) < 15.0, errors


def test_a_recorder_killed_mid_write_leaves_a_recording_that_replays(virtual, tmp_path) -> None:
    rig_file = _rig_file(virtual, tmp_path / "rig.toml", "tcp://127.0.0.1:*", RecordingConfig())
    out = tmp_path / "killed.trec"
    recorder = subprocess.Popen(
        [sys.executable, "-m", "trackerd", "record", "--config", str(rig_file), str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    index = out / "pairs.idx"
    try:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and recorder.poll() is None:
            if index.exists() and index.stat().st_size >= FILE_HEADER.size + 30 * INDEX_ENTRY.size:
                break
            time.sleep(0.02)
        os.kill(recorder.pid, signal.SIGKILL)
    finally:
        recorder.wait(10)
        recorder.communicate()
    assert recorder.returncode == -signal.SIGKILL
    check = trackerd("recording", "check", out, "--json")
    report = json.loads(check.stdout)
    assert check.returncode == 1 and not report["closed"]
    assert report["pairs"] >= 30 and report["replayable"] == report["pairs"]
    assert any("no end record" in p for p in report["problems"])
    run, replayed = replay_and_listen(out, "--speed", "max", "--json", endpoint=f"ipc://{tmp_path}/replay.sock")
    assert run.returncode == 0, run.stderr
    assert "warning" in run.stderr and "no end record" in run.stderr
    assert json.loads(run.stdout)["pairs"] == report["pairs"]
    hits = [m for t, m in replayed if t == "hit"]
    assert len(hits) > 0.8 * report["pairs"]
    errors = _errors_to_truth_mm(virtual, out, hits)
    assert np.median(errors) < 5.0 and np.percentile(errors, 95) < 15.0, errors


def test_record_stops_at_its_limit_with_the_cameras_described(virtual, tmp_path) -> None:
    rig_file = _rig_file(virtual, tmp_path / "rig.toml", "tcp://127.0.0.1:*", RecordingConfig())
    run = trackerd("record", "--config", rig_file, tmp_path / "ten.trec", "--pairs", "10")
    assert run.returncode == 0, run.stderr
    assert "10 pairs" in run.stderr and "[stopped: pair limit]" in run.stderr
    with Recording.open(tmp_path / "ten.trec") as recording:
        assert recording.problems == [] and len(recording) == 10
        assert recording.metadata.end is not None and recording.metadata.end.reason == "pair limit"
        for cam in recording.cameras:
            assert cam.serial == f"SIM-{cam.id.upper()}" and cam.vendor and cam.model
        assert recording.metadata.rig_file == str(rig_file.resolve())


def test_snap_saves_one_pair_raw_and_annotated_and_prints_its_hit(virtual, tmp_path) -> None:
    import cv2

    from trackerd.config.loader import load_rig
    from trackerd.images import read_frame
    from trackerd.locator import Locator

    rig_file = _rig_file(virtual, tmp_path / "rig.toml", "tcp://127.0.0.1:*", RecordingConfig())
    run = trackerd("snap", "--config", rig_file, tmp_path / "snaps", "--name", "aim")
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith("snap aim: hit: wall (")
    record = json.loads((tmp_path / "snaps" / "aim.json").read_text())
    rig = load_rig(rig_file).config
    frames = []
    for cam, saved in zip(rig.cameras, record["cameras"], strict=True):
        view = cv2.imread(str(tmp_path / "snaps" / saved["view"]))
        assert view.shape == (1080, 1920, 3)
        frame, fmt = read_frame(tmp_path / "snaps" / saved["raw"], cam)
        assert fmt == "BayerRG8" and frame.shape == (1080, 1920)
        frames.append(frame)
        assert f"{cam.id}: red (" in run.stdout
    # The raw files are the pair exactly: located again, they give the same ends and hit.
    fix = Locator(rig).locate(frames)
    assert fix.status == record["status"] == "hit"
    assert [float(v) for v in fix.hit.wall_xy_m] == record["wall_xy_m"]
    for k, saved in enumerate(record["cameras"]):
        # The snap keeps the detector's centroids (the fix may have refined them into outline centres).
        assert [float(v) for v in fix.detections[k].red.centroid_px] == saved["ends"]["red"]["centroid_px"]


def test_a_full_disk_ends_record_with_one_line_saying_what_was_kept(virtual, small_disk, tmp_path) -> None:
    rig_file = _rig_file(virtual, tmp_path / "rig.toml", "tcp://127.0.0.1:*", RecordingConfig(min_free_space_mb=0))
    out = small_disk / "full.trec"
    run = trackerd("record", "--config", rig_file, out, "--seconds", "30")
    assert run.returncode == 1 and "Traceback" not in run.stderr, run.stderr
    lines = run.stderr.splitlines()
    # The start line and progress lines, then the outcome: one line, no log record or summary beside it.
    assert lines[0].startswith(f"trackerd record: recording left, right to {out}")
    assert all(line.startswith(f"{out}: ") for line in lines[1:-1]), lines
    assert "ERROR" not in run.stderr and "dropped:" not in run.stderr
    with Recording.open(out) as recording:
        kept = len(recording)
        assert kept >= 1 and recording.metadata.end is not None
        assert recording.metadata.end.reason.startswith("disk full")
    assert lines[-1].startswith(f"trackerd record: {out}/pairs.dat: disk full, stopped at {kept} pairs"), lines[-1]
    assert f"what was written stays readable: {kept} pairs (" in lines[-1] and lines[-1].endswith(f"in {out}")
    assert trackerd("recording", "check", out).returncode == 0


def test_record_and_snap_run_their_own_virtual_rig_beside_another(virtual, tmp_path) -> None:
    """The module's virtual rig holds PREFIX; --prefix and --subnet give record and snap their own."""
    own = ("--virtual", "figure8", "--prefix", "trkdrec2", "--subnet", "10.213.221.0/24")
    run = trackerd("record", "--config", "config/simulated.toml", tmp_path / "beside.trec", "--pairs", "3", *own)
    assert run.returncode == 0, run.stderr
    with Recording.open(tmp_path / "beside.trec") as recording:
        assert len(recording) == 3 and recording.problems == []
        assert [cam.address for cam in recording.rig().cameras] == ["10.213.221.2", "10.213.221.6"]
    run = trackerd("snap", "--config", "config/simulated.toml", tmp_path / "snaps", "--name", "beside", *own)
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "snaps" / "beside.json").exists()
    held = trackerd(
        "record",
        "--config",
        "config/simulated.toml",
        tmp_path / "held.trec",
        "--pairs",
        "3",
        "--virtual",
        "figure8",
        "--prefix",
        PREFIX,
        "--subnet",
        "10.213.222.0/24",
    )
    assert held.returncode == 1 and "Traceback" not in held.stderr
    assert f"trackerd-{PREFIX}.lock" in held.stderr and not (tmp_path / "held.trec").exists()
