"""Each end as a measurement the pointer fit can weigh: where it is in a camera's normalised image
plane, and how well that is known in each direction.

Two measurements of an end exist (docs/detection.md):

* the detector's centroid of the thresholded blob, with the coverage of every
  pixel: very precise *across* the pointer's image (the rod hides a ball
  symmetrically about the pointer's axis, 0.02-0.05 px), but pulled along the
  pointer by the rod, and in any direction by a finger, the presenter's body, a
  specular highlight, or light too dim for the thresholds to take the whole ball;
* the ball's fitted outline (:mod:`trackerd.detect.ballfit`): the circle through
  the visible rim, which none of those pull, a little less precise (0.05-0.1 px).

:func:`measure_end` fits the outline (:func:`measure_ends`: every camera's ends of a pair, their outlines
fitted together) and, where the centroid agrees with it
across the pointer, adds the centroid's information in that direction; where it
does not agree, the centroid is left out as biased. The result is one 2-vector
in undistorted normalised coordinates with its 2x2 covariance, the input of
:func:`trackerd.geometry.pointer_fit.fit_pointer`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.detect.ballfit import BallFit, BallLook, fit_looks
from trackerd.detect.circle import MIN_SCALE_PX
from trackerd.detect.colour import SampleGrid
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.sphere import fit_sphere_direction

Array = NDArray[np.float64]

EXCESS_SHARE = 0.5
"""A partial outline's circle larger than the ball's by some excess has its centre off by this share of
the excess either way, as a standard error (:func:`partial_arc_error`)."""

MAX_RADIUS_RATIO = 1.3
"""A ball's fitted outline more than this much larger or smaller than a ball at its distance is left out
of the pointer fit (when its end is measured by two other cameras)."""

MIN_SIGMA_PX = 0.05
"""No end is measured better than this (pixels, 1 sigma), whatever its fit says."""

RESIDUAL_SHARE = 0.5
"""And not better than this share of its outline's scatter about the circle: a blurred, noisy or partly
mixed rim, whose points scatter more, is not a circle as exactly as its centre's statistical error
says, and the benchmark on randomized scenes (trackerd bench robustness) finds the errors that large."""

FALLBACK_SIGMA_PX = 0.6
FALLBACK_SIGMA_SHARE = 0.6
"""A centroid whose ball outline could not be fitted is used with an isotropic error of the larger of
FALLBACK_SIGMA_PX and this share of the ball's radius: it is all there is, and whatever hides the
outline pulls it by up to the radius (a ball a quarter visible, on randomized scenes, was off by its
whole radius; at a quarter of the radius, the old share, that one measurement moved a hit by 10 mm
while two other cameras measured the end well)."""

ERROR_FLOOR_RADIUS_PX = 10.0
"""Beyond this image radius (pixels) an outline's stated error floor shrinks as 1 / radius
(:func:`error_floor_px`). A larger ball's outline has more rim and more independent rim points, and its
centre's actual error falls with its size: measured end by end against the true centres on `trackerd bench
robustness` (seeds 7 and 2026: 1,916 whole outlines on clean frames; along each end's least certain
direction), a robust 0.20-0.23 px at radius 6-8 px, 0.08-0.11 at 13-22, 0.05-0.07 beyond 22, where their
stated error with the plain floor (half the rim's scatter, which the fit never takes below 0.25 px) was
0.17-0.25 px at every size (docs/geometry.md, "A large ball's stated error follows its size"). Below this
radius the floor stays: small balls' errors are at or above what it states."""

COMBINED_FLOOR_SHARE = 0.5
"""An outline joined by its centroid keeps this share of the outline's error floor (RESIDUAL_SHARE)."""

WHOLE_RIM_FRACTION = 0.9
"""An outline whose rim agrees with its circle on fewer of the rays off the pointer's axis than this is
partly hidden by something besides the rod (a ray or two lost to noise leaves more)."""

CLEAN_RIM_SCATTER_PX = 0.5
"""A ball's rim points scatter about its circle by up to about this much (pixels, RMS) where only sensor
noise, pixel sampling and blur disturb them (whole rims on randomized scenes: 0.25 px median, 0.39 px at the
third quartile, 0.61 px at the ninth decile). A partly hidden outline that scatters more has taken some other
edge into its rim (a hand's, a picture's), and the centre it fits is pulled by about that excess; being one
systematic pull, it does not shrink with the number of rim points as the cone's covariance does."""

DISTURBED_CENTROID_SHARE = 1.0
"""A centroid's weight across the pointer is that of an error grown by this share of its outline's scatter
beyond the fit's least (BallFit.residual_px beyond ballfit.MIN_SCALE_PX, in quadrature): what moves a rim off
its circle (motion blur's smear, shading, the mixed pixels at a hand) moves the coverage centroid of the same
pixels too. Weighed at centroid_sigma_px whatever its rim, a blurred ball's centroid pulled the outline's
centre with it (trackerd bench robustness --seed 7, blur "strong": 5.8 % of hits beyond 3 sigma, 1.2 %
beyond 5). Measured from the clean rim's 0.5 px instead (CLEAN_RIM_SCATTER_PX), one hit of seed 2026 stayed
beyond 5 sigma (docs/geometry.md, "Weights and errors")."""

AGREE_SIGMAS = 3.0
"""The centroid joins the outline's measurement across the pointer when the two agree there within
this many of their combined standard errors."""


@dataclass(frozen=True)
class EndMeasurement:
    """One end in one camera, as the pointer fit takes it."""

    camera: int
    colour: str
    centre_px: Array
    """Where the measurement puts the ball's centre's image (the outline's centre, or the centroid)."""
    normalised: Array
    """(2,) undistorted normalised coordinates of the ball's centre (outline) or image centroid."""
    covariance: Array
    """(2, 2) covariance of ``normalised``."""
    radius_px: float
    """The ball's image radius (from its outline, or the blob's area when there is none)."""
    source: str
    """'outline', 'outline+centroid' (the centroid agreed across the pointer and was combined) or 'centroid'."""
    rim_fraction: float
    """Share of the outline seen (0 for a centroid alone)."""
    fit: BallFit | None = None
    error_covariance: Array | None = None
    """(2, 2) covariance of ``normalised``'s actual error (:func:`honest_covariance`), for the hit's
    uncertainty; None: ``covariance``. ``covariance`` stays the weight the pointer fit gives the
    measurement (with RESIDUAL_SHARE's floor, which stood in for what this models per measurement), so
    that modelling the errors moves no hit."""

    fit_error: Array | None = None
    """(2, 2) error (normalised units squared) the refined pointer fit gave this measurement beyond
    ``actual_covariance``: an outline of the wrong size for the ball's distance there (trackerd/refine.py,
    :func:`partial_arc_error`). The outline's centroid offset carries it to the tracked pairs that follow
    (trackerd/tracked_ends.py); None: nothing added."""

    @property
    def actual_covariance(self) -> Array:
        """The covariance of the measurement's actual error: ``error_covariance`` where modelled, else
        ``covariance``."""
        return self.covariance if self.error_covariance is None else self.error_covariance


def expected_radius_px(camera: CameraModel, point_m: Array, ball_radius_m: float) -> float:
    """The image radius of a ball of ``ball_radius_m`` centred at ``point_m`` (its silhouette's half-angle,
    times the focal length)."""
    distance = float(np.linalg.norm(point_m - camera.centre_m))
    return float(camera.focal_px * ball_radius_m / math.sqrt(max(distance**2 - ball_radius_m**2, 1e-6)))


def hidden_share(camera: CameraModel, far_m: Array, near_m: Array, ball_radius_m: float) -> float:
    """The share of the silhouette of the ball at ``far_m`` that the ball at ``near_m`` covers in ``camera``
    (0 where that one is not the nearer). Angles from the camera's centre, so the lens plays no part: each
    silhouette is a disc of the ball's angular radius, and the covered part is the two discs' overlap."""
    to_far = np.asarray(far_m, dtype=np.float64) - camera.centre_m
    to_near = np.asarray(near_m, dtype=np.float64) - camera.centre_m
    far_d, near_d = float(np.linalg.norm(to_far)), float(np.linalg.norm(to_near))
    if near_d >= far_d or near_d <= ball_radius_m:
        return 0.0
    far_r = math.asin(min(1.0, ball_radius_m / far_d))
    near_r = math.asin(min(1.0, ball_radius_m / near_d))
    apart = math.acos(max(-1.0, min(1.0, float(to_far @ to_near) / (far_d * near_d))))
    if apart >= far_r + near_r:
        return 0.0
    if apart <= near_r - far_r:  # the nearer, larger disc covers the farther one whole
        return 1.0
    # The lens where two discs overlap (the nearer one is the larger, so it cannot lie inside the farther).
    cos_far = (apart**2 + far_r**2 - near_r**2) / (2.0 * apart * far_r)
    cos_near = (apart**2 + near_r**2 - far_r**2) / (2.0 * apart * near_r)
    lens = (
        far_r**2 * math.acos(max(-1.0, min(1.0, cos_far)))
        + near_r**2 * math.acos(max(-1.0, min(1.0, cos_near)))
        - 0.5
        * math.sqrt(
            max(
                0.0,
                (-apart + far_r + near_r)
                * (apart + far_r - near_r)
                * (apart - far_r + near_r)
                * (apart + far_r + near_r),
            )
        )
    )
    return min(1.0, lens / (math.pi * far_r**2))


def ball_sized(radius_px: float, expected_px: float) -> bool:
    """Whether an outline's radius is within MAX_RADIUS_RATIO of a ball's expected one, either way."""
    return 1.0 / MAX_RADIUS_RATIO <= radius_px / expected_px <= MAX_RADIUS_RATIO


def across_pointer(red_px: Array, blue_px: Array) -> Array | None:
    """The unit vector across the pointer's image in one camera, from its two ends' centroids (pixels);
    None when they coincide."""
    along = np.asarray(red_px, dtype=np.float64) - np.asarray(blue_px, dtype=np.float64)
    length = float(np.hypot(*along))
    return np.array([-along[1], along[0]]) / length if length > 1e-9 else None


def same_ball(centroid_px: Array, measurement: EndMeasurement) -> bool:
    """Whether a detector's centroid is of the ball a measurement is of (within half its radius)."""
    return float(np.hypot(*(centroid_px - measurement.centre_px))) <= 0.5 * measurement.radius_px


@dataclass(frozen=True, slots=True)
class EndRequest:
    """One end to measure (:func:`measure_end`'s arguments but the centroid's sigma, the same for a pair's ends)."""

    frame: NDArray[np.uint8]
    grid: SampleGrid
    camera: CameraModel
    camera_index: int
    colour: str
    rough_px: Array
    radius_px: float
    centroid_px: Array | None
    across_px: Array | None


def measure_end(
    frame: NDArray[np.uint8],
    grid: SampleGrid,
    camera: CameraModel,
    camera_index: int,
    colour: str,
    rough_px: Array,
    radius_px: float,
    centroid_px: Array | None,
    across_px: Array | None,
    centroid_sigma_px: float,
) -> EndMeasurement | None:
    """Measure one end near ``rough_px`` (see the module).

    ``across_px`` is a unit vector across the pointer's image in this camera (None when unknown); the
    centroid is combined only in that direction, and only when it agrees with the outline there. Even a
    blob that is the whole ball is not trusted against its outline: light from one side leaves the
    shaded side's pixels less covered, which pulls the coverage centroid towards the lit side by a pixel
    or more (randomized scenes, crimson paint), where the outline's rim, found at each ray's own level,
    stays put. Returns None when neither an outline nor a centroid is there.
    """
    request = EndRequest(frame, grid, camera, camera_index, colour, rough_px, radius_px, centroid_px, across_px)
    return measure_ends([request], centroid_sigma_px)[0]


def measure_ends(requests: Sequence[EndRequest], centroid_sigma_px: float) -> list[EndMeasurement | None]:
    """:func:`measure_end` for each of ``requests`` (every camera's ends of a pair): their outlines fitted in one
    batched measurement over all the cameras' windows (:func:`trackerd.detect.ballfit.fit_looks`), the same
    fits as one at a time."""
    looks = [
        BallLook(
            request.frame,
            request.grid,
            request.colour,
            float(request.rough_px[0]),
            float(request.rough_px[1]),
            request.radius_px,
            None if request.across_px is None else (float(-request.across_px[1]), float(request.across_px[0])),
        )
        for request in requests
    ]
    fits = fit_looks(looks)
    return [_measured(request, fit, centroid_sigma_px) for request, fit in zip(requests, fits, strict=True)]


def _measured(request: EndRequest, fit: BallFit, centroid_sigma_px: float) -> EndMeasurement | None:
    """One end's measurement from its outline's ``fit`` (see :func:`measure_end`)."""
    camera, camera_index, colour = request.camera, request.camera_index, request.colour
    centroid_px, across_px, radius_px = request.centroid_px, request.across_px, request.radius_px
    if not fit.found:
        if centroid_px is None:
            return None
        normalised = camera.normalized_from_pixels(np.asarray(centroid_px)[None])[0]
        sigma = max(FALLBACK_SIGMA_PX, FALLBACK_SIGMA_SHARE * radius_px) / camera.focal_px
        return EndMeasurement(
            camera_index,
            colour,
            np.asarray(centroid_px, dtype=np.float64),
            normalised,
            np.eye(2) * sigma * sigma,
            radius_px,
            "centroid",
            0.0,
            fit,
        )
    measurement = from_fit(camera, camera_index, colour, fit)
    if measurement is None or centroid_px is None or across_px is None:
        return measurement
    combined = _with_centroid(
        camera,
        measurement.normalised,
        measurement.covariance,
        measurement.actual_covariance,
        np.asarray(centroid_px, dtype=np.float64),
        np.asarray(across_px, dtype=np.float64),
        centroid_sigma_px,
        fit.radius_px,
        fit.residual_px,
    )
    if combined is None:
        return measurement
    normalised, covariance, error_covariance = combined
    # The centroid sharpens the measurement across the pointer; part of the model's own error stays.
    floor_px = COMBINED_FLOOR_SHARE * weight_floor_px(fit)
    covariance = covariance + np.eye(2) * (floor_px / camera.focal_px) ** 2
    error_covariance = (
        error_covariance + np.eye(2) * (COMBINED_FLOOR_SHARE * error_floor_px(fit) / camera.focal_px) ** 2
    )
    if fit.rim_fraction < WHOLE_RIM_FRACTION:
        # Something besides the rod hides part of the ball (a hand, the presenter, a picture of its colour):
        # that pulls its centroid across the pointer, and the outline of what is left along with it, by more
        # than either's error says. The centroid's pull on the outline's value is then an error of its size.
        shift = normalised - measurement.normalised
        error_covariance = measurement.actual_covariance + np.outer(shift, shift)
    return EndMeasurement(
        camera_index,
        colour,
        fit.centre_px,
        normalised,
        covariance,
        fit.radius_px,
        "outline+centroid",
        fit.rim_fraction,
        fit,
        error_covariance,
    )


def from_fit(camera: CameraModel, camera_index: int, colour: str, fit: BallFit) -> EndMeasurement | None:
    """An end measured by its fitted outline alone: the cone through its rim points, undistorted."""
    focal = camera.focal_px
    rim = camera.normalized_from_pixels(fit.rim_px)
    cone = fit_sphere_direction(rim, rim_sigma_normalised=fit.residual_px / focal)
    if cone is None:
        return None
    floor_px = weight_floor_px(fit)
    covariance = cone.covariance + np.eye(2) * (floor_px / focal) ** 2
    return EndMeasurement(
        camera_index,
        colour,
        fit.centre_px,
        cone.normalised,
        covariance,
        fit.radius_px,
        "outline",
        fit.rim_fraction,
        fit,
        honest_covariance(fit, cone.covariance, focal) + np.eye(2) * (error_floor_px(fit) / focal) ** 2,
    )


def weight_floor_px(fit: BallFit, share: float = 1.0) -> float:
    """The least error (pixels, 1 sigma per axis) an outline's centre is weighed by: RESIDUAL_SHARE of its rim's
    scatter about the circle, times ``share``, MIN_SIGMA_PX at least."""
    return max(MIN_SIGMA_PX, RESIDUAL_SHARE * fit.residual_px * share)


def error_floor_px(fit: BallFit) -> float:
    """The least error an outline's centre is stated to have: its weight's floor for balls up to
    ERROR_FLOOR_RADIUS_PX, shrinking as 1 / radius beyond it.

    The weight keeps the plain floor (so no hit moves); this one is for the hit's uncertainty."""
    return weight_floor_px(fit, min(1.0, ERROR_FLOOR_RADIUS_PX / fit.radius_px) if fit.radius_px > 0 else 1.0)


def honest_covariance(fit: BallFit, cone_covariance: Array, focal_px: float) -> Array:
    """The error an outline's centre direction actually has (normalised units squared, without the floor),
    where the cone's covariance (from its rim points' scatter, each taken as independent) says less:

    * neighbouring rim points on a small ball share their noise (:func:`trackerd.detect.ballfit.independent_rims`):
      the cone's covariance is for len(rim) independent points, the rim holds only ``independent_rims``;
    * a partial outline takes part of any smooth departure from a circle (blur, shading, the mixed pixels
      where a hand meets the ball) for a shift of its centre
      (:func:`trackerd.detect.ballfit.arc_deformation_covariance`);
    * a partial outline (rim fraction under WHOLE_RIM_FRACTION) whose rim scatters more than
      CLEAN_RIM_SCATTER_PX has some other edge in its rim: the excess scatter, in quadrature, is an isotropic
      error of its centre.
    """
    covariance = cone_covariance
    if fit.independent_rims > 0:
        covariance = covariance * max(1.0, len(fit.rim_px) / fit.independent_rims)
    if fit.arc_covariance_px is not None:
        covariance = covariance + fit.arc_covariance_px / (focal_px * focal_px)
    if fit.rim_fraction < WHOLE_RIM_FRACTION:
        excess_px2 = max(fit.residual_px**2 - CLEAN_RIM_SCATTER_PX**2, 0.0)
        covariance = covariance + np.eye(2) * (excess_px2 / (focal_px * focal_px))
    return covariance


def partial_arc_error(fit: BallFit, expected_radius_px: float, focal_px: float) -> Array:
    """The error (normalised units squared) of a partial outline's centre whose radius is not the one a ball
    has at its distance, and which the guided look could not fit again at that radius.

    A circle fitted to an arc can grow or shrink and still follow the arc by moving its centre along the
    arc's axis: to first order, forcing the radius down by dr moves the least-squares centre by
    dr (sum u u^T)^-1 (sum u), u the unit vectors from the centre to the rim points (towards the arc).
    That is zero for a whole outline, two thirds of dr for three quarters of one, dr for half, more for less
    (tests/test_refine.py holds it to the centre a circle of the expected radius fits). That shift is the
    error's size, along its direction.

    A circle smaller than the ball is the outline of the part of it that shows, and its rim holds the edge
    of whatever hides the rest (a finger, a hand, the presenter), whose side the arc tells only where the
    rim left is the ball's own: its centre is off across the arc's axis too, by about as much as its radius
    is short (59 such outlines in installations 0-25 and 0-23 of `bench robustness` seeds 7 and 2026: half
    of it at the median, one and a half at the 90th percentile; a circle larger than the ball, a twentieth
    at the median). So a circle that is too small has that shortfall besides, in every direction.

    A circle larger than the ball holds rim points that are not the ball's (the edge of the finger on it,
    or of something of its colour touching it), and the ball's own outline lies within it, anywhere: its
    centre is off by up to the excess, in any direction (uniformly within a disc of that radius: half of it
    either way, as a standard error), but no more than the arc's own shift: a whole rim too large is a glow
    or a blur all round the ball, centred on it. Seen where a finger covered a third of a ball (`bench
    robustness --seed 11 --follow 20`, installation 12, frames 13-16: a circle 7.5 px for 6.3, its centre
    1.5 px off across the arc's axis, stated 0.4 px there, the hits 18-22 mm off at 2.3-3.1 mm sigma); and
    a whole one (installation 27: 40 px for 31 round an orange-red ball in warm light, 0.5 px off).
    """
    outward = fit.rim_px - fit.centre_px
    outward = outward / np.maximum(np.linalg.norm(outward, axis=1, keepdims=True), 1e-12)
    spread = outward.T @ outward
    if len(fit.rim_px) < 3 or np.linalg.cond(spread) > 1e6:
        # Too few rim points, or all along one line (a sliver of arc): the centre is free; as wrong as the radius.
        wrong = abs(fit.radius_px - expected_radius_px) / focal_px
        return np.eye(2) * wrong * wrong
    shift_px = (fit.radius_px - expected_radius_px) * np.linalg.solve(spread, outward.sum(axis=0))
    shift = shift_px / focal_px
    short = max(expected_radius_px - fit.radius_px, 0.0) / focal_px
    # A whole rim larger than the ball is a glow or a blur all round it, which leaves its centre where it is
    # (`bench robustness --seed 11 --follow 20`, installation 27: a circle 30 % too large, 0.5 px off): only
    # as far as the arc is partial, as its shift says, can what is not the ball be on one side of it.
    excess = EXCESS_SHARE * max(fit.radius_px - expected_radius_px, 0.0) / focal_px
    beyond = min(excess, float(np.hypot(shift[0], shift[1])))
    error: Array = np.outer(shift, shift) + np.eye(2) * (short * short + beyond * beyond)
    return error


def _with_centroid(
    camera: CameraModel,
    normalised: Array,
    covariance: Array,
    error_covariance: Array,
    centroid_px: Array,
    across_px: Array,
    centroid_sigma_px: float,
    radius_px: float,
    rim_scatter_px: float,
) -> tuple[Array, Array, Array] | None:
    """The outline's measurement with the centroid's across-the-pointer information added, when they
    agree across the pointer: (value, its covariance as a weight, the covariance of its actual error);
    None when they do not agree (the centroid is pulled by something).

    The actual error is the outline's (``error_covariance`` E_o, which may exceed what its weight
    ``covariance`` says) and the centroid's (as weighed), carried through the same combination (the
    sandwich W^-1 (I_o E_o I_o + I_c) W^-1, I_o and I_c the two weights' information, W their sum).

    The centroid joins where it agrees as a clean ball's would (``centroid_sigma_px``), and is weighed by a
    larger error where its outline's rim scatters (DISTURBED_CENTROID_SHARE)."""
    focal = camera.focal_px
    # Across the pointer in normalised units: the pixel direction is close enough (the lens map is smooth).
    across = across_px / max(float(np.linalg.norm(across_px)), 1e-12)
    # A centroid is the centre of the ball's image ellipse, which lies 1 / cos^2 of the ball's half-angle
    # further from the optical axis than the ray through the ball's centre (trackerd/geometry/sphere.py).
    half_angle_sin = min(radius_px / focal, 0.5)
    centroid_n = camera.normalized_from_pixels(centroid_px[None])[0] * (1.0 - half_angle_sin**2)
    difference = float((centroid_n - normalised) @ across)
    sigma_c = centroid_sigma_px / focal
    sigma_o = math.sqrt(max(float(across @ covariance @ across), 0.0))
    if abs(difference) > AGREE_SIGMAS * math.hypot(sigma_c, sigma_o):
        return None
    # Joined only where a clean ball's centroid would agree (a disturbed one's larger error must not admit
    # a pulled centroid), but weighed by its disturbed error: it pulls the outline less.
    disturbance_px = math.sqrt(max(rim_scatter_px**2 - MIN_SCALE_PX**2, 0.0))
    sigma_c = math.hypot(centroid_sigma_px, DISTURBED_CENTROID_SHARE * disturbance_px) / focal
    # Information form: the outline's full 2x2 plus the centroid's across the pointer only.
    info_o = np.linalg.inv(covariance)
    info_c = np.outer(across, across) / (sigma_c * sigma_c)
    info = info_o + info_c
    cov = np.linalg.inv(info)
    # The centroid's value across the pointer; along it, the outline's (info_c has nothing along).
    mean = cov @ (info_o @ normalised + info_c @ centroid_n)
    actual = cov @ (info_o @ error_covariance @ info_o + info_c) @ cov
    # float64 already: typed, not copied (NumPy's stubs give inv and @ a looser dtype).
    return (
        np.asarray(mean, dtype=np.float64),
        np.asarray(cov, dtype=np.float64),
        np.asarray(actual, dtype=np.float64),
    )
