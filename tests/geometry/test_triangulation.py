"""Triangulation: closest approach of two rays (eq. 15-17, skew rays) and N-camera least squares."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from trackerd.errors import GeometryError
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.rotation import world_from_camera_ypr
from trackerd.geometry.triangulation import (
    closest_approach,
    triangulate_least_squares,
    triangulate_pixels,
)


def test_intersecting_rays_meet_with_zero_gap() -> None:
    # C1 = (0,0,0) along (1,1,0) and C2 = (2,0,0) along (-1,1,0) cross at (1,1,0): the
    # coplanarity condition of eq. 16 holds and eq. 17 gives s = t = 1.
    result = closest_approach([0, 0, 0], [1, 1, 0], [2, 0, 0], [-1, 1, 0])
    np.testing.assert_allclose(result.midpoint_m, [1, 1, 0], atol=1e-15)
    assert result.gap_m == pytest.approx(0.0, abs=1e-15)
    assert (result.s, result.t) == pytest.approx((1.0, 1.0))


def test_skew_rays_give_the_midpoint_and_length_of_the_common_perpendicular() -> None:
    # Ray A runs along the x axis; ray B runs along +y through (3, -2, 1). Their common
    # perpendicular joins (3, 0, 0) on A to (3, 0, 1) on B.
    result = closest_approach([0, 0, 0], [2, 0, 0], [3, -2, 1], [0, 1, 0])
    np.testing.assert_allclose(result.midpoint_m, [3, 0, 0.5], atol=1e-15)
    assert result.gap_m == pytest.approx(1.0)
    assert result.s == pytest.approx(1.5)  # in units of A's (non-unit) direction
    assert result.t == pytest.approx(2.0)


def test_skew_rays_at_an_angle() -> None:
    # A: x axis. B: through (1, 0, 2) along (0, 1, 1); its closest point to A is (1, -1, 1)
    # on B at t = -1 and (1, 0, 0) on A, a gap of sqrt(2).
    result = closest_approach([0, 0, 0], [1, 0, 0], [1, 0, 2], [0, 1, 1])
    np.testing.assert_allclose(result.midpoint_m, [1, -0.5, 0.5], atol=1e-15)
    assert result.gap_m == pytest.approx(np.sqrt(2.0))
    assert (result.s, result.t) == pytest.approx((1.0, -1.0))


def test_closest_approach_works_on_batches() -> None:
    origins_a = np.array([[0, 0, 0], [0, 0, 0]], dtype=float)
    dirs_a = np.array([[1, 1, 0], [2, 0, 0]], dtype=float)
    origins_b = np.array([[2, 0, 0], [3, -2, 1]], dtype=float)
    dirs_b = np.array([[-1, 1, 0], [0, 1, 0]], dtype=float)
    result = closest_approach(origins_a, dirs_a, origins_b, dirs_b)
    np.testing.assert_allclose(result.midpoint_m, [[1, 1, 0], [3, 0, 0.5]], atol=1e-15)
    np.testing.assert_allclose(result.gap_m, [0, 1], atol=1e-15)


@pytest.mark.parametrize(
    "direction_b",
    [
        [2, 0, 0],  # parallel
        [-1, 0, 0],  # antiparallel
        [1, 1e-9, 0],  # parallel within 1e-9 rad
        [0, 0, 0],  # no direction at all
    ],
)
def test_parallel_or_degenerate_rays_raise(direction_b: list[float]) -> None:
    with pytest.raises(GeometryError, match="parallel"):
        closest_approach([0, 0, 0], [1, 0, 0], [0, 1, 0], direction_b)


def test_one_bad_pair_in_a_batch_raises() -> None:
    with pytest.raises(GeometryError):
        closest_approach(np.zeros((2, 3)), [[1, 0, 0], [1, 0, 0]], [[0, 1, 0], [0, 1, 0]], [[0, 1, 0], [1, 0, 0]])


def test_least_squares_with_three_cameras_hand_computed() -> None:
    # Three skew lines parallel to the axes: along x through (0, a, b), along y through
    # (c, 0, d), along z through (e, f, 0). The squared distances are (y-a)^2 + (z-b)^2,
    # (x-c)^2 + (z-d)^2 and (x-e)^2 + (y-f)^2, minimised at x = (c+e)/2, y = (a+f)/2,
    # z = (b+d)/2.
    a, b, c, d, e, f = 1.0, 2.0, 3.0, -1.0, 0.5, 4.0
    origins = np.array([[0, a, b], [c, 0, d], [e, f, 0]])
    directions = np.array([[5, 0, 0], [0, 1, 0], [0, 0, -2]])  # lengths and signs do not matter
    point, distances = triangulate_least_squares(origins, directions)
    expected = np.array([(c + e) / 2, (a + f) / 2, (b + d) / 2])
    np.testing.assert_allclose(point, expected, atol=1e-14)
    x, y, z = expected
    np.testing.assert_allclose(
        distances,
        np.sqrt([(y - a) ** 2 + (z - b) ** 2, (x - c) ** 2 + (z - d) ** 2, (x - e) ** 2 + (y - f) ** 2]),
        atol=1e-14,
    )


def test_least_squares_of_two_rays_is_the_closest_approach_midpoint() -> None:
    point, distances = triangulate_least_squares([[0, 0, 0], [1, 0, 2]], [[1, 0, 0], [0, 1, 1]])
    np.testing.assert_allclose(point, [1, -0.5, 0.5], atol=1e-14)
    np.testing.assert_allclose(distances, [np.sqrt(0.5)] * 2, atol=1e-14)


def test_least_squares_ignores_cameras_that_did_not_see_the_point() -> None:
    origins = np.array([[0, 0, 0], [np.nan] * 3, [2, 0, 0]])
    directions = np.array([[1, 1, 0], [np.nan] * 3, [-1, 1, 0]])
    point, distances = triangulate_least_squares(origins, directions)
    np.testing.assert_allclose(point, [1, 1, 0], atol=1e-14)
    assert distances.shape == (2,)
    with pytest.raises(GeometryError, match="two or more"):
        triangulate_least_squares(origins[:2], directions[:2])


def test_least_squares_rejects_parallel_rays() -> None:
    with pytest.raises(GeometryError, match="parallel"):
        triangulate_least_squares([[0, 0, 0], [0, 1, 0], [0, 2, 0]], [[1, 0, 0], [1, 0, 0], [-1, 0, 0]])


def test_rays_without_a_direction_or_with_nan_are_geometry_errors() -> None:
    # Regression: a zero direction reached np.linalg.solve (LinAlgError), NaN read "parallel within nan".
    with pytest.raises(GeometryError, match="has no length"):
        triangulate_least_squares([[0, 0, 0], [1, 0, 0]], [[0, 0, 0], [0, 0, 1]])
    with pytest.raises(GeometryError, match="direction is not finite"):
        closest_approach([0, 0, 0], [np.nan, 0, 1], [1, 0, 0], [0, 0, 1])
    with pytest.raises(GeometryError, match="origin is not finite"):
        closest_approach([0, 0, 0], [0, 0, 1], [np.inf, 0, 0], [0, 1, 1])


def three_cameras() -> list[CameraModel]:
    matrix = np.array([[1400.0, 0, 959.5], [0, 1400.0, 539.5], [0, 0, 1]])
    distortion = np.array([-0.05, 0.02, 0.0, 0.0, 0.0])
    poses = [
        ((-0.8, 1.5, 0.5), 119.7, -19.1),
        ((4.4576, 1.5, 0.5), -119.7, -19.1),
        ((1.8, 2.4, 5.0), 0.0, -15.0),
    ]
    return [
        CameraModel.from_pose(f"c{i}", 1920, 1080, matrix, distortion, np.array(pos), world_from_camera_ypr(y, p, 0))
        for i, (pos, y, p) in enumerate(poses)
    ]


def test_triangulate_pixels_from_three_cameras_and_with_one_missing() -> None:
    cameras = three_cameras()
    point = np.array([1.9, 1.1, 2.2])
    pixels = np.vstack([cam.project(point) for cam in cameras])
    assert all(cam.contains(px[None])[0] for cam, px in zip(cameras, pixels, strict=True))
    found, distances = triangulate_pixels(cameras, pixels)
    np.testing.assert_allclose(found, point, atol=1e-9)
    assert np.all(distances < 1e-9)
    pixels[1] = np.nan  # the second camera lost the point
    found, distances = triangulate_pixels(cameras, pixels)
    np.testing.assert_allclose(found, point, atol=1e-9)
    assert distances.shape == (2,)


# Where a presenter's pointer can be: in front of the wall, in view of both cameras.
room_points = st.tuples(st.floats(0.8, 2.8), st.floats(0.5, 1.6), st.floats(1.2, 2.8))


@settings(max_examples=200, deadline=None)
@given(point=room_points, rig=st.sampled_from(["simulated", "datawall"]))
def test_property_project_into_both_cameras_and_triangulate_back(
    example_rig_cameras: dict[str, list[CameraModel]], point: tuple[float, float, float], rig: str
) -> None:
    cameras = example_rig_cameras[rig]
    target = np.array(point)
    pixels = [cam.project(target) for cam in cameras]
    assume(all(cam.contains(px)[0] for cam, px in zip(cameras, pixels, strict=True)))
    (o1, d1), (o2, d2) = (cam.pixel_to_ray(px) for cam, px in zip(cameras, pixels, strict=True))
    result = closest_approach(o1[0], d1[0], o2[0], d2[0])
    assert np.linalg.norm(result.midpoint_m - target) < 1e-9
    assert result.gap_m < 1e-9
    assert result.s > 0 and result.t > 0  # in front of both cameras
    least_squares, _ = triangulate_least_squares(np.vstack([o1, o2]), np.vstack([d1, d2]))
    assert np.linalg.norm(least_squares - target) < 1e-9


@settings(max_examples=200, deadline=None)
@given(point=room_points, offset_px=st.tuples(st.floats(-2.0, 2.0), st.floats(-2.0, 2.0)))
def test_property_skew_rays_feet_are_mutually_nearest(
    simulated_cameras: list[CameraModel],
    point: tuple[float, float, float],
    offset_px: tuple[float, float],
) -> None:
    # Moving one image point off its true place makes the rays skew (unless it moves
    # along the epipolar line). The feet of the common perpendicular are each the point
    # of their ray nearest to the other ray, and the gap cannot exceed the distance
    # from the true point, which lies on ray B, to the moved ray A.
    cameras = simulated_cameras
    target = np.array(point)
    pixels = [cam.project(target) for cam in cameras]
    assume(all(cam.contains(px, margin_px=3.0)[0] for cam, px in zip(cameras, pixels, strict=True)))
    o1, d1 = (v[0] for v in cameras[0].pixel_to_ray(pixels[0] + np.array(offset_px)))
    o2, d2 = (v[0] for v in cameras[1].pixel_to_ray(pixels[1]))
    result = closest_approach(o1, d1, o2, d2)
    foot_a, foot_b = o1 + result.s * d1, o2 + result.t * d2
    assert result.gap_m == pytest.approx(np.linalg.norm(foot_a - foot_b), abs=1e-12)
    np.testing.assert_allclose(result.midpoint_m, (foot_a + foot_b) / 2, atol=1e-12)
    assert abs((foot_b - foot_a) @ d1) < 1e-9 and abs((foot_b - foot_a) @ d2) < 1e-9
    to_target = target - o1
    target_from_ray_a = np.linalg.norm(to_target - (to_target @ d1) * d1)
    assert result.gap_m <= target_from_ray_a + 1e-12
