"""The same acquisition checks against real cameras, run only when asked for.

    TRACKERD_HARDWARE=1 TRACKERD_RIG=/etc/trackerd/rig.toml .venv/bin/python -m pytest -m hardware -s

The rig file names the real cameras (by serial, address or device id) and the
acquisition settings to test (trigger mode, PTP). Cameras reached through pylon
(``backend = "pylon"``: Basler cameras, a CoaXPress grabber's GenTL producer) or any
vendor's GenTL producer (``backend = "gentl"`` with ``producer``: a CameraLink or
CoaXPress grabber) are tested the same way; they need the trackerd[gentl] extra.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import pytest

pytestmark = [
    pytest.mark.hardware,
    pytest.mark.aravis,
    pytest.mark.skipif(
        os.environ.get("TRACKERD_HARDWARE") != "1" or not os.environ.get("TRACKERD_RIG"),
        reason="real cameras: set TRACKERD_HARDWARE=1 and TRACKERD_RIG to the rig file naming them",
    ),
]


@pytest.fixture(scope="module")
def rig():
    from trackerd.config.loader import load_rig

    return load_rig(os.environ["TRACKERD_RIG"]).config


def test_the_rigs_cameras_are_listed(rig) -> None:
    producers = sorted({cam.producer for cam in rig.cameras if cam.producer})
    asked = [arg for producer in producers for arg in ("--producer", producer)]
    result = subprocess.run(
        [sys.executable, "-m", "trackerd", "cameras", "--json", *asked], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stdout
    seen = json.loads(result.stdout)["cameras"]
    for cam in rig.cameras:
        names = {value for device in seen for value in (device["serial"], device["address"], device["device_id"])}
        assert {cam.serial, cam.address, cam.device_id} & names, f"camera {cam.id} not found"


def test_real_cameras_deliver_pairs(rig) -> None:
    from trackerd.acquisition.live import LivePairSource

    pairs = []
    with LivePairSource(rig) as source:
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            pair = source.next_pair(0.5)
            if pair is not None:
                pairs.append(pair)
        status = source.status()
    print("\n" + json.dumps(status.to_dict(), indent=2))
    assert pairs, "no pair in 10 s"
    assert all(c.state == "streaming" and c.losses == 0 for c in status.cameras)
    frames = sum(c.frames for c in status.cameras)
    failed = sum(sum(c.failed_buffers.values()) for c in status.cameras)
    assert failed <= 0.01 * frames, f"{failed} failed buffers of {frames} frames"
    if rig.acquisition.trigger == "software":
        assert len({p.frames[0].frame_id - p.frames[1].frame_id for p in pairs}) == 1
    if rig.acquisition.ptp:
        assert all(c.ptp_state is not None for c in status.cameras)
    stamps = [p.timestamp_ns for p in pairs]
    assert stamps == sorted(stamps)
