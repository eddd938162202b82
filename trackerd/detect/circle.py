"""A robust circle through rim points, for one outline or for many at once.

A ball's outline (trackerd/detect/ballfit.py) is a set of rim points, some of which belong to whatever
hides or touches the ball. :func:`robust_circles` fits a circle to each of several such sets in one
NumPy pass (the search fits a hundred seeds a frame; one at a time, NumPy's per-call cost was most of
it): the best of a fixed set of three-point circles, then iteratively reweighted least squares with
Tukey's biweight. :func:`robust_circle` is the same for one set.

The row helpers here (:func:`row_medians`, :func:`median_of`, :func:`clipped`) are what both this
module and the rim search use where NumPy's general functions cost more than the work on 48 rays.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

TUKEY_C = 4.685
"""Tukey's biweight constant, in units of the residuals' robust scale."""

MIN_SCALE_PX = 0.25
"""The rim residuals' scale is never taken below this (exact renders would otherwise give zero)."""

MIN_POINTS = 5
"""Fewer rim points than this (or fewer keeping a weight) make no circle."""

ROUNDS = 6
"""Reweighting rounds at most; a fit whose centre moves less than 0.001 px in a round stops there."""

Circle = tuple[Array, float, Array, float]
"""A fitted circle: centre (2,), radius, per-point weights (0 for points left out), the residuals' robust scale."""


def robust_circle(points: Array, trials: int = 48, radius_range_px: tuple[float, float] | None = None) -> Circle | None:
    """A circle through most of ``points`` (N, 2), ignoring the rest (see :func:`robust_circles`)."""
    points = np.asarray(points, dtype=np.float64)
    return robust_circles(points[None], np.array([len(points)]), trials, radius_range_px)[0]


def robust_circles(
    points: Array,
    counts: NDArray[np.intp],
    trials: int = 48,
    radius_range_px: tuple[float, float] | Array | None = None,
) -> list[Circle | None]:
    """For each set k, the circle through most of its points ``points[k, :counts[k]]`` ((K, N, 2); what lies
    beyond ``counts[k]`` is ignored), or None where they make none.

    Starts from the best of ``trials`` circles through three of the points (the most points within two
    scales of it; the same triples for the same number of points, so a fit is reproducible), then
    iteratively reweighted least squares with Tukey's biweight, the scale re-estimated from the median
    absolute residual each round. With ``radius_range_px`` (one range, or one per set: (K, 2)) only circles
    of a radius in that range are started from or returned.
    """
    sets, width = points.shape[:2]
    counts = np.asarray(counts, dtype=np.intp)
    results: list[Circle | None] = [None] * sets
    live = np.flatnonzero(counts >= MIN_POINTS)
    if len(live) == 0:
        return results
    valid = np.arange(width)[None, :] < counts[live, None]  # (L, N)
    # Padding is set to zero (never NaN): a zero weight then keeps it out of every sum.
    x = np.where(valid, points[live, :, 0], 0.0)
    y = np.where(valid, points[live, :, 1], 0.0)
    triples = np.stack([_triples(n, trials) for n in counts[live].tolist()])  # (L, T, 3)
    rows = np.arange(len(live))[:, None]
    ax, ay = x[rows, triples[..., 0]], y[rows, triples[..., 0]]
    bx, by = x[rows, triples[..., 1]], y[rows, triples[..., 1]]
    cx, cy = x[rows, triples[..., 2]], y[rows, triples[..., 2]]
    # Circumcentres of all triples of all sets at once.
    d = 2.0 * (ax * (by - cy) + bx * (cy - ay) + cx * (ay - by))
    good = np.abs(d) > 1e-9
    d = np.where(good, d, 1.0)
    a2, b2, c2 = ax * ax + ay * ay, bx * bx + by * by, cx * cx + cy * cy
    ux = (a2 * (by - cy) + b2 * (cy - ay) + c2 * (ay - by)) / d
    uy = (a2 * (cx - bx) + b2 * (ax - cx) + c2 * (bx - ax)) / d
    r = np.hypot(ax - ux, ay - uy)
    if radius_range_px is not None:
        bounds = np.broadcast_to(np.asarray(radius_range_px, dtype=np.float64), (sets, 2))[live]
        smallest, largest = bounds[:, :1], bounds[:, 1:]
        good &= (r >= smallest) & (r <= largest)
    started = good.any(axis=1)
    typical = masked_row_medians(r, good)
    tolerance = 2.0 * np.maximum(MIN_SCALE_PX, 0.05 * typical)
    residual = np.abs(np.hypot(x[:, None, :] - ux[..., None], y[:, None, :] - uy[..., None]) - r[..., None])
    support = good[..., None] & (residual < tolerance[:, None, None]) & valid[:, None, :]
    best = np.argmax(support.sum(axis=2), axis=1)
    at = np.arange(len(live))
    radius = r[at, best]
    # Coordinates about each set's starting circle's centre: the weighted moments below are then of the
    # size of the ball, not of the image, and the plain (uncentred) normal equations lose nothing to
    # rounding. Their terms' products are formed once; a round is then one matrix product.
    origin = np.column_stack([ux[at, best], uy[at, best]])
    on = valid.astype(np.float64)
    px, py = (x - origin[:, :1]) * on, (y - origin[:, 1:]) * on
    terms = np.stack([px, py, on, px * px + py * py], axis=2)  # x, y, 1 and x^2 + y^2 (zero for padding)
    products = (terms[..., :, None] * terms[..., None, :]).reshape(len(live), width, 16)
    centre_x, centre_y = np.zeros((len(live), 1)), np.zeros((len(live), 1))
    radius = radius[:, None]
    weights = on
    scale = np.full((len(live), 1), MIN_SCALE_PX)
    active = started.copy()
    failed = ~started
    for _ in range(ROUNDS):
        if not active.any():
            break
        # Every row is computed each round (cheaper than picking out the active ones); only the active
        # ones take the result.
        res = np.hypot(px - centre_x, py - centre_y) - radius
        round_scale = np.fmax(MIN_SCALE_PX, 1.4826 * masked_row_medians(np.abs(res), weights > 0))[:, None]
        z = res / (TUKEY_C * round_scale)
        w = np.maximum(1.0 - z * z, 0.0)
        w = w * w * on
        usable = active & (np.add.reduce(w > 0, axis=1) >= MIN_POINTS)
        # Weighted algebraic circle, x^2 + y^2 = a x + b y + c: a few rounds converge to the geometric fit
        # for small residuals.
        moments = (w[:, None, :] @ products).reshape(-1, 4, 4)
        solution, solved = _solve3(moments[:, :3, :3], moments[:, :3, 3], usable)
        half_a, half_b = solution[:, :1] / 2.0, solution[:, 1:2] / 2.0
        r2 = solution[:, 2:] + half_a * half_a + half_b * half_b
        ok = solved & (r2[:, 0] > 0)
        moved = np.hypot(half_a - centre_x, half_b - centre_y)[:, 0]
        if ok.all():
            # Every row still going (always so for one set) takes its round as it is.
            centre_x, centre_y, radius, scale, weights = half_a, half_b, np.sqrt(r2), round_scale, w
        else:
            failed |= active & ~ok
            took = ok[:, None]
            centre_x, centre_y = np.where(took, half_a, centre_x), np.where(took, half_b, centre_y)
            radius = np.where(took, np.sqrt(np.where(took, r2, 1.0)), radius)
            scale = np.where(active[:, None], round_scale, scale)
            weights = np.where(active[:, None], w, weights)
        active = ok & (moved >= 1e-3)
    z = (np.hypot(px - centre_x, py - centre_y) - radius) / (TUKEY_C * scale)
    final = np.maximum(1.0 - z * z, 0.0) ** 2
    radius, scale = radius[:, 0], scale[:, 0]
    in_range = ~failed
    if radius_range_px is not None:
        in_range &= (radius >= smallest[:, 0]) & (radius <= largest[:, 0])
    for j in np.flatnonzero(in_range).tolist():
        index = int(live[j])
        centre = origin[j] + np.array([centre_x[j, 0], centre_y[j, 0]])
        results[index] = (centre, float(radius[j]), final[j, : counts[index]], float(scale[j]))
    return results


def _solve3(matrices: Array, right: Array, usable: NDArray[np.bool_]) -> tuple[Array, NDArray[np.bool_]]:
    """Each usable 3x3 system solved; (solutions, which were solved): a singular one fails alone."""
    if usable.all():
        try:
            solved_all = np.asarray(np.linalg.solve(matrices, right[..., None])[..., 0], dtype=np.float64)
            return solved_all, usable
        except np.linalg.LinAlgError:
            pass
    solution = np.zeros(right.shape)
    solved = usable.copy()
    if not usable.any():
        return solution, solved
    try:
        solution[usable] = np.linalg.solve(matrices[usable], right[usable][..., None])[..., 0]
    except np.linalg.LinAlgError:
        for i in np.flatnonzero(usable).tolist():
            try:
                solution[i] = np.linalg.solve(matrices[i], right[i])
            except np.linalg.LinAlgError:
                solved[i] = False
    return solution, solved


_TRIPLES: dict[int, NDArray[np.intp]] = {}


def _triples(n: int, trials: int) -> NDArray[np.intp]:
    """Fixed, well spread index triples for ``n`` points (cached): the same every call, so a fit is
    reproducible, and cheap."""
    key = n * 1000 + trials
    cached = _TRIPLES.get(key)
    if cached is None:
        rng = np.random.default_rng(n)
        cached = np.sort(np.array([rng.choice(n, 3, replace=False) for _ in range(trials)]), axis=1)
        _TRIPLES[key] = cached
    return cached


def row_medians(values: Array) -> Array:
    """Median of each row's finite values (NaN for a row with none); np.nanmedian is ten times slower."""
    return masked_row_medians(values, np.isfinite(values))


def masked_row_medians(values: Array, mask: NDArray[np.bool_]) -> Array:
    """Median of each row's values where ``mask`` (NaN for a row with none)."""
    if len(values) == 1:
        # One row (a single fit's every round): the plain median is half the time of the row machinery.
        kept = values[0][mask[0]]
        return np.array([median_of(kept) if len(kept) else np.nan])
    ordered = np.sort(np.where(mask, values, np.inf), axis=1)
    count = np.add.reduce(mask, axis=1)
    width = values.shape[1]
    flat = ordered.ravel()
    base = np.arange(0, values.size, width)
    low = flat[base + np.maximum((count - 1) // 2, 0)]
    high = flat[base + np.minimum(count // 2, width - 1)]
    return np.where(count > 0, 0.5 * (low + high), np.nan)


def median_of(values: Array) -> float:
    """np.median of a small 1-D array, the same value (the middle one, or the mean of the two): np.median's
    generality costs 40 us a call, and a ball's fit takes a dozen (`trackerd bench robustness`'s searches)."""
    ordered = np.sort(values)
    middle = len(ordered) // 2
    if len(ordered) % 2:
        return float(ordered[middle])
    return float((ordered[middle - 1] + ordered[middle]) / 2.0)


def clipped(values: NDArray[np.intp], low: int | NDArray[np.intp], high: int | NDArray[np.intp]) -> NDArray[np.intp]:
    """np.clip for index arrays (the same values): np.clip's dispatch costs more than the work on 48 rays."""
    return np.minimum(np.maximum(values, low), high)
