"""Scene description and random poses (trackerd/sim/scene.py)."""

from __future__ import annotations

import numpy as np

from trackerd.config.rig_geometry import camera_model, wall_frame
from trackerd.sim.scene import PointerPose, build_room, pose_aimed_at, pose_visible, random_pose, true_wall_hit


def test_random_poses_point_at_the_wall_and_are_seen_by_both_cameras(simulated_rig) -> None:
    rng = np.random.default_rng(0)
    wall = wall_frame(simulated_rig.wall)
    cameras = [camera_model(c) for c in simulated_rig.cameras]
    on_wall = 0
    for _ in range(100):
        pose = random_pose(simulated_rig, rng, cameras, wall)
        assert abs(pose.length_m - simulated_rig.pointer.length_m) < 1e-12
        assert pose_visible(pose, cameras)
        hit = true_wall_hit(pose, wall)
        assert hit.wall_xy_m is not None
        on_wall += hit.on_wall
        low, high = simulated_rig.simulation.presenter_distance_m
        assert low - 1e-9 <= wall.plane.signed_distance_m(pose.front_m) <= high + 1e-9
    # 90 % are aimed inside the display by default.
    assert 80 <= on_wall <= 98


def test_true_hit_of_an_aimed_pose_is_its_target(simulated_rig) -> None:
    wall = wall_frame(simulated_rig.wall)
    target = wall.from_wall_m(np.array([1.0, 0.5]))
    pose = pose_aimed_at(np.array([2.0, 0.6, 1.8]), target, 0.45)
    hit = true_wall_hit(pose, wall)
    np.testing.assert_allclose(hit.wall_xy_m, [1.0, 0.5], atol=1e-12)
    assert hit.on_wall
    away = PointerPose(pose.back_m, pose.front_m)
    assert true_wall_hit(away, wall).wall_xy_m is None


def test_room_is_reproducible_and_holds_the_cameras(simulated_rig) -> None:
    wall = wall_frame(simulated_rig.wall)
    room = build_room(simulated_rig, wall)
    assert room.fingerprint == build_room(simulated_rig, wall).fingerprint
    assert len(room.patches) + len(room.balls) == simulated_rig.simulation.clutter
    lower, upper = np.array(room.lower_m), np.array(room.upper_m)
    for cam in simulated_rig.cameras:
        centre = camera_model(cam).centre_m
        assert np.all(centre > lower) and np.all(centre < upper)
