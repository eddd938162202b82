"""The rig file's cameras and wall as geometry: the one place that turns configuration into arrays.

trackerd/geometry works on NumPy arrays only and knows nothing of the rig file;
this adapter builds its :class:`~trackerd.geometry.camera.CameraModel` and
:class:`~trackerd.geometry.wall.WallFrame` from the validated models, and makes
the geometric checks the loader reports with the file's name (a lens that folds
over near the corners, a wall with a camera behind it).

The loader imports this module only when it has geometry to check: NumPy and
OpenCV take a quarter of a second to import, which commands that only read a
rig need not pay.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from trackerd.config.models import (
    CameraConfig,
    FovIntrinsics,
    OpenCVExtrinsics,
    OpenCVIntrinsics,
    PoseExtrinsics,
    RigConfig,
    WallConfig,
    horizontal_focal_px,
)
from trackerd.errors import ConfigError, GeometryError
from trackerd.geometry.camera import CameraModel, border_pixels
from trackerd.geometry.rotation import rotation_from_rvec, world_from_camera_ypr
from trackerd.geometry.wall import WallFrame


def camera_model(cam: CameraConfig) -> CameraModel:
    """The model of a camera's validated configuration (intrinsics and extrinsics set; ValueError if not).

    A ``model = "fov"`` lens is the report's simple camera (eq. 14): the focal length in pixels from
    the field of view, the principal point at the image's centre, no distortion.
    """
    if cam.intrinsics is None or cam.extrinsics is None:
        raise ValueError(f"camera '{cam.id}' needs intrinsics and extrinsics")
    intr = cam.intrinsics
    if isinstance(intr, FovIntrinsics):
        fx = horizontal_focal_px(intr, cam.width_px)
        if intr.vertical_fov_deg is None:
            fy = fx
        else:
            fy = (cam.height_px / 2.0) / np.tan(np.radians(intr.vertical_fov_deg) / 2.0)
        # Centre of an image W pixels wide, in OpenCV's pixel-centre coordinates.
        cx, cy = (cam.width_px - 1) / 2.0, (cam.height_px - 1) / 2.0
        dist: tuple[float, ...] = ()
    else:
        assert isinstance(intr, OpenCVIntrinsics)
        fx, fy, cx, cy, dist = intr.fx_px, intr.fy_px, intr.cx_px, intr.cy_px, intr.distortion
    matrix = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    ext = cam.extrinsics
    if isinstance(ext, PoseExtrinsics):
        world_from_cam = world_from_camera_ypr(ext.yaw_deg, ext.pitch_deg, ext.roll_deg)
        rotation = world_from_cam.T
        translation = -rotation @ np.asarray(ext.position_m, dtype=float)
    else:
        assert isinstance(ext, OpenCVExtrinsics)
        if ext.rvec is not None:
            rotation = rotation_from_rvec(np.asarray(ext.rvec))
        else:
            rotation = np.asarray(ext.rotation_matrix, dtype=float)
        translation = np.asarray(ext.tvec_m, dtype=float)
    return CameraModel(cam.id, cam.width_px, cam.height_px, matrix, np.asarray(dist), rotation, translation)


def wall_frame(wall: WallConfig) -> WallFrame:
    """The frame of a validated wall configuration; ConfigError (naming the wall) if it fixes no plane."""
    display = None
    if wall.display_width_px is not None and wall.display_height_px is not None:
        display = (wall.display_width_px, wall.display_height_px)
    try:
        if wall.corners_m is not None:
            return WallFrame.from_corners(np.array(wall.corners_m), display, wall.planarity_tolerance_m)
        assert wall.points_m is not None and wall.origin_m is not None
        assert wall.x_direction is not None and wall.y_direction is not None
        assert wall.width_m is not None and wall.height_m is not None
        return WallFrame.from_points(
            np.array(wall.points_m),
            np.array(wall.origin_m),
            np.array(wall.x_direction),
            np.array(wall.y_direction),
            wall.width_m,
            wall.height_m,
            display,
            wall.planarity_tolerance_m,
        )
    except GeometryError as err:
        raise ConfigError(f"wall: {err}") from err


MAX_LENS_INVERSION_PX = 0.01
"""A pixel taken to its ray and projected back must land this close to where it started."""


def lens_fold_px(cam: CameraConfig) -> tuple[float, tuple[float, float]]:
    """How far a pixel on the image border, taken to its ray and projected back, lands from where it
    started (the worst over the border, px), and that pixel. Above MAX_LENS_INVERSION_PX the lens
    model folds over: a calibration fitted without points near the corners can have the distorted
    radius stop growing with the true radius there."""
    model = camera_model(cam)
    if not model.has_distortion:
        return 0.0, (0.0, 0.0)
    border = border_pixels(cam.width_px, cam.height_px)
    # A lens that folds over can send a ray to infinity and back: that is the finding, not a warning.
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        origins, directions = model.pixel_to_ray(border)
        miss = np.linalg.norm(model.project(origins + directions) - border, axis=1)
    miss = np.where(np.isfinite(miss), miss, np.inf)
    worst = int(np.argmax(miss))
    return float(miss[worst]), (float(border[worst][0]), float(border[worst][1]))


def check_lens(cam: CameraConfig, where: str) -> None:
    """Refuse a distortion model that cannot be inverted out to the image's edges (lens_fold_px):
    the rays trackerd finds for those pixels would be silently wrong."""
    miss, (u, v) = lens_fold_px(cam)
    if miss > MAX_LENS_INVERSION_PX:
        raise ConfigError(
            f"{where}.intrinsics.distortion: the lens model folds over near the image edge: the ray"
            f" for pixel ({u:.1f}, {v:.1f}) projects back {miss:.3g} px away, so the"
            " calibration does not hold out to the corners (calibrate with the board near them,"
            " or with fewer distortion terms: --distortion 4)"
        )


def check_wall_in_front(rig: RigConfig, wall_path: Path | None) -> None:
    """Build the wall frame once so an impossible wall is reported now, naming its file."""
    assert rig.wall is not None
    try:
        wall = wall_frame(rig.wall)
    except ConfigError as err:
        raise ConfigError(f"{wall_path}: {err}") from err
    # Corners listed clockwise (seen from the room) give a frame whose normal points
    # into the wall and whose x runs up it; every camera then sits behind the wall.
    behind = [
        cam.id
        for cam in rig.cameras
        if cam.extrinsics is not None
        and cam.intrinsics is not None
        and wall.plane.signed_distance_m(camera_model(cam).centre_m) < 0
    ]
    if behind:
        key = "wall.corners_m" if rig.wall.corners_m is not None else "wall.x_direction/y_direction"
        raise ConfigError(
            f"{wall_path}: {key}: camera(s) {', '.join(behind)} would be behind the wall; list the corners"
            " bottom-left, bottom-right, top-right, top-left as seen from the room (x right, y up)"
        )


def check_rig_geometry(rig: RigConfig, path: Path, *, check_wall: bool = True) -> None:
    """The geometric checks load_rig makes (lens invertible to the corners, a sane wall in front of
    the cameras), for a rig assembled in memory, with errors naming ``path``."""
    complete = rig.wall is not None
    for cam in rig.cameras:
        if cam.intrinsics is None or cam.extrinsics is None:
            complete = False
            continue
        check_lens(cam, f"{path}: cameras.{cam.id}")
    if complete and check_wall:
        check_wall_in_front(rig, path)
