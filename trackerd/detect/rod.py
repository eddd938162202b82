"""Which way the pointer's rod leaves a ball, in one image.

The rod is the one thing joining the two balls. Where it crosses anything lighter than it (the wall, a
picture, a shirt) it shows as a dark line a few pixels wide, and that line leaves each ball towards the
other. So where a camera measured both ends, the rod at one of them says whether what was measured as the
other is that ball: a rod that clearly leaves the first ball some degrees away from it, and no rod towards
it, says it is not (`bench robustness --seed 11`, installation 12, frame 14: the edge of a navy sleeve 66
px from a red ball, taken for the blue ball the sleeve hid, while the rod left the red ball 14 degrees
away).

A verdict needs a clear dark line in some direction: over a dark background, a hand or the presenter's
body, no line shows, and the answer is "nothing clear". A line that is not the rod can still give one (a
picture's edge or a stroke of text leaving the ball's rim while the rod itself is hidden near the ball):
over every hit of `bench robustness` seeds 7, 2026 and 11, one correct measurement in 22,421 was objected
to (docs/detection.md, "The rod between the ends").
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.detect.colour import SampleGrid, brightest_at

ROD_OFF_DEG = 8.0
"""An end's measurement is left out of the pointer fit when, in its camera, the rod clearly leaves the other
end's sound ball at least this far from the direction to it (:meth:`trackerd.refine.RefinedPath._off_the_rod`)..."""

ROD_CLEAR = 0.75
"""...along a direction where at least this share of the rod's points are darker than both its sides..."""

ROD_ABSENT = 0.25
"""...and at most this share along any direction within :data:`NEAR_DEG` of the one to the
measurement."""

ROD_CONTRAST = 12.0
"""Grey levels by which a point on the rod must be darker than both sides of it to count: here in the brightest
of its colours (:func:`~trackerd.detect.colour.brightest_at`: the rod is dark in all three, a red picture
only in green and blue), in :func:`trackerd.detect.select.rod_evidence` in green."""

FAN_DEG = 40
"""Directions examined, either side of the one asked about (whole degrees)."""

FAN_STEP_DEG = 2
"""Between directions: the rod's own width spans a few of them at the reach's middle."""

NEAR_DEG = 4
"""Directions this close to the one asked about count as towards it: a measured centre a few pixels off (part
of a ball) puts the rod a few degrees from the direction to it."""

RIM_MARGIN_PX = 2.0
"""Points start this far outside the ball's rim, and stop this far short of the other ball's: a rim's pixels
mix ball and background, and a fitted radius is a pixel or so off."""

SAMPLES = 12
"""Points along each direction."""

MIN_REACH_PX = 8.0
"""Less free rod than this between the two balls' rims is not enough to tell a direction by."""

MAX_REACH_DIAMETERS = 3.0
"""Along at most this many of the ball's diameters: near its ball, the rod is nearly straight in any lens,
and less of it is hidden by what lies in front of it further along."""

SIDE_MARGIN_PX = 3.0
"""A side sample lies this far beyond the rod's edge."""

_OFFSETS_DEG = np.arange(-FAN_DEG, FAN_DEG + 1, FAN_STEP_DEG)
_OFFSETS_RAD = np.radians(_OFFSETS_DEG)
_NEAR = np.abs(_OFFSETS_DEG) <= NEAR_DEG
_STEPS = np.stack(
    [np.ones(3 * SAMPLES), np.tile(np.linspace(0.0, 1.0, SAMPLES), 3), np.repeat([0.0, 1.0, -1.0], SAMPLES)], axis=1
)
"""(1, fraction of the reach, side's sign) of each point: SAMPLES along the line, then as many either side of it."""
_ONES = np.ones(SAMPLES)

Brightness = Callable[[NDArray[np.uint8], SampleGrid, NDArray[np.float64]], NDArray[np.float64]]
"""How bright a frame is at points (N, 2) given as (x, y) pixels: :func:`~trackerd.detect.colour.green_at` or
:func:`~trackerd.detect.colour.brightest_at`."""


def darker_share(
    frame: NDArray[np.uint8],
    grid: SampleGrid,
    origin_px: NDArray[np.float64],
    directions: NDArray[np.float64],
    start_px: float,
    reach_px: float,
    side_px: float,
    brightness: Brightness = brightest_at,
) -> NDArray[np.float64]:
    """For each unit direction (D, 2) from ``origin_px``, the share of SAMPLES points spread from ``start_px``
    to ``start_px + reach_px`` along it that are ROD_CONTRAST darker than both points ``side_px`` either side
    of it -> (D,) in [0, 1]: how clearly a dark line (the rod) runs that way."""
    # Every point as (distance along, distance across) = _STEPS (3 S, 3) @ scale (3, 2), turned into each
    # direction's frame by one (2, 2 D) matrix: two small products in place of broadcasting over (D, 3, S, 2)
    # (rod_bearing's 41 directions: 100 -> 70 us a call); for one direction (select.rod_evidence) about 3 us
    # dearer than arithmetic written out for it, kept for one measurement under both.
    scale = np.array([[start_px, 0.0], [reach_px, 0.0], [0.0, side_px]])
    turn = np.empty((2, len(directions), 2))
    turn[0] = directions
    turn[1, :, 0] = -directions[:, 1]
    turn[1, :, 1] = directions[:, 0]
    points = (_STEPS @ (scale @ turn.reshape(2, -1))).reshape(-1, 2) + origin_px  # (3 S D, 2)
    lum = brightness(frame, grid, points).reshape(3, SAMPLES, len(directions))
    darker = np.minimum(lum[1], lum[2]) - lum[0]  # (S, D)
    # Counted by a product with ones: count_nonzero along an axis costs several times more here.
    counts = _ONES @ np.greater(darker, ROD_CONTRAST).astype(np.float64)
    shares: NDArray[np.float64] = counts / SAMPLES
    return shares


@dataclass(frozen=True, slots=True)
class RodBearing:
    """The rod's darkness along a fan of directions from a ball's centre."""

    offset_deg: float
    """Direction of the clearest rod, from the direction asked about (positive: towards the image's +y from
    +x)."""
    evidence: float
    """Share of that direction's points darker than both sides, in [0, 1]."""
    evidence_toward: float
    """The largest such share within NEAR_DEG of the direction asked about."""


def rod_bearing(
    frame: NDArray[np.uint8],
    grid: SampleGrid,
    centre_px: NDArray[np.float64],
    radius_px: float,
    toward_px: NDArray[np.float64],
    toward_radius_px: float,
    rod_half_width_px: float,
) -> RodBearing | None:
    """The rod's darkness leaving a ball (``centre_px``, ``radius_px``) towards a point (the other ball's
    measured centre and radius), and within FAN_DEG of that direction; None when the two centres coincide.

    Along the free stretch between the two balls' rims, at most MAX_REACH_DIAMETERS long. Where the other
    ball would touch or hide this one (less than MIN_REACH_PX between them), no rod could show between them,
    and the fan is examined over the longest reach: whatever rod shows there leaves the ball elsewhere.
    """
    offset = np.asarray(toward_px, dtype=np.float64) - np.asarray(centre_px, dtype=np.float64)
    distance = float(math.hypot(offset[0], offset[1]))
    if distance < 1e-6:
        return None
    start = radius_px + RIM_MARGIN_PX
    longest = MAX_REACH_DIAMETERS * 2.0 * radius_px
    reach = min(distance - toward_radius_px - RIM_MARGIN_PX - start, longest)
    if reach < MIN_REACH_PX:
        reach = max(longest, MIN_REACH_PX)
    angles = math.atan2(offset[1], offset[0]) + _OFFSETS_RAD
    along = np.stack([np.cos(angles), np.sin(angles)], axis=-1)  # (D, 2)
    evidence = darker_share(frame, grid, centre_px, along, start, reach, rod_half_width_px + SIDE_MARGIN_PX)
    # Of equally clear directions (a rod several pixels wide is dark along a few), the one nearest the
    # direction asked about.
    clearest = np.flatnonzero(evidence == evidence.max())
    best = int(clearest[np.argmin(np.abs(_OFFSETS_DEG[clearest]))])
    return RodBearing(float(_OFFSETS_DEG[best]), float(evidence[best]), float(evidence[_NEAR].max()))


ROUND_STEP_DEG = 2
"""Between directions looked along all round a ball, as FAN_STEP_DEG."""

RIVAL_APART_DEG = 20
"""Directions further than this from the clearest are another line (an edge, the rod's far side of a ball
seen end-on), not the rod's own width."""

_ROUND_RAD = np.radians(np.arange(0, 360, ROUND_STEP_DEG))
_ROUND = np.stack([np.cos(_ROUND_RAD), np.sin(_ROUND_RAD)], axis=-1)


@dataclass(frozen=True, slots=True)
class RodLeaving:
    """The clearest dark line leaving a ball, looked for all round it."""

    direction: NDArray[np.float64]
    """(2,) unit image direction: the middle of the run of equally clearest directions next to each other."""
    evidence: float
    """Share of its points darker than both sides, in [0, 1]."""
    rival: float
    """The clearest share more than RIVAL_APART_DEG away from it."""


def rod_leaving(
    frame: NDArray[np.uint8],
    grid: SampleGrid,
    centre_px: NDArray[np.float64],
    radius_px: float,
    rod_half_width_px: float,
) -> RodLeaving:
    """Which way the rod leaves a ball (``centre_px``, ``radius_px``) when where the other ball is is not
    known: :func:`darker_share` all round it, over MAX_REACH_DIAMETERS of the ball's diameter beyond its rim.
    The caller judges ``evidence`` and ``rival`` (a clear line, and no other as clear)."""
    reach = max(MAX_REACH_DIAMETERS * 2.0 * radius_px, MIN_REACH_PX)
    evidence = darker_share(
        frame,
        grid,
        np.asarray(centre_px, dtype=np.float64),
        _ROUND,
        radius_px + RIM_MARGIN_PX,
        reach,
        rod_half_width_px + SIDE_MARGIN_PX,
    )
    best = int(np.argmax(evidence))
    count = len(_ROUND)
    # The rod's width spans neighbouring directions: the middle of the run of directions as clear as the best
    # that holds it (wrapping round), at most RIVAL_APART_DEG either way.
    lower = upper = 0
    most = RIVAL_APART_DEG // ROUND_STEP_DEG
    while upper < most and evidence[(best + upper + 1) % count] == evidence[best]:
        upper += 1
    while lower < most and evidence[(best - lower - 1) % count] == evidence[best]:
        lower += 1
    middle = (best + (upper - lower) / 2.0) * ROUND_STEP_DEG
    direction = np.array([math.cos(math.radians(middle)), math.sin(math.radians(middle))])
    apart_deg = np.abs((np.arange(count) - best + count // 2) % count - count // 2) * ROUND_STEP_DEG
    rivals = evidence[apart_deg > RIVAL_APART_DEG]
    return RodLeaving(direction, float(evidence[best]), float(rivals.max()) if rivals.size else 0.0)
