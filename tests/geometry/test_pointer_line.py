"""The pointer's line (trackerd/geometry/pointer_line.py, camera_set.py) against a plain reference written here.

The package computes every set of a pair (the measurement and its moved copies)
in one batched call of each function; the reference below takes one set at a
time, spelled the textbook way (np.cross, SVD, lstsq, eq. 17's closest approach),
so a batching or broadcasting mistake shows as a disagreement.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from trackerd.errors import GeometryError
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.camera_set import CameraSet, across_sigma_px, estimate_line, hit_uncertainty_m, moved_across
from trackerd.geometry.pointer_line import (
    MIN_PLANE_ANGLE_SIN,
    estimate_pointer_line,
    interpretation_plane_normals,
    lines_from_planes,
    sphere_centre_scale,
    world_rays,
)
from trackerd.geometry.triangulation import closest_approach, triangulate_least_squares
from trackerd.geometry.wall import WallFrame

# ----------------------------------------------------------------- the reference, one set at a time


def reference_planes_line(centres: np.ndarray, front_dirs: np.ndarray, back_dirs: np.ndarray):
    """(point nearest the centres' mean, unit direction, sine between the planes) of the planes' line."""
    normals = np.cross(front_dirs, back_dirs)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    _, singular, vt = np.linalg.svd(normals)
    direction = vt[-1]
    if len(normals) == 2:
        conditioning = float(np.linalg.norm(np.cross(normals[0], normals[1])))
    else:  # the eigenvalues of N^T N are the squared singular values
        conditioning = float(singular[0] * singular[1] / (len(normals) / 2.0))
    system = np.vstack([normals, direction])
    targets = np.append(np.sum(normals * centres, axis=1), direction @ centres.mean(axis=0))
    point = np.linalg.lstsq(system, targets, rcond=None)[0]
    return point, direction, conditioning


def reference_line(centres: np.ndarray, front_dirs: np.ndarray, back_dirs: np.ndarray, min_plane_sin: float):
    """(front, back, front gap, back gap, method) for one set of world rays (C, 3)."""
    point, direction, conditioning = reference_planes_line(centres, front_dirs, back_dirs)
    if conditioning < min_plane_sin:
        if len(centres) == 2:
            front = closest_approach(centres[0], front_dirs[0], centres[1], front_dirs[1])
            back = closest_approach(centres[0], back_dirs[0], centres[1], back_dirs[1])
            return front.midpoint_m, back.midpoint_m, float(front.gap_m), float(back.gap_m), "points"
        (front, front_d), (back, back_d) = (triangulate_least_squares(centres, d) for d in (front_dirs, back_dirs))
        return front, back, 2 * front_d.max(), 2 * back_d.max(), "points"
    ends, gaps = [], []
    for dirs in (front_dirs, back_dirs):
        # Eq. 17's closest approach of the line (as a ray from its point) to each camera's ray,
        # weighted by sin^2 of their angle.
        places, weights = [], []
        for centre, ray in zip(centres, dirs, strict=True):
            approach = closest_approach(point, direction, centre, ray)
            places.append(float(approach.s))
            weights.append(1.0 - (direction @ ray / np.linalg.norm(ray)) ** 2)
        ends.append(point + np.average(places, weights=weights) * direction)
        gaps.append(
            max(
                float(closest_approach(centres[i], dirs[i], centres[j], dirs[j]).gap_m)
                for i in range(len(centres))
                for j in range(i + 1, len(centres))
            )
        )
    return ends[0], ends[1], gaps[0], gaps[1], "planes"


def _scene(rng: np.random.Generator, cameras: int):
    """Cameras around a room and a pointer in front of them; rays a little off the ends, not of unit length."""
    angles = np.linspace(-1.2, 1.2, cameras) + rng.normal(0, 0.1, cameras)
    centres = np.column_stack([1.8 + 3.0 * np.sin(angles), 1.4 + rng.normal(0, 0.3, cameras), 3.0 * np.cos(angles)])
    middle = np.array([1.8, 1.0, 1.6]) + rng.normal(0, 0.4, 3)
    axis = rng.normal(0, 1, 3)
    axis /= np.linalg.norm(axis)
    front, back = middle + 0.225 * axis, middle - 0.225 * axis
    front_dirs = (front - centres + rng.normal(0, 0.002, (cameras, 3))) * rng.uniform(0.5, 2.0, (cameras, 1))
    back_dirs = (back - centres + rng.normal(0, 0.002, (cameras, 3))) * rng.uniform(0.5, 2.0, (cameras, 1))
    return centres, front_dirs, back_dirs


# ----------------------------------------------------------------- the batched functions


@pytest.mark.parametrize("cameras", [2, 3, 4])
def test_batched_planes_lines_are_the_reference_set_by_set(cameras: int) -> None:
    rng = np.random.default_rng(cameras)
    scenes = [_scene(rng, cameras) for _ in range(60)]
    centres = scenes[0][0]
    # One rig: every set shares the first scene's centres, with each scene's rays.
    front = np.stack([s[1] for s in scenes])
    back = np.stack([s[2] for s in scenes])
    points, directions, conditioning = lines_from_planes(centres, interpretation_plane_normals(front, back))
    assert points.shape == (60, 3) and directions.shape == (60, 3) and conditioning.shape == (60,)
    for index in range(60):
        point, direction, sine = reference_planes_line(centres, front[index], back[index])
        assert conditioning[index] == pytest.approx(sine, abs=1e-12)
        np.testing.assert_allclose(abs(directions[index] @ direction), 1.0, atol=1e-12)  # either sign
        np.testing.assert_allclose(points[index], point, atol=1e-9)


@pytest.mark.parametrize("cameras", [2, 3, 4])
def test_the_pointer_line_is_the_reference(cameras: int) -> None:
    rng = np.random.default_rng(10 + cameras)
    methods = []
    for _ in range(300):
        centres, front_dirs, back_dirs = _scene(rng, cameras)
        line = estimate_pointer_line(centres, front_dirs, back_dirs)
        front, back, front_gap, back_gap, method = reference_line(centres, front_dirs, back_dirs, MIN_PLANE_ANGLE_SIN)
        assert line.method == method
        np.testing.assert_allclose(line.front_m, front, atol=1e-9)
        np.testing.assert_allclose(line.back_m, back, atol=1e-9)
        assert line.front_gap_m == pytest.approx(front_gap, abs=1e-12)
        assert line.back_gap_m == pytest.approx(back_gap, abs=1e-12)
        methods.append(method)
    assert methods.count("planes") > 200
    if cameras == 2:
        assert "points" in methods  # nearly parallel planes happen in these scenes, and are tried


def test_world_rays_are_each_cameras_rotation_applied(simulated_cameras) -> None:
    view = CameraSet.build(simulated_cameras)
    normalised = np.random.default_rng(1).normal(0, 0.3, (5, 2, 2, 2))
    rays = world_rays(normalised, view.rotations)
    for b, k, e in np.ndindex(5, 2, 2):
        expected = simulated_cameras[k].rotation.T @ np.append(normalised[b, k, e], 1.0)
        np.testing.assert_allclose(rays[b, k, e], expected, atol=1e-15)


# ----------------------------------------------------------------- one pair's estimate and its spread


def _looking_at(camera_id: str, like: CameraModel, position_m: np.ndarray, target_m: np.ndarray) -> CameraModel:
    """A lens-free camera with ``like``'s intrinsics at ``position_m`` looking at ``target_m`` (image y down)."""
    forward = (target_m - position_m) / np.linalg.norm(target_m - position_m)
    right = np.cross([0.0, -1.0, 0.0], forward)
    right /= np.linalg.norm(right)
    axes = np.column_stack([right, np.cross(forward, right), forward])
    return CameraModel.from_pose(camera_id, like.width_px, like.height_px, like.matrix, np.zeros(0), position_m, axes)


@pytest.fixture(params=[2, 3], ids=["2 cameras", "3 cameras"])
def rig_cameras(request, simulated_cameras) -> list[CameraModel]:
    """The simulated rig's two cameras, or those and a third above and behind the room's middle."""
    if request.param == 2:
        return list(simulated_cameras)
    above = _looking_at("above", simulated_cameras[0], np.array([1.8, 2.6, 4.0]), np.array([1.8, 0.7, 1.5]))
    return [*simulated_cameras, above]


def _random_pointer(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    middle = np.array([rng.uniform(0.5, 3.0), rng.uniform(0.3, 1.2), rng.uniform(1.0, 2.5)])
    axis = np.array([rng.normal(0, 0.3), rng.normal(0, 0.3), -1.0])
    axis /= np.linalg.norm(axis)
    return middle + 0.2 * axis, middle - 0.2 * axis


def _normalised_of(cameras, front_m: np.ndarray, back_m: np.ndarray) -> np.ndarray:
    """Exact normalised coordinates (C, 2 ends, 2) of two points (no lens, so no undistortion's rounding)."""
    in_camera = [cam.to_camera_frame(np.stack([front_m, back_m])) for cam in cameras]
    return np.stack([points[:, :2] / points[:, 2:] for points in in_camera])


def _reference_hit_xy(view: CameraSet, normalised: np.ndarray, wall: WallFrame) -> np.ndarray:
    rays = [[cam.rotation.T @ np.append(normalised[k, e], 1.0) for e in (0, 1)] for k, cam in enumerate(view.cameras)]
    point, direction, _ = reference_planes_line(
        view.centres_m, np.array([r[0] for r in rays]), np.array([r[1] for r in rays])
    )
    plane = wall.plane
    hit = point - (plane.signed_distance_m(point) / (direction @ plane.normal)) * direction
    return wall.to_wall_m(hit)


def test_the_pairs_line_is_the_reference(rig_cameras) -> None:
    """What the locator takes: estimate_line's line from normalised coordinates, against the reference on
    the same rays (the batched sets' axes (set, camera, end) turned into the reference's (end, camera))."""
    view = CameraSet.build(rig_cameras)
    rng = np.random.default_rng(6)
    methods: list[str] = []
    for _ in range(20):
        normalised = _normalised_of(rig_cameras, *_random_pointer(rng)) + rng.normal(0, 2e-4, (len(rig_cameras), 2, 2))
        line = estimate_line(normalised, view, MIN_PLANE_ANGLE_SIN, None, across_px=0.5).line
        rays = np.array(
            [[cam.rotation.T @ np.append(normalised[k, e], 1.0) for k, cam in enumerate(rig_cameras)] for e in (0, 1)]
        )
        front, back, front_gap, back_gap, method = reference_line(view.centres_m, rays[0], rays[1], MIN_PLANE_ANGLE_SIN)
        assert line.method == method
        methods.append(method)
        np.testing.assert_allclose(line.front_m, front, atol=1e-9)
        np.testing.assert_allclose(line.back_m, back, atol=1e-9)
        assert line.front_gap_m == pytest.approx(front_gap, abs=1e-12)
        assert line.back_gap_m == pytest.approx(back_gap, abs=1e-12)
        assert line.front_gap_m > 1e-5  # the noise makes the rays miss: the gaps are measured, not zero
    assert methods.count("planes") >= 15


def test_the_moved_sets_and_the_spread_are_the_reference_set_by_set(rig_cameras, datawall_wall) -> None:
    """Every moved set's line is what the same coordinates give alone, and the uncertainty is the spread
    of those sets' planes' wall hits around the measurement's, summed in quadrature."""
    view = CameraSet.build(rig_cameras)
    cameras = len(rig_cameras)
    rng = np.random.default_rng(4)
    for _ in range(10):
        normalised = _normalised_of(rig_cameras, *_random_pointer(rng))
        estimate = estimate_line(normalised, view, MIN_PLANE_ANGLE_SIN, None, across_px=0.5)
        sets = moved_across(normalised, view.focal_px, 0.5)
        assert sets.shape == (1 + 2 * cameras, cameras, 2, 2)
        for index, moved in enumerate(sets):
            changed = np.argwhere(np.any(moved != normalised, axis=-1))
            if index == 0:
                assert len(changed) == 0
                continue
            # Set 1 + 2k + e moves camera k's end e, by 0.5 px across camera k's image of the pointer.
            assert changed.tolist() == [[(index - 1) // 2, (index - 1) % 2]]
            k, e = changed[0]
            shift = (moved[k, e] - normalised[k, e]) * view.focal_px[k]
            along = normalised[k, 0] - normalised[k, 1]
            assert np.linalg.norm(shift) == pytest.approx(0.5, rel=1e-12)
            assert abs(shift @ along) < 1e-12
            alone = estimate_line(moved, view, MIN_PLANE_ANGLE_SIN, None)
            np.testing.assert_allclose(estimate.plane_points_m[index], alone.plane_points_m[0], atol=1e-12)
        hits = np.array([_reference_hit_xy(view, moved, datawall_wall) for moved in sets])
        expected = np.sqrt(np.sum((hits[1:] - hits[0]) ** 2))
        assert hit_uncertainty_m(estimate, datawall_wall) == pytest.approx(expected, rel=1e-9)
        # A camera's two ends erring together (correlation rho across the pointer): each camera's two moves
        # add as vectors with weight rho, v_f^2 + v_b^2 + 2 rho v_f . v_b.
        moves = (hits[1:] - hits[0]).reshape(cameras, 2, 2)
        for rho in (0.3, 1.0):
            correlated = np.sum(moves**2) + 2.0 * rho * np.sum(moves[:, 0] * moves[:, 1])
            assert hit_uncertainty_m(estimate, datawall_wall, rho) == pytest.approx(np.sqrt(correlated), rel=1e-9)
        together = np.sum(np.sum(moves, axis=1) ** 2)  # rho 1: both ends of a camera moved at once
        assert hit_uncertainty_m(estimate, datawall_wall, 1.0) == pytest.approx(np.sqrt(together), rel=1e-9)


def test_each_end_moves_by_its_own_error_across_the_pointer(rig_cameras) -> None:
    """With one distance per end, set 1 + 2k + e moves camera k's end e by that end's distance; and an end's
    error across the pointer is its covariance read in that direction, whatever its error along."""
    view = CameraSet.build(rig_cameras)
    rng = np.random.default_rng(5)
    normalised = _normalised_of(rig_cameras, *_random_pointer(rng))
    distances = rng.uniform(0.05, 0.5, size=(len(rig_cameras), 2))
    sets = moved_across(normalised, view.focal_px, distances)
    for index, moved in enumerate(sets[1:]):
        k, e = index // 2, index % 2
        shift = (moved[k, e] - normalised[k, e]) * view.focal_px[k]
        assert np.linalg.norm(shift) == pytest.approx(distances[k, e], rel=1e-12)
    # Covariances 0.3 px along each camera's image of the pointer and 0.1 px across it (or 0.2, the back end).
    along = normalised[:, 0] - normalised[:, 1]
    along /= np.linalg.norm(along, axis=-1, keepdims=True)
    across = np.stack([-along[:, 1], along[:, 0]], axis=-1)
    covariances = np.empty((len(rig_cameras), 2, 2, 2))
    for k in range(len(rig_cameras)):
        for e, across_px in enumerate((0.1, 0.2)):
            covariances[k, e] = (
                0.3**2 * np.outer(along[k], along[k]) + across_px**2 * np.outer(across[k], across[k])
            ) / view.focal_px[k] ** 2
    np.testing.assert_allclose(
        across_sigma_px(normalised, covariances, view.focal_px), np.tile([0.1, 0.2], (len(rig_cameras), 1)), rtol=1e-9
    )


def test_the_sphere_correction_scales_each_end_by_its_own_depth(rig_cameras) -> None:
    """A ball's image centroid lies (1 - r^2 / Z^2) further from the image centre than its centre's image:
    the corrected line is the line of the coordinates scaled by each end's depth in each camera, the
    depth at which that end's rays triangulate."""
    view = CameraSet.build(rig_cameras)
    rng = np.random.default_rng(5)
    front, back = np.array([1.2, 0.8, 0.9]), np.array([1.1, 0.7, 1.3])
    normalised = _normalised_of(rig_cameras, front, back) + rng.normal(0, 1e-4, (len(rig_cameras), 2, 2))
    radius = 0.2  # a huge ball, so that the correction is far above rounding
    plain = estimate_line(normalised, view, MIN_PLANE_ANGLE_SIN, None).line
    corrected = estimate_line(normalised, view, MIN_PLANE_ANGLE_SIN, radius).line
    depths = np.zeros((len(rig_cameras), 2))
    for end in (0, 1):
        rays = np.array([cam.rotation.T @ np.append(normalised[k, end], 1.0) for k, cam in enumerate(rig_cameras)])
        point, _ = triangulate_least_squares(view.centres_m, rays)
        depths[:, end] = [cam.to_camera_frame(point[None])[0, 2] for cam in rig_cameras]
    scaled = normalised * sphere_centre_scale(depths, radius)[..., None]
    again = estimate_line(scaled, view, MIN_PLANE_ANGLE_SIN, None).line
    np.testing.assert_allclose(corrected.front_m, again.front_m, atol=1e-12)
    np.testing.assert_allclose(corrected.back_m, again.back_m, atol=1e-12)
    assert np.linalg.norm(corrected.front_m - plain.front_m) > 1e-3


def test_degenerate_views_are_refused_or_fall_back(simulated_cameras) -> None:
    centres = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    view = CameraSet.build(simulated_cameras)
    with pytest.raises(GeometryError, match="undefined"):
        estimate_line(
            np.array([[[0.1, 0.2], [np.nan, 0.1]], [[0.0, 0.1], [0.2, 0.3]]]), view, MIN_PLANE_ANGLE_SIN, 0.02, 0.5
        )
    with pytest.raises(GeometryError, match="end-on"):
        estimate_pointer_line(centres, [[0.0, 0.0, 1.0], [0.0, 0.1, 1.0]], [[0.0, 0.0, 2.0], [0.1, 0.0, 1.0]])
    # Both planes the same plane (the pointer in the plane of the baseline): the two triangulated points.
    line = estimate_pointer_line(centres, [[0.2, 0.0, 1.0], [-0.2, 0.0, 1.0]], [[0.4, 0.0, 1.0], [0.1, 0.0, 1.0]])
    assert line.method == "points" and line.plane_angle_sin < 1e-12
    normals = interpretation_plane_normals(
        np.array([[[0.2, 0.0, 1.0], [-0.2, 0.0, 1.0]], [[0.2, 0.1, 1.0], [-0.2, 0.0, 1.0]]]),
        np.array([[[0.4, 0.0, 1.0], [0.1, 0.0, 1.0]], [[0.4, 0.0, 1.0], [0.1, 0.0, 1.0]]]),
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no division by zero on the way
        points, _, conditioning = lines_from_planes(centres, normals)
    assert np.all(np.isnan(points[0])) and conditioning[0] < 1e-12  # parallel: no point
    assert np.all(np.isfinite(points[1])) and conditioning[1] > 0.01  # the other set is unaffected


def test_no_spread_for_a_line_parallel_to_the_wall(simulated_cameras, datawall_wall) -> None:
    view = CameraSet.build(simulated_cameras)
    # Upright at constant depth: the planes' line never meets the wall's plane.
    normalised = _normalised_of(simulated_cameras, np.array([1.5, 0.8, 1.5]), np.array([1.5, 0.4, 1.5]))
    estimate = estimate_line(normalised, view, MIN_PLANE_ANGLE_SIN, None, across_px=0.5)
    assert abs(estimate.plane_directions[0] @ datawall_wall.plane.normal) < 1e-9
    assert hit_uncertainty_m(estimate, datawall_wall) is None
    assert hit_uncertainty_m(estimate_line(normalised, view, MIN_PLANE_ANGLE_SIN, None), datawall_wall) is None
