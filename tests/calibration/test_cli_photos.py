"""An operator with a folder of real photos: `trackerd calibrate intrinsics` and `stereo` as a new user
runs them, on OpenCV's stereo sample photos (grey JPEGs named left01.jpg / right01.jpg) from Mono8
cameras, as photographed and under glare, against plain OpenCV on the same photos."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.calibration.test_cli import INTRINSICS, one_line_error, trackerd
from tests.calibration.test_real_photos import RMS_MARGIN, _photos, _plain_opencv, _plain_stereo

REPO = Path(__file__).resolve().parents[2]
PHOTOS = REPO / "tests" / "data" / "opencv-stereo-chessboard"
BOARD = ("--board", "chessboard:10x7:25")
STEREO = ("calibrate", "stereo", "--config", "rig.toml")


def _mono_rig(workspace: Path) -> None:
    """A new installation's rig as an operator writes it before calibrating: two 640x480 Mono8
    cameras and the calibration file to write, nothing else (no lens, pose, wall or pointer yet)."""
    cameras = "".join(
        f'\n[[cameras]]\nid = "{side}"\nwidth_px = 640\nheight_px = 480\npixel_format = "Mono8"\n'
        for side in ("left", "right")
    )
    (workspace / "rig.toml").write_text(
        f'version = 1\nname = "photos"\ncalibration = "photos-calibration.toml"\n{cameras}'
    )


def photo_workspace(workspace: Path) -> Path:
    """The rig above and the photos as they come, in ``photos/``; returns the workspace."""
    _mono_rig(workspace)
    shutil.copytree(PHOTOS, workspace / "photos")
    return workspace


@pytest.mark.parametrize("variant", ["as photographed", "veiling glare"])
def test_a_folder_of_photos_calibrates_as_well_as_plain_opencv(variant: str, tmp_path: Path) -> None:
    photos = _photos(variant)
    folder = tmp_path / "photos"
    folder.mkdir()
    for side in ("left", "right"):
        for name, image in photos[side]:
            assert cv2.imwrite(str(folder / f"{side}{name}.png"), image)
    _mono_rig(tmp_path)
    plain = {side: _plain_opencv(photos[side]) for side in ("left", "right")}

    # Intrinsics from the folder: the camera's own photos are taken from it, every one kept.
    for side in ("left", "right"):
        run = trackerd(*INTRINSICS, side, *BOARD, "photos", "--json", cwd=tmp_path)
        assert run.returncode == 0, run.stderr
        assert f"photos: the 13 named for camera {side} of its 26 image(s)" in run.stderr
        report = json.loads(run.stdout)
        assert len(report["views"]) == 13 and not report["rejected"]
        assert all(view["detector"] for view in report["views"])
        assert report["rms_px"] <= RMS_MARGIN * plain[side][1], (side, report["rms_px"], plain[side][1])
        # Under glare the left camera's k3 runs away where no corner was seen (the lens would fold
        # over at the bottom-left corner): the four-term lens is kept, and said so.
        dropped_k3 = "k3 left out (--distortion 4): with it the lens folds over near pixel" in run.stderr
        assert dropped_k3 == (variant == "veiling glare" and side == "left"), run.stderr
        assert len(report["distortion"]) == (4 if dropped_k3 else 5)

    # Stereo from the same folder, paired by the names' camera prefix.
    run = trackerd(*STEREO, *BOARD, "--pairs", "photos", "--json", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert "photos: 13 pair(s), files named <camera><name> (left, right)" in run.stderr
    stereo = json.loads(run.stdout)
    size = photos["left"][0][1].shape[::-1]
    plain_rms = _plain_stereo(plain["left"][0], plain["right"][0], plain["left"][2], plain["right"][2], size)
    assert stereo["rms_px"] <= RMS_MARGIN * plain_rms, (stereo["rms_px"], plain_rms)

    # The same photos in one folder per camera pair alike.
    for side in ("left", "right"):
        (tmp_path / "split" / side).mkdir(parents=True)
        for path in folder.glob(f"{side}*.png"):
            shutil.copy(path, tmp_path / "split" / side / path.name)
    run = trackerd(*STEREO, *BOARD, "--pairs", "split", "--json", "--dry-run", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert "split: 13 pair(s), subfolders left/, right/ (files paired by name)" in run.stderr
    assert json.loads(run.stdout)["rms_px"] == pytest.approx(stereo["rms_px"], abs=1e-6)


def test_a_mono8_rig_calibrates_but_does_not_track_and_snapshots_need_a_live_source(tmp_path: Path) -> None:
    photo_workspace(tmp_path)
    run = trackerd(*INTRINSICS, "left", *BOARD, "--snapshots", "saved", "photos", cwd=tmp_path)
    one_line_error(run, "--snapshots is for --live and --recording", "IMAGE... files are on disk already")
    assert not (tmp_path / "saved").exists()
    # Too few views: refused below the floor, and with --force calibrated with the warning in the JSON.
    few = [f"photos/left0{k}.jpg" for k in (1, 2, 3, 4, 5)]
    run = trackerd(*INTRINSICS, "left", *BOARD, "--min-views", "4", *few, cwd=tmp_path)
    one_line_error(run, "--min-views 4 is under 6", "give --force")
    run = trackerd(
        *INTRINSICS, "left", *BOARD, "--min-views", "4", "--force", "--dry-run", "--json", *few, cwd=tmp_path
    )
    assert run.returncode == 0, run.stderr
    assert any("calibrated from 5 views, fewer than the 8" in w for w in json.loads(run.stdout)["warnings"])
    run = trackerd(*STEREO, *BOARD, "--min-pairs", "2", "--pairs", "photos", cwd=tmp_path)
    one_line_error(run, "--min-pairs 2 is under 3", "cannot be told from the others")
    # The new rig passes config check, which names the first step; tracking would refuse it.
    run = trackerd("config", "check", "rig.toml", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith("rig.toml: OK for calibration; not ready to track yet: calibration: ")
    assert "`trackerd calibrate intrinsics --config rig.toml --camera left` writes it" in run.stdout
    run = trackerd("config", "check", "--ready", "rig.toml", cwd=tmp_path)
    assert run.returncode == 2 and "Traceback" not in run.stderr
    # The pointer steps say the same.
    pairs = tmp_path / "pairs"
    pairs.mkdir()
    for side in ("left", "right"):
        image = np.zeros((480, 640), np.uint8)
        assert cv2.imwrite(str(pairs / f"01-{side}.png"), image)
    run = trackerd("calibrate", "check", "--config", "rig.toml", "--pairs", "pairs", cwd=tmp_path)
    one_line_error(run, "camera 'left' is Mono8", "only a colour camera tells apart")


def test_a_wrong_board_size_is_answered_with_the_board_in_the_photos_and_config_check_names_each_next_step(
    tmp_path: Path,
) -> None:
    photo_workspace(tmp_path)
    intrinsics = (*INTRINSICS, "left")
    # Inner corners given as squares, one too many each way, or the long side one too long: OpenCV also
    # finds parts of the board (5 x 8 inside 9 x 6) and grids running onto its margin (9 x 7); the hint
    # names the board itself, the way round it was given.
    for given, shown, board in (("9x6", "9 x 6", "10x7"), ("11x8", "9 x 6", "10x7"), ("6x9", "6 x 9", "7x10")):
        run = trackerd(*intrinsics, "--board", f"chessboard:{given}:25", "photos", "--dry-run", cwd=tmp_path)
        one_line_error(run, f"shows {shown}: give --board chessboard:{board}:25")
    # After the first camera's lens, config check names the second's, not the stereo step.
    assert trackerd(*intrinsics, *BOARD, "photos", cwd=tmp_path).returncode == 0
    run = trackerd("config", "check", "rig.toml", cwd=tmp_path)
    assert run.returncode == 0 and "cameras[1] ('right') has no intrinsics" in run.stdout, run.stdout
    assert "`trackerd calibrate intrinsics --camera right --config rig.toml`" in run.stdout

    # With both lenses, stereo given the wrong board says which board the photos show.
    run = trackerd(*INTRINSICS, "right", *BOARD, "photos", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    run = trackerd(*STEREO, "--board", "chessboard:9x6:25", "--pairs", "photos", "--dry-run", cwd=tmp_path)
    one_line_error(run, "no pair in 13 had the board seen by both cameras", "give --board chessboard:10x7:25")
    # A report run again replaces its own section and pictures.
    for photos in (["photos"], [f"photos/left{k:02d}.jpg" for k in (1, 2, 3, 4, 5, 6, 7, 8, 9)]):
        run = trackerd(*intrinsics, *BOARD, *photos, "--report", "report", "--dry-run", cwd=tmp_path)
        assert run.returncode == 0, run.stderr
    index = (tmp_path / "report" / "index.html").read_text()
    assert index.count("<h2>camera left</h2>") == 1 and "in 9 views" in index
    assert len(list((tmp_path / "report").glob("left-view-*.png"))) == 9
