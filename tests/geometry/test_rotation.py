"""Rotation conventions of geometry/rotation.py (eq. 18-22), each pinned by a concrete case."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackerd.config.models import CameraConfig, FovIntrinsics, PoseExtrinsics
from trackerd.config.rig_geometry import camera_model
from trackerd.geometry.rotation import (
    R_REST,
    rotation_about_x,
    rotation_about_y,
    rotation_about_z,
    rotation_angle_deg,
    rotation_from_rvec,
    rvec_from_rotation,
    world_from_camera_ypr,
    ypr_from_world_from_camera,
)

S30, C30 = 0.5, np.sqrt(3.0) / 2.0


def optical_axis(yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """The camera's +z axis (where it looks) in world coordinates."""
    return world_from_camera_ypr(yaw_deg, pitch_deg, roll_deg)[:, 2]


def test_camera_at_rest_looks_along_world_minus_z_with_image_down_being_world_down() -> None:
    rotation = world_from_camera_ypr(0.0, 0.0, 0.0)
    np.testing.assert_allclose(rotation, R_REST, atol=1e-15)
    np.testing.assert_allclose(rotation[:, 0], [1, 0, 0], atol=1e-15)  # image right = world right
    np.testing.assert_allclose(rotation[:, 1], [0, -1, 0], atol=1e-15)  # image down = world down
    np.testing.assert_allclose(rotation[:, 2], [0, 0, -1], atol=1e-15)  # looks into the wall


def test_positive_yaw_turns_the_optical_axis_right() -> None:
    # Facing the wall (-z), "right" is world +x.
    np.testing.assert_allclose(optical_axis(90.0, 0.0, 0.0), [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(optical_axis(30.0, 0.0, 0.0), [S30, 0, -C30], atol=1e-15)
    np.testing.assert_allclose(optical_axis(-30.0, 0.0, 0.0), [-S30, 0, -C30], atol=1e-15)


def test_positive_pitch_tilts_the_optical_axis_up() -> None:
    np.testing.assert_allclose(optical_axis(0.0, 30.0, 0.0), [0, S30, -C30], atol=1e-15)
    np.testing.assert_allclose(optical_axis(0.0, -30.0, 0.0), [0, -S30, -C30], atol=1e-15)


def test_positive_roll_turns_the_camera_clockwise_seen_from_behind() -> None:
    # Seen from behind a camera looking at the wall, world +x is right and +y up.
    # Clockwise by 90 degrees, the camera's right side (its x axis) ends up pointing
    # down and its bottom (its y axis) pointing left; the optical axis does not move.
    rotation = world_from_camera_ypr(0.0, 0.0, 90.0)
    np.testing.assert_allclose(rotation[:, 0], [0, -1, 0], atol=1e-15)
    np.testing.assert_allclose(rotation[:, 1], [-1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(rotation[:, 2], [0, 0, -1], atol=1e-15)
    small = world_from_camera_ypr(0.0, 0.0, 10.0)[:, 0]
    assert small[0] > 0 and small[1] < 0  # right side dips: clockwise


def test_yaw_is_applied_before_pitch() -> None:
    # Pan right by 90 (looking along +x), then tilt up by 30 about the panned x axis:
    # the camera looks along +x and up. Tilting first and then panning about the
    # world's vertical would give the same here only if pitch were lost, so this
    # pins the order (eq. 21).
    np.testing.assert_allclose(optical_axis(90.0, 30.0, 0.0), [C30, S30, 0], atol=1e-15)
    # After the pan, the camera's right points into the room (+z).
    np.testing.assert_allclose(world_from_camera_ypr(90.0, 0.0, 0.0)[:, 0], [0, 0, 1], atol=1e-15)


def test_roll_is_applied_last_about_the_optical_axis() -> None:
    for roll in (-120.0, 35.0, 90.0):
        np.testing.assert_allclose(optical_axis(40.0, 25.0, roll), optical_axis(40.0, 25.0, 0.0), atol=1e-15)


def test_elementary_rotations_are_right_handed() -> None:
    # A right-handed rotation by +90 degrees about x takes y to z, about y takes z to x,
    # about z takes x to y (eq. 18-20 as the report's figure 8 draws them).
    quarter = np.pi / 2
    np.testing.assert_allclose(rotation_about_x(quarter) @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(rotation_about_y(quarter) @ [0, 0, 1], [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(rotation_about_z(quarter) @ [1, 0, 0], [0, 1, 0], atol=1e-15)


def test_worked_example_in_docs_geometry() -> None:
    # docs/geometry.md works through a camera at (-1.3, 1.4, 3.0) with yaw 72.3 and
    # pitch -16.9 and the report's 60-degree lens; its numbers must stay right.
    rotation = world_from_camera_ypr(72.3, -16.9, 0.0)
    np.testing.assert_allclose(
        rotation,
        [[0.30403, -0.27694, 0.91152], [0.0, -0.95681, -0.29070], [0.95266, 0.08838, -0.29090]],
        atol=5e-6,
    )
    yaw, pitch = np.radians([72.3, -16.9])
    np.testing.assert_allclose(
        rotation[:, 2],
        [np.sin(yaw) * np.cos(pitch), np.sin(pitch), -np.cos(yaw) * np.cos(pitch)],
        atol=1e-15,
    )
    pose = PoseExtrinsics(kind="pose", position_m=(-1.3, 1.4, 3.0), yaw_deg=72.3, pitch_deg=-16.9)
    lens = FovIntrinsics(model="fov", horizontal_fov_deg=60.0)
    config = CameraConfig(
        id="left",
        width_px=1920,
        height_px=1080,
        pixel_format="BayerRG8",
        intrinsics=lens,
        extrinsics=pose,
    )
    cam = camera_model(config)
    in_camera = cam.to_camera_frame(np.array([1.8288, 0.4572, 0.0]))[0]
    np.testing.assert_allclose(in_camera, [-1.9067, -0.2296, 3.9987], atol=5e-5)
    np.testing.assert_allclose(cam.project(np.array([1.8288, 0.4572, 0.0]))[0], [166.6, 444.0], atol=0.05)


angles = st.floats(-179.0, 179.0)
pitches = st.floats(-89.0, 89.0)


@settings(max_examples=200, deadline=None)
@given(yaw=angles, pitch=pitches, roll=angles)
def test_yaw_pitch_roll_round_trip(yaw: float, pitch: float, roll: float) -> None:
    rotation = world_from_camera_ypr(yaw, pitch, roll)
    np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(rotation) == pytest.approx(1.0, abs=1e-14)
    back = ypr_from_world_from_camera(rotation)
    np.testing.assert_allclose(back, [yaw, pitch, roll], atol=1e-7)
    np.testing.assert_allclose(world_from_camera_ypr(*back), rotation, atol=1e-14)


@pytest.mark.parametrize("pitch", [90.0, -90.0])
def test_straight_up_or_down_keeps_the_rotation_and_reports_zero_roll(pitch: float) -> None:
    rotation = world_from_camera_ypr(30.0, pitch, 20.0)
    yaw, pitch_back, roll = ypr_from_world_from_camera(rotation)
    assert pitch_back == pytest.approx(pitch)
    assert roll == 0.0
    np.testing.assert_allclose(world_from_camera_ypr(yaw, pitch_back, roll), rotation, atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(
    axis=st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: np.linalg.norm(v) > 0.1),
    # OpenCV's Rodrigues rounds rotations below about 1e-5 rad (0.0006 degrees) to a zero
    # vector, so the round trip starts at 0.01 degrees.
    angle_deg=st.floats(0.01, 179.0),
)
def test_rodrigues_round_trip_and_angle(axis: tuple[float, float, float], angle_deg: float) -> None:
    rvec = np.asarray(axis) / np.linalg.norm(axis) * np.radians(angle_deg)
    rotation = rotation_from_rvec(rvec)
    assert rotation_angle_deg(rotation) == pytest.approx(angle_deg, abs=1e-6)
    np.testing.assert_allclose(rotation_from_rvec(rvec_from_rotation(rotation)), rotation, atol=1e-12)


def test_rodrigues_vector_about_world_x_is_a_right_handed_rotation() -> None:
    np.testing.assert_allclose(rotation_from_rvec(np.array([np.pi / 2, 0, 0])), rotation_about_x(np.pi / 2), atol=1e-15)
    assert rotation_angle_deg(np.eye(3)) == 0.0
