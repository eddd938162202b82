"""The wall: planes (eq. 23-25), line-plane intersection (eq. 26-28) and the wall's 2D frame."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from trackerd.errors import GeometryError
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.rotation import rotation_from_rvec
from trackerd.geometry.triangulation import closest_approach
from trackerd.geometry.wall import (
    Plane,
    WallFrame,
    fit_plane,
    intersect_line_plane,
    plane_from_three_points,
)

Vec3 = tuple[float, float, float]
WIDTH_M, HEIGHT_M = 3.6576, 0.9144
DATAWALL_CORNERS = np.array([[0, 0, 0], [WIDTH_M, 0, 0], [WIDTH_M, HEIGHT_M, 0], [0, HEIGHT_M, 0]])

coordinate = st.floats(-5.0, 5.0)
points3 = st.tuples(coordinate, coordinate, coordinate)


def tilted_corners() -> np.ndarray:
    """A 2 x 1 m wall turned and tilted in space, corners BL, BR, TR, TL."""
    rotation = rotation_from_rvec(np.array([0.3, -0.7, 0.2]))
    flat = np.array([[0, 0, 0], [2.0, 0, 0], [2.0, 1.0, 0], [0, 1.0, 0]])
    return flat @ rotation.T + np.array([0.5, -1.0, 2.0])


# ----------------------------------------------------------------- planes (eq. 23-25)


def test_plane_from_three_points_hand_case() -> None:
    plane = plane_from_three_points([0, 0, 2], [1, 0, 2], [0, 1, 2])
    # (D2 - D1) x (D3 - D1) = +z: eq. 25's (A, B, C) follows the right-hand rule.
    np.testing.assert_allclose(plane.normal, [0, 0, 1], atol=1e-15)
    assert plane.offset_m == pytest.approx(-2.0)
    np.testing.assert_allclose(plane.coefficients, [0, 0, 1, -2], atol=1e-15)
    # Section 3.7: positive on the normal's side, negative on the other, zero on it.
    np.testing.assert_allclose(plane.signed_distance_m([[5, 5, 5], [0, 0, -1], [3, -4, 2]]), [3, -3, 0], atol=1e-15)


@settings(max_examples=200, deadline=None)
@given(p1=points3, p2=points3, p3=points3)
def test_property_three_point_plane_matches_the_least_squares_plane(p1: Vec3, p2: Vec3, p3: Vec3) -> None:
    pts = np.array([p1, p2, p3])
    cross = np.cross(pts[1] - pts[0], pts[2] - pts[0])
    assume(np.linalg.norm(cross) > 1e-3)  # clearly not colinear
    plane = plane_from_three_points(*pts)
    fitted, residuals = fit_plane(pts)
    np.testing.assert_allclose(plane.normal, cross / np.linalg.norm(cross), atol=1e-9)
    assert np.max(np.abs(plane.signed_distance_m(pts))) < 1e-9
    assert np.max(np.abs(residuals)) < 1e-9
    # the least-squares normal's sign is arbitrary; the plane is the same
    sign = np.sign(fitted.normal @ plane.normal)
    np.testing.assert_allclose(sign * fitted.coefficients, plane.coefficients, atol=1e-9)


def test_fit_plane_residuals_are_signed_distances() -> None:
    pts = np.array([[0, 0, 0.01], [1, 0, -0.01], [1, 1, 0.01], [0, 1, -0.01], [0.5, 0.5, 0.0]])
    plane, residuals = fit_plane(pts)
    sign = np.sign(plane.normal[2])
    np.testing.assert_allclose(sign * plane.normal, [0, 0, 1], atol=1e-12)
    assert plane.offset_m == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(sign * residuals, [0.01, -0.01, 0.01, -0.01, 0.0], atol=1e-12)


@pytest.mark.parametrize(
    "points",
    [
        [[0, 0, 0], [1, 1, 1], [3, 3, 3]],  # on one line
        [[1, 2, 3], [1, 2, 3], [4, 5, 6]],  # two coincide
        [[1, 2, 3]] * 3,  # all coincide
        [[0, 0, 0], [1, 0, 0], [2, 1e-12, 0]],  # colinear to within a picometre
    ],
)
def test_colinear_points_are_rejected(points: list[list[float]]) -> None:
    with pytest.raises(GeometryError, match="colinear"):
        plane_from_three_points(*np.array(points, dtype=float))
    with pytest.raises(GeometryError, match="colinear"):
        fit_plane(np.array([*points, points[0]], dtype=float))


def test_a_thin_but_real_triangle_is_accepted() -> None:
    plane = plane_from_three_points([0, 0, 0], [10, 0, 0], [5, 1e-6, 0])
    np.testing.assert_allclose(np.abs(plane.normal), [0, 0, 1], atol=1e-12)


def test_fit_plane_needs_three_points() -> None:
    with pytest.raises(GeometryError, match="three or more"):
        fit_plane(np.array([[0, 0, 0], [1, 0, 0]], dtype=float))


# ----------------------------------------------------------------- line and plane (eq. 26-28)

WALL_Z0 = Plane(np.array([0.0, 0.0, 1.0]), 0.0)


def test_line_toward_the_plane_hits_it_ahead() -> None:
    hit = intersect_line_plane([1, 2, 3], [1.5, 2, 2], WALL_Z0)
    np.testing.assert_allclose(hit.point_m, [2.5, 2, 0], atol=1e-15)
    assert hit.u == pytest.approx(3.0)


def test_line_pointing_away_from_the_plane_has_negative_u() -> None:
    # The pointer's back end at z = 3 and its front end at z = 4: pointing into the room.
    # The line still meets the wall, but behind the start (u < 0), which is not a hit.
    hit = intersect_line_plane([1, 2, 3], [1, 2, 4], WALL_Z0)
    np.testing.assert_allclose(hit.point_m, [1, 2, 0], atol=1e-15)
    assert hit.u == pytest.approx(-3.0)


def test_u_is_eq_28_for_an_unnormalised_plane() -> None:
    # eq. 28 with the report's own (A, B, C, D), not scaled to a unit normal.
    a, b, c, d = 2.0, -1.0, 4.0, -3.0
    r, blue = np.array([1.0, 2.0, 3.0]), np.array([0.5, 1.0, 1.0])
    u_report = (a * r[0] + b * r[1] + c * r[2] + d) / (
        a * (r[0] - blue[0]) + b * (r[1] - blue[1]) + c * (r[2] - blue[2])
    )
    scale = np.linalg.norm([a, b, c])
    hit = intersect_line_plane(r, blue, Plane(np.array([a, b, c]) / scale, d / scale))
    assert hit.u == pytest.approx(u_report, rel=1e-14)
    point = r + u_report * (blue - r)  # eq. 26
    np.testing.assert_allclose(hit.point_m, point, atol=1e-14)
    assert a * point[0] + b * point[1] + c * point[2] + d == pytest.approx(0.0, abs=1e-13)  # eq. 27


@pytest.mark.parametrize(
    ("start", "through", "message"),
    [
        ([0, 0, 1], [1, 0, 1], "parallel"),  # parallel, off the plane
        ([0, 0, 0], [1, 1, 0], "parallel"),  # in the plane: infinitely many points
        ([0, 0, 1], [1, 0, 1 + 1e-9], "parallel"),  # parallel within 1e-9
        ([1, 1, 1], [1, 1, 1], "coincide"),
    ],
)
def test_parallel_or_degenerate_lines_are_rejected(start: list[float], through: list[float], message: str) -> None:
    with pytest.raises(GeometryError, match=message):
        intersect_line_plane(start, through, WALL_Z0)


def test_intersect_works_on_batches() -> None:
    hit = intersect_line_plane([[0, 0, 2], [1, 1, 1]], [[0, 0, 1], [1, 1, 2]], WALL_Z0)
    np.testing.assert_allclose(hit.point_m, [[0, 0, 0], [1, 1, 0]], atol=1e-15)
    np.testing.assert_allclose(hit.u, [2.0, -1.0])


unit_vectors = st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: np.linalg.norm(v) > 0.2)


@settings(max_examples=200, deadline=None)
@given(
    normal=unit_vectors,
    offset_m=st.floats(-5.0, 5.0),
    on_plane=st.tuples(st.floats(-5.0, 5.0), st.floats(-5.0, 5.0)),
    start=points3,
    gap_m=st.floats(0.05, 1.0),
)
def test_property_build_a_plane_and_intersect(
    normal: Vec3, offset_m: float, on_plane: tuple[float, float], start: Vec3, gap_m: float
) -> None:
    n = np.asarray(normal) / np.linalg.norm(normal)
    plane = Plane(n, offset_m)
    # a known point on the plane, from two in-plane directions
    e1 = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    target = -offset_m * n + on_plane[0] * e1 + on_plane[1] * e2
    start_m = np.asarray(start)
    to_target = target - start_m
    distance = np.linalg.norm(to_target)
    assume(distance > 0.1 and abs(to_target @ n) > 0.05 * distance)  # not grazing the plane
    # the "front end" sits gap_m along the line toward the target
    through_m = start_m + gap_m * to_target / distance
    hit = intersect_line_plane(start_m, through_m, plane)
    assert np.linalg.norm(hit.point_m - target) < 1e-9
    assert hit.u == pytest.approx(distance / gap_m, rel=1e-9)
    assert abs(plane.signed_distance_m(hit.point_m)) < 1e-9


# ----------------------------------------------------------------- the wall's frame


def test_datawall_frame_from_corners(datawall_wall: WallFrame) -> None:
    wall = datawall_wall
    np.testing.assert_allclose(wall.origin_m, [0, 0, 0], atol=1e-15)
    np.testing.assert_allclose(wall.x_axis, [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(wall.y_axis, [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(wall.normal, [0, 0, 1], atol=1e-15)  # toward the room
    assert (wall.width_m, wall.height_m) == pytest.approx((WIDTH_M, HEIGHT_M))
    np.testing.assert_allclose(wall.corners_m, DATAWALL_CORNERS, atol=1e-15)
    assert (wall.display_width_px, wall.display_height_px) == (7680, 1920)


def test_frame_from_corners_and_from_points_agree() -> None:
    corners = tilted_corners()
    by_corners = WallFrame.from_corners(corners, display_px=(1920, 960))
    # three points on the wall that are not corners, plus the frame
    points = [
        corners[0] + 0.3 * (corners[1] - corners[0]),
        corners[2],
        corners[3] + 0.5 * (corners[0] - corners[3]),
    ]
    by_points = WallFrame.from_points(
        np.array(points),
        corners[0],
        corners[1] - corners[0],
        corners[3] - corners[0],
        2.0,
        1.0,
        (1920, 960),
    )
    by_many_points = WallFrame.from_points(
        corners, corners[0], corners[1] - corners[0], corners[3] - corners[0], 2.0, 1.0, (1920, 960)
    )
    for frame in (by_points, by_many_points):
        np.testing.assert_allclose(frame.origin_m, by_corners.origin_m, atol=1e-12)
        np.testing.assert_allclose(frame.x_axis, by_corners.x_axis, atol=1e-12)
        np.testing.assert_allclose(frame.y_axis, by_corners.y_axis, atol=1e-12)
        np.testing.assert_allclose(frame.corners_m, corners, atol=1e-12)
        assert (frame.width_m, frame.height_m) == pytest.approx((by_corners.width_m, by_corners.height_m))
    assert (by_corners.width_m, by_corners.height_m) == pytest.approx((2.0, 1.0))


def test_from_points_makes_rough_axis_hints_exact() -> None:
    # An origin 5 cm off the plane, an x hint with a component out of the wall and a
    # y hint leaning along x: the frame projects and orthogonalises them.
    frame = WallFrame.from_points(DATAWALL_CORNERS[:3], [0, 0, 0.05], [1, 0, 0.2], [0.3, 1, 0], WIDTH_M, HEIGHT_M)
    np.testing.assert_allclose(frame.origin_m, [0, 0, 0], atol=1e-15)
    np.testing.assert_allclose(frame.x_axis, [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(frame.y_axis, [0, 1, 0], atol=1e-15)


def test_frame_from_nearly_coplanar_corners_keeps_its_origin_on_the_plane() -> None:
    # Corners measured with a few millimetres of error (within the 10 mm tolerance):
    # the frame's origin must lie on the plane it reports, as from_points makes it.
    corners = DATAWALL_CORNERS + np.array([[0, 0, 0.004], [0, 0, -0.004], [0, 0, 0.004], [0, 0, -0.004]])
    # Regression: from_corners took corner 0 as the origin as measured, 4 mm off the
    # fitted plane, so the frame's plane was that far from the best fit.
    frame = WallFrame.from_corners(corners)
    distances = frame.plane.signed_distance_m(corners)
    np.testing.assert_allclose(distances, [0.004, -0.004, 0.004, -0.004], atol=1e-12)
    np.testing.assert_allclose(np.abs(frame.fit_residuals_m), np.abs(distances), atol=1e-12)
    np.testing.assert_allclose(frame.origin_m, [0, 0, 0], atol=1e-12)


def test_corners_that_are_not_coplanar_are_rejected() -> None:
    corners = DATAWALL_CORNERS + np.array([[0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0.2]])
    with pytest.raises(GeometryError, match=r"corners_m are not coplanar.*tolerance 10.0 mm"):
        WallFrame.from_corners(corners)
    frame = WallFrame.from_corners(corners, planarity_tolerance_m=0.06)  # +-50 mm residuals
    assert np.max(np.abs(frame.fit_residuals_m)) == pytest.approx(0.05, abs=1e-3)


def test_one_stray_point_among_many_is_named() -> None:
    pts = np.array([[x, y, 0.0] for x in (0.0, 1.0, 2.0) for y in (0.0, 1.0)])
    pts[4, 2] = 0.1
    with pytest.raises(GeometryError, match=r"check points_m\[4\]"):
        WallFrame.from_points(pts, [0, 0, 0], [1, 0, 0], [0, 1, 0], 2.0, 1.0)


def test_axis_hints_that_do_not_fix_a_frame_are_rejected() -> None:
    with pytest.raises(GeometryError, match="x direction"):
        WallFrame.from_points(DATAWALL_CORNERS[:3], [0, 0, 0], [0, 0, 1], [0, 1, 0], 1.0, 1.0)
    with pytest.raises(GeometryError, match="y direction"):
        WallFrame.from_points(DATAWALL_CORNERS[:3], [0, 0, 0], [1, 0, 0], [2, 0, 0], 1.0, 1.0)


def test_axis_hints_nearly_along_the_normal_or_each_other_are_rejected() -> None:
    # Regression: a wall 1 mm off flat with x_direction = [0, 0, 1] gave an x axis 45 degrees
    # from anything the operator meant, decided by the bump.
    bumped = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.001], [2.0, 1.0, 0.0]])
    with pytest.raises(GeometryError, match=r"x direction points (8\d|90)\.\d degrees out of the wall's plane"):
        WallFrame.from_points(bumped, [0, 0, 0], [0, 0, 1], [0, 1, 0], 2.0, 1.0, None, 0.01)
    with pytest.raises(GeometryError, match=r"y direction is 2\d\.\d degrees from its x direction"):
        WallFrame.from_points(bumped, [0, 0, 0], [1, 0, 0], [1, 0.5, 0], 2.0, 1.0, None, 0.01)
    # A direction measured a few degrees off is still fine, and squared up in the plane.
    frame = WallFrame.from_points(bumped, [0, 0, 0], [1, 0.05, 0.08], [0.03, 1, 0], 2.0, 1.0, None, 0.01)
    assert abs(float(frame.x_axis @ frame.y_axis)) < 1e-12
    assert float(frame.x_axis[0]) > 0.99


def test_display_pixels_of_the_wall_corners(datawall_wall: WallFrame) -> None:
    wall_xy = datawall_wall.to_wall_m(datawall_wall.corners_m)
    np.testing.assert_allclose(wall_xy, [[0, 0], [WIDTH_M, 0], [WIDTH_M, HEIGHT_M], [0, HEIGHT_M]], atol=1e-15)
    # bottom-left, bottom-right, top-right, top-left -> the display's own corners, y down
    np.testing.assert_allclose(
        datawall_wall.to_display_px(wall_xy),
        [[0, 1920], [7680, 1920], [7680, 0], [0, 0]],
        atol=1e-9,
    )
    np.testing.assert_allclose(datawall_wall.to_display_px([WIDTH_M / 2, HEIGHT_M / 2]), [3840, 960], atol=1e-9)


def test_display_pixels_need_a_display_size() -> None:
    frame = WallFrame.from_corners(DATAWALL_CORNERS)
    assert not frame.has_display
    with pytest.raises(ValueError, match="no display size"):
        frame.to_display_px([1.0, 0.5])


def test_on_wall_includes_its_edges_and_nothing_beyond(datawall_wall: WallFrame) -> None:
    eps = 1e-9
    inside = [[0, 0], [WIDTH_M, HEIGHT_M], [WIDTH_M, 0], [0, HEIGHT_M], [1.0, 0.5]]
    outside = [[-eps, 0.5], [WIDTH_M + eps, 0.5], [1.0, -eps], [1.0, HEIGHT_M + eps], [-1.0, -1.0]]
    assert datawall_wall.on_wall(np.array(inside, dtype=float)).tolist() == [True] * 5
    assert datawall_wall.on_wall(np.array(outside, dtype=float)).tolist() == [False] * 5


@settings(max_examples=200, deadline=None)
@given(x=st.floats(-2.0, 4.0), y=st.floats(-1.0, 2.0))
def test_property_wall_coordinates_round_trip(x: float, y: float) -> None:
    frame = WallFrame.from_corners(tilted_corners())
    world = frame.from_wall_m(np.array([x, y]))
    assert abs(frame.plane.signed_distance_m(world)) < 1e-9
    np.testing.assert_allclose(frame.to_wall_m(world), [x, y], atol=1e-9)


# ----------------------------------------------------------------- end to end


@settings(max_examples=200, deadline=None)
@given(
    target=st.tuples(st.floats(0.2, WIDTH_M - 0.2), st.floats(0.1, HEIGHT_M - 0.1)),
    front=st.tuples(st.floats(1.0, 2.8), st.floats(0.6, 1.5), st.floats(1.3, 2.6)),
    length_m=st.floats(0.3, 0.6),
)
def test_property_pointer_seen_by_both_cameras_hits_where_it_points(
    simulated_cameras: list[CameraModel],
    datawall_wall: WallFrame,
    target: tuple[float, float],
    front: tuple[float, float, float],
    length_m: float,
) -> None:
    # A pointer whose front end is at `front`, aimed at a known spot on the wall: project
    # both ends into both cameras, triangulate each, extend the line to the wall.
    aim_m = datawall_wall.from_wall_m(np.array(target))
    front_m = np.array(front)
    back_m = front_m + length_m * (front_m - aim_m) / np.linalg.norm(front_m - aim_m)
    ends = []
    for end in (back_m, front_m):
        pixels = [cam.project(end) for cam in simulated_cameras]
        assume(all(cam.contains(px)[0] for cam, px in zip(simulated_cameras, pixels, strict=True)))
        (o1, d1), (o2, d2) = (cam.pixel_to_ray(px) for cam, px in zip(simulated_cameras, pixels, strict=True))
        ends.append(closest_approach(o1[0], d1[0], o2[0], d2[0]).midpoint_m)
    hit = intersect_line_plane(ends[0], ends[1], datawall_wall.plane)
    assert hit.u > 1.0  # beyond the front end, ahead of the pointer
    wall_xy = datawall_wall.to_wall_m(hit.point_m)
    np.testing.assert_allclose(wall_xy, target, atol=1e-9)
    assert datawall_wall.on_wall(wall_xy)
