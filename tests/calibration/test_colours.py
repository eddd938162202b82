"""`trackerd calibrate pointer`: the pointer's colours learned in a room, on rendered rooms the default
thresholds were not tuned on (dark paint in dim light, a picture as red as the ball), and as a command on
files on disk."""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from tests.rooms import BLANK, DIM, RED_PICTURE, room, waved
from trackerd.calibration import CalibrationError
from trackerd.calibration.colours import ColourLearner
from trackerd.calibration.live import save_frame
from trackerd.config.loader import dump_rig, load_rig
from trackerd.detect.detector import ColourEndDetector
from trackerd.sim.appearance import Look


def _learn(rig, renderer, *, content=None, count: int = 8):
    rng = np.random.default_rng(5)
    learner = ColourLearner(rig, renderer.cameras, wanted=count)
    for pose in waved(count):
        learner.feed(
            [
                (cam.camera_id, renderer.render(i, pose, rng, content=content).image, "BayerRG8")
                for i, cam in enumerate(renderer.cameras)
            ]
        )
    return learner.result("2026-12-02")


def test_dark_paint_in_dim_light_gets_thresholds_the_detector_finds_it_with():
    rig, renderer = room(DIM, noise_sigma=2.0, shot_noise=0.3)
    figures = _learn(rig, renderer, content=BLANK)
    assert figures.used == 8
    red, blue = figures.colours.red, figures.colours.blue
    # Below the defaults (which miss this paint), above the room.
    assert red.background_excess < red.min_excess < rig.detector.red.min_excess
    assert blue.background_excess < blue.min_excess < rig.detector.blue.min_excess
    assert blue.margin > 10
    # In this light the presenter's hand is nearly as red as the dark red paint: said, with where it is.
    assert red.margin < 0.25 * red.ball_excess
    (warning,) = figures.warnings
    assert warning.startswith("red: the margin to the room is only") and " in camera " in warning
    (before, tried), (after, _) = figures.detector_check["before"], figures.detector_check["after"]
    assert before <= tried // 4 and after >= tried - 1, figures.detector_check
    # A pose not learned from, in both cameras: the detector's own search with the learned thresholds
    # finds both ends where they are; with the defaults it does not.
    learned = rig.detector.model_copy(
        update={
            c: rig.detector.red.model_copy(
                update={"min_excess": figures.colours.of(c).min_excess, "min_value": figures.colours.of(c).min_value}
            )
            for c in ("red", "blue")
        }
    )
    pose = next(waved(1, offset=0.37))
    rng = np.random.default_rng(9)
    for index, cam in enumerate(renderer.cameras):
        view = renderer.render(index, pose, rng, content=BLANK)
        plain = ColourEndDetector(rig.detector, "BayerRG8", cam.width_px, cam.height_px, rig.pointer).detect(view.image)
        assert not plain.both_found
        found = ColourEndDetector(learned, "BayerRG8", cam.width_px, cam.height_px, rig.pointer).detect(view.image)
        for colour in ("red", "blue"):
            end = found.end(colour)
            assert end.found, end.reason
            assert np.linalg.norm(end.centroid_px - view.truth.centroid_px[colour]) < 1.5


def test_a_picture_as_red_as_the_ball_is_named_with_its_camera_and_place():
    rig, renderer = room()
    clear = _learn(rig, renderer, content=BLANK, count=4)
    assert not clear.warnings and clear.colours.red.margin > 40
    figures = _learn(rig, renderer, content=RED_PICTURE, count=6)
    red = figures.colours.red
    assert red.margin <= 0 < clear.colours.red.margin
    # The threshold still takes the ball; the warning says that only the geometry tells them apart.
    assert red.min_excess < red.ball_excess
    (warning,) = [w for w in figures.warnings if w.startswith("red:")]
    assert "only the geometry" in warning and "camera " in warning and " near (" in warning
    assert figures.colours.blue.margin > 40 and not [w for w in figures.warnings if w.startswith("blue:")]


def test_no_pointer_in_view_teaches_nothing():
    rig, renderer = room()
    rng = np.random.default_rng(1)
    learner = ColourLearner(rig, renderer.cameras)
    for _ in range(3):
        learner.feed(
            [(cam.camera_id, renderer.render(i, None, rng).image, "BayerRG8") for i, cam in enumerate(renderer.cameras)]
        )
    with pytest.raises(CalibrationError, match="not located well in any of 3 pair"):
        learner.result("2026-12-02")


def test_an_end_too_grey_to_be_told_by_colour_is_named_when_nothing_is_learned():
    """A blue end painted nearly grey is never located, and waving longer does not help: the refusal names
    the end the locator missed (the commonest reason), and what would help."""
    grey_blue = Look(red_rgb=DIM.red_rgb, blue_rgb=(0.07, 0.07, 0.08), gain=DIM.gain)
    rig, renderer = room(grey_blue, noise_sigma=2.0, shot_noise=0.3)
    with pytest.raises(CalibrationError) as refused:
        _learn(rig, renderer, content=BLANK, count=3)
    text = str(refused.value)
    assert "not located well in any of 3 pair(s)" in text
    most = text.split("most often (3 of 3): ", 1)[1]
    assert most.startswith("no blue ball seen"), text
    assert "a brighter paint" in most


def _trackerd(*args, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "trackerd", *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=300
    )


def test_the_command_learns_from_files_writes_the_calibration_and_the_rig_file_overrides(tmp_path: Path):
    rig, renderer = room(DIM, noise_sigma=2.0, shot_noise=0.3)
    rng = np.random.default_rng(2)
    for k, pose in enumerate(waved(6)):
        for index, cam in enumerate(renderer.cameras):
            save_frame(
                tmp_path / "waving", f"{k:02d}-{cam.camera_id}", renderer.render(index, pose, rng).image, "BayerRG8"
            )
    rig_text = dump_rig(rig.model_copy(update={"calibration": Path("cal.toml")}))
    (tmp_path / "rig.toml").write_text(rig_text)
    run = _trackerd("calibrate", "pointer", "--config", "rig.toml", "--pairs", "waving", "--json", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    result = json.loads(run.stdout)
    assert result["used"] == 6 and result["written"].endswith("cal.toml")
    written = tomllib.loads((tmp_path / "cal.toml").read_text())["pointer_colours"]
    assert written == result["pointer_colours"]
    # The daemon's rig takes the learned thresholds...
    loaded = load_rig(tmp_path / "rig.toml").config
    assert loaded.detector.red.min_excess == written["red"]["min_excess"] < 70
    assert loaded.detector.blue.min_excess == written["blue"]["min_excess"] < 60
    assert loaded.pointer_colours is not None and loaded.pointer_colours.frames == 6
    # ... except where the rig file gives its own, which stays an override; the report says so, and the
    # threshold it was run with is the one in force (the learned one), not the default.
    (tmp_path / "rig.toml").write_text(rig_text + "\n[detector.red]\nmin_excess = 90\n")
    loaded = load_rig(tmp_path / "rig.toml")
    assert loaded.config.detector.red.min_excess == 90
    assert loaded.config.detector.blue.min_excess == written["blue"]["min_excess"]
    assert loaded.threshold_sources == {"red": "rig file", "blue": "learned"}
    run = _trackerd(
        "calibrate", "pointer", "--config", "rig.toml", "--pairs", "waving", "--dry-run", "--json", cwd=tmp_path
    )
    assert run.returncode == 0, run.stderr
    again = json.loads(run.stdout)
    assert any("the rig file sets [detector.red], which stays in force" in note for note in again["notes"])
    assert "dry run: nothing written" in again["notes"]
    assert again["thresholds_before"] == {"red": 90, "blue": written["blue"]["min_excess"]}
    # Written again, the file keeps the access it was given (the daemon's group reads it).
    (tmp_path / "cal.toml").chmod(0o640)
    run = _trackerd("calibrate", "pointer", "--config", "rig.toml", "--pairs", "waving", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "cal.toml").stat().st_mode & 0o777 == 0o640
    assert len(list(tmp_path.glob("cal.toml.bak-*"))) == 1
    # Frames without the pointer: one clear line, exit 1, the calibration file untouched.
    before = (tmp_path / "cal.toml").read_bytes()
    for index, cam in enumerate(renderer.cameras):
        save_frame(tmp_path / "empty", f"00-{cam.camera_id}", renderer.render(index, None, rng).image, "BayerRG8")
    run = _trackerd("calibrate", "pointer", "--config", "rig.toml", "--pairs", "empty", cwd=tmp_path)
    assert run.returncode == 1 and "Traceback" not in run.stderr
    assert "the pointer was not located well in any of 1 pair(s)" in run.stderr
    assert (tmp_path / "cal.toml").read_bytes() == before
    # Refused before anything is read: options of --live with --pairs, a folder that is not there for
    # --output (never created), [pointer_colours] in the rig file itself.
    for args, says in (
        (("--pairs", "waving", "--frames", "5"), "--frames: only with --live or --recording"),
        (("--pairs", "waving", "--output", "no/such/cal.toml"), "no such folder; not written"),
    ):
        run = _trackerd("calibrate", "pointer", "--config", "rig.toml", *args, cwd=tmp_path)
        assert run.returncode == 1 and "Traceback" not in run.stderr and says in run.stderr, run.stderr
    assert not (tmp_path / "no").exists()
    # A rig that names no calibration file, without --output: refused before a pair is read (it said so
    # only once every pair was learnt from; live, after the pointer had been waved for nothing).
    (tmp_path / "nameless.toml").write_text(dump_rig(rig))
    run = _trackerd("calibrate", "pointer", "--config", "nameless.toml", "--pairs", "waving", cwd=tmp_path)
    assert run.returncode == 1 and "the rig names no calibration file" in run.stderr, run.stderr
    assert "waving:" not in run.stdout + run.stderr  # the folder was never read
    inline = tmp_path / "inline.toml"
    colours = (tmp_path / "cal.toml").read_text().split("[pointer_colours]", 1)[1]
    inline.write_text(rig_text + "\n[pointer_colours]" + colours)
    run = _trackerd("calibrate", "pointer", "--config", inline, "--live", "--source", "simulated", cwd=tmp_path)
    assert run.returncode == 1 and "the rig file gives [pointer_colours] itself" in run.stderr, run.stderr
    # A hand-edited threshold above what the ball reaches is refused where the file is read.
    edited = (
        (tmp_path / "cal.toml")
        .read_text()
        .replace(f"min_excess = {written['red']['min_excess']}", "min_excess = 250", 1)
    )
    (tmp_path / "cal.toml").write_text(edited)
    run = _trackerd("config", "check", "rig.toml", cwd=tmp_path)
    assert run.returncode == 2 and "would never pass the colour test" in run.stderr, run.stderr
