"""A ball's outline, found where it is visible and fitted with a circle: a centre that partial occlusion,
shading and a brightness the thresholds were not set for do not pull.

The thresholded blob of an end is only the part of the ball that passes the
colour test: in dim light its shaded side fails, a specular highlight punches a
hole in it, and the rod, a finger or the presenter's body hides part of it from
a camera behind the presenter. Its centroid then moves by pixels, which the
wall magnifies to centimetres. The *outline* of the ball, where it is visible,
is still a circle (a perspective sphere's image is an ellipse within a small
fraction of a pixel of one at the sizes seen here; the locator fits the exact
cone, :func:`trackerd.geometry.sphere.fit_sphere_direction`), and its centre is
the ball's.

So, around a rough position (a blob's centre, a tracked position, a prediction):

1. the colour's *excess* (its sample minus the larger of the other channels
   interpolated at the sample's own position; :func:`trackerd.detect.colour.excess_window`)
   is read along 48 rays from the rough centre, every 0.5 px, by bilinear
   interpolation on the colour's own sample lattice;
2. along each ray the rim is where the excess falls through the midpoint
   between the ball's level on that ray (the highest excess inside) and the
   background's level beyond it: a threshold of that ray's own, so shading,
   gain and white balance do not move it;
3. a circle is fitted to the rim points robustly (the best of many three-point
   circles, then iteratively reweighted least squares with Tukey's weights),
   which leaves out the stretches of rim that belong to an occluder (points
   inside the circle) or to a background of the ball's colour (outside it);
4. twice: the second pass starts from the first circle.

The result carries the rim points that agree with the circle (for the
locator's exact fit), the share of rays whose rim agreed (how much of the
outline is visible), the rim points' scatter and the centre's standard error.

Many balls are measured at once where many are asked for (:func:`fit_balls`: a
frame's search seeds; :func:`fit_looks`: every camera's ends of a pair): their
rays gathered together, their rims found and their circles fitted
(:func:`trackerd.detect.circle.robust_circles`) in one set of arrays. Each fit is
the one :func:`fit_ball` gives alone.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.detect.circle import Circle, clipped, median_of, robust_circle, robust_circles, row_medians
from trackerd.detect.colour import EXCESS_SCALE, SampleGrid, cells_around, channel_windows, excess_window

Array = NDArray[np.float64]

RAYS = 48
"""Directions the outline is looked for along."""

STEP_PX = 0.5
"""Spacing of the samples along each ray."""

MIN_CONTRAST = 10.0
"""A ray's ball level must exceed its background level by this many grey levels for a rim to count."""

MIN_RIM_FRACTION = 0.35
"""At least this share of the rays must find a rim that agrees with the circle."""

ROD_EXCLUSION_DEG = 30.0
"""Rays this close to the pointer's axis (either way) are not used when the axis is given."""

MAX_SCATTER_PX = 1.5
MAX_SCATTER_SHARE = 0.12
"""A rim scattering about its circle by more than the larger of these (pixels, share of the radius) is
not a ball's outline (a bar, a letter, a smear)."""

CORRELATION_CELLS = 1.5
"""The length (in lattice spacings) over which the noise of a bilinearly interpolated lattice of independent
samples stays correlated: (integral of the triangle kernel)^2 / integral of its square = 1.5 spacings."""

LEVERAGE_LIMIT = 0.5
"""A rim point whose leverage on the circle (its share of the fit's three parameters, centre and radius;
the leverages sum to 3) is over this holds the circle up nearly alone: the circle is then fitted again
without it, and how far its centre moves is an error of the centre (:func:`_leaning_shift`). A whole
outline's points have leverages near 3/48, the ends of a 90-degree arc 0.5."""

RESTING_ERROR_SHARE = 0.5
"""A circle that no longer exists without its most leaned-on rim point has an error of this share of its
radius, either way: where it is rests on that one point."""


@dataclass(frozen=True, slots=True)
class BallFit:
    """A ball's circle in one image, or why there is none."""

    found: bool
    centre_px: Array
    """(x, y) of the circle's centre; NaN when not found."""
    radius_px: float
    rim_px: Array
    """(N, 2) rim points that agree with the circle."""
    rim_fraction: float
    """Share of the rays looked along (all, or those off the pointer's axis) whose rim agrees with the
    circle: how much of the outline is visible."""
    residual_px: float
    """Robust scatter of the agreeing rim points about the circle."""
    centre_sigma_px: float
    """Standard error of the centre along each axis, from the scatter and the rim's coverage."""
    contrast: float
    """Median ball-over-background excess on the agreeing rays, grey levels."""
    reason: str | None = None
    independent_rims: float = math.nan
    """How many of the agreeing rim points are independent measurements of the outline: fewer than there
    are on a small ball, whose neighbouring rays cross the rim closer together than the samples each
    rim is interpolated from (:func:`independent_rims`)."""
    arc_covariance_px: Array | None = None
    """(2, 2) error of the centre (pixels squared) from a smooth departure of the visible arc from a circle
    (:func:`arc_deformation_covariance`): zero for a whole outline, large for half of one; and, where one rim
    point holds the circle up nearly alone, from how far the centre moves without it (:func:`_leaning_shift`)."""

    @staticmethod
    def missing(reason: str) -> BallFit:
        nan = np.full(2, np.nan)
        return BallFit(False, nan, math.nan, np.zeros((0, 2)), 0.0, math.nan, math.nan, 0.0, reason)


_ANGLES = np.linspace(0.0, 2.0 * math.pi, RAYS, endpoint=False)
_COS, _SIN = np.cos(_ANGLES), np.sin(_ANGLES)


@dataclass(frozen=True, slots=True)
class BallLook:
    """One ball for :func:`fit_looks`: the frame it is in (with its sample grid), its colour, where to start
    (x_px, y_px) and its rough radius_px there, the direction of the pointer's image at it and the map to the
    units in which its outline is a circle (``axis`` and ``view``, as :func:`fit_ball`'s)."""

    frame: NDArray[np.uint8]
    grid: SampleGrid
    colour: str
    x_px: float
    y_px: float
    radius_px: float
    axis: tuple[float, float] | None = None
    view: Array | None = None


@dataclass(frozen=True, slots=True)
class _Options:
    """How the outlines are looked for (fit_ball's keyword arguments), the same for every ball of a batch."""

    rising_rims: bool
    centre_slack_px: float | None
    tint: Array | None


_PLAIN = _Options(False, None, None)


def fit_ball(
    frame: NDArray[np.uint8],
    grid: SampleGrid,
    colour: str,
    x_px: float,
    y_px: float,
    radius_px: float,
    *,
    axis: tuple[float, float] | None = None,
    radius_range_px: tuple[float, float] | None = None,
    passes: int = 2,
    rising_rims: bool = False,
    centre_slack_px: float | None = None,
    view: Array | None = None,
    tint: Array | None = None,
) -> BallFit:
    """The circle of the ``colour`` ball near (x_px, y_px), of roughly ``radius_px`` (see the module).

    ``axis``: the direction of the pointer's image at this ball, (dx, dy) towards the other ball. The
    rays within ROD_EXCLUSION_DEG of it, either way, are left out: there the rod (and the handle behind
    the back ball) meets the ball, and the rim is a mix of ball and rod that pulls a fit along the
    pointer. Leaving out both directions keeps what is left symmetric about the axis.
    ``radius_range_px``: only circles of a radius in this range are considered (where the geometry says
    how large the ball must be): the ball's arc is then found even where its outline runs into a disc
    of its colour of another size.
    ``rising_rims``: also take the rim where the colour rises into something more of the ball's colour
    (:func:`_rising_rims`). Only where the geometry has said where the ball is and how large: elsewhere
    such a rise is as often the edge of a hand or a picture as a ball's, and on randomized scenes taking
    it everywhere moved more good fits than it rescued.
    ``centre_slack_px`` (with ``radius_range_px``): the ball's centre is known to within this of each
    pass's start, so a rim point nearer than the smallest radius, or farther than the largest, by more
    than this cannot be on the ball's outline, and is left out before the circle is fitted
    (:func:`_annulus`): where the ball touches something of its colour (a letter, a picture), the colour
    falls only at that thing's far edge, and those rims would pull the fit into a larger circle through
    both.
    ``view``: a 2x2 map from image offsets near the ball to offsets in which its outline is a circle
    (:func:`trackerd.geometry.sphere.view_map`: a ball far off a wide lens's axis images as an ellipse
    stretched away from the axis). The rays, the circle and ``radius_px``, ``radius_range_px`` and the
    result's radius and scatter are then in those units; the centre and the rim points stay in pixels.
    ``tint``: weights (3,) of the colour's own channel, green and the other colour; the rims are then looked
    for in that combination of the channels (in grey levels) instead of the colour's excess over the others
    (:func:`trackerd.detect.guided.ball_tint`: a ball before a picture of nearly its colour can differ from it in
    another direction).
    """
    options = _Options(rising_rims, centre_slack_px, tint)
    ranges = None if radius_range_px is None else np.array([radius_range_px], dtype=np.float64)
    look = BallLook(frame, grid, colour, x_px, y_px, radius_px, axis, view)
    return _fits([look], ranges, options, passes)[0]


def fit_balls(
    frame: NDArray[np.uint8],
    grid: SampleGrid,
    colour: str,
    starts_px: Array,
    *,
    radius_range_px: tuple[float, float] | Array | None = None,
    rising_rims: bool = False,
    passes: int = 2,
) -> list[BallFit]:
    """:func:`fit_ball` from each start ``starts_px`` (K, 3: x, y, rough radius), all of one colour in one frame:
    the same fits, measured together (the rays of all starts sampled in one gather, their rims found and
    their circles fitted in one set of arrays: trackerd.detect.circle.robust_circles). The search fits
    every seed of a frame this way; one at a time, NumPy's cost per call was most of a fit's.
    ``radius_range_px``: one range for every start, or one per start (K, 2)."""
    starts = np.asarray(starts_px, dtype=np.float64).reshape(-1, 3)
    looks = [BallLook(frame, grid, colour, x, y, r) for x, y, r in starts.tolist()]
    ranges = None
    if radius_range_px is not None:
        ranges = np.broadcast_to(np.asarray(radius_range_px, dtype=np.float64), (len(starts), 2))
    return _fits(looks, ranges, _Options(rising_rims, None, None), passes)


def fit_looks(looks: Sequence[BallLook], passes: int = 2) -> list[BallFit]:
    """:func:`fit_ball` for each of ``looks``, in any frames and colours (every camera's ends of a pair, the
    search's seeds fitted again in their views): the same fits, measured together as :func:`fit_balls`'s are."""
    return _fits(list(looks), None, _PLAIN, passes)


def _fits(looks: list[BallLook], ranges: Array | None, options: _Options, passes: int) -> list[BallFit]:
    """Each look's fit in ``passes`` passes, each pass from the one before's circle; a look whose pass
    finds no ball keeps that pass's answer. ``ranges``: each look's radius range (K, 2), or None."""
    fits = [BallFit.missing("not looked for")] * len(looks)
    centres = np.zeros((len(looks), 2))
    radii = np.zeros(len(looks))
    pending: list[int] = []
    for k, look in enumerate(looks):
        x, y, r = float(look.x_px), float(look.y_px), float(look.radius_px)
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(r)) or r <= 0:
            fits[k] = BallFit.missing("no position to look at")
            continue
        centres[k] = (x, y)
        radii[k] = max(r, 2.0)
        pending.append(k)
    for _ in range(passes):
        if not pending:
            break
        found = _one_pass(
            [looks[k] for k in pending],
            centres[pending],
            radii[pending],
            None if ranges is None else ranges[pending],
            options,
        )
        still: list[int] = []
        for k, fit in zip(pending, found, strict=True):
            fits[k] = fit
            if fit.found:
                centres[k] = fit.centre_px
                radii[k] = fit.radius_px
                still.append(k)
        pending = still
    return fits


def _one_pass(
    looks: list[BallLook], centres: Array, radii: Array, ranges: Array | None, options: _Options
) -> list[BallFit]:
    """One pass of the fit from each look's (centre, radius): rays, rims, the robust circle, its errors."""
    results: list[BallFit | None] = [None] * len(centres)
    measured: list[int] = []
    windows: list[NDArray[np.float32]] = []
    rhos: list[Array] = []
    lattice_uv: list[tuple[Array, Array]] = []
    lattices: list[float] = []
    for k, (look, (cx, cy), radius) in enumerate(zip(looks, centres.tolist(), radii.tolist(), strict=True)):
        frame, grid, colour, view = look.frame, look.grid, look.colour, look.view
        # The rays run in the view's units (where the outline is a circle); ``image`` takes them back to pixels.
        image = np.eye(2) if view is None else np.linalg.inv(view)
        stretch = 1.0 if view is None else float(np.linalg.norm(image, 2))
        if view is None:
            along_x, along_y = _COS, _SIN
        else:
            along_x = image[0, 0] * _COS + image[0, 1] * _SIN
            along_y = image[1, 0] * _COS + image[1, 1] * _SIN
        reach = 2.0 * radius + 3.0
        region = cells_around(grid, colour, cx, cy, reach * stretch)
        if region[1] - region[0] < 3 or region[3] - region[2] < 3:
            results[k] = BallFit.missing("the ball is at the frame's edge")
            continue
        if options.tint is None:
            excess, _ = excess_window(frame, grid, colour, region)
            windows.append(excess.astype(np.float32) / np.float32(EXCESS_SCALE))
        else:
            windows.append(
                np.tensordot(options.tint.astype(np.float32), channel_windows(frame, grid, colour, region), axes=1)
            )
        # Samples along the rays, as lattice coordinates of the window.
        s = grid.cell_px
        dr, dc = grid.offset(colour)
        rho = np.arange(0.15 * radius, reach, STEP_PX)
        xs = cx + along_x[:, None] * rho[None, :]
        ys = cy + along_y[:, None] * rho[None, :]
        lattice_uv.append(((xs - dc) / s - region[2], (ys - dr) / s - region[0]))
        rhos.append(rho)
        # The colour's sample lattice's spacing in the rays' units.
        lattices.append(float(s) if view is None else float(s) * math.sqrt(abs(float(np.linalg.det(view)))))
        measured.append(k)
    if measured:
        lattice = np.array(lattices)
        rims = np.full((len(measured), RAYS), np.nan)
        contrasts = np.full((len(measured), RAYS), np.nan)
        for group in _similar_lengths([len(rho) for rho in rhos]):
            width = len(rhos[group[-1]])
            rho_rows = np.full((len(group), width), np.nan)
            # Beyond a start's own rays (shorter for a smaller ball) the samples are outside every window: NaN.
            u = np.full((len(group), RAYS, width), -1.0)
            v = np.full((len(group), RAYS, width), -1.0)
            for j, g in enumerate(group):
                rho, (uj, vj) = rhos[g], lattice_uv[g]
                rho_rows[j, : len(rho)] = rho
                u[j, :, : len(rho)] = uj
                v[j, :, : len(rho)] = vj
            profiles = _bilinear_windows([windows[g] for g in group], u, v)  # (starts, RAYS, samples)
            group_rims, group_contrasts = _rims(
                profiles.reshape(-1, width),
                np.repeat(rho_rows, RAYS, axis=0),
                np.repeat(radii[[measured[g] for g in group]], RAYS),
                np.repeat(lattice[group], RAYS),
                options.rising_rims,
            )
            rims[group] = group_rims.reshape(-1, RAYS)
            contrasts[group] = group_contrasts.reshape(-1, RAYS)
        outlines = _outlines(
            [looks[k] for k in measured],
            centres[measured],
            radii[measured],
            None if ranges is None else ranges[measured],
            rims,
            contrasts,
            lattice,
            options,
        )
        for k, fit in zip(measured, outlines, strict=True):
            results[k] = fit
    return [fit if fit is not None else BallFit.missing("not looked for") for fit in results]


def _similar_lengths(lengths: list[int]) -> list[list[int]]:
    """The indices of ``lengths`` in groups of similar length, each group's longest last: the rays of a
    group are sampled in one array as long as its longest, and a seed of a large blob among small balls
    would otherwise make every start's rays that long (twice the samples of one at a time)."""
    order = sorted(range(len(lengths)), key=lengths.__getitem__)
    groups: list[list[int]] = []
    for index in order:
        if groups and lengths[index] <= 1.25 * lengths[groups[-1][0]] + 4:
            groups[-1].append(index)
        else:
            groups.append([index])
    return groups


def _outlines(
    looks: list[BallLook],
    centres: Array,
    radii: Array,
    ranges: Array | None,
    rims: Array,
    contrasts: Array,
    lattice: Array,
    options: _Options,
) -> list[BallFit]:
    """Each start's circle from its rims ((K, RAYS): the rim's distance along each ray, NaN for none) and
    the centre's errors (each start's ``axis`` and ``view`` from its look)."""
    usable = np.full(len(centres), RAYS)
    for k, look in enumerate(looks):
        axis, view = look.axis, look.view
        if axis is not None and view is not None:
            axis = (
                float(view[0, 0] * axis[0] + view[0, 1] * axis[1]),
                float(view[1, 0] * axis[0] + view[1, 1] * axis[1]),
            )
        if axis is not None and math.hypot(*axis) > 0:
            ax, ay = axis[0] / math.hypot(*axis), axis[1] / math.hypot(*axis)
            off_axis = np.abs(_COS * ax + _SIN * ay) < math.cos(math.radians(ROD_EXCLUSION_DEG))
            rims[k] = np.where(off_axis, rims[k], np.nan)
            usable[k] = int(np.count_nonzero(off_axis))
    if options.centre_slack_px is not None and ranges is not None:
        rims = _annulus(rims, ranges, options.centre_slack_px)
    results: list[BallFit | None] = [None] * len(centres)
    ok = np.isfinite(rims)
    counts = np.count_nonzero(ok, axis=1)
    points = np.zeros((len(centres), RAYS, 2))
    for k in range(len(centres)):
        if counts[k] < max(6, int(MIN_RIM_FRACTION * usable[k])):
            results[k] = BallFit.missing(f"the ball's outline is not visible (rim on {counts[k]} of {usable[k]} rays)")
            counts[k] = 0
            continue
        rim = rims[k, ok[k]]
        points[k, : counts[k]] = np.column_stack([centres[k, 0] + _COS[ok[k]] * rim, centres[k, 1] + _SIN[ok[k]] * rim])
    circles = robust_circles(points, counts, radius_range_px=ranges)
    for k, circle in enumerate(circles):
        if results[k] is not None:
            continue
        if circle is None:
            results[k] = BallFit.missing("the rim points are not a circle")
            continue
        contrast = contrasts[k, ok[k]]
        bounds = None if ranges is None else (float(ranges[k, 0]), float(ranges[k, 1]))
        results[k] = _outline(
            points[k, : counts[k]],
            contrast,
            circle,
            centres[k],
            radii[k],
            bounds,
            int(usable[k]),
            float(lattice[k]),
            looks[k].view,
        )
    return [fit for fit in results if fit is not None]


def _outline(
    points: Array,
    contrast: Array,
    circle: Circle,
    start: Array,
    radius: float,
    radius_range_px: tuple[float, float] | None,
    usable: int,
    lattice: float,
    view: Array | None,
) -> BallFit:
    """One start's ball from its rim ``points`` (in the rays' units), their ``contrast`` and their ``circle``."""
    centre, r, weights, scale = circle
    circle_points, circle_centre = points, centre  # in the rays' units, where the outline is a circle
    if view is not None:
        # Back to pixels: the centre, and the rim points (for the exact cone fit, which undistorts them).
        image = np.linalg.inv(view)
        centre = start + image @ (centre - start)
        points = start + (points - start) @ image.T
    agree = weights > 0.0
    fraction = float(np.count_nonzero(agree)) / usable
    if fraction < MIN_RIM_FRACTION or not (0.3 * radius <= r <= 3.0 * radius):
        return BallFit.missing(f"too little of the ball's outline is a circle ({fraction:.0%} of its rays)")
    if scale > max(MAX_SCATTER_PX, MAX_SCATTER_SHARE * r):
        return BallFit.missing(f"the outline is not round (its rim scatters by {scale:.1f} px about a circle)")
    used = points[agree]
    # The centre's standard error: the scatter over the rim, spread over the directions it covers.
    directions = (used - centre) / r
    if view is not None:
        directions = (used - centre) @ view.T / r
    information = directions.T @ (directions * weights[agree, None])
    smallest = float(np.linalg.eigvalsh(information)[0])
    independent = independent_rims(len(used), r, lattice)
    sigma = scale / math.sqrt(max(smallest, 1e-9)) * math.sqrt(len(used) / independent)
    contrast_level = median_of(contrast[agree])
    arc = arc_deformation_covariance(directions, weights[agree], scale)
    leaning = _leaning_shift(circle_points, weights, circle_centre, r, radius_range_px)
    if leaning is not None and view is not None:
        leaning = np.linalg.inv(view) @ leaning
    arc = arc + (np.eye(2) * (RESTING_ERROR_SHARE * r) ** 2 if leaning is None else np.outer(leaning, leaning))
    return BallFit(True, centre, r, used, fraction, scale, sigma, contrast_level, None, independent, arc)


def _leaning_shift(
    points: Array, weights: Array, centre: Array, radius: float, radius_range_px: tuple[float, float] | None
) -> Array | None:
    """How far the circle's centre (fitted to ``points`` with ``weights``, robust_circle's) moves without the
    rim point it leans on most, when that point's leverage is over LEVERAGE_LIMIT; zero otherwise; None when
    without it the other points make no circle (of a radius in ``radius_range_px``, else of any radius).

    Where a hand or the presenter's body hides most of a ball, its outline is a short arc, and the circle's
    radius and its centre along the arc's axis are fixed together by little. A rim point across the ball, where
    the colour falls at the edge of what hides it, then fixes both on its own, and the fit agrees with it
    exactly (its residual is zero, whatever it is): neither the rim's scatter nor a deformed arc says anything
    is uncertain. Leaving the point out and fitting again does: `bench robustness --seed 404`, installation 0,
    frame 38 (the back ball 62 % visible in one camera, 36-40 % in the other): a circle 2.0 px smaller than
    the ball's through such a point, its centre 6.7 px off with a stated error of 0.8 px, the hit 42.9 mm off
    at a sigma of 4.3 mm; leaving the point out moves the centre 1.9 px, and the hit's sigma is 13.2 mm.
    The shift is capped at RESTING_ERROR_SHARE of the radius, the error of a centre with no circle left."""
    agree = weights > 0.0
    used, w = points[agree], weights[agree]
    directions = (used - centre) / radius
    design = np.column_stack([directions, np.ones(len(used))])
    try:
        inverse = np.linalg.inv(design.T @ (design * w[:, None]))
    except np.linalg.LinAlgError:
        return None
    leverage = w * np.einsum("ij,jk,ik->i", design, inverse, design)
    most = int(np.argmax(leverage))
    if leverage[most] <= LEVERAGE_LIMIT:
        return np.zeros(2)
    rest = np.delete(used, most, axis=0)
    # Without the point the arc may want a radius outside the range: where it is then is still the answer.
    without = robust_circle(rest, radius_range_px=radius_range_px)
    if without is None and radius_range_px is not None:
        without = robust_circle(rest)
    if without is None:
        return None
    shift = without[0] - centre
    # A refit that jumps further than an unknown centre's error (a near-straight arc's circle, far away) says
    # no more than that the centre rests on the point: it is capped at that error's size, along its way.
    length, limit = float(np.hypot(shift[0], shift[1])), RESTING_ERROR_SHARE * radius
    return shift * (limit / length) if length > limit else shift


def _annulus(rim: Array, ranges: Array, slack_px: float) -> Array:
    """The rims ((K, RAYS): distances from each pass's start, NaN for none) that a circle of a radius in its
    start's range (``ranges``, (K, 2)) centred within ``slack_px`` of the start can pass through; NaN for the
    others."""
    inside = (rim >= ranges[:, :1] - slack_px) & (rim <= ranges[:, 1:] + slack_px)
    return np.where(inside, rim, np.nan)


def arc_deformation_covariance(directions: Array, weights: Array, amplitude_px: float) -> Array:
    """The centre's error (2, 2), pixels squared, when the outline departs from a circle by smooth waves of
    ``amplitude_px`` (two per turn, either phase) that the fit on the rim points at unit
    ``directions`` (N, 2) from the centre, with ``weights`` (N,), does not model.

    Motion blur stretches a ball's image, shading and the mixed pixels where a hand or the rod meets the
    ball bend its outline; a fit to the whole outline averages such waves out (they are orthogonal to a
    shift of the centre), but a fit to part of it takes part of each wave for a shift: the more of the
    outline is missing, the more. The rim's own scatter about its circle is the measured size of such
    departures."""
    c, s = directions[:, 0], directions[:, 1]
    design = np.column_stack([c, s, np.ones_like(c)]) * weights[:, None]
    try:
        projection = np.linalg.solve(design.T @ design, design.T)  # (3, N): the fit's response to the rims
    except np.linalg.LinAlgError:
        return np.eye(2) * (10.0 * amplitude_px) ** 2
    waves = np.stack([c * c - s * s, 2.0 * c * s])
    shifts = (projection @ (waves * weights[None, :]).T)[:2] * amplitude_px  # (2, 2)
    covariance: Array = shifts @ shifts.T
    return covariance


def independent_rims(count: int, radius_px: float, lattice_px: float) -> float:
    """How many independent outline measurements ``count`` rim points on neighbouring rays of a circle of
    ``radius_px`` are, on a colour lattice of ``lattice_px`` spacing.

    Each rim is found on samples bilinearly interpolated from the lattice, so two rims closer than a
    lattice spacing or two share their noise: the noise of a bilinearly interpolated white lattice is
    correlated over CORRELATION_CELLS spacings (the integral of the interpolation kernel's
    autocorrelation). The rays are 2 pi r / RAYS apart on the rim; where that is less than the
    correlation length, the rim points count only as often as the correlation length fits into the arc
    they cover. Taking all 48 as independent made the centre of a ball 5 px across two to three times
    more certain than its errors on randomized scenes (`trackerd bench robustness`)."""
    spacing_px = 2.0 * math.pi * radius_px / RAYS
    return max(3.0, count * min(1.0, spacing_px / (CORRELATION_CELLS * lattice_px)))


def _bilinear_windows(images: list[NDArray[np.float32]], u: Array, v: Array) -> Array:
    """Each of ``images`` at its own fractional (column u[k], row v[k]) (u, v: (K, ...)), NaN outside it.

    The windows are gathered from one flat array of them all: one gather for every start's rays, and a
    third of the time of indexing each window by (row, column)."""
    shape = (len(images),) + (1,) * (u.ndim - 1)
    heights = np.array([image.shape[0] for image in images]).reshape(shape)
    widths = np.array([image.shape[1] for image in images]).reshape(shape)
    sizes = np.array([image.size for image in images])
    bases = (np.cumsum(sizes) - sizes).reshape(shape)
    inside = (u >= 0) & (v >= 0) & (u <= widths - 1) & (v <= heights - 1)
    u0 = clipped(np.floor(u).astype(np.intp), 0, np.maximum(widths - 2, 0))
    v0 = clipped(np.floor(v).astype(np.intp), 0, np.maximum(heights - 2, 0))
    fu = u - u0
    fv = v - v0
    flat = np.concatenate([image.ravel() for image in images]) if len(images) > 1 else images[0].ravel()
    at = bases + v0 * widths + u0
    top = flat.take(at) * (1.0 - fu) + flat.take(at + 1) * fu
    bottom = flat.take(at + widths) * (1.0 - fu) + flat.take(at + widths + 1) * fu
    out = top * (1.0 - fv) + bottom * fv
    return np.where(inside, out, np.nan)


def _rims(
    profile: Array, rho: Array, radius: Array, lattice_px: float | Array, rising_rims: bool = False
) -> tuple[Array, Array]:
    """Per ray (a row of ``profile``, sampled at its row of ``rho``, NaN beyond the ray's last sample; the
    ball's rough ``radius`` per row; ``lattice_px``: the sample lattice's spacing, one for all or per row), the
    radius where the excess falls through the midpoint of the levels just inside and just outside the rim
    (NaN where there is no such fall), and that ray's contrast.

    The fall is first located against the ray's own ball level (the highest excess inside) and its
    background level (beyond 1.5 radii); the midpoint is then taken between the levels a lattice
    spacing and a half either side of it, so a ball that darkens towards its limb (or is shaded on
    one side) does not pull its rim inwards.
    """
    step = rho[:, 1] - rho[:, 0]
    halves = np.maximum(1, np.round(1.5 * lattice_px / step)).astype(np.intp)
    if np.all(halves == halves[0]):
        return _rims_at(profile, rho, radius, step, int(halves[0]), rising_rims)
    rim, contrast = np.full(len(profile), np.nan), np.full(len(profile), np.nan)
    for half in np.unique(halves):
        rows = halves == half
        rim[rows], contrast[rows] = _rims_at(profile[rows], rho[rows], radius[rows], step[rows], int(half), rising_rims)
    return rim, contrast


def _rims_at(
    profile: Array, rho: Array, radius: Array, step: Array, half: int, rising_rims: bool
) -> tuple[Array, Array]:
    """:func:`_rims` for rays whose levels either side of a rim lie ``half`` samples from it."""
    rays, width = profile.shape
    row = np.arange(rays)
    index = np.arange(width)
    last = np.count_nonzero(np.isfinite(rho), axis=1) - 1
    inner = rho <= 1.25 * radius[:, None]
    outer = rho >= 1.5 * radius[:, None]
    with np.errstate(all="ignore"):
        peak_at = np.nanargmax(np.where(inner & np.isfinite(profile), profile, -np.inf), axis=1)
        peak = profile[row, peak_at]
        background = row_medians(np.where(outer, profile, np.nan))
        contrast = peak - background
        threshold = 0.5 * (peak + background)
        below = (profile < threshold[:, None]) & (index[None, :] > peak_at[:, None])
    has = below.any(axis=1) & (contrast >= MIN_CONTRAST) & np.isfinite(contrast)
    first = np.argmax(below, axis=1)
    # The levels either side of the fall, then the fall through their midpoint near it.
    local, span, values = _levels_around(profile, last, first, np.maximum(first - 1 - half, peak_at), half, threshold)
    falls = (values[:, :-1] >= local[:, None]) & (values[:, 1:] < local[:, None])
    found_local = falls.any(axis=1)
    # The fall nearest the first one (the last such fall before it, else the first after it).
    last_before = np.where(found_local, (falls.shape[1] - 1) - np.argmax(falls[:, ::-1], axis=1), 0)
    k = np.where(found_local, span[row, last_before], clipped(first - 1, 0, last))
    level = np.where(found_local, local, threshold)
    a = profile[row, k]
    b = profile[row, clipped(k + 1, 0, last)]
    with np.errstate(all="ignore"):
        frac = np.clip((a - level) / (a - b), 0.0, 1.0)
    rim = rho[row, k] + frac * step
    rim = np.where(has & np.isfinite(rim), rim, np.nan)
    if not rising_rims:
        return rim, contrast
    rising, rise_rim, rise_contrast = _rising_rims(profile, rho, radius, step, last, background, has, half)
    rim = np.where(rising, rise_rim, rim)
    contrast = np.where(rising, rise_contrast, contrast)
    return rim, contrast


def _rising_rims(
    profile: Array,
    rho: Array,
    radius: Array,
    step: Array,
    last: NDArray[np.intp],
    background: Array,
    falling: NDArray[np.bool_],
    half: int,
) -> tuple[NDArray[np.bool_], Array, Array]:
    """The rims of the rays (of those without a falling rim) that cross from the ball into something *more*
    of its colour: a shaded ball before a bright picture of its own hue, whose colour excess rises at the
    rim rather than falls. There the rim is where the excess rises through the midpoint of the ball's own
    level (the median over its inner part) and the background's; returns (which rays, rim, contrast).

    Without them such a ball had no outline on that side and, before a large enough picture, none at all
    (`bench robustness`: a dark red ball before a bright red block or the red letters of a slide)."""
    rays = profile.shape[0]
    row = np.arange(rays)
    core = rho <= 0.6 * radius[:, None]
    ball = row_medians(np.where(core, profile, np.nan))
    with np.errstate(all="ignore"):
        contrast = background - ball
        level = 0.5 * (ball + background)
        candidates = ~falling & (contrast >= MIN_CONTRAST) & np.isfinite(contrast)
        above = (profile >= level[:, None]) & (rho >= 0.5 * radius[:, None])
    if not np.any(candidates):
        return candidates, np.full(rays, np.nan), contrast
    first = np.argmax(above, axis=1)
    found = candidates & above.any(axis=1) & (first > 0)
    # As for a fall: the midpoint of the levels just either side of the rise, since a shaded ball is darker
    # at its limb than over its inner part, and the inner level alone puts the rim outside the ball.
    local, span, values = _levels_around(profile, last, first, first - 1 - half, half, level)
    with np.errstate(all="ignore"):
        rises = (values[:, :-1] < local[:, None]) & (values[:, 1:] >= local[:, None])
    has_local = rises.any(axis=1)
    k = np.where(has_local, span[row, np.argmax(rises, axis=1)], clipped(first - 1, 0, last))
    used = np.where(has_local, local, level)
    a = profile[row, k]
    b = profile[row, clipped(k + 1, 0, last)]
    with np.errstate(all="ignore"):
        frac = np.clip((used - a) / (b - a), 0.0, 1.0)
    rim = rho[row, k] + frac * step
    found &= np.isfinite(rim) & (a < used)
    return found, np.where(found, rim, np.nan), contrast


def _levels_around(
    profile: Array,
    last: NDArray[np.intp],
    first: NDArray[np.intp],
    inside_at: NDArray[np.intp],
    half: int,
    fallback: Array,
) -> tuple[Array, NDArray[np.intp], Array]:
    """Per ray, the midpoint of the levels at ``inside_at`` and ``half`` samples beyond ``first`` (where a
    rim was first seen; ``fallback`` where either is missing), and the samples around ``first`` to look
    for the rim's crossing of it: (midpoints, their indices (R, 2 half + 2), their values). ``last``: each
    ray's last sample."""
    row = np.arange(len(profile))
    inside = clipped(inside_at, 0, last)
    outside = clipped(first + half, 0, last)
    with np.errstate(all="ignore"):
        local = 0.5 * (profile[row, inside] + profile[row, outside])
        local = np.where(np.isfinite(local), local, fallback)
    offsets = np.arange(-half - 1, half + 1)
    span = clipped(first[:, None] + offsets[None, :], 0, last[:, None])
    return local, span, profile[row[:, None], span]
