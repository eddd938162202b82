"""Turning calibration results into the calibration file's entries, and keeping its world frame straight.

World frames (docs/calibration.md, "World frame"):

* ``camera <id>``: camera 1's own frame, as in the report (section 3.1). Stereo
  calibration of a rig whose first camera has no pose yet gives this.
* the rig's frame: when camera 1 already has a pose (in the rig file, or from an
  earlier calibration), stereo calibration keeps camera 1 where it is and places
  camera 2 relative to it, so the frame (and the rig's wall) stays valid.
* ``wall``: origin at the display's bottom-left corner, x along the wall, y up,
  z into the room. The wall step (touches or pointing) re-expresses every camera
  in this frame and writes the wall's corners in it, so the file needs nothing
  else from the rig.

Each camera's ``info`` table records the frame under ``world_frame``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from trackerd.calibration.board import BoardSpec
from trackerd.calibration.intrinsics import IntrinsicsResult
from trackerd.calibration.stereo import StereoResult
from trackerd.calibration.store import WORLD_FRAME_KEY, today, with_camera, with_wall
from trackerd.calibration.wall import WallFit
from trackerd.config.models import (
    CalibrationFile,
    FovIntrinsics,
    OpenCVExtrinsics,
    RigConfig,
    WallConfig,
)
from trackerd.config.rig_geometry import camera_model
from trackerd.geometry.rotation import rvec_from_rotation

Array = NDArray[np.float64]


def extrinsics_config(rotation: Array, translation_m: Array) -> OpenCVExtrinsics:
    """World-to-camera (R, t) as the calibration file stores it (a Rodrigues vector)."""
    rx, ry, rz = (float(v) for v in rvec_from_rotation(rotation))
    tx, ty, tz = (float(v) for v in np.asarray(translation_m).ravel())
    return OpenCVExtrinsics(kind="opencv", rvec=(rx, ry, rz), tvec_m=(tx, ty, tz))


def camera_pose(rig: RigConfig, camera_id: str) -> tuple[Array, Array] | None:
    """A camera's current world-to-camera (R, t) in the (merged) rig, or None if it has no pose."""
    cam = rig.camera(camera_id)
    if cam.extrinsics is None:
        return None
    # CameraModel needs intrinsics to be built; the pose does not depend on them.
    if cam.intrinsics is None:
        cam = cam.model_copy(update={"intrinsics": FovIntrinsics(model="fov", horizontal_fov_deg=60.0)})
    model = camera_model(cam)
    return model.rotation.copy(), model.translation_m.copy()


def apply_intrinsics(
    calibration: CalibrationFile, camera_id: str, result: IntrinsicsResult, spec: BoardSpec, source: str
) -> CalibrationFile:
    """The calibration with one camera's intrinsics replaced, and their provenance in ``info``."""
    info: dict[str, Any] = {
        "intrinsics_date": today(),
        "intrinsics_board": str(spec),
        "intrinsics_views": len(result.view_names),
        "intrinsics_rms_px": round(result.rms_px, 4),
        "intrinsics_coverage": round(result.coverage.fraction, 3),
        "intrinsics_source": source,
    }
    return with_camera(calibration, camera_id, intrinsics=result.to_config(), info=info)


def apply_stereo(
    calibration: CalibrationFile,
    rig: RigConfig,
    camera1: str,
    camera2: str,
    result: StereoResult,
    spec: BoardSpec,
    source: str,
    *,
    keep_frame: bool = True,
) -> tuple[CalibrationFile, str]:
    """The calibration with both cameras' extrinsics from a stereo result; returns (file, world frame).

    With ``keep_frame`` and camera 1 already posed in ``rig`` (the merged rig),
    camera 1 stays where it is and camera 2 is placed relative to it. Otherwise
    the world becomes camera 1's frame, and a [wall] table of the old frame is
    removed (it no longer matches; calibrate the wall next).
    """
    pose1 = camera_pose(rig, camera1) if keep_frame else None
    entry1 = calibration.cameras.get(camera1)
    if pose1 is not None:
        r1, t1 = pose1
        frame = str((entry1.info.get(WORLD_FRAME_KEY) if entry1 else None) or "rig")
    else:
        r1, t1 = np.eye(3), np.zeros(3)
        frame = f"camera {camera1}"
        calibration = with_wall(calibration, None)
    r2 = result.rotation @ r1
    t2 = result.rotation @ t1 + result.translation_m
    info: dict[str, Any] = {
        WORLD_FRAME_KEY: frame,
        "extrinsics_date": today(),
        "extrinsics_method": f"stereo with {camera1}",
        "extrinsics_board": str(spec),
        "extrinsics_pairs": len(result.pair_names),
        "stereo_rms_px": round(result.rms_px, 4),
        "epipolar_rms_px": round(result.epipolar_rms_px, 4),
        "baseline_m": round(result.baseline_m, 6),
        "extrinsics_source": source,
    }
    calibration = with_camera(
        calibration,
        camera1,
        extrinsics=extrinsics_config(r1, t1),
        info={
            WORLD_FRAME_KEY: frame,
            "extrinsics_date": info["extrinsics_date"],
            "extrinsics_method": f"reference of the stereo pair with {camera2}"
            if pose1 is None
            else "kept (stereo reference)",
        },
    )
    calibration = with_camera(calibration, camera2, extrinsics=extrinsics_config(r2, t2), info=info)
    return calibration, frame


def apply_wall_fit(
    calibration: CalibrationFile, rig: RigConfig, fit: WallFit, method: str, display_px: tuple[int, int] | None
) -> CalibrationFile:
    """Re-express every posed camera in the wall frame and write the wall's corners in it.

    ``rig`` is the merged rig whose camera poses the fit was made with.
    """
    for cam in rig.cameras:
        pose = camera_pose(rig, cam.id)
        if pose is None:
            continue
        rotation, translation = fit.camera_in_wall_frame(*pose)
        calibration = with_camera(
            calibration,
            cam.id,
            extrinsics=extrinsics_config(rotation, translation),
            info={WORLD_FRAME_KEY: "wall", "wall_date": today(), "wall_method": method},
        )
    width, height = fit.width_m, fit.height_m
    wall: dict[str, Any] = {
        "corners_m": [[0.0, 0.0, 0.0], [width, 0.0, 0.0], [width, height, 0.0], [0.0, height, 0.0]],
    }
    if display_px is not None:
        wall["display_width_px"], wall["display_height_px"] = display_px
    if rig.wall is not None and rig.wall.planarity_tolerance_m != 0.01:
        wall["planarity_tolerance_m"] = rig.wall.planarity_tolerance_m
    return with_wall(calibration, WallConfig.model_validate(wall))


def apply_measured_wall(calibration: CalibrationFile, wall: WallConfig) -> CalibrationFile:
    """The calibration with a [wall] measured in the cameras' current frame (the report's way)."""
    return with_wall(calibration, wall)


def world_frames(calibration: CalibrationFile) -> dict[str, str]:
    """camera id -> the world frame its extrinsics are in, as recorded."""
    return {
        cid: str(entry.info.get(WORLD_FRAME_KEY, "unknown"))
        for cid, entry in calibration.cameras.items()
        if entry.extrinsics is not None
    }


def relative_pose(rotation1: Array, translation1: Array, rotation2: Array, translation2: Array) -> tuple[Array, Array]:
    """Camera 2 relative to camera 1 from both world poses: ``x2 = R x1 + T``."""
    rotation = np.asarray(rotation2) @ np.asarray(rotation1).T
    return rotation, np.asarray(translation2) - rotation @ np.asarray(translation1)
