"""CameraModel: projection, rays, pixel conventions, every lens model.

Building one from the rig file's forms is the adapter's (tests/config/test_rig_geometry.py).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from trackerd.geometry.camera import CameraModel
from trackerd.geometry.rotation import world_from_camera_ypr

WIDTH_PX, HEIGHT_PX = 1920, 1080

# name -> (K, distortion): every OpenCV distortion vector length, and a wide-angle lens
# (88 degrees across, strong barrel) whose corners are where undistortion is hardest.
LENSES = {
    "pinhole": ([[1660.0, 0, 959.5], [0, 1660.0, 539.5], [0, 0, 1]], []),
    "k1k2p1p2": (
        [[1660.0, 0, 962.5], [0, 1655.0, 538.0], [0, 0, 1]],
        [-0.08, 0.05, 0.0004, -0.0003],
    ),
    "simulated_rig": (
        [[1660.0, 0, 962.5], [0, 1660.0, 538.0], [0, 0, 1]],
        [-0.08, 0.05, 0.0004, -0.0003, 0.0],
    ),
    "wide_angle_barrel": (
        [[1000.0, 0, 962.5], [0, 1000.0, 538.0], [0, 0, 1]],
        [-0.3, 0.15, 0.001, -0.001, -0.02],
    ),
    # A wide lens (100 degrees across) whose radial map flattens near the corners without
    # folding (a draw of the randomized simulator): OpenCV's fixed-point inverse does not
    # converge there in any number of iterations; CameraModel inverts it by Newton's method.
    "wide_angle_flattening": (
        [[799.68, 0, 931.23], [0, 798.50, 525.12], [0, 0, 1]],
        [-0.33781, 0.057999, -0.00017266, 0.000020395, 0.0],
    ),
    # The same with a rational term (k4): Newton's method through OpenCV's projection and its derivatives.
    "wide_angle_flattening_rational": (
        [[799.68, 0, 931.23], [0, 798.50, 525.12], [0, 0, 1]],
        [-0.34, 0.057999, -0.00017266, 0.000020395, 0.0, 0.02, 0.0, 0.0],
    ),
    "rational": (
        [[1660.0, 0, 962.5], [0, 1660.0, 538.0], [0, 0, 1]],
        [-0.1, 0.05, 0.001, 0.0005, -0.01, 0.02, 0.01, -0.005],
    ),
    "thin_prism": (
        [[1660.0, 0, 962.5], [0, 1660.0, 538.0], [0, 0, 1]],
        [-0.1, 0.05, 0.001, 0.0005, -0.01, 0.02, 0.01, -0.005, 0.001, -0.0005, 0.0008, 0.0003],
    ),
    "tilted": (
        [[1660.0, 0, 962.5], [0, 1660.0, 538.0], [0, 0, 1]],
        [
            -0.1,
            0.05,
            0.001,
            0.0005,
            -0.01,
            0.02,
            0.01,
            -0.005,
            0.001,
            -0.0005,
            0.0008,
            0.0003,
            0.01,
            -0.02,
        ],
    ),
}


def lens_camera(name: str, yaw_deg: float = 20.0, pitch_deg: float = -10.0, roll_deg: float = 3.0) -> CameraModel:
    matrix, distortion = LENSES[name]
    return CameraModel.from_pose(
        name,
        WIDTH_PX,
        HEIGHT_PX,
        np.array(matrix),
        np.array(distortion),
        np.array([0.3, 1.2, 2.5]),
        world_from_camera_ypr(yaw_deg, pitch_deg, roll_deg),
    )


def image_grid(width_px: int, height_px: int, steps: int) -> np.ndarray:
    """(N, 2) pixels on a grid that includes the image's outermost edges and exact corners."""
    uu, vv = np.meshgrid(np.linspace(-0.5, width_px - 0.5, steps), np.linspace(-0.5, height_px - 0.5, steps))
    return np.column_stack([uu.ravel(), vv.ravel()])


# ----------------------------------------------------------------- pixel conventions


def test_pixel_axes_run_right_and_down() -> None:
    # A camera at rest at the origin looks at the wall (-z): a point to the world's right
    # lands right of the principal point, a point above lands above it (smaller y).
    matrix = np.array([[1000.0, 0.0, 960.0], [0.0, 1000.0, 540.0], [0.0, 0.0, 1.0]])
    cam = CameraModel.from_pose(
        "cam", WIDTH_PX, HEIGHT_PX, matrix, np.zeros(0), np.zeros(3), world_from_camera_ypr(0.0, 0.0, 0.0)
    )
    pixels = cam.project(np.array([[0.0, 0.0, -2.0], [0.5, 0.0, -2.0], [0.0, 0.5, -2.0]]))
    np.testing.assert_allclose(pixels, [[960.0, 540.0], [1210.0, 540.0], [960.0, 290.0]], atol=1e-12)


def test_points_behind_or_on_the_camera_plane_project_to_nan() -> None:
    cam = lens_camera("simulated_rig", 0.0, 0.0, 0.0)
    centre = cam.centre_m
    # the camera looks along world -z: +z is behind it, +x lies in its focal plane
    offsets = np.array([[0, 0, 1.0], [1.0, 0, 0], [0, 0, -1.0]])
    pixels = cam.project(centre + offsets)
    assert np.all(np.isnan(pixels[:2]))
    assert np.all(np.isfinite(pixels[2]))


def test_contains_counts_the_outer_pixel_edges_as_inside() -> None:
    cam = lens_camera("pinhole")
    inside = cam.contains(np.array([[-0.5, -0.5], [1919.5, 1079.5], [-0.51, 10.0], [10.0, 1079.51], [5.0, 5.0]]))
    assert inside.tolist() == [True, True, False, False, True]
    assert cam.contains(np.array([[5.0, 5.0], [6.0, 6.0]]), margin_px=6.0).tolist() == [False, True]


def test_pixel_to_ray_starts_at_the_centre_with_unit_directions() -> None:
    cam = lens_camera("simulated_rig")
    origins, dirs = cam.pixel_to_ray(image_grid(WIDTH_PX, HEIGHT_PX, 5))
    assert origins.shape == dirs.shape == (25, 3)
    np.testing.assert_allclose(origins, np.broadcast_to(cam.centre_m, (25, 3)), atol=0)
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=1), 1.0, atol=1e-15)


# ----------------------------------------------------------------- round trips


@pytest.mark.parametrize("lens", sorted(LENSES))
def test_pixel_to_ray_then_project_returns_the_pixel_up_to_the_corners(lens: str) -> None:
    cam = lens_camera(lens)
    pixels = image_grid(WIDTH_PX, HEIGHT_PX, 49)  # includes the four outermost corners
    origins, dirs = cam.pixel_to_ray(pixels)
    for depth_m in (0.4, 3.0):
        back = cam.project(origins + depth_m * dirs)
        assert np.max(np.linalg.norm(back - pixels, axis=1)) < 1e-6


def test_wide_angle_lens_moves_its_corners_by_hundreds_of_pixels() -> None:
    # The round trips above are only a test of undistortion if the distortion is strong:
    # the wide-angle lens images its corner rays over 200 px from where a pinhole would.
    cam = lens_camera("wide_angle_barrel")
    corners = np.array([[-0.5, -0.5], [1919.5, -0.5], [1919.5, 1079.5], [-0.5, 1079.5]])
    origins, dirs = cam.pixel_to_ray(corners)
    pinhole = cam.with_intrinsics(cam.matrix, np.zeros(0))
    shift_px = np.linalg.norm(pinhole.project(origins + dirs) - corners, axis=1)
    assert np.all(shift_px > 200.0)


@pytest.mark.parametrize("lens", ["wide_angle_flattening", "wide_angle_flattening_rational"])
def test_a_lens_opencvs_fixed_point_cannot_invert_is_inverted_by_newton(lens: str) -> None:
    # The round trip above is a test of the Newton path only if OpenCV's own inverse, iterated
    # as far as CameraModel used to (200 times), misses somewhere on this lens's border.
    cam = lens_camera(lens)
    border = image_grid(WIDTH_PX, HEIGHT_PX, 49)
    fixed_point = cv2.undistortPoints(
        border.reshape(-1, 1, 2),
        cam.matrix,
        cam.distortion,
        criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-14),
    ).reshape(-1, 2)
    rays = np.column_stack([fixed_point, np.ones(len(border))]) @ cam.rotation
    assert np.max(np.linalg.norm(cam.project(cam.centre_m + rays) - border, axis=1)) > 0.1
    origins, dirs = cam.pixel_to_ray(border)
    assert np.max(np.linalg.norm(cam.project(origins + dirs) - border, axis=1)) < 1e-6


@pytest.mark.parametrize("lens", sorted(LENSES))
def test_project_then_pixel_to_ray_passes_through_the_point(lens: str) -> None:
    cam = lens_camera(lens)
    rng = np.random.default_rng(3)
    # points spread over the view at depths of 0.5-6 m, in camera coordinates
    norm = rng.uniform([-0.5, -0.3], [0.5, 0.3], size=(200, 2))
    depth = rng.uniform(0.5, 6.0, size=(200, 1))
    points = (np.column_stack([norm, np.ones(200)]) * depth - cam.translation_m) @ cam.rotation
    origins, dirs = cam.pixel_to_ray(cam.project(points))
    offsets = points - origins
    perpendicular = offsets - np.sum(offsets * dirs, axis=1, keepdims=True) * dirs
    assert np.max(np.linalg.norm(perpendicular, axis=1)) < 1e-9


@settings(max_examples=200, deadline=None)
@given(
    u=st.floats(-0.5, WIDTH_PX - 0.5),
    v=st.floats(-0.5, HEIGHT_PX - 0.5),
    depth_m=st.floats(0.2, 10.0),
    yaw=st.floats(-180.0, 180.0),
    pitch=st.floats(-80.0, 80.0),
    roll=st.floats(-180.0, 180.0),
    lens=st.sampled_from(sorted(LENSES)),
)
def test_property_pixel_ray_pixel(
    u: float, v: float, depth_m: float, yaw: float, pitch: float, roll: float, lens: str
) -> None:
    cam = lens_camera(lens, yaw, pitch, roll)
    pixel = np.array([[u, v]])
    origin, direction = cam.pixel_to_ray(pixel)
    point = origin + depth_m * direction
    assume(np.all(np.isfinite(point)))
    np.testing.assert_allclose(cam.project(point), pixel, atol=1e-6)
