"""`trackerd cameras`: what Aravis sees, run as a user would run it (a subprocess)."""

from __future__ import annotations

import json
import os
import selectors
import subprocess
import sys
import uuid
from collections.abc import Iterator

import pytest
from acq_helpers import TEST_PREFIX, TEST_SUBNET, needs_aravis, needs_netns

from trackerd.config.models import RigConfig
from trackerd.sim.netns import PrefixLock

pytestmark = [pytest.mark.aravis, needs_aravis]


def trackerd(*args: str, prefix: tuple[str, ...] = ()) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*prefix, sys.executable, "-m", "trackerd", *args], capture_output=True, text=True, timeout=60
    )


@needs_netns
@pytest.mark.root
def test_no_camera_says_so_and_exits_1() -> None:
    """In a fresh network namespace nothing can answer discovery."""
    namespace = f"{TEST_PREFIX}-empty-{uuid.uuid4().hex[:6]}"
    subprocess.run(["ip", "netns", "add", namespace], check=True)
    try:
        subprocess.run(["ip", "-n", namespace, "link", "set", "lo", "up"], check=True)
        result = trackerd("cameras", prefix=("ip", "netns", "exec", namespace))
        as_json = trackerd("cameras", "--json", prefix=("ip", "netns", "exec", namespace))
        one = trackerd("cameras", "SIM-LEFT", prefix=("ip", "netns", "exec", namespace))
    finally:
        subprocess.run(["ip", "netns", "del", namespace], check=True)
    assert result.returncode == 1
    assert result.stdout.startswith("no camera found")
    assert as_json.returncode == 1 and json.loads(as_json.stdout)["cameras"] == []
    # Asked for one camera, the answer is about that camera, on one line.
    assert one.returncode == 1 and "Traceback" not in one.stderr
    assert one.stderr.startswith("trackerd cameras: no camera 'SIM-LEFT': Aravis sees no GigE Vision"), one.stderr


@needs_netns
@pytest.mark.root
def test_the_simulated_cameras_are_listed_and_described(simulated_rig: RigConfig, out_dir) -> None:
    from trackerd.sim.rig import VirtualRig

    with VirtualRig(
        simulated_rig, synthetic=True, network="netns", prefix=TEST_PREFIX, subnet=TEST_SUBNET, out_dir=out_dir
    ):
        listing = trackerd("cameras", "--json")
        detail = trackerd("cameras", "SIM-RIGHT", "--json")
        text = trackerd("cameras", "10.213.200.2")
    assert listing.returncode == 0, listing.stderr
    found = {c["serial"]: c for c in json.loads(listing.stdout)["cameras"]}
    assert found["SIM-LEFT"]["address"] == "10.213.200.2"
    assert found["SIM-RIGHT"]["protocol"] == "GigEVision"
    camera = json.loads(detail.stdout)["camera"]
    assert camera["serial"] == "SIM-RIGHT"
    assert "BayerRG8" in camera["pixel_formats"]
    assert "Software" in camera["trigger_sources"] and camera["software_trigger"]
    assert camera["width_px"][1] >= 1920 and camera["height_px"][1] >= 1080
    assert text.returncode == 0
    assert "SIM-LEFT" in text.stdout and "trigger sources" in text.stdout


def test_an_unknown_camera_is_one_line_and_exit_1() -> None:
    result = trackerd("cameras", "NO-SUCH-CAMERA", "--fake")
    assert result.returncode == 1
    assert result.stderr.strip().startswith("trackerd cameras: no camera 'NO-SUCH-CAMERA' among those found")
    assert "Traceback" not in result.stderr


ROUTED_PREFIX = "trkdtr"
"""Names of the routed camera's namespaces and links (not matched by the virtual rigs' clean-up)."""
ROUTED_CAMERA = "10.213.201.10"
NOBODY_THERE = "10.213.201.11"
"""On the camera's subnet, beyond the router, with no host behind it."""


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, timeout=10)


def _remove_routed_network() -> None:
    for command in (
        ["netns", "del", f"{ROUTED_PREFIX}-cam"],
        ["netns", "del", f"{ROUTED_PREFIX}-router"],
        ["link", "del", f"{ROUTED_PREFIX}0h"],
        ["route", "del", "10.213.201.8/29"],
    ):
        subprocess.run(["ip", *command], capture_output=True, timeout=10)


@pytest.fixture
def routed_camera(tmp_path) -> Iterator[str]:
    """A simulated camera one router away (host - router - camera namespaces): unicast reaches it,
    broadcast discovery does not, as with a camera on another subnet of a plant network."""
    lock = PrefixLock(ROUTED_PREFIX)
    lock.acquire()
    _remove_routed_network()  # left by a run that crashed; we hold the lock
    router, camera_ns = f"{ROUTED_PREFIX}-router", f"{ROUTED_PREFIX}-cam"
    camera = None
    try:
        _ip("netns", "add", router)
        _ip("netns", "add", camera_ns)
        _ip("link", "add", f"{ROUTED_PREFIX}0h", "type", "veth", "peer", "name", f"{ROUTED_PREFIX}0r", "netns", router)
        _ip("-n", router, "link", "add", f"{ROUTED_PREFIX}1r", "type", "veth", "peer", "name", f"{ROUTED_PREFIX}1c")
        _ip("-n", router, "link", "set", f"{ROUTED_PREFIX}1c", "netns", camera_ns)
        _ip("addr", "add", "10.213.201.1/30", "dev", f"{ROUTED_PREFIX}0h")
        _ip("link", "set", f"{ROUTED_PREFIX}0h", "up")
        _ip("-n", router, "addr", "add", "10.213.201.2/30", "dev", f"{ROUTED_PREFIX}0r")
        _ip("-n", router, "addr", "add", "10.213.201.9/29", "dev", f"{ROUTED_PREFIX}1r")
        for link in ("lo", f"{ROUTED_PREFIX}0r", f"{ROUTED_PREFIX}1r"):
            _ip("-n", router, "link", "set", link, "up")
        subprocess.run(
            ["ip", "netns", "exec", router, "sysctl", "-qw", "net.ipv4.ip_forward=1"], check=True, timeout=10
        )
        _ip("-n", camera_ns, "addr", "add", f"{ROUTED_CAMERA}/29", "dev", f"{ROUTED_PREFIX}1c")
        for link in ("lo", f"{ROUTED_PREFIX}1c"):
            _ip("-n", camera_ns, "link", "set", link, "up")
        _ip("-n", camera_ns, "route", "add", "default", "via", "10.213.201.9")
        _ip("route", "add", "10.213.201.8/29", "via", "10.213.201.2")
        camera = subprocess.Popen(
            [
                "ip", "netns", "exec", camera_ns, sys.executable, "-m", "trackerd.sim.gvcamera",
                "--interface", f"{ROUTED_PREFIX}1c", "--serial", "SIM-ROUTED", "--synthetic", "64x48",
                "--parent-pid", str(os.getpid()),
            ],
            stdout=subprocess.PIPE,
            stderr=(tmp_path / "camera.log").open("w"),
            text=True,
        )  # fmt: skip
        assert camera.stdout is not None
        with selectors.DefaultSelector() as selector:
            selector.register(camera.stdout, selectors.EVENT_READ)
            ready = camera.stdout.readline() if selector.select(30) else ""
        assert ready.startswith("ready"), (tmp_path / "camera.log").read_text()
        yield ROUTED_CAMERA
    finally:
        if camera is not None:
            camera.terminate()
            camera.wait(10)
            if camera.stdout is not None:
                camera.stdout.close()
        _remove_routed_network()
        lock.release()


@needs_netns
@pytest.mark.root
def test_a_camera_beyond_broadcast_is_described_by_its_address(routed_camera: str) -> None:
    """Issue 15: `trackerd cameras ADDRESS` looked only through broadcast discovery, which stops at
    the router, and said no camera where Aravis opens one by that address."""
    listing = trackerd("cameras", "--json")
    text = trackerd("cameras", routed_camera)
    as_json = trackerd("cameras", routed_camera, "--json")
    # The premise: broadcast discovery does not see it.
    assert "SIM-ROUTED" not in {c["serial"] for c in json.loads(listing.stdout)["cameras"]}
    assert text.returncode == 0, text.stderr
    assert "SIM-ROUTED" in text.stdout and routed_camera in text.stdout
    assert "trigger sources" in text.stdout and "pixel formats" in text.stdout
    assert as_json.returncode == 0, as_json.stderr
    out = json.loads(as_json.stdout)
    assert [(c["serial"], c["address"]) for c in out["cameras"]] == [("SIM-ROUTED", routed_camera)]
    assert out["camera"]["serial"] == "SIM-ROUTED" and "BayerRG8" in out["camera"]["pixel_formats"]


@needs_netns
@pytest.mark.root
def test_no_answer_at_an_address_is_one_line_and_exit_1(routed_camera: str) -> None:
    """An address that is routed but where no camera answers: one line naming it and what to check."""
    result = trackerd("cameras", NOBODY_THERE)
    assert result.returncode == 1
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert lines[0].startswith(f"trackerd cameras: no camera answers at {NOBODY_THERE}"), lines[0]
    assert "route" in lines[0] and "3956" in lines[0]
