"""The adapter from the rig file to the geometry (trackerd/config/rig_geometry.py): each camera form
gives the same model, the report's FOV camera follows eq. 14, and a wall that fixes no plane is a
ConfigError naming the wall."""

from __future__ import annotations

import math

import numpy as np
import pytest

from trackerd.config.models import (
    CameraConfig,
    FovIntrinsics,
    OpenCVExtrinsics,
    OpenCVIntrinsics,
    PoseExtrinsics,
    WallConfig,
)
from trackerd.config.rig_geometry import camera_model, wall_frame
from trackerd.errors import ConfigError
from trackerd.geometry.camera import report_pixel_pitch
from trackerd.geometry.rotation import rvec_from_rotation, world_from_camera_ypr

WIDTH_PX, HEIGHT_PX = 1920, 1080
POSE = PoseExtrinsics(kind="pose", position_m=(-0.8, 1.5, 0.5), yaw_deg=119.7, pitch_deg=-19.1, roll_deg=0.5)
SIM_LENS = OpenCVIntrinsics(
    model="opencv",
    fx_px=1660.0,
    fy_px=1660.0,
    cx_px=962.5,
    cy_px=538.0,
    distortion=(-0.08, 0.05, 0.0004, -0.0003, 0.0),
)
WIDTH_M, HEIGHT_M = 3.6576, 0.9144
DATAWALL_CORNERS = np.array([[0, 0, 0], [WIDTH_M, 0, 0], [WIDTH_M, HEIGHT_M, 0], [0, HEIGHT_M, 0]])


def camera_config(intrinsics: object, extrinsics: object) -> CameraConfig:
    return CameraConfig(
        id="cam",
        width_px=WIDTH_PX,
        height_px=HEIGHT_PX,
        pixel_format="BayerRG8",
        intrinsics=intrinsics,
        extrinsics=extrinsics,
    )


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    cos = np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b)
    return math.degrees(math.acos(min(1.0, cos)))


# ----------------------------------------------------------------- the report's model (eq. 14)


def test_fov_intrinsics_follow_eq_14() -> None:
    fov = FovIntrinsics(model="fov", horizontal_fov_deg=60.0, focal_length_mm=8.0)
    cam = camera_model(camera_config(fov, POSE))
    # eq. 14: one pixel spans f tan(hfov / 2) / (width / 2) on the image plane, so the
    # focal length in pixels is f over that span, whatever f is.
    pitch_mm = report_pixel_pitch(8.0, 60.0, WIDTH_PX)
    assert pitch_mm == pytest.approx(8.0 * math.tan(math.radians(30.0)) / 960.0, rel=1e-15)
    assert cam.matrix[0, 0] == pytest.approx(8.0 / pitch_mm, rel=1e-12)
    assert cam.matrix[0, 0] == pytest.approx(960.0 / math.tan(math.radians(30.0)), rel=1e-12)
    assert cam.matrix[1, 1] == cam.matrix[0, 0]  # square pixels when no vertical FOV is given
    assert (cam.matrix[0, 2], cam.matrix[1, 2]) == (959.5, 539.5)  # the image centre
    assert not cam.has_distortion


def test_fov_model_edges_of_the_image_are_half_the_field_of_view_off_axis() -> None:
    fov = FovIntrinsics(model="fov", horizontal_fov_deg=60.0, vertical_fov_deg=40.0)
    cam = camera_model(camera_config(fov, POSE))
    axis = cam.world_from_camera[:, 2]
    _, dirs = cam.pixel_to_ray(
        np.array(
            [
                [-0.5, 539.5],
                [1919.5, 539.5],  # left and right edges, mid height
                [959.5, -0.5],
                [959.5, 1079.5],  # top and bottom edges, mid width
                [959.5, 539.5],  # centre
            ]
        )
    )
    assert [angle_deg(d, axis) for d in dirs] == pytest.approx([30.0, 30.0, 20.0, 20.0, 0.0], abs=1e-9)


def test_focal_length_does_not_change_any_ray() -> None:
    near = camera_model(camera_config(FovIntrinsics(model="fov", horizontal_fov_deg=50.0), POSE))
    far = camera_model(camera_config(FovIntrinsics(model="fov", horizontal_fov_deg=50.0, focal_length_mm=35.0), POSE))
    np.testing.assert_array_equal(near.matrix, far.matrix)


# ----------------------------------------------------------------- extrinsics forms


def test_pose_form_puts_the_optical_centre_at_position_m() -> None:
    cam = camera_model(camera_config(SIM_LENS, POSE))
    np.testing.assert_allclose(cam.centre_m, POSE.position_m, atol=1e-15)
    np.testing.assert_allclose(cam.world_from_camera, world_from_camera_ypr(119.7, -19.1, 0.5), atol=1e-15)


def test_rodrigues_and_matrix_forms_agree_with_the_pose_form() -> None:
    pose_cam = camera_model(camera_config(SIM_LENS, POSE))
    rotation, translation = pose_cam.rotation, pose_cam.translation_m
    by_rvec = camera_model(
        camera_config(
            SIM_LENS,
            OpenCVExtrinsics(kind="opencv", rvec=tuple(rvec_from_rotation(rotation)), tvec_m=tuple(translation)),
        )
    )
    by_matrix = camera_model(
        camera_config(
            SIM_LENS,
            OpenCVExtrinsics(
                kind="opencv",
                rotation_matrix=tuple(tuple(row) for row in rotation),
                tvec_m=tuple(translation),
            ),
        )
    )
    points = np.array([[1.0, 1.0, 2.0], [2.5, 0.4, 1.5], [0.2, 1.8, 3.0]])
    for cam in (by_rvec, by_matrix):
        np.testing.assert_allclose(cam.rotation, rotation, atol=1e-14)
        np.testing.assert_allclose(cam.centre_m, POSE.position_m, atol=1e-13)
        np.testing.assert_allclose(cam.project(points), pose_cam.project(points), atol=1e-9)


def test_opencv_form_is_world_to_camera() -> None:
    # A half turn about x maps the world's (y up, z out of the wall) to OpenCV's camera
    # frame (y down, z forward) of a camera at rest; t = -R C puts it at C = (1, 2, 3).
    centre = np.array([1.0, 2.0, 3.0])
    rotation = np.diag([1.0, -1.0, -1.0])
    cam = camera_model(
        camera_config(
            SIM_LENS,
            OpenCVExtrinsics(kind="opencv", rvec=(math.pi, 0.0, 0.0), tvec_m=tuple(-rotation @ centre)),
        )
    )
    rest = camera_model(camera_config(SIM_LENS, PoseExtrinsics(kind="pose", position_m=(1.0, 2.0, 3.0))))
    np.testing.assert_allclose(cam.rotation, rest.rotation, atol=1e-15)
    np.testing.assert_allclose(cam.centre_m, centre, atol=1e-15)


def test_a_camera_needs_intrinsics_and_extrinsics() -> None:
    with pytest.raises(ValueError, match="needs intrinsics and extrinsics"):
        camera_model(camera_config(None, POSE))


# ----------------------------------------------------------------- the wall


def test_wall_forms_agree_and_geometry_errors_become_config_errors() -> None:
    corners = tuple(tuple(c) for c in DATAWALL_CORNERS.tolist())
    by_corners = wall_frame(WallConfig(corners_m=corners))
    by_points = wall_frame(
        WallConfig(
            points_m=corners[:3],
            origin_m=(0, 0, 0),
            x_direction=(1, 0, 0),
            y_direction=(0, 1, 0),
            width_m=WIDTH_M,
            height_m=HEIGHT_M,
        )
    )
    np.testing.assert_allclose(by_points.corners_m, by_corners.corners_m, atol=1e-15)
    with pytest.raises(ConfigError, match=r"^wall: .*colinear"):
        wall_frame(
            WallConfig(
                points_m=((0, 0, 0), (1, 0, 0), (2, 0, 0)),
                origin_m=(0, 0, 0),
                x_direction=(1, 0, 0),
                y_direction=(0, 1, 0),
                width_m=1.0,
                height_m=1.0,
            )
        )
