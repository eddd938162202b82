"""Which way the rod leaves a ball (trackerd/detect/rod.py), on rendered frames of the pointer."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.rooms import POINTER, room, waved
from trackerd.detect.colour import brightest_at, green_at, sample_grid
from trackerd.detect.rod import FAN_STEP_DEG, ROD_ABSENT, ROD_CLEAR, darker_share, rod_bearing, rod_leaving
from trackerd.joint.looks import ROD_DIRECTION_ERROR_DEG

ROD_SHARE = POINTER["rod_diameter_m"] / POINTER["end_diameter_m"]


def _turned(centre_px, point_px, degrees: float):
    """``point_px`` turned about ``centre_px`` by ``degrees`` (towards +y from +x)."""
    a = math.radians(degrees)
    d = np.asarray(point_px) - centre_px
    return centre_px + np.array([d[0] * math.cos(a) - d[1] * math.sin(a), d[0] * math.sin(a) + d[1] * math.cos(a)])


def _views():
    rig, renderer = room()
    rng = np.random.default_rng(5)
    for pose in waved(3):
        for index, camera in enumerate(rig.cameras):
            view = renderer.render(index, pose, rng)
            grid = sample_grid(camera.pixel_format, camera.width_px, camera.height_px)
            truth = view.truth
            ends = {
                c: (np.asarray(truth.centroid_px[c]), math.sqrt(truth.area_px[c] / math.pi)) for c in ("red", "blue")
            }
            yield view.image, grid, ends


@pytest.mark.parametrize("turn_deg", [0.0, 12.0, -25.0])
def test_the_rod_is_found_leaving_each_ball_towards_the_other(turn_deg: float) -> None:
    """Asked about the direction to the other ball, the rod lies along it; asked about a direction turned
    away from it, the rod is found turned back by as much, and none lies along the direction asked about."""
    checked = 0
    for image, grid, ends in _views():
        for colour, other in (("red", "blue"), ("blue", "red")):
            (centre, radius), (far, far_radius) = ends[colour], ends[other]
            bearing = rod_bearing(
                image, grid, centre, radius, _turned(centre, far, turn_deg), far_radius, ROD_SHARE * radius
            )
            assert bearing is not None
            assert bearing.evidence >= ROD_CLEAR
            assert abs(bearing.offset_deg + turn_deg) <= 2 * FAN_STEP_DEG, (bearing, turn_deg)
            if turn_deg == 0.0:
                assert bearing.evidence_toward >= ROD_CLEAR
            else:
                assert bearing.evidence_toward <= ROD_ABSENT
            checked += 1
    assert checked == 12


def test_beside_a_candidate_touching_the_ball_the_rod_is_found_where_it_leaves() -> None:
    """A candidate touching the ball leaves no room for a rod between them: the fan is examined over the
    longest reach, and the rod is found leaving the ball where it does, not towards the candidate."""
    checked = 0
    for image, grid, ends in _views():
        (centre, radius), (far, _) = ends["red"], ends["blue"]
        along = (far - centre) / np.linalg.norm(far - centre)
        touching = _turned(centre, centre + (2.0 * radius + 2.0) * along, 20.0)
        bearing = rod_bearing(image, grid, centre, radius, touching, radius, ROD_SHARE * radius)
        assert bearing is not None
        assert bearing.evidence >= ROD_CLEAR and bearing.evidence_toward <= ROD_ABSENT, bearing
        assert abs(bearing.offset_deg + 20.0) <= 2 * FAN_STEP_DEG, bearing
        checked += 1
    assert checked == 6


def test_a_dark_line_over_a_red_picture_shows_in_the_brightest_colour_not_in_green() -> None:
    """The shared measurement under both uses: a grey line drawn 30 degrees from +x on a saturated red
    surface. Read in each pixel's brightest colour (the rod's check) it is there and nowhere else; read in
    green (the selection's rod evidence) it cannot show, since green is as dark off the line as on it."""
    grid = sample_grid("RGB8", 200, 160)
    frame = np.zeros(grid.frame_shape, np.uint8)
    frame[..., 0] = 220  # red picture
    frame[..., 1] = 30
    frame[..., 2] = 40
    origin = np.array([40.0, 40.0])
    yy, xx = np.mgrid[0:160, 0:200]
    line_direction = np.array([math.cos(math.radians(30)), math.sin(math.radians(30))])
    distance_off_px = np.abs((xx - origin[0]) * line_direction[1] - (yy - origin[1]) * line_direction[0])
    frame[distance_off_px <= 1.5] = (25, 25, 25)  # the rod: dark in every colour
    angles = np.radians(np.arange(0, 61, 2))
    directions = np.stack([np.cos(angles), np.sin(angles)], axis=-1)

    bright = darker_share(frame, grid, origin, directions, 10.0, 80.0, 4.5, brightest_at)
    green = darker_share(frame, grid, origin, directions, 10.0, 80.0, 4.5, green_at)

    off_deg = np.abs(np.degrees(angles) - 30)
    assert bright[15] == 1.0  # 30 degrees
    # A direction a few degrees off still crosses the line near the origin, at its first point or so.
    assert bright[off_deg > 6].max() <= 1 / 12
    assert bright[off_deg > 14].max() == 0.0
    assert green.max() == 0.0


def test_the_rod_is_found_all_round_a_ball_without_being_told_where_the_other_is() -> None:
    """Asked about no direction (the other ball is not found), the clearest dark line leaving either ball is
    the rod, towards the other ball, and no line elsewhere is as clear."""
    checked = 0
    for image, grid, ends in _views():
        for colour, other in (("red", "blue"), ("blue", "red")):
            (centre, radius), (far, _) = ends[colour], ends[other]
            leaving = rod_leaving(image, grid, centre, radius, ROD_SHARE * radius)
            towards = (far - centre) / np.linalg.norm(far - centre)
            off_deg = math.degrees(math.acos(min(float(leaving.direction @ towards), 1.0)))
            assert leaving.evidence >= ROD_CLEAR and leaving.rival < leaving.evidence, leaving
            assert off_deg <= ROD_DIRECTION_ERROR_DEG, (off_deg, leaving)
            checked += 1
    assert checked == 12


def test_no_rod_leaves_a_ball_on_a_plain_surface() -> None:
    grid = sample_grid("RGB8", 200, 160)
    frame = np.full(grid.frame_shape, 180, np.uint8)
    yy, xx = np.mgrid[0:160, 0:200]
    frame[np.hypot(xx - 100, yy - 80) <= 10] = (200, 20, 20)
    leaving = rod_leaving(frame, grid, np.array([100.0, 80.0]), 10.0, 2.0)
    assert leaving.evidence == 0.0
