"""`trackerd run` and `trackerd cameras` on two of pylon's emulated cameras, as real processes.

The emulated cameras serve a rendered pointer scene of the simulated rig (written
as image files by trackerd.sim.camemu); the daemon's hits, received over ZeroMQ,
are checked against the scene's true wall hit.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
import zmq

from trackerd.acquisition.pylon import pylon_missing_reason
from trackerd.config.loader import dump_rig
from trackerd.config.models import RigConfig
from trackerd.sim.camemu import emulated_rig
from trackerd.sim.motion import make_motion
from trackerd.sim.scene import true_wall_hit

PYLON_MISSING = pylon_missing_reason()
needs_pylon = pytest.mark.skipif(
    PYLON_MISSING is not None, reason=f"needs pypylon (pip install 'trackerd[gentl]'): {PYLON_MISSING}"
)
ENDPOINT = "tcp://127.0.0.1:5587"
EMULATION = dict(os.environ, PYLON_CAMEMU="2")


def trackerd(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "trackerd", *args], capture_output=True, text=True, timeout=60, env=env or EMULATION
    )


@pytest.fixture(scope="module")
def still_scene(
    tmp_path_factory: pytest.TempPathFactory, simulated_rig: RigConfig, renderer
) -> tuple[list[Path], np.ndarray]:
    """The pointer held still in front of the wall, one image file per camera (rendered with the session's
    renderer, whose room backgrounds are cached), and the true wall hit."""
    pose = make_motion("still", simulated_rig)(0.0)
    rng = np.random.default_rng(5)
    out = tmp_path_factory.mktemp("camemu")
    dirs = []
    for i, cam in enumerate(simulated_rig.cameras):
        cam_dir = out / cam.id
        cam_dir.mkdir()
        assert cv2.imwrite(str(cam_dir / "frame-00000.bmp"), renderer.render(i, pose, rng).image)
        dirs.append(cam_dir)
    return dirs, true_wall_hit(pose, renderer.wall).wall_xy_m


def daemon_rig(simulated_rig: RigConfig, image_dirs: list[Path], tmp_path: Path) -> Path:
    rig = emulated_rig(simulated_rig, image_dirs, trigger="software", frame_rate_hz=30.0)
    zmq_cfg = rig.outputs.zmq.model_copy(update={"endpoints": (ENDPOINT,), "status_interval_ms": 250.0})
    rig = rig.model_copy(update={"outputs": rig.outputs.model_copy(update={"zmq": zmq_cfg})})
    path = tmp_path / "rig.toml"
    path.write_text(dump_rig(rig))
    return path


@pytest.mark.pylon
@needs_pylon
def test_the_daemon_tracks_the_pointer_on_two_emulated_cameras(simulated_rig, still_scene, tmp_path: Path) -> None:
    image_dirs, true_xy = still_scene
    rig_file = daemon_rig(simulated_rig, image_dirs, tmp_path)
    ctx = zmq.Context()
    sub = ctx.socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"")
    sub.connect(ENDPOINT)
    daemon = subprocess.Popen(
        [sys.executable, "-m", "trackerd", "run", "--config", str(rig_file)],
        env=EMULATION,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    messages: list[tuple[str, dict]] = []
    try:
        deadline = time.monotonic() + 90.0

        def enough() -> bool:
            hits = sum(t == "hit" for t, _ in messages)
            running = any(t == "status" and m["state"] == "running" for t, m in messages[-40:])
            return hits >= 30 and running

        while time.monotonic() < deadline and not enough() and daemon.poll() is None:
            if sub.poll(100):
                topic, payload = sub.recv_multipart()
                messages.append((topic.decode(), json.loads(payload)))
        daemon.send_signal(signal.SIGTERM)
        code = daemon.wait(timeout=20)
    finally:
        if daemon.poll() is None:
            daemon.kill()
        _, err = daemon.communicate()
        sub.close(0)
        ctx.term()
    assert code == 0, err
    assert enough(), (sum(t == "hit" for t, _ in messages), err[-2000:])
    status = [m for t, m in messages if t == "status" and m["state"] == "running"][-1]
    assert [c["state"] for c in status["cameras"]] == ["streaming", "streaming"]
    assert status["pairing"]["mode"] == "trigger count"
    # The hits are the scene's true wall hit, within the accuracy budget (5 mm).
    hits = np.array([[m["wall_x_m"], m["wall_y_m"]] for t, m in messages if t == "hit"])
    error_m = np.linalg.norm(hits - true_xy, axis=1)
    assert np.median(error_m) < 0.005 and np.max(error_m) < 0.015, (np.median(error_m), np.max(error_m))


@pytest.mark.pylon
@needs_pylon
def test_cameras_lists_the_emulated_cameras_with_their_backend() -> None:
    listing = trackerd("cameras", "--json")
    detail = trackerd("cameras", "0815-0001")
    assert listing.returncode == 0, listing.stderr
    pylon = [c for c in json.loads(listing.stdout)["cameras"] if c["backend"] == "pylon"]
    assert [(c["serial"], c["protocol"]) for c in pylon] == [
        ("0815-0000", "BaslerCamEmu"),
        ("0815-0001", "BaslerCamEmu"),
    ]
    assert detail.returncode == 0, detail.stderr
    assert "Emulation (0815-0001)" in detail.stdout and "pylon" in detail.stdout
    assert "BayerRG8" in detail.stdout and "software trigger supported" in detail.stdout


def test_without_pypylon_the_pylon_backend_names_the_extra_to_install(simulated_rig, tmp_path: Path) -> None:
    """A real process in which pypylon cannot be imported (as on a machine without the extra)."""
    rig_file = daemon_rig(simulated_rig, [tmp_path / "left", tmp_path / "right"], tmp_path)
    without = "import sys; sys.modules['pypylon'] = None; from trackerd.cli.main import main; sys.exit(main())"
    result = subprocess.run(
        [sys.executable, "-c", without, "run", "--config", str(rig_file)],
        capture_output=True,
        text=True,
        timeout=60,
        env=EMULATION,
    )
    assert result.returncode != 0
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert "backend = 'pylon' needs pypylon" in lines[0] and "pip install 'trackerd[gentl]'" in lines[0]
