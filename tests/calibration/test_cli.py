"""`trackerd calibrate` as a real process, on rendered images: a new installation end to end, and bad input."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import cv2
import numpy as np
import pytest
from calibration_frames import FrameSet, copy_set

from trackerd.config.loader import load_rig
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.rotation import rotation_angle_deg

REPO = Path(__file__).resolve().parents[2]
SIMULATED = REPO / "config" / "simulated.toml"


def trackerd(*args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "trackerd", *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=300
    )


def one_line_error(run: subprocess.CompletedProcess[str], *fragments: str) -> str:
    assert run.returncode == 1, run
    assert "Traceback" not in run.stderr
    errors = [line for line in run.stderr.splitlines() if line.startswith("trackerd calibrate:")]
    assert len(errors) == 1, run.stderr
    for fragment in fragments:
        assert fragment in errors[0], errors[0]
    return errors[0]


def blank_rig_text() -> str:
    """The simulated rig as a new installation: no intrinsics or extrinsics, a calibration file named."""
    lines = [line for line in SIMULATED.read_text().splitlines() if not line.startswith(("intrinsics", "extrinsics"))]
    text = "\n".join(lines) + "\n"
    return text.replace('name = "simulated-datawall"', 'name = "new-wall"\ncalibration = "new-wall-calibration.toml"')


@pytest.fixture
def workspace(
    tmp_path: Path,
    intrinsics_frames: FrameSet,
    stereo_frames: FrameSet,
    pointing_frames: FrameSet,
    pointer_frames: FrameSet,
) -> Path:
    (tmp_path / "rig.toml").write_text(blank_rig_text())
    for cam in ("left", "right"):
        copy_set(
            intrinsics_frames,
            tmp_path / f"intrinsics-{cam}",
            [n for n in intrinsics_frames.names() if n.startswith(f"{cam}-")],
        )
    copy_set(stereo_frames, tmp_path / "pairs")
    copy_set(pointing_frames, tmp_path / "pointing")
    copy_set(pointer_frames, tmp_path / "waving")
    return tmp_path


def images(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder.parent)) for p in folder.glob("*.png"))


def test_a_new_installation_end_to_end(workspace: Path) -> None:
    """intrinsics (both cameras), stereo, wall by pointing, then `config check` and `calibrate check`."""
    calibration = workspace / "new-wall-calibration.toml"
    for cam in ("left", "right"):
        run = trackerd(
            "calibrate",
            "intrinsics",
            "--config",
            "rig.toml",
            "--camera",
            cam,
            "--board",
            "chessboard:10x7:60",
            *images(workspace / f"intrinsics-{cam}"),
            cwd=workspace,
        )
        assert run.returncode == 0, run.stderr
        assert f"camera {cam}: RMS reprojection error 0.0" in run.stdout
        assert "image coverage" in run.stdout and "written:" in run.stdout
    info = tomllib.loads(calibration.read_text())["cameras"]["left"]["info"]
    assert info["intrinsics_board"] == "chessboard:10x7:60" and info["intrinsics_views"] >= 12
    assert info["intrinsics_rms_px"] < 0.15 and "intrinsics_date" in info
    assert len(list(workspace.glob("new-wall-calibration.toml.bak-*"))) == 1

    run = trackerd(
        "calibrate",
        "stereo",
        "--config",
        "rig.toml",
        "--board",
        "chessboard:10x7:100",
        "--pairs",
        "pairs",
        "--json",
        cwd=workspace,
    )
    assert run.returncode == 0, run.stderr
    stereo = json.loads(run.stdout)
    assert stereo["world_frame"] == "camera left"
    assert abs(stereo["baseline_m"] - 6.2576) < 0.002
    assert stereo["epipolar_rms_px"] < 0.2 and len(stereo["pairs"]) >= 8
    assert not [r for r in stereo["rejected"] if "sync" in r["reason"]]
    assert "next: `trackerd calibrate wall`" in run.stderr

    # The same pairs as a recording (imported, as an operator would record the board): the same stereo result.
    run = trackerd("recording", "import", "--config", "rig.toml", "pairs", "board.trec", cwd=workspace)
    assert run.returncode == 0, run.stderr
    run = trackerd(
        "calibrate", "stereo", "--config", "rig.toml", "--board", "chessboard:10x7:100",
        "--recording", "board.trec", "--json", cwd=workspace,
    )
    assert run.returncode == 0, run.stderr
    from_recording = json.loads(run.stdout)
    assert abs(from_recording["baseline_m"] - stereo["baseline_m"]) < 0.001
    assert from_recording["epipolar_rms_px"] < 0.2 and len(from_recording["pairs"]) >= 8

    run = trackerd("calibrate", "wall", "--config", "rig.toml", "--point", "--pairs", "pointing", cwd=workspace)
    assert run.returncode == 0, run.stderr
    assert "(as configured); the targets imply 3.6" in run.stdout and "world frame: the wall frame" in run.stdout

    run = trackerd("config", "check", "rig.toml", cwd=workspace)
    assert run.returncode == 0, run.stderr
    assert "geometry from new-wall-calibration.toml" in run.stdout

    # The recovered cameras are where the true ones are, in the true wall frame.
    truth = [CameraModel.from_config(c) for c in load_rig(SIMULATED).config.cameras]
    recovered = [CameraModel.from_config(c) for c in load_rig(workspace / "rig.toml").config.cameras]
    for true_cam, cam in zip(truth, recovered, strict=True):
        assert np.linalg.norm(cam.centre_m - true_cam.centre_m) < 0.03
        assert rotation_angle_deg(cam.rotation @ true_cam.rotation.T) < 0.5

    run = trackerd("calibrate", "check", "--config", "rig.toml", "--pairs", "waving", "--json", cwd=workspace)
    assert run.returncode == 0, run.stdout + run.stderr
    figures = json.loads(run.stdout)
    assert figures["fixes"] >= 10 and not figures["suspect"]
    assert figures["ray_gap_mm"]["p50"] < 3.0
    assert len(list(workspace.glob("new-wall-calibration.toml.bak-*"))) == 4  # one per step that wrote


@pytest.fixture
def calibrated(workspace: Path) -> Path:
    """The workspace with the left camera's intrinsics already written."""
    run = trackerd(
        "calibrate",
        "intrinsics",
        "--config",
        "rig.toml",
        "--camera",
        "left",
        "--board",
        "chessboard:10x7:60",
        *images(workspace / "intrinsics-left"),
        cwd=workspace,
    )
    assert run.returncode == 0, run.stderr
    return workspace


def _unchanged(workspace: Path):
    calibration = workspace / "new-wall-calibration.toml"
    before = calibration.read_bytes()
    files = sorted(p.name for p in workspace.iterdir())

    def check() -> None:
        assert calibration.read_bytes() == before
        assert sorted(p.name for p in workspace.iterdir()) == files

    return check


def test_bad_input_gives_one_clear_line_and_overwrites_nothing(calibrated: Path) -> None:
    ws = calibrated
    unchanged = _unchanged(ws)
    base = ("calibrate", "intrinsics", "--config", "rig.toml", "--camera", "left")

    # No board in any image: pointer scenes.
    run = trackerd(*base, "--board", "chessboard:10x7:60", *images(ws / "waving")[:6], cwd=ws)
    one_line_error(run, "no usable view of the board in 6 image(s)", "no board found in any", "counts squares")
    # The board is there, but described wrongly (inner corners instead of squares).
    run = trackerd(*base, "--board", "chessboard:9x6:60", *images(ws / "intrinsics-left")[:3], cwd=ws)
    one_line_error(run, "no board found in any")
    # Too few views.
    run = trackerd(*base, "--board", "chessboard:10x7:60", *images(ws / "intrinsics-left")[:4], cwd=ws)
    one_line_error(run, "too few usable views: 4, need at least 8")
    # An image of another size.
    small = ws / "small.png"
    image = cv2.imread(
        images(ws / "intrinsics-left")[0] and str(ws / images(ws / "intrinsics-left")[0]), cv2.IMREAD_UNCHANGED
    )
    assert cv2.imwrite(str(small), cv2.resize(image, (960, 540)))
    unchanged = _unchanged(ws)
    run = trackerd(*base, "--board", "chessboard:10x7:60", *images(ws / "intrinsics-left"), "small.png", cwd=ws)
    one_line_error(run, "small.png: image is 960x540 but camera 'left' is configured for 1920x1080")
    # An unknown camera, and a recording that is not there.
    run = trackerd(
        "calibrate",
        "intrinsics",
        "--config",
        "rig.toml",
        "--camera",
        "middle",
        "--board",
        "chessboard:10x7:60",
        "x.png",
        cwd=ws,
    )
    one_line_error(run, "no camera 'middle' in the rig; it has left, right")
    run = trackerd(*base, "--board", "chessboard:10x7:60", "--recording", "session.trec", cwd=ws)
    one_line_error(run, "session.trec: no such recording")
    unchanged()


def test_pairs_out_of_sync_and_incomplete_pairs_are_refused(calibrated: Path) -> None:
    ws = calibrated
    run = trackerd(
        "calibrate",
        "intrinsics",
        "--config",
        "rig.toml",
        "--camera",
        "right",
        "--board",
        "chessboard:10x7:60",
        *images(ws / "intrinsics-right"),
        cwd=ws,
    )
    assert run.returncode == 0
    stereo = ("calibrate", "stereo", "--config", "rig.toml", "--board", "chessboard:10x7:100")
    # Every right image belongs to the next pair: the cameras were not triggered together.
    shifted = ws / "shifted"
    shifted.mkdir()
    names = sorted(p.stem.rsplit("-", 1)[0] for p in (ws / "pairs").glob("*-left.png"))
    for k, name in enumerate(names):
        shutil.copy(ws / "pairs" / f"{name}-left.png", shifted / f"{name}-left.png")
        shutil.copy(ws / "pairs" / f"{names[(k + 1) % len(names)]}-right.png", shifted / f"{name}-right.png")
    unchanged = _unchanged(ws)
    run = trackerd(*stereo, "--pairs", "shifted", cwd=ws)
    one_line_error(run, "pairs out of sync", "same instant")
    # A moment with only one camera's image.
    (shifted / f"{names[3]}-right.png").unlink()
    run = trackerd(*stereo, "--pairs", "shifted", cwd=ws)
    one_line_error(run, f"'{names[3]}' has {names[3]}-left.png but no image from right")
    # A symmetric chessboard cannot be numbered alike by both cameras.
    run = trackerd(
        "calibrate", "stereo", "--config", "rig.toml", "--board", "chessboard:9x7:100", "--pairs", "pairs", cwd=ws
    )
    one_line_error(run, "looks the same turned by 180 degrees")
    unchanged()


def test_bad_board_spec_is_an_argument_error(workspace: Path) -> None:
    run = trackerd(
        "calibrate", "intrinsics", "--config", "rig.toml", "--camera", "left", "--board", "10x7", "a.png", cwd=workspace
    )
    assert run.returncode == 2
    assert "expected chessboard:COLSxROWS:SQUARE_MM" in run.stderr.splitlines()[-1]


def test_dry_run_reports_and_writes_nothing(workspace: Path) -> None:
    run = trackerd(
        "calibrate",
        "intrinsics",
        "--config",
        "rig.toml",
        "--camera",
        "right",
        "--board",
        "chessboard:10x7:60",
        "--dry-run",
        "--json",
        *images(workspace / "intrinsics-right"),
        cwd=workspace,
    )
    assert run.returncode == 0, run.stderr
    report = json.loads(run.stdout)
    assert report["written"] is None and report["rms_px"] < 0.15
    assert len(report["views"]) >= 12 and report["coverage"]["fraction"] > 0.8
    assert "dry run: nothing written" in run.stderr
    assert not (workspace / "new-wall-calibration.toml").exists()


def test_wall_from_measured_points_the_reports_way(tmp_path: Path) -> None:
    rig = tmp_path / "rig.toml"
    rig.write_text(
        SIMULATED.read_text().replace('name = "simulated-datawall"', 'name = "sim"\ncalibration = "cal.toml"')
    )
    measured = tmp_path / "wall.toml"
    # Four points measured on the wall plane z = 0 (one 1.5 mm off), and the display's frame.
    measured.write_text(
        "[wall]\npoints_m = [[0.2, 0.1, 0.0], [3.4, 0.1, 0.0015], [3.4, 0.8, 0.0], [0.2, 0.8, 0.0]]\n"
        "origin_m = [0.0, 0.0, 0.0]\nx_direction = [1.0, 0.0, 0.0]\ny_direction = [0.0, 1.0, 0.0]\n"
        "width_m = 3.6576\nheight_m = 0.9144\ndisplay_width_px = 7680\ndisplay_height_px = 1920\n"
    )
    run = trackerd("calibrate", "wall", "--config", rig, "--points", measured, cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert "wall from 4 measured points" in run.stdout
    run = trackerd("calibrate", "wall", "--config", rig, "--points", measured, "--json", cwd=tmp_path)
    residuals = json.loads(run.stdout)["residuals_mm"]
    # One point 1.5 mm off the plane of the other three: each is 0.375 mm from the best fit.
    assert [abs(r) for r in residuals] == pytest.approx([0.375] * 4, abs=0.005)
    assert np.sign(residuals).tolist() in ([-1, 1, -1, 1], [1, -1, 1, -1])
    loaded = load_rig(rig)
    assert loaded.sources["wall"] == "from cal.toml"
    bad = tmp_path / "bad.toml"
    bad.write_text("[wall]\npoints_m = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]\n")
    run = trackerd("calibrate", "wall", "--config", rig, "--points", bad, cwd=tmp_path)
    one_line_error(run, "bad.toml: wall: points_m needs three or more points")


def test_live_check_on_the_simulated_source(tmp_path: Path) -> None:
    """--live drives the same session code on a PairSource; here the simulator renders the frames."""
    rig = tmp_path / "rig.toml"
    rig.write_text(SIMULATED.read_text())
    run = trackerd(
        "calibrate", "check", "--config", rig, "--live", "--source", "simulated", "--fixes", "6", "--json", cwd=tmp_path
    )
    assert run.returncode == 0, run.stderr
    figures = json.loads(run.stdout)
    assert figures["fixes"] >= 6
    assert "wave the pointer around" in run.stderr
