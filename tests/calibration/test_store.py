"""Writing the calibration file: loads back through the loader, atomic, backed up, never half-written."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np
import pytest

from trackerd.calibration import CalibrationError
from trackerd.calibration.store import (
    backup_path,
    open_rig,
    render_calibration,
    require_output,
    with_camera,
    with_wall,
    write_calibration,
)
from trackerd.calibration.update import extrinsics_config
from trackerd.config.loader import load_calibration, load_rig
from trackerd.config.models import CalibrationFile, OpenCVIntrinsics, WallConfig
from trackerd.config.rig_geometry import camera_model
from trackerd.geometry.rotation import rotation_from_rvec

REPO = Path(__file__).resolve().parents[2]

BLANK_RIG = """\
version = 1
name = "new-wall"
calibration = "new-wall-calibration.toml"

[[cameras]]
id = "left"
width_px = 1920
height_px = 1080
pixel_format = "BayerRG8"

[[cameras]]
id = "right"
width_px = 1920
height_px = 1080
pixel_format = "BayerRG8"

[wall]
corners_m = [[0.0, 0.0, 0.0], [3.6576, 0.0, 0.0], [3.6576, 0.9144, 0.0], [0.0, 0.9144, 0.0]]

[pointer]
length_m = 0.45
end_diameter_m = 0.04
"""


def intrinsics(fx: float = 1660.123456789012) -> OpenCVIntrinsics:
    return OpenCVIntrinsics(
        model="opencv",
        fx_px=fx,
        fy_px=1659.9876543210987,
        cx_px=962.5000000000001,
        cy_px=538.0,
        distortion=(-0.0801234567890123, 0.05, 4e-4, -3e-4, 1.2345e-7),
    )


def simulated_poses() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    rig = load_rig(REPO / "config" / "simulated.toml").config
    return {c.id: (m.rotation, m.translation_m) for c in rig.cameras for m in [camera_model(c)]}


@pytest.fixture
def blank_rig(tmp_path: Path) -> Path:
    path = tmp_path / "new-wall.toml"
    path.write_text(BLANK_RIG)
    return path


def complete_calibration() -> CalibrationFile:
    calibration = CalibrationFile()
    for cam_id, (rotation, translation) in simulated_poses().items():
        calibration = with_camera(
            calibration,
            cam_id,
            intrinsics=intrinsics(),
            extrinsics=extrinsics_config(rotation, translation),
            info={"intrinsics_views": 14, "intrinsics_rms_px": 0.0686, "world_frame": "wall"},
        )
    return calibration


def test_open_rig_reads_a_rig_without_geometry_or_calibration_file(blank_rig: Path) -> None:
    context = open_rig(blank_rig)
    assert context.calibration == CalibrationFile()
    assert context.calibration_path == blank_rig.parent / "new-wall-calibration.toml"
    assert not context.calibration_path.exists()
    with pytest.raises(CalibrationError, match="camera 'left' has no intrinsics or extrinsics yet"):
        context.complete()


def test_written_file_loads_through_the_loader_and_round_trips(blank_rig: Path) -> None:
    context = open_rig(blank_rig)
    calibration = complete_calibration()
    assert write_calibration(context, calibration, "test") is None  # nothing to back up yet
    again = load_calibration(context.calibration_path)
    assert again == calibration
    # The rig now loads completely, and each camera is where the calibration put it.
    loaded = load_rig(blank_rig)
    assert loaded.sources["left"] == "from new-wall-calibration.toml"
    model = camera_model(loaded.config.camera("right"))
    rotation, translation = simulated_poses()["right"]
    assert np.allclose(model.rotation, rotation, atol=1e-15)
    assert np.allclose(model.translation_m, translation, atol=1e-15)
    assert model.matrix[0, 0] == intrinsics().fx_px  # bit for bit


def test_rewriting_keeps_a_timestamped_backup(blank_rig: Path) -> None:
    context = open_rig(blank_rig)
    first = complete_calibration()
    write_calibration(context, first, "first")
    original = context.calibration_path.read_text()
    second = with_camera(first, "left", intrinsics=intrinsics(fx=1661.0))
    when = dt.datetime(2026, 11, 22, 14, 3, 5)
    backup = write_calibration(open_rig(blank_rig), second, "second", now=when)
    assert backup == blank_rig.parent / "new-wall-calibration.toml.bak-20261122-140305"
    assert backup.read_text() == original
    assert load_calibration(context.calibration_path).cameras["left"].intrinsics.fx_px == 1661.0
    # A second backup in the same second gets its own name.
    assert backup_path(context.calibration_path, when).name.endswith("bak-20261122-140305-2")
    assert not list(blank_rig.parent.glob(".*.tmp"))


def test_a_calibration_the_loader_would_refuse_is_not_written(blank_rig: Path) -> None:
    context = open_rig(blank_rig)
    write_calibration(context, complete_calibration(), "good")
    before = context.calibration_path.read_bytes()
    outside = intrinsics().model_copy(update={"cx_px": 2500.0})
    bad = with_camera(complete_calibration(), "left", intrinsics=outside.model_dump())
    with pytest.raises(CalibrationError, match=r"not written: .*principal point \(2500.0, 538.0\) lies outside"):
        write_calibration(open_rig(blank_rig), bad, "bad")
    assert context.calibration_path.read_bytes() == before
    assert len(list(blank_rig.parent.iterdir())) == 2  # rig and calibration: no backup, no temp file


def test_a_folding_lens_is_refused_before_writing(blank_rig: Path) -> None:
    context = open_rig(blank_rig)
    folding = intrinsics().model_copy(update={"distortion": (0.9, -5.0, 0.0, 0.0, 0.0)})
    bad = with_camera(complete_calibration(), "right", intrinsics=folding.model_dump())
    with pytest.raises(CalibrationError, match=r"not written: .*folds over near the image edge"):
        write_calibration(context, bad, "bad")
    assert not context.calibration_path.exists()


def test_cameras_behind_the_wall_are_refused_unless_the_wall_is_not_calibrated_yet(blank_rig: Path) -> None:
    # In camera 1's frame the rig's wall (z = 0, facing +z) can put a camera behind it.
    calibration = CalibrationFile()
    poses = {"left": (np.eye(3), np.zeros(3)), "right": (np.eye(3), np.array([-1.0, -1.0, 3.0]))}
    for cam_id, (r, t) in poses.items():
        calibration = with_camera(calibration, cam_id, intrinsics=intrinsics(), extrinsics=extrinsics_config(r, t))
    with pytest.raises(CalibrationError, match="right would be behind the wall"):
        write_calibration(open_rig(blank_rig), calibration, "stereo")
    write_calibration(open_rig(blank_rig), calibration, "stereo", check_wall=False)
    assert load_calibration(open_rig(blank_rig).calibration_path) == calibration


def test_with_camera_merges_info_and_with_wall_replaces_or_removes() -> None:
    calibration = with_camera(CalibrationFile(), "left", intrinsics=intrinsics(), info={"a": 1})
    calibration = with_camera(calibration, "left", info={"b": "two"})
    assert calibration.cameras["left"].info == {"a": 1, "b": "two"}
    assert calibration.cameras["left"].intrinsics == intrinsics()
    wall = WallConfig(corners_m=((0, 0, 0), (2, 0, 0), (2, 1, 0), (0, 1, 0)))
    assert with_wall(calibration, wall).wall == wall
    assert with_wall(with_wall(calibration, wall), None).wall is None


def test_render_calibration_writes_readable_toml() -> None:
    text = render_calibration(complete_calibration(), "trackerd calibrate intrinsics --camera left")
    assert text.startswith("# trackerd calibrate intrinsics --camera left\n")
    assert "[cameras.left.intrinsics]" in text
    rvec = [float(v) for v in text.split("rvec = [")[1].split("]")[0].split(",")]
    assert np.allclose(rotation_from_rvec(np.array(rvec)), simulated_poses()["left"][0], atol=1e-15)


def test_a_rig_without_a_calibration_file_needs_output(tmp_path: Path) -> None:
    path = tmp_path / "rig.toml"
    path.write_text(BLANK_RIG.replace('calibration = "new-wall-calibration.toml"\n', ""))
    with pytest.raises(CalibrationError, match=r"names no calibration file; add calibration = .* or pass --output"):
        require_output(open_rig(path))
    assert require_output(open_rig(path, tmp_path / "out.toml")) == tmp_path / "out.toml"


def test_a_folder_that_cannot_be_written_is_one_error_and_the_old_file_stays(tmp_path: Path) -> None:
    """Found by a new user's audit: on a read-only file system the temporary file's creation, outside the
    write's error handling, escaped as an OSError (a traceback, the calibration's result lost without a word)."""
    import os
    import subprocess

    if os.geteuid() != 0:
        pytest.skip("mounting a read-only filesystem needs root")
    mount = tmp_path / "ro"
    mount.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mount)], check=True)
    try:
        rig = mount / "new-wall.toml"
        rig.write_text(BLANK_RIG)
        write_calibration(open_rig(rig), complete_calibration(), "first")
        before = (mount / "new-wall-calibration.toml").read_bytes()
        subprocess.run(["mount", "-o", "remount,ro", str(mount)], check=True)
        second = with_camera(complete_calibration(), "left", intrinsics=intrinsics(fx=1661.0).model_dump())
        with pytest.raises(CalibrationError, match=r"new-wall-calibration.toml: cannot write the calibration file: "):
            write_calibration(open_rig(rig), second, "second")
        assert (mount / "new-wall-calibration.toml").read_bytes() == before
    finally:
        subprocess.run(["umount", "-l", str(mount)], check=False)
