"""The locator: from end centroids (or images) to the pointer's line and wall hit (trackerd/locator.py).

Centroids here are the renderer's exact ground truth, so these tests isolate the
geometry from the detector; tests/detect and the accuracy benchmark cover the rest.
"""

from __future__ import annotations

import numpy as np
import pytest

from trackerd.geometry.camera import CameraModel
from trackerd.geometry.pointer_line import pointer_from_points
from trackerd.geometry.rotation import world_from_camera_ypr
from trackerd.locator import Locator
from trackerd.sim.scene import PointerPose, random_pose, true_wall_hit


def _truth_centroids(renderer, pose, rng, key="centroid_px"):
    views = [renderer.render(i, pose, rng, noise=False) for i in range(len(renderer.cameras))]
    return tuple({c: getattr(v.truth, key)[c] for c in ("red", "blue")} for v in views)


@pytest.fixture(scope="module")
def rendered_poses(renderer, simulated_rig):
    """Twenty random poses with their exact visible-region centroids in both cameras."""
    rng = np.random.default_rng(17)
    cases = []
    while len(cases) < 20:
        pose = random_pose(simulated_rig, rng)
        centroids = _truth_centroids(renderer, pose, rng)
        if all(np.all(np.isfinite(c[k])) for c in centroids for k in c):
            cases.append((pose, centroids))
    return cases


def test_exact_centroids_give_the_true_wall_hit(simulated_rig, renderer, rendered_poses) -> None:
    locator = Locator(simulated_rig)
    errors_mm = []
    for pose, centroids in rendered_poses:
        truth = true_wall_hit(pose, locator.wall)
        fix = locator.locate_centroids(centroids)
        assert fix.status in ("hit", "off_wall")
        assert fix.hit.on_wall == truth.on_wall or abs(truth.wall_xy_m[0]) < 0.01
        errors_mm.append(np.linalg.norm(fix.hit.wall_xy_m - truth.wall_xy_m) * 1000)
        # Ends lie within a few millimetres of the true centres (the rod's occlusion slides them).
        assert np.linalg.norm(fix.line.front_m - pose.front_m) < 0.005
        assert abs(fix.line.length_m - pose.length_m) < 0.01
    assert np.median(errors_mm) < 0.5
    assert np.max(errors_mm) < 3.0


def test_planes_beat_two_points_when_the_rod_hides_part_of_a_ball(simulated_rig, rendered_poses) -> None:
    """The report's two-point line inherits the along-pointer bias of occluded centroids; planes do not."""
    locator = Locator(simulated_rig)
    planes, points = [], []
    for pose, centroids in rendered_poses:
        truth = true_wall_hit(pose, locator.wall).wall_xy_m
        fix = locator.locate_centroids(centroids)
        planes.append(np.linalg.norm(fix.hit.wall_xy_m - truth))
        rays = [
            np.array(
                [
                    cam.pixel_to_ray(np.asarray(c[colour])[None])[1][0]
                    for cam, c in zip(locator.cameras, centroids, strict=True)
                ]
            )
            for colour in ("red", "blue")
        ]
        line = pointer_from_points(locator._centres, rays[0], rays[1])
        from trackerd.geometry.wall import intersect_line_plane

        hit = intersect_line_plane(line.back_m, line.front_m, locator.wall.plane).point_m
        points.append(np.linalg.norm(locator.wall.to_wall_m(hit) - truth))
    assert np.median(planes) < np.median(points) / 3


def test_reported_uncertainty_matches_the_spread_of_noisy_fixes(simulated_rig, rendered_poses) -> None:
    locator = Locator(simulated_rig)
    sigma = simulated_rig.locator.centroid_sigma_px
    rng = np.random.default_rng(0)
    _, centroids = rendered_poses[0]
    reported = locator.locate_centroids(centroids).uncertainty_m
    hits = []
    for _ in range(300):
        noisy = tuple({k: v + rng.normal(0, sigma, 2) for k, v in c.items()} for c in centroids)
        hits.append(locator.locate_centroids(noisy).hit.wall_xy_m)
    hits = np.array(hits)
    spread = np.sqrt(np.sum(np.var(hits, axis=0)))
    # Isotropic noise of sigma per axis has sigma across the pointer, which is all the estimate models.
    assert reported == pytest.approx(spread, rel=0.3)


def test_reported_uncertainty_is_the_moved_planes_spread(simulated_rig, rendered_poses) -> None:
    """The fix's uncertainty is the spread of its estimate's moved sets on the wall
    (trackerd/geometry/camera_set.py, held to a reference in tests/geometry/test_pointer_line.py),
    made with the rig's centroid sigma and the sphere correction the line had."""
    from trackerd.geometry.camera_set import estimate_line, hit_uncertainty_m

    locator = Locator(simulated_rig)
    sigma = simulated_rig.locator.centroid_sigma_px
    view = locator.camera_set
    radius = locator.pointer.end_diameter_m / 2.0
    for _, centroids in rendered_poses:
        fix = locator.locate_centroids(centroids)
        normalised = np.stack(
            [
                cam.normalized_from_pixels(np.array([c[locator.front_colour], c[locator.back_colour]]))
                for cam, c in zip(locator.cameras, centroids, strict=True)
            ]
        )
        estimate = estimate_line(normalised, view, locator._min_plane_sin, radius, sigma)
        np.testing.assert_array_equal(estimate.line.front_m, fix.line.front_m)
        assert fix.uncertainty_m == hit_uncertainty_m(estimate, locator.wall)
        # Twice the sigma, twice the spread: the moves are small enough to be linear.
        doubled = hit_uncertainty_m(
            estimate_line(normalised, view, locator._min_plane_sin, radius, 2 * sigma), locator.wall
        )
        assert doubled == pytest.approx(2 * fix.uncertainty_m, rel=1e-3)


def test_status_for_each_kind_of_failure(simulated_rig, renderer, rendered_poses) -> None:
    locator = Locator(simulated_rig)
    _, centroids = rendered_poses[0]
    # A missing end.
    missing = (dict(centroids[0], blue=None), centroids[1])
    fix = locator.locate_centroids(missing)
    assert fix.status == "not_found" and "blue" in fix.reason and not fix.found
    # Pointing away from the wall: swap which end is in front.
    swapped = tuple({"red": c["blue"], "blue": c["red"]} for c in centroids)
    fix = locator.locate_centroids(swapped)
    assert fix.status == "away" and fix.hit is None and fix.found
    # One camera sees a different pose: the rays do not meet, or the length is wrong.
    _, other_centroids = rendered_poses[1]
    mixed = (centroids[0], other_centroids[1])
    fix = locator.locate_centroids(mixed)
    assert fix.status == "rejected" and not fix.found


def test_pointing_off_the_display_and_parallel(simulated_rig, renderer) -> None:
    locator = Locator(simulated_rig)
    rng = np.random.default_rng(3)
    wall = locator.wall
    tip = wall.origin_m + np.array([1.8, 0.6, 2.0])
    off = PointerPose(tip, tip - 0.45 * np.array([0.2, -0.6, -1.0]) / np.linalg.norm([0.2, -0.6, -1.0]))
    fix = locator.locate_centroids(_truth_centroids(renderer, off, rng, key="centre_px"))
    assert fix.status == "off_wall" and fix.hit is not None and not fix.hit.on_wall
    parallel = PointerPose(tip, tip - np.array([0.45, 0.0, 0.0]))
    fix = locator.locate_centroids(_truth_centroids(renderer, parallel, rng, key="centre_px"))
    assert fix.status == "parallel"


def test_a_third_camera_needs_no_new_math(simulated_rig, renderer, rendered_poses) -> None:
    """N >= 2 cameras: add a camera above the wall and locate with all three."""
    pose, centroids = rendered_poses[2]
    base = renderer.cameras[0]
    third = CameraModel.from_pose(
        "top",
        base.width_px,
        base.height_px,
        base.matrix,
        np.zeros(0),
        np.array([1.8, 2.0, 0.3]),
        world_from_camera_ypr(180.0, -45.0, 0.0),
    )
    cameras = [*renderer.cameras, third]
    top = simulated_rig.cameras[0].model_copy(update={"id": "top"})
    rig = simulated_rig.model_copy(update={"cameras": (*simulated_rig.cameras, top)})
    locator = Locator(rig, cameras=cameras)
    third_centroids = {colour: third.project(pose.centre_of(colour, "red")[None])[0] for colour in ("red", "blue")}
    fix = locator.locate_centroids((*centroids, third_centroids))
    truth = true_wall_hit(pose, locator.wall).wall_xy_m
    assert fix.status in ("hit", "off_wall")
    assert np.linalg.norm(fix.hit.wall_xy_m - truth) < 0.003

    # The third camera misses an end (the presenter's hand over it): the two that saw both still
    # give the hit, from the same math as a two-camera rig.
    for missed in ("red", "blue"):
        partial = {**third_centroids, missed: None}
        fix3 = locator.locate_centroids((*centroids, partial))
        fix2 = Locator(simulated_rig, cameras=renderer.cameras).locate_centroids(centroids)
        assert fix3.status == fix2.status
        np.testing.assert_allclose(fix3.hit.wall_xy_m, fix2.hit.wall_xy_m, atol=1e-12)
        assert fix3.uncertainty_m == pytest.approx(fix2.uncertainty_m, rel=1e-9)
    # With only one camera seeing both ends there is nothing to triangulate: say who missed what.
    right_without_red = {"red": None, "blue": centroids[1]["blue"]}
    lonely = locator.locate_centroids((centroids[0], right_without_red, {**third_centroids, "blue": None}))
    assert lonely.status == "not_found"
    assert lonely.reason == "right: no red end; top: no blue end"


def test_a_third_camera_that_sees_nothing_does_not_stop_the_fix(simulated_rig, renderer) -> None:
    """From images: an empty view from a third camera leaves the other two to locate the pointer."""
    rng = np.random.default_rng(5)
    pose = random_pose(simulated_rig, rng)
    views = [renderer.render(i, pose, rng) for i in range(len(renderer.cameras))]
    empty = np.zeros_like(views[0].image)
    top = simulated_rig.cameras[0].model_copy(update={"id": "top"})
    rig = simulated_rig.model_copy(update={"cameras": (*simulated_rig.cameras, top)})
    fix3 = Locator(rig).locate([views[0].image, views[1].image, empty])
    fix2 = Locator(simulated_rig).locate([views[0].image, views[1].image])
    assert fix2.status in ("hit", "off_wall"), fix2.reason
    assert fix3.status == fix2.status
    np.testing.assert_allclose(fix3.hit.wall_xy_m, fix2.hit.wall_xy_m, atol=1e-12)
    assert not fix3.detections[2].red.found and not fix3.detections[2].blue.found


def test_a_pair_without_the_pointer_ends_tracking(simulated_rig, renderer) -> None:
    """After a pair whose ends make no pointer (each camera sees one, in different places: a camera bumped,
    or each detector on something else), every camera's detector searches its next frame in full instead of
    looking only where its windows were (Locator._lost), and the pointer is found again at once."""
    rng = np.random.default_rng(5)
    poses = [random_pose(simulated_rig, rng) for _ in range(2)]
    locator = Locator(simulated_rig)
    seen = [renderer.render(i, poses[0], rng).image for i in range(2)]
    assert locator.locate(seen).found
    assert [d.search for d in locator.locate(seen).detections] == ["window", "window"]
    torn = [renderer.render(0, poses[0], rng).image, renderer.render(1, poses[1], rng).image]
    fix = locator.locate(torn)
    assert not fix.found and [d.both_found for d in fix.detections] == [True, True], fix.reason
    again = locator.locate(seen)
    assert [d.search for d in again.detections] == ["full", "full"] and again.found, again.reason


def test_the_search_waits_longer_the_longer_nothing_is_found(simulated_rig, renderer, searches) -> None:
    """The pointer found, then 600 pairs without it (ten seconds at 60 pairs a second): the search over every
    camera's candidates runs every search_every_pairs-th pair for its first eight tries, then twice as long
    after each, up to search_longest_pairs (RefinedPath._search_wait): 13 searches, where the fixed cadence
    made 100 (each 0.2-0.9 s before a photo on the display). The pointer back, it is found at once."""
    rng = np.random.default_rng(5)
    pose = random_pose(simulated_rig, rng)
    seen = [renderer.render(i, pose, rng).image for i in range(2)]
    locator = Locator(simulated_rig)
    assert locator.locate(seen).found and not searches
    empty = [np.zeros_like(image) for image in seen]
    searched_at = []
    for pair in range(600):
        ran = len(searches)
        assert not locator.locate(empty).found
        searched_at += [pair] * (len(searches) - ran)
    every, longest = simulated_rig.locator.search_every_pairs, simulated_rig.locator.search_longest_pairs
    waits = np.diff(searched_at).tolist()
    assert searched_at[0] == 0 and waits[:7] == [every] * 7, searched_at
    assert waits[7:] == [min(every << k, longest) for k in range(1, len(waits) - 6)], searched_at
    assert len(searched_at) == 13, searched_at
    assert locator.locate(seen).found
