"""`trackerd cameras`: what Aravis sees, run as a user would run it (a subprocess)."""

from __future__ import annotations

import json
import subprocess
import sys
import uuid

import pytest
from acq_helpers import TEST_PREFIX, TEST_SUBNET, needs_aravis, needs_netns

from trackerd.config.models import RigConfig

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
