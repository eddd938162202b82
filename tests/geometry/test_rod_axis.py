"""The other ball from one ball's point and the rod's image direction in each camera
(trackerd/geometry/rod_axis.py)."""

from __future__ import annotations

import math

import numpy as np

from trackerd.geometry.camera import CameraModel
from trackerd.geometry.rod_axis import other_ball_along_rod

K = np.array([[1600.0, 0.0, 960.0], [0.0, 1600.0, 540.0], [0.0, 0.0, 1.0]])
BALL_R = 0.018
LENGTH = 0.42
FOUND = np.array([1.7, 0.6, 1.5])
OTHER = FOUND + np.array([0.15, 0.05, 0.6]) / np.linalg.norm([0.15, 0.05, 0.6]) * LENGTH


def _camera(name: str, position, target=(1.8, 0.6, 1.2)) -> CameraModel:
    position = np.asarray(position, float)
    forward = np.asarray(target, float) - position
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    return CameraModel.from_pose(
        name, 1920, 1080, K, np.zeros(0), position, np.column_stack([right, np.cross(forward, right), forward])
    )


SIDE = [_camera("left", [-1.0, 1.4, 2.0]), _camera("right", [4.6, 1.4, 2.0])]
# Behind the presenter, both above the pointer's line, one nearer: their planes through it 9 degrees apart
# (side-on: 31).
BEHIND = [_camera("back", [2.6, 1.9, 5.6]), _camera("back-near", [2.0, 1.9, 4.0])]


def _leaving(cameras, turn_deg=None):
    """Each camera's (found ball's centre, unit direction to the other ball); camera k's turned by turn_deg."""
    leaving = {}
    for index, camera in enumerate(cameras):
        found, other = camera.project(np.stack([FOUND, OTHER]))
        direction = (other - found) / np.linalg.norm(other - found)
        if turn_deg is not None and turn_deg[0] == index:
            a = math.radians(turn_deg[1])
            direction = np.array(
                [
                    direction[0] * math.cos(a) - direction[1] * math.sin(a),
                    direction[0] * math.sin(a) + direction[1] * math.cos(a),
                ]
            )
        leaving[index] = (found, direction)
    return leaving


def test_exact_directions_put_the_other_ball_where_each_camera_sees_it() -> None:
    for cameras in (SIDE, BEHIND):
        sightings = other_ball_along_rod(cameras, FOUND, _leaving(cameras), LENGTH, BALL_R, 3.0)
        assert [s.camera for s in sightings] == [0, 1]
        for sighting in sightings:
            camera = cameras[sighting.camera]
            truth = camera.project(OTHER[None])[0]
            assert np.hypot(*(sighting.expected_px - truth)) < 1e-6
            expected_radius = camera.focal_px * BALL_R / np.linalg.norm(OTHER - camera.centre_m)
            assert abs(sighting.radius_px - expected_radius) < 1e-9


def test_a_direction_off_by_less_than_the_error_moves_the_ball_less_than_the_spread() -> None:
    """And the spread is several times larger where the cameras' planes are nearly parallel (behind the
    presenter) than side-on: there the look must cover more of the rod's line."""
    spreads = {}
    for name, cameras in (("side", SIDE), ("behind", BEHIND)):
        nominal = other_ball_along_rod(cameras, FOUND, _leaving(cameras), LENGTH, BALL_R, 3.0)
        spreads[name] = [s.spread_px for s in nominal]
        for turned in (0, 1):
            for turn_deg in (-2.5, 1.5, 2.5):
                moved = other_ball_along_rod(cameras, FOUND, _leaving(cameras, (turned, turn_deg)), LENGTH, BALL_R, 3.0)
                for before, after in zip(nominal, moved, strict=True):
                    shift = float((after.expected_px - before.expected_px) @ before.along)
                    assert abs(shift) <= before.spread_px, (name, turned, turn_deg, shift, before.spread_px)
    assert min(spreads["behind"]) > 3.0 * max(spreads["side"]), spreads


def test_one_camera_or_rods_that_disagree_give_no_prediction() -> None:
    leaving = _leaving(SIDE)
    assert other_ball_along_rod(SIDE, FOUND, {0: leaving[0]}, LENGTH, BALL_R, 3.0) == []
    # The right camera's rod leaving the other way: no side of the found ball is along both.
    reversed_right = {0: leaving[0], 1: (leaving[1][0], -leaving[1][1])}
    assert other_ball_along_rod(SIDE, FOUND, reversed_right, LENGTH, BALL_R, 3.0) == []
