"""A ball looked for where the geometry puts it: its centre, its image radius and where the rod meets it
are known, so its outline is fitted with the radius held close to the geometry's, as touching something of
its colour, or in its tint, and kept only where it is of the pointer's colour by the search's hue test.

The search's looks for a ball no camera offered (trackerd/joint/search.py, through trackerd/joint/looks.py)
and the refined path's look where the last pair's pointer has moved to (trackerd/refine.py) ask for it;
docs/detection.md, "When the room is not the one the thresholds were set for", has the cases it
was made for.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

from trackerd.detect.ballfit import BallFit, fit_ball
from trackerd.detect.colour import SampleGrid, cells_around, channel_windows
from trackerd.detect.search import hue_mask, vivid_mask

Array = NDArray[np.float64]

MAX_GUIDED_RESIDUAL_PX = 1.0
"""A ball looked for where the geometry puts it must be a circle this closely (rim scatter, pixels)..."""

MAX_GUIDED_RESIDUAL_SHARE = 0.1
"""...or within this share of its expected radius, where that is more: a large ball's rim in motion blur or
under a hand scatters by more than a pixel about its circle and is still plainly a ball (`bench robustness`
seed 7, installation 2, frame 1: a dark blue ball of 18 px radius, in strong blur, 1.45 px). The search's own
limit is looser (:data:`trackerd.detect.ballfit.MAX_SCATTER_SHARE`, 0.12): there nothing says where a ball is."""

GUIDED_SIZE = 1.15
"""And its radius within this factor of a ball's at the distance the geometry puts it."""

TINT_PAINT_DN = 10.0
"""Where the geometry puts a ball, its colour's own channel must exceed both others by this (grey levels) for
the ball to be looked for by its tint (:func:`ball_tint`): it is the pointer's paint, however dull."""

TINT_CONTRAST_DN = 15.0
"""And it must differ from its surroundings by this (grey levels, the length of the colour difference): less
is no outline to fit."""

TOUCHING_LARGEST = 1.05
"""Where that fails, the ball may touch something of its colour; it is fitted again with its radius at most
this factor of the geometry's (an outline's rim lies on or just inside the ball's silhouette; a circle through
the ball's arc and the far edge of a letter it touches is larger; :func:`guided_fits`)..."""

TOUCHING_SLACK_PX = 3.0
"""...and the rim points that no such circle centred within this of where the geometry puts the ball can
pass through left out (the far edges of what it touches)."""


def guided_scatter_limit_px(radius_px: float) -> float:
    """How far a guided fit's rim may scatter about its circle (in the units of ``radius_px``)."""
    return max(MAX_GUIDED_RESIDUAL_PX, MAX_GUIDED_RESIDUAL_SHARE * radius_px)


def guided_fits(
    image: NDArray[np.uint8],
    grid: SampleGrid,
    colour: str,
    x_px: float,
    y_px: float,
    radius_px: float,
    axis: tuple[float, float] | None,
    view: Array | None = None,
    vivid: bool = False,
) -> Iterator[BallFit]:
    """The ball looked for where the geometry puts it (centre, image radius, and the direction where the rod
    meets it), for the joint choice's ``look``: its outlines that are round within
    :func:`guided_scatter_limit_px`, in order of preference, each made only when the one before was not
    taken; none after one not of the pointer's colour (:func:`_of_its_colour`: then something else is
    there). Fitted in its colour's excess, then as touching something of its colour (below), then in its
    tint (:func:`ball_tint`). With ``view`` (:func:`trackerd.geometry.sphere.view_map`), the radius, the
    circle and its scatter are in the view's units (``fit_ball``'s ``view``); the slack below then is too.

    The geometry knows the ball's size to a few percent, so the fit keeps its radius within GUIDED_SIZE and
    takes rising rims (a shaded ball before a brighter surface of its hue). Where that fails (or the caller
    refuses the outline) the ball may
    touch something of its colour (a letter, a picture): on those rays the colour falls only at that
    thing's far edge, and a larger circle through the ball's arc and that edge fits best. So it is fitted
    again with the radius at most TOUCHING_LARGEST of the geometry's and the rims no such circle centred
    within TOUCHING_SLACK_PX of the start can pass through left out. ``vivid``: its colour may pass the
    search's looser test instead (:func:`trackerd.detect.search.vivid_mask`; the search's last resort).
    ``next(guided_fits(...), None)`` is the preferred outline, or None.

    The caller judges each outline against where the geometry allows the ball and asks for the next when it
    is not there: a dark ball before a brighter picture of its hue can give, in the excess, a round outline
    a radius away from it, while its tint gives the ball (`bench robustness --seed 11`, installation 29,
    frame 16: 8 px from where the look started, on a ball of 8 px)."""
    # Plain first; then as a ball touching something of its colour; last in its tint.
    for largest, slack_px, in_excess in (
        (GUIDED_SIZE, None, True),
        (TOUCHING_LARGEST, TOUCHING_SLACK_PX, True),
        (GUIDED_SIZE, None, False),
    ):
        tint = None
        if not in_excess:
            # A ball before a picture with as much of its colour's excess has no rim in the excess, but has one
            # in the direction (in colour) from the picture to the ball.
            tint = ball_tint(image, grid, colour, x_px, y_px, radius_px)
            if tint is None:
                return
        fit = fit_ball(
            image,
            grid,
            colour,
            x_px,
            y_px,
            radius_px,
            axis=axis,
            radius_range_px=(radius_px / GUIDED_SIZE, radius_px * largest),
            rising_rims=in_excess,
            centre_slack_px=slack_px,
            view=view,
            tint=tint,
        )
        if fit.found and fit.residual_px <= guided_scatter_limit_px(radius_px):
            if not _of_its_colour(image, grid, colour, fit, view, vivid):
                return
            yield fit


def _of_its_colour(
    image: NDArray[np.uint8], grid: SampleGrid, colour: str, fit: BallFit, view: Array | None, vivid: bool = False
) -> bool:
    """Whether what a guided fit found is of the pointer's colour by the search's relative hue thresholds
    (:data:`~trackerd.detect.search.RELATIVE_EXCESS`, :data:`~trackerd.detect.search.MIN_EXCESS`), applied to its
    inner half's median colour: the look fits any round edge of the right size where the geometry points, and a
    corner of a tan sleeve in warm light, only 22 % redder than it is green, once made a red end out of
    junk in two cameras for a ball hidden in one (`bench robustness` seed 7, installation 23, frame 38: a
    hit 736 mm off at 17 sigma). The balls the looks rightly found on the frames looked into were 43-91 % (dim,
    dark, blurred, merged). With ``vivid``, the search's looser test (:func:`~trackerd.detect.search.vivid_mask`)
    passes it too."""
    radius_px = fit.radius_px if view is None else fit.radius_px / math.sqrt(abs(float(np.linalg.det(view))))
    colours = colour_medians(image, grid, colour, float(fit.centre_px[0]), float(fit.centre_px[1]), radius_px)
    if colours is None:
        return False
    own, green, other = colours[0]
    if plain_colour(own, green, other):
        return True
    return vivid and bool(vivid_mask(np.array(own), np.array(own - max(green, other)), np.array(min(green, other))))


def plain_colour(own: float, green: float, other: float) -> bool:
    """Whether a colour (its own channel, green, the other colour) passes the search's plain hue test."""
    return bool(hue_mask(np.array(own), np.array(own - max(green, other))))


def colour_medians(
    image: NDArray[np.uint8], grid: SampleGrid, colour: str, x_px: float, y_px: float, radius_px: float
) -> tuple[Array, Array | None] | None:
    """The median colour (the colour's own channel, green, the other colour, at the colour's samples) over the
    inner half of a ball's radius, and over the ring from 1.5 to 2.2 radii around it (None where the frame's
    edge leaves fewer than 8 samples of it); None at the frame's edge. Medians: a rod or a hand across part of
    either does not move them."""
    s = grid.cell_px
    dr, dc = grid.offset(colour)
    region = cells_around(grid, colour, x_px, y_px, 2.2 * radius_px)
    if region[1] - region[0] < 3 or region[3] - region[2] < 3:
        return None
    channels = channel_windows(image, grid, colour, region)
    rows = (np.arange(region[0], region[1]) * s + dr - y_px)[:, None]
    cols = (np.arange(region[2], region[3]) * s + dc - x_px)[None, :]
    distance = np.hypot(rows, cols)
    inner = distance <= max(0.5 * radius_px, 0.75 * s)
    ring = (distance >= 1.5 * radius_px) & (distance <= 2.2 * radius_px)
    if not inner.any():
        return None
    ball: Array = np.median(channels[:, inner], axis=1).astype(np.float64)
    around: Array | None = None
    if np.count_nonzero(ring) >= 8:
        around = np.median(channels[:, ring], axis=1).astype(np.float64)
    return ball, around


def ball_tint(
    image: NDArray[np.uint8], grid: SampleGrid, colour: str, x_px: float, y_px: float, radius_px: float
) -> Array | None:
    """The direction in colour (weights of the colour's own channel, green and the other colour) from what
    surrounds the place where the geometry puts a ball to what is there, for ``fit_ball``'s ``tint``; None
    where that place is not of the ball's colour (its own channel not above both others by TINT_PAINT_DN) or
    does not differ from its surroundings by TINT_CONTRAST_DN.

    The colours of the ball and of its surroundings are :func:`colour_medians`."""
    colours = colour_medians(image, grid, colour, x_px, y_px, radius_px)
    if colours is None:
        return None
    ball, around = colours
    if around is None or ball[0] < max(ball[1], ball[2]) + TINT_PAINT_DN:
        return None
    direction = (ball - around).astype(np.float64)
    size = float(np.linalg.norm(direction))
    if size < TINT_CONTRAST_DN:
        return None
    tint: Array = direction / size
    return tint
