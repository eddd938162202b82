"""Fixtures for the configuration tests: a small rig and calibration to edit, and the real CLI."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

# A small but complete rig: two FOV cameras either side of a 2 x 1 m wall given by points.
# Tests edit it rather than the example rigs, whose values other work may change.
MINIMAL_RIG = """\
version = 1
name = "minimal"

[[cameras]]
id = "left"
width_px = 640
height_px = 480
pixel_format = "RGB8"
intrinsics = { model = "fov", horizontal_fov_deg = 60.0 }
extrinsics = { kind = "pose", position_m = [-0.5, 1.0, 1.5], yaw_deg = 30.0 }

[[cameras]]
id = "right"
serial = "CAM-0002"
width_px = 640
height_px = 480
pixel_format = "BGR8"
intrinsics = { model = "fov", horizontal_fov_deg = 60.0, focal_length_mm = 6.0 }
extrinsics = { kind = "pose", position_m = [2.5, 1.0, 1.5], yaw_deg = -30.0 }

[wall]
points_m = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
origin_m = [0.0, 0.0, 0.0]
x_direction = [1.0, 0.0, 0.0]
y_direction = [0.0, 1.0, 0.0]
width_m = 2.0
height_m = 1.0

[pointer]
length_m = 0.45
end_diameter_m = 0.04

[detector]
min_area_px = 12.0

[outputs.zmq]
endpoints = ["tcp://127.0.0.1:5560"]
"""

# A calibration file for MINIMAL_RIG's left camera: an OpenCV lens and an OpenCV pose.
LEFT_CALIBRATION = """\
version = 1

[cameras.left]
extrinsics = { kind = "opencv", rvec = [3.1, 0.1, 0.05], tvec_m = [0.4, 1.1, 1.6] }
info = { date = "2026-01-01", views = 24, rms_px = 0.21 }

[cameras.left.intrinsics]
model = "opencv"
fx_px = 550.0
fy_px = 551.0
cx_px = 321.0
cy_px = 239.0
distortion = [-0.05, 0.01, 0.0, 0.0]
"""


def _edit(text: str, old: str, new: str) -> str:
    count = text.count(old)
    if count != 1:
        raise AssertionError(f"expected one {old!r} in the rig text, found {count}")
    return text.replace(old, new)


@pytest.fixture
def edit() -> Callable[[str, str, str], str]:
    """``edit(text, old, new)``: text with its one occurrence of old replaced (fails otherwise),
    so a test can never silently check an unmodified file."""
    return _edit


@pytest.fixture
def minimal_rig() -> str:
    return MINIMAL_RIG


@pytest.fixture
def left_calibration() -> str:
    return LEFT_CALIBRATION


@pytest.fixture
def run_check(tmp_path: Path) -> Callable[..., subprocess.CompletedProcess[str]]:
    """Run the real ``trackerd config check FILE [ARGS]`` in a subprocess, in tmp_path."""

    def run(file: str | Path, *extra: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "trackerd", "config", "check", str(file), *extra],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        )

    return run


@pytest.fixture
def check_in_process(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> Callable[..., subprocess.CompletedProcess[str]]:
    """The same as run_check, but calling the `trackerd` entry point in this process:
    the same code and output at a twentieth of the cost, for the cases that need no
    separate process to be believed."""
    from trackerd.cli.main import main

    def run(file: str | Path, *extra: str) -> subprocess.CompletedProcess[str]:
        monkeypatch.chdir(tmp_path)
        code = main(["config", "check", str(file), *extra])
        captured = capsys.readouterr()
        return subprocess.CompletedProcess([], code, captured.out, captured.err)

    return run


@pytest.fixture
def write(tmp_path: Path) -> Callable[[str, str], Path]:
    """Write text to tmp_path/<name> and return the path."""

    def write_file(name: str, text: str) -> Path:
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        return path

    return write_file
