"""The other ball from one ball's point and the rod's image direction in each camera
(trackerd/geometry/rod_axis.py)."""

from __future__ import annotations

import math

import numpy as np

from trackerd.geometry.camera import CameraModel
from trackerd.geometry.rod_axis import other_ball_along_rod
from trackerd.sim.random_cameras import aimed_camera

BALL_R = 0.018
LENGTH = 0.42
FOUND = np.array([1.7, 0.6, 1.5])
OTHER = FOUND + np.array([0.15, 0.05, 0.6]) / np.linalg.norm([0.15, 0.05, 0.6]) * LENGTH
TARGET = np.array([1.8, 0.6, 1.2])


def _camera(name: str, position) -> CameraModel:
    return aimed_camera(name, np.asarray(position, float), TARGET, 1920, 1080, 60.0)


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


def test_cameras_in_one_plane_with_the_pointer_give_no_prediction() -> None:
    """The second camera moved from the first along the pointer: both planes are the same plane, and the
    axis could lie anywhere in it."""
    first = np.array([-1.0, 1.4, 2.0])
    cameras = [_camera("left", first), _camera("left-along", first + 0.8 * (OTHER - FOUND) / LENGTH)]
    assert other_ball_along_rod(cameras, FOUND, _leaving(cameras), LENGTH, BALL_R, 3.0) == []
