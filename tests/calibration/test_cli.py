"""`trackerd calibrate` as a real process, on rendered images: a new installation end to end, and bad input."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pytest
from calibration_frames import FrameSet, copy_set

from trackerd.config.loader import load_rig
from trackerd.config.rig_geometry import camera_model
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


def new_workspace(
    folder: Path,
    intrinsics_frames: FrameSet,
    stereo_frames: FrameSet,
    pointing_frames: FrameSet,
    pointer_frames: FrameSet,
) -> Path:
    """A new installation's folder: the blank rig and every step's rendered input."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "rig.toml").write_text(blank_rig_text())
    for cam in ("left", "right"):
        copy_set(
            intrinsics_frames,
            folder / f"intrinsics-{cam}",
            [n for n in intrinsics_frames.names() if n.startswith(f"{cam}-")],
        )
    copy_set(stereo_frames, folder / "pairs")
    copy_set(pointing_frames, folder / "pointing")
    copy_set(pointer_frames, folder / "waving")
    return folder


@pytest.fixture
def workspace(
    tmp_path: Path,
    intrinsics_frames: FrameSet,
    stereo_frames: FrameSet,
    pointing_frames: FrameSet,
    pointer_frames: FrameSet,
) -> Path:
    return new_workspace(tmp_path, intrinsics_frames, stereo_frames, pointing_frames, pointer_frames)


INTRINSICS = ("calibrate", "intrinsics", "--config", "rig.toml", "--camera")
"""`trackerd calibrate intrinsics` on the workspace's rig, up to the camera id."""


def images(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder.parent)) for p in folder.glob("*.png"))


def calibrate_intrinsics(workspace: Path, cam: str) -> subprocess.CompletedProcess[str]:
    """`trackerd calibrate intrinsics` for one camera from its images in the workspace; it must succeed."""
    run = trackerd(
        *INTRINSICS, cam, "--board", "chessboard:10x7:60", *images(workspace / f"intrinsics-{cam}"), cwd=workspace
    )
    assert run.returncode == 0, run.stderr
    return run


@dataclass(frozen=True)
class Calibrated:
    """A new installation's folder after `calibrate intrinsics`, made once for the module (each run
    takes seconds); a test that uses it works in its own copy."""

    folder: Path
    runs: dict[str, subprocess.CompletedProcess[str]]
    """The intrinsics runs that made it, by camera, in order."""

    def copy_to(self, destination: Path) -> Path:
        shutil.copytree(self.folder, destination, dirs_exist_ok=True)
        return destination


@pytest.fixture(scope="module")
def left_lens(
    tmp_path_factory: pytest.TempPathFactory,
    intrinsics_frames: FrameSet,
    stereo_frames: FrameSet,
    pointing_frames: FrameSet,
    pointer_frames: FrameSet,
) -> Calibrated:
    """The left camera's intrinsics written (the first calibration step of a new installation)."""
    folder = new_workspace(
        tmp_path_factory.mktemp("left-lens"), intrinsics_frames, stereo_frames, pointing_frames, pointer_frames
    )
    return Calibrated(folder, {"left": calibrate_intrinsics(folder, "left")})


@pytest.fixture(scope="module")
def both_lenses(left_lens: Calibrated, tmp_path_factory: pytest.TempPathFactory) -> Calibrated:
    """Then the right camera's too (its run keeps the left-only calibration as a backup)."""
    folder = left_lens.copy_to(tmp_path_factory.mktemp("both-lenses"))
    return Calibrated(folder, {**left_lens.runs, "right": calibrate_intrinsics(folder, "right")})


def test_a_new_installation_end_to_end(both_lenses: Calibrated, tmp_path: Path) -> None:
    """intrinsics (both cameras), stereo, wall by pointing, then `config check` and `calibrate check`."""
    workspace = both_lenses.copy_to(tmp_path)
    calibration = workspace / "new-wall-calibration.toml"
    for cam, run in both_lenses.runs.items():
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
    # The file written passes config check, which says the rig cannot track yet and which step comes next
    # (not that the wall is wrong); --ready, as a reload script uses it, fails it.
    run = trackerd("config", "check", "rig.toml", cwd=workspace)
    assert run.returncode == 0 and "behind the wall" not in run.stdout, run.stderr
    assert run.stdout.startswith("rig.toml: OK for calibration; not ready to track yet: ")
    assert "camera left's frame" in run.stdout and "next: `trackerd calibrate wall --config rig.toml`" in run.stdout
    run = trackerd("config", "check", "--ready", "rig.toml", cwd=workspace)
    assert run.returncode == 2 and "next: `trackerd calibrate wall --config rig.toml`" in run.stderr

    # The same pairs as a recording (imported, as an operator would record the board): the same stereo result.
    run = trackerd("recording", "import", "--config", "rig.toml", "pairs", "board.trec", cwd=workspace)
    assert run.returncode == 0, run.stderr
    # A dry run from it writes nothing at all: no calibration file, no snapshots.
    before = calibration.read_bytes()
    run = trackerd(
        "calibrate",
        "stereo",
        "--config",
        "rig.toml",
        "--board",
        "chessboard:10x7:100",
        "--recording",
        "board.trec",
        "--dry-run",
        cwd=workspace,
    )
    assert run.returncode == 0, run.stderr
    assert calibration.read_bytes() == before and not (workspace / "calibration-snapshots").exists()
    run = trackerd(
        "calibrate",
        "stereo",
        "--config",
        "rig.toml",
        "--board",
        "chessboard:10x7:100",
        "--recording",
        "board.trec",
        "--json",
        cwd=workspace,
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
    truth = [camera_model(c) for c in load_rig(SIMULATED).config.cameras]
    recovered = [camera_model(c) for c in load_rig(workspace / "rig.toml").config.cameras]
    for true_cam, cam in zip(truth, recovered, strict=True):
        assert np.linalg.norm(cam.centre_m - true_cam.centre_m) < 0.03
        assert rotation_angle_deg(cam.rotation @ true_cam.rotation.T) < 0.5

    run = trackerd("calibrate", "check", "--config", "rig.toml", "--pairs", "waving", "--json", cwd=workspace)
    assert run.returncode == 0, run.stdout + run.stderr
    figures = json.loads(run.stdout)
    assert figures["fixes"] >= 10 and not figures["suspect"]
    assert figures["ray_gap_mm"]["p50"] < 3.0
    assert len(list(workspace.glob("new-wall-calibration.toml.bak-*"))) == 4  # one per step that wrote
    # Images without the pointer are no evidence either way: a failure, not a pass.
    run = trackerd("calibrate", "check", "--config", "rig.toml", "--pairs", "pairs", cwd=workspace)
    one_line_error(run, "no pointer fixes in 10 frame pair(s): nothing to check the calibration against")


@pytest.fixture
def calibrated(left_lens: Calibrated, tmp_path: Path) -> Path:
    """A workspace with the left camera's intrinsics already written."""
    return left_lens.copy_to(tmp_path)


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
    base = (*INTRINSICS, "left")

    # No board in any image: pointer scenes. Nothing says the size is wrong.
    run = trackerd(*base, "--board", "chessboard:10x7:60", *images(ws / "waving")[:6], cwd=ws)
    line = one_line_error(
        run,
        "no usable view of the board in 6 image(s)",
        "no detector found 9 x 6 inner corners",
        "nor a neighbouring size",
        "in view, lit and in focus",
    )
    assert "--board" not in line
    # The board is there, but described wrongly (inner corners instead of squares): the size it has is named.
    run = trackerd(*base, "--board", "chessboard:9x6:60", *images(ws / "intrinsics-left")[:3], cwd=ws)
    one_line_error(run, "none shows 8 x 5 inner corners", "shows 9 x 6", "give --board chessboard:10x7:60")
    # Too few views.
    run = trackerd(*base, "--board", "chessboard:10x7:60", *images(ws / "intrinsics-left")[:4], cwd=ws)
    one_line_error(run, "too few usable views: 4, need at least 8")
    # An image of another size.
    small = ws / "small.png"
    image = cv2.imread(str(ws / images(ws / "intrinsics-left")[0]), cv2.IMREAD_UNCHANGED)
    assert cv2.imwrite(str(small), cv2.resize(image, (960, 540)))
    unchanged = _unchanged(ws)
    run = trackerd(*base, "--board", "chessboard:10x7:60", *images(ws / "intrinsics-left"), "small.png", cwd=ws)
    one_line_error(run, "small.png: image is 960x540 but camera 'left' is configured for 1920x1080")
    # An unknown camera, and a recording that is not there.
    run = trackerd(*INTRINSICS, "middle", "--board", "chessboard:10x7:60", "x.png", cwd=ws)
    one_line_error(run, "no camera 'middle' in the rig; it has left, right")
    run = trackerd(*base, "--board", "chessboard:10x7:60", "--recording", "session.trec", cwd=ws)
    one_line_error(run, "session.trec: no such recording")
    unchanged()


def test_pairs_out_of_sync_and_incomplete_pairs_are_refused(both_lenses: Calibrated, tmp_path: Path) -> None:
    ws = both_lenses.copy_to(tmp_path)
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


def test_bad_board_spec_is_an_argument_error(tmp_path: Path) -> None:
    (tmp_path / "rig.toml").write_text(blank_rig_text())
    run = trackerd(
        "calibrate", "intrinsics", "--config", "rig.toml", "--camera", "left", "--board", "10x7", "a.png", cwd=tmp_path
    )
    assert run.returncode == 2
    assert "expected chessboard:COLSxROWS:SQUARE_MM" in run.stderr.splitlines()[-1]


def test_dry_run_reports_and_writes_nothing(tmp_path: Path, intrinsics_frames: FrameSet) -> None:
    workspace = tmp_path
    (workspace / "rig.toml").write_text(blank_rig_text())
    right = [n for n in intrinsics_frames.names() if n.startswith("right-")]
    copy_set(intrinsics_frames, workspace / "intrinsics-right", right)
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


def simulated_rig_with_calibration_file(folder: Path) -> Path:
    """config/simulated.toml (cameras and wall inline, so every step can run) naming cal.toml."""
    rig = folder / "rig.toml"
    rig.write_text(
        SIMULATED.read_text().replace('name = "simulated-datawall"', 'name = "sim"\ncalibration = "cal.toml"')
    )
    return rig


def test_a_wall_fit_above_max_rms_mm_is_not_written_and_names_the_points_that_are_off(
    tmp_path: Path, pointing_frames: FrameSet
) -> None:
    rig = simulated_rig_with_calibration_file(tmp_path)
    copy_set(pointing_frames, tmp_path / "pointing")
    # Every image filed under the next target (the operator aimed at 'br' when asked for 'bl', ...).
    labels = ["bl", "bottom", "br", "right", "tr", "top", "tl", "left"]
    shifted = tmp_path / "shifted"
    for label, wrong in zip(labels, labels[1:] + labels[:1], strict=True):
        copy_set(
            pointing_frames,
            shifted,
            [f"{label}-1", f"{label}-2"],
            rename=lambda name, a=label, b=wrong: name.replace(f"{a}-", f"{b}-", 1),
        )
    (tmp_path / "cal.toml").write_text("version = 1\n")
    before = (tmp_path / "cal.toml").read_bytes()
    run = trackerd("calibrate", "wall", "--config", rig, "--point", "--pairs", "shifted", cwd=tmp_path)
    error = one_line_error(run, "exceeds --max-rms-mm 10.0 mm: not written", "off by more than the limit: pointing ")
    assert "wall: RMS residual" in run.stdout  # the report is shown, so the operator sees every residual
    assert (tmp_path / "cal.toml").read_bytes() == before and not list(tmp_path.glob("cal.toml.bak-*"))
    assert sum(f"pointing {label} " in error for label in labels) >= 4
    # The correctly labelled images give a few millimetres and are written.
    run = trackerd("calibrate", "wall", "--config", rig, "--point", "--pairs", "pointing", "--json", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    report = json.loads(run.stdout)
    assert report["rms_mm"] < 5.0 and report["written"] and (tmp_path / "cal.toml").read_bytes() != before
    # The limit is the operator's to set.
    run = trackerd(
        "calibrate", "wall", "--config", rig, "--point", "--pairs", "pointing", "--max-rms-mm", "0.5", cwd=tmp_path
    )
    one_line_error(run, "exceeds --max-rms-mm 0.5 mm: not written")


def test_live_touch_on_the_simulated_rig_touches_targets_both_cameras_see(tmp_path: Path) -> None:
    """The simulated presenter follows the prompts; the display's corners are out of one camera's
    view, so the step says so and touches the corners and centre of the strip both see instead."""
    rig = simulated_rig_with_calibration_file(tmp_path)
    run = trackerd(
        "calibrate",
        "wall",
        "--config",
        rig,
        "--touch",
        "--live",
        "--source",
        "simulated",
        "--dry-run",
        "--json",
        cwd=tmp_path,
    )
    assert run.returncode == 0, run.stderr
    assert "the default targets are not all in view of both cameras: 'bl': only right sees it;" in run.stderr
    assert "  view-bl      x 1.49 m, y 0.10 m  display pixel (3129, 1710)" in run.stderr
    report = json.loads(run.stdout)
    residuals = {r["label"]: r for r in report["residuals"]}
    assert list(residuals) == ["view-bl", "view-br", "view-tr", "view-tl", "view-centre"]
    # Each capture is where its target is: within millimetres, not shifted to another target.
    assert all(r["in_plane_mm"] < 5.0 and abs(r["plane_mm"]) < 2.0 for r in residuals.values()), residuals
    assert report["rms_mm"] < 3.0 and report["written"] is None and not (tmp_path / "cal.toml").exists()
    assert not (tmp_path / "calibration-snapshots").exists()  # a dry run writes nothing
    # Targets named explicitly that a camera cannot see are refused up front, saying where to touch.
    run = trackerd(
        "calibrate",
        "wall",
        "--config",
        rig,
        "--touch",
        "--live",
        "--source",
        "simulated",
        "--use",
        "bl,centre,tr",
        cwd=tmp_path,
    )
    one_line_error(
        run, "'bl': only right sees it; 'tr': only left sees it", "x 1.49-2.18 m", "--targets FILE", "--point"
    )


def test_live_pointing_on_the_simulated_rig_files_each_capture_under_its_target(tmp_path: Path) -> None:
    """The default plan, in which some of the presenter's first poses cannot be located (the rod
    hides a ball from one camera): those are retried for the same target, never shifted onto the next."""
    rig = simulated_rig_with_calibration_file(tmp_path)
    run = trackerd(
        "calibrate",
        "wall",
        "--config",
        rig,
        "--point",
        "--live",
        "--source",
        "simulated",
        "--dry-run",
        "--json",
        cwd=tmp_path,
    )
    assert run.returncode == 0, run.stderr
    assert "pointer not located" in run.stderr  # there was something to retry
    report = json.loads(run.stdout)
    labels = [r["label"] for r in report["residuals"]]
    assert labels == [label for label in ("bl", "br", "tr", "tl", "centre") for _ in (1, 2)], labels
    assert report["rms_mm"] < 5.0, report
    used = [r for r in report["residuals"] if r["used"]]
    assert len(used) >= 9 and max(r["miss_mm"] for r in used) < 10.0, report


def test_each_step_names_its_own_inputs_and_a_missing_input_file_is_a_bad_input(tmp_path: Path) -> None:
    rig = simulated_rig_with_calibration_file(tmp_path)
    board = ("--board", "chessboard:10x7:100")
    run = trackerd("calibrate", "intrinsics", "--config", rig, "--camera", "left", *board, cwd=tmp_path)
    one_line_error(run, "give the input: IMAGE... files, --live, or --recording R")
    for step in (("stereo", *board), ("wall", "--point"), ("check",)):
        run = trackerd("calibrate", *step, "--config", rig, cwd=tmp_path)
        one_line_error(run, "give the input: --pairs DIR, --live, or --recording R")
    # A file the user names as input is bad input (exit 1) whether it is missing or wrong inside.
    run = trackerd("calibrate", "wall", "--config", rig, "--points", "missing.toml", cwd=tmp_path)
    one_line_error(run, "missing.toml: no such file")
    (tmp_path / "bad.toml").write_text("[wall\n")
    run = trackerd("calibrate", "wall", "--config", rig, "--points", "bad.toml", cwd=tmp_path)
    one_line_error(run, "bad.toml: not valid TOML")
    run = trackerd(
        "calibrate", "wall", "--config", rig, "--touch", "--pairs", ".", "--targets", "missing.toml", cwd=tmp_path
    )
    one_line_error(run, "missing.toml: no such file")
    # The rig itself stays a configuration problem.
    run = trackerd("calibrate", "check", "--config", "missing-rig.toml", "--live", cwd=tmp_path)
    assert run.returncode == 2 and "missing-rig.toml: no such file" in run.stderr


def test_stereo_warns_when_the_baseline_disagrees_with_the_rigs(tmp_path: Path, stereo_frames: FrameSet) -> None:
    """The 100 mm board declared as 60 mm: every length, the baseline too, comes out 40 % short."""
    rig = simulated_rig_with_calibration_file(tmp_path)
    copy_set(stereo_frames, tmp_path / "pairs")
    base = ("calibrate", "stereo", "--config", rig, "--pairs", "pairs", "--dry-run", "--json")
    run = trackerd(*base, "--board", "chessboard:10x7:60", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    report = json.loads(run.stdout)
    assert report["baseline_m"] == pytest.approx(6.2576 * 0.6, abs=0.01)
    [warning] = report["warnings"]
    assert "differs from the rig's 6.2576 m by -40.0 %" in warning and "would be 100.0 mm, not 60 mm" in warning
    assert "WARNING: baseline 3.75" in run.stderr
    run = trackerd(*base, "--board", "chessboard:10x7:100", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["warnings"] == [] and "WARNING" not in run.stderr
