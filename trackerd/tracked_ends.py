"""Tracked ends between refined pairs: each detector centroid corrected by its ball's outline as last
measured, and the error that correction leaves.

The detector's centroid of a ball is pulled off the ball's centre by whatever hides or shades part of it:
the rod over the front ball when the cameras look along the pointer, light from one side, a dim paint the
thresholds take only the core of. In randomized rooms (`trackerd bench robustness --follow`) tracked
centroids were 0.7 px off at the median and 2.9 px at the ninth decile, and the quick path that trusted
them as 0.05 px measurements put 2.9-7.8 % of hits beyond 5 sigma. The pull changes slowly as the pointer
moves: the difference between a ball's outline and its centroid at a refined pair, added to the centroid
one to eleven pairs later, leaves 0.20-0.26 px at the median (an outline itself: 0.17 px), and it grows
with the ball's image size, with how much its visible area has changed beyond what its distance explains,
and a little with how far the ball has moved since (docs/geometry.md, "Tracked ends").

So the locator keeps, per camera and end, the offset its last outline measurement found
(:class:`EndOffset`), adds it to every tracked centroid's normalised coordinates, states each corrected
end's error from its size and how far it has drifted since (:func:`drift_px`, :func:`corrected_end`), and
measures an end's outline again once it has moved about :data:`STALE_MOVED_PX` or its area has changed by
more than :data:`STALE_AREA_LOG` (:func:`staleness`, :func:`is_stale`): about a millisecond for that one
end, where a refined pair of two cameras takes four or five. An end the next pair would find stale, carried on
by its last step (:func:`due_next_pair`), is measured one pair early, between pairs, so that no pair waits for
it (:meth:`trackerd.locator.Locator.measure_ahead`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.ends import EndMeasurement
from trackerd.geometry.camera import CameraModel

Array = NDArray[np.float64]

FLOOR_SHARE = 0.008
"""A corrected end's error beyond its outline's, in every direction, is at least this share of the ball's image
radius (pixels per pixel of radius, in quadrature): the two are measured on different frames, and each frame's
noise and light move a ball's centroid anew, more for a larger ball. Fitted with the two constants below on
60 followed installations (`bench robustness --follow 20`, seeds 7 and 2026, 30 each; 7,106 tracked ends 0 to
11 pairs after their outline, each error split along and across the pointer's image; throwaway analysis
described in the closing note of issue 13): across the pointer, which is what turns the line, 80 % within 1
standard error, 96 % within 2, 0.9 % beyond 3, 0.03 % beyond 5 (a normal: 68, 95, 0.3, 0); along it 72, 95,
0.9 and 0.06 %. Cautious in the bulk, for a heavier tail than a normal's, which the fit's chi-square gate
(locator.TRACKED_REDUCED_CHI2) sends to the refined path where it shows. The errors across the pointer grow
with the ball's radius (0.06 px at the median below 9 px, 0.22 px above 25 px) and not measurably with how far
it has moved within the staleness limits below."""

AREA_DRIFT_SHARE = 0.5
"""And by this share of the ball's radius per unit of |ln| of its visible area's change beyond what its
distance explains: more or less of a ball hidden, more or less of it above the thresholds."""

DRIFT_PER_PX = 0.0025
"""And by this many pixels per pixel its ball has moved in the image since its outline was measured."""

END_CORRELATION = 0.3
"""The correlation of one camera's two corrected ends' errors (across the pointer and along it alike), for the
hit's stated uncertainty (the fit still weighs each end alone). Measured on the same tracked ends, each error
over its stated standard error: across 0.13 and 0.41, along 0.23 and 0.35 (seeds 7 and 2026; held-out seed
11: 0.50 and 0.52). Errors that move both ends one way shift the line rather than turn it, and the wall's
distance magnifies only the turn; stated as if independent, the tracked hits' uncertainties covered 84-89 %
of their errors within 1 standard error where the first sightings' cover 72-76 %."""

STALE_MOVED_PX = 50.0
"""An end whose ball has moved this far in the image since its outline (or, with its area change, as far as
:func:`staleness` adds up to) is measured by its outline again: the error model above was fitted on ends
that had moved less, so how far a correction can be carried beyond it is not known. (The first error model
set this limit where its stated error passed twice the outline's; it is kept as it was, and with it what
re-measuring costs.)"""

STALE_AREA_RADIUS_PX = 2.5
"""What a change of visible area counts for in :func:`staleness`: |ln| of the change times the ball's radius,
over this. Only a large ball (beyond 25 px) is made stale by it before STALE_AREA_LOG does."""

STALE_AREA_LOG = 0.1
"""And an end whose visible area has changed by more than this (|ln| of the ratio, distance explained) is
measured again whatever its travel: past it the corrected centroid was 0.84 px off at the median."""

AHEAD_SHARE = 1.0
"""An end whose :func:`stale_share`, carried on by the step it made since the pair before, would pass this at
the next pair is measured again between pairs, on the images of the pair just located
(:meth:`trackerd.locator.Locator.measure_ahead`), so that the next pair does not wait for its outline. At 1,
the end is measured one pair before it would have been, about as often as in the pair (on the `figure8` loop
27 ends in three passes, against 20); 0.8 measured 46 and was no nearer (2.03 mm median against 1.73). A
ball that speeds up beyond its last step is still measured in the pair (1 of the 28 there)."""

GUIDED_RADIUS_RATIO = 1.15
"""An end measured again must have an outline within this factor of the radius it had, scaled by its
distance: another size is another thing of its colour beside the ball (a disc on the display)."""


@dataclass(frozen=True, slots=True)
class EndOffset:
    """What the last outline measurement of one end in one camera found beside the detector's centroid."""

    offset_n: Array
    """(2,) normalised: the outline's ball-centre direction minus the centroid's (lens removed)."""
    centroid_px: Array
    """(2,) the detector's centroid then."""
    area_px: float
    """The detector's blob area then."""
    depth_m: float
    """The end's depth in this camera then (from the refined line; 0 when unknown)."""
    radius_px: float
    """The ball's image radius (its outline's)."""
    covariance_n: Array
    """(2, 2) the outline measurement's error covariance (normalised units), with what the refined pointer fit
    added for an outline of the wrong size (EndMeasurement.fit_error)."""


def end_offset(
    camera: CameraModel, measurement: EndMeasurement, centroid_px: Array, area_px: float, depth_m: float
) -> EndOffset | None:
    """The offset of one end's outline measurement from its centroid; None when the measurement is the
    centroid itself (no outline to correct by)."""
    if measurement.source == "centroid" or area_px <= 0.0:
        return None
    centroid_n = camera.normalized_from_pixels(np.asarray(centroid_px, dtype=np.float64)[None])[0]
    if not np.isfinite(centroid_n).all():
        return None
    return EndOffset(
        measurement.normalised - centroid_n,
        np.array(centroid_px, dtype=np.float64),
        float(area_px),
        float(depth_m),
        float(measurement.radius_px),
        np.array(
            measurement.actual_covariance
            if measurement.fit_error is None
            else measurement.actual_covariance + measurement.fit_error,
            dtype=np.float64,
        ),
    )


def area_change_log(offset: EndOffset, area_px: float, depth_m: float) -> float:
    """|ln| of the visible area's change since the outline, beyond what the change of distance explains
    (an image's area goes as 1 / depth^2); the plain ratio when either depth is unknown."""
    if area_px <= 0.0:
        return math.inf
    change = math.log(area_px / offset.area_px)
    if depth_m > 0.0 and offset.depth_m > 0.0:
        change += 2.0 * math.log(depth_m / offset.depth_m)
    return abs(change)


def moved_px(offset: EndOffset, centroid_px: Array) -> float:
    """How far the ball's centroid has moved since its outline was measured (pixels)."""
    return math.hypot(float(centroid_px[0] - offset.centroid_px[0]), float(centroid_px[1] - offset.centroid_px[1]))


def staleness(offset: EndOffset, moved: float, area_change: float) -> float:
    """How far the correction has been carried since the outline, as a share of how far it may be: the ball's
    displacement (over STALE_MOVED_PX) and its area's change (:func:`area_change_log`, times its radius over
    STALE_AREA_RADIUS_PX), in quadrature. Above 1 the end is stale (:func:`is_stale`)."""
    return math.hypot(moved / STALE_MOVED_PX, area_change * offset.radius_px / STALE_AREA_RADIUS_PX)


def is_stale(staleness_share: float, area_change: float) -> bool:
    """Whether an end should be measured by its outline again before its centroid is trusted."""
    return area_change > STALE_AREA_LOG or staleness_share > 1.0


def stale_share(offset: EndOffset, moved: float, area_change: float) -> float:
    """How far the correction has been carried as a share of the nearer of its two limits (:func:`staleness`,
    and STALE_AREA_LOG for the area alone): :func:`is_stale` exactly when above 1."""
    return max(staleness(offset, moved, area_change), area_change / STALE_AREA_LOG)


def due_next_pair(share: float, share_before: float) -> bool:
    """Whether an end at ``share`` (:func:`stale_share`) now and ``share_before`` at the pair before (0 for an
    outline measured at that pair) should be measured ahead (:data:`AHEAD_SHARE`): its share carried on by the
    last step, never back (a ball that came back towards where its outline was measured may leave again)."""
    return share + max(share - share_before, 0.0) > AHEAD_SHARE


def drift_px(offset: EndOffset, moved: float, area_change: float) -> float:
    """A corrected end's error beyond its outline's (pixels, 1 sigma, each direction): FLOOR_SHARE of the
    ball's radius, its displacement since the outline and its area's change (:func:`area_change_log`), in
    quadrature."""
    radius = offset.radius_px
    return math.sqrt(
        (FLOOR_SHARE * radius) ** 2 + (AREA_DRIFT_SHARE * area_change * radius) ** 2 + (DRIFT_PER_PX * moved) ** 2
    )


def corrected_end(
    offset: EndOffset, centroid_n: Array, moved_px: float, area_change: float, focal_px: float
) -> tuple[Array, Array]:
    """A tracked centroid (normalised, lens removed) corrected by its offset, and the error covariance that
    leaves (normalised units): the outline measurement's, and the drift (:func:`drift_px`) the same in every
    direction."""
    drift = drift_px(offset, moved_px, area_change) / focal_px
    covariance: Array = offset.covariance_n + drift * drift * np.eye(2)
    corrected: Array = centroid_n + offset.offset_n
    return corrected, covariance


def end_depth_m(camera: CameraModel, point_m: Array) -> float:
    """A world point's depth in a camera (0 when behind it)."""
    depth = float(camera.rotation[2] @ point_m + camera.translation_m[2])
    return depth if depth > 0.0 else 0.0
