"""Calibration input from folders: which images are a camera's, on real files."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.calibration.test_cli_photos import photo_workspace
from trackerd.calibration import CalibrationError
from trackerd.calibration.inputs import image_files


def _touch(folder: Path, *names: str) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for name in names:
        (folder / name).write_bytes(b"")


def test_a_folder_gives_the_images_named_for_the_camera(tmp_path: Path) -> None:
    _touch(tmp_path / "both", "left01.jpg", "right01.jpg", "02-left.png", "02-right.png", "left2-03.png")
    files, said = image_files([tmp_path / "both"], "left", ["left", "right", "left2"])
    assert [f.name for f in files] == ["02-left.png", "left01.jpg"]
    assert said == [f"{tmp_path / 'both'}: the 2 named for camera left of its 5 image(s)"]
    # A folder of another camera's images only is refused, not taken as this one's.
    _touch(tmp_path / "right-only", "right01.jpg", "right02.jpg")
    with pytest.raises(CalibrationError, match=r"no image named for camera left .*named for right"):
        image_files([tmp_path / "right-only"], "left", ["left", "right"])
    # Images named for no camera are all taken, and it is said.
    _touch(tmp_path / "plain", "a.png", "b.png")
    files, said = image_files([tmp_path / "plain", tmp_path / "both" / "left01.jpg"], "cam0", ["cam0", "cam1"])
    assert [f.name for f in files] == ["a.png", "b.png", "left01.jpg"]
    assert "all 2 image(s) (none is named for a camera; all are taken as cam0's)" in said[0]


def test_a_board_recorded_with_a_rig_that_cannot_track_does_not_replay_as_if_it_could(tmp_path: Path) -> None:
    """`recording import` takes a Mono8 rig without wall or pointer (a board for calibration); replaying
    that recording on its own rig is refused in one line, naming what is missing."""
    photo_workspace(tmp_path)

    def trackerd(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "trackerd", *args], cwd=tmp_path, capture_output=True, text=True, timeout=120
        )

    run = trackerd("recording", "import", "--config", "rig.toml", "photos", "board.trec")
    assert run.returncode == 0, run.stderr
    assert "13 pairs imported" in run.stdout
    run = trackerd("replay", "board.trec", "--speed", "max")
    assert run.returncode == 2 and "Traceback" not in run.stderr, run.stderr
    line = run.stderr.strip().splitlines()[-1]
    assert "the recorded rig cannot track" in line and "give one that can with --config" in line
