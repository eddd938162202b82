"""`trackerd run` and `trackerd cameras` on two of viky.cti's virtual devices (backend = "gentl"), as real processes.

viky draws a bouncing ball, not a pointer: the daemon is checked for pairs and camera states in its
status messages over ZeroMQ, not for hits.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import zmq
from viky_helpers import needs_viky, viky_cti, viky_daemon_rig

from trackerd.config.loader import dump_rig
from trackerd.config.models import RigConfig

ENDPOINT = "tcp://127.0.0.1:5591"


def write_rig(simulated_rig: RigConfig, tmp_path: Path) -> Path:
    path = tmp_path / "rig.toml"
    path.write_text(dump_rig(viky_daemon_rig(simulated_rig, ENDPOINT)))
    return path


@pytest.mark.gentl
@needs_viky
def test_the_daemon_pairs_frames_of_two_viky_devices(simulated_rig: RigConfig, tmp_path: Path) -> None:
    rig_file = write_rig(simulated_rig, tmp_path)
    ctx = zmq.Context()
    sub = ctx.socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"status")
    sub.connect(ENDPOINT)
    daemon = subprocess.Popen(
        [sys.executable, "-m", "trackerd", "run", "--config", str(rig_file)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    statuses: list[dict] = []
    try:
        deadline = time.monotonic() + 60.0

        def enough() -> bool:
            # Running, and pairs formed since the first running status: the daemon keeps pairing.
            running = [m for m in statuses if m["state"] == "running"]
            return len(running) >= 2 and running[-1]["pairing"]["pairs"] >= running[0]["pairing"]["pairs"] + 10

        while time.monotonic() < deadline and not enough() and daemon.poll() is None:
            if sub.poll(100):
                _, payload = sub.recv_multipart()
                statuses.append(json.loads(payload))
        daemon.send_signal(signal.SIGTERM)
        code = daemon.wait(timeout=20)
    finally:
        if daemon.poll() is None:
            daemon.kill()
        _, err = daemon.communicate()
        sub.close(0)
        ctx.term()
    assert code == 0, err
    assert enough(), (statuses[-1:] or None, err[-2000:])
    status = [m for m in statuses if m["state"] == "running"][-1]
    assert [c["state"] for c in status["cameras"]] == ["streaming", "streaming"]
    assert [c["id"] for c in status["cameras"]] == ["left", "right"]
    assert all(c["frames"] > 0 and c["losses"] == 0 for c in status["cameras"])
    assert status["pairing"]["mode"] == "host time"


@needs_viky
def test_cameras_lists_what_a_producer_offers_with_its_backend() -> None:
    cti = str(viky_cti())
    listing = subprocess.run(
        [sys.executable, "-m", "trackerd", "cameras", "--json", "--producer", cti],
        capture_output=True,
        text=True,
        timeout=60,
    )
    detail = subprocess.run(
        [sys.executable, "-m", "trackerd", "cameras", "--producer", cti, "VikyTL_DEV_green"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert listing.returncode == 0, listing.stderr
    gentl = [c for c in json.loads(listing.stdout)["cameras"] if c["backend"] == "gentl"]
    assert [c["device_id"] for c in gentl] == ["VikyTL_DEV_red", "VikyTL_DEV_green", "VikyTL_DEV_blue"]
    assert {c["producer"] for c in gentl} == {str(Path(cti).resolve())}
    assert detail.returncode == 0, detail.stderr
    assert "VikyTL_DEV_green: Machine Vision Games Ltd. Viky" in detail.stdout
    assert "RGBa8, Mono8" in detail.stdout and "100 - 800 px" in detail.stdout


def test_cameras_names_a_missing_producer_file(tmp_path: Path) -> None:
    missing = tmp_path / "grabber.cti"
    result = subprocess.run(
        [sys.executable, "-m", "trackerd", "cameras", "--producer", str(missing)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode != 0
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert str(missing) in lines[0] and "no such file" in lines[0]


def test_without_harvesters_the_gentl_backend_names_the_extra_to_install(simulated_rig, tmp_path: Path) -> None:
    """A real process in which harvesters cannot be imported (as on a machine without the extra)."""
    data = simulated_rig.model_dump()
    for cam in data["cameras"]:
        cam.update(backend="gentl", producer=str(tmp_path / "any.cti"), serial="X", address=None)
    rig_file = tmp_path / "rig.toml"
    rig_file.write_text(dump_rig(RigConfig.model_validate(data)))
    without = "import sys; sys.modules['harvesters'] = None; from trackerd.cli.main import main; sys.exit(main())"
    result = subprocess.run(
        [sys.executable, "-c", without, "run", "--config", str(rig_file)], capture_output=True, text=True, timeout=60
    )
    assert result.returncode != 0
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert "backend = 'gentl' needs harvesters" in lines[0] and "pip install 'trackerd[gentl]'" in lines[0]
