"""A template recogniser for strokes of the wall hit, in the "$1 unistroke" family (Wobbrock, Wilson
and Li, UIST 2007), adapted to gestures whose direction matters.

A stroke (the hit's path between two pauses) and every template go through the
same steps:

1. **resample** the path to ``POINTS`` points equally spaced along it, so speed
   and frame rate do not matter, only shape and order;
2. **normalise**: move the centroid to the origin and scale uniformly to unit
   RMS radius. Uniform scaling (not $1's squashing into a square) keeps straight
   swipes straight and keeps a circle round;
3. **rotate**: a *rotation-invariant* template (a circle, which may start
   anywhere) is compared after turning both to their indicative angle (centroid
   to first point) and searching +-45 degrees around it; a *directional* template
   (a swipe, where left and up differ only by rotation) is compared only within
   +-``max_rotation_deg`` of its recorded orientation;
4. **distance**: the mean distance between corresponding points, minimised over
   the rotation (every 2 degrees); the **score** is ``1 - d / sqrt(2)``
   (1: identical; a circle against its mirror image scores about 0.1).

Pure functions on NumPy arrays; the templates themselves are data
(trackerd/interaction/templates.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

POINTS = 64
"""Points per resampled stroke."""
INVARIANT_SEARCH_DEG = 45.0
"""Rotation searched around the indicative angle for rotation-invariant templates ($1's choice)."""
SEARCH_PRECISION_DEG = 2.0
SCORE_SCALE = math.sqrt(2.0)
"""Distance at which the score reaches 0: the half-diagonal of the square around a unit circle."""


def path_length(points: Array) -> float:
    """Length of a polyline (N, 2)."""
    if len(points) < 2:
        return 0.0
    return float(np.sum(np.hypot(*np.diff(points, axis=0).T)))


def resample(points: Array, count: int = POINTS) -> Array:
    """``count`` points (count, 2) equally spaced along the polyline ``points`` (N, 2), ends included.

    Raises ValueError for a path of zero length (nothing to resample).
    """
    points = np.asarray(points, dtype=np.float64)
    steps = np.hypot(*np.diff(points, axis=0).T)
    cumulative = np.concatenate([[0.0], np.cumsum(steps)])
    total = float(cumulative[-1])
    if not total > 0.0:
        raise ValueError("the stroke has no length")
    targets = np.linspace(0.0, total, count)
    x = np.interp(targets, cumulative, points[:, 0])
    y = np.interp(targets, cumulative, points[:, 1])
    return np.column_stack([x, y])


def normalise(points: Array) -> Array:
    """Centroid at the origin and RMS radius 1 (uniform scale): (N, 2) -> (N, 2)."""
    centred: Array = points - points.mean(axis=0)
    radius = math.sqrt(float(np.mean(np.sum(centred * centred, axis=1))))
    if not radius > 0.0:
        raise ValueError("the stroke has no extent")
    return centred / radius


def indicative_angle(points: Array) -> float:
    """Angle (radians) from a normalised stroke's centroid (the origin) to its first point."""
    return math.atan2(float(points[0, 1]), float(points[0, 0]))


def rotate(points: Array, angle_rad: float) -> Array:
    """Points (N, 2) turned anticlockwise by ``angle_rad`` about the origin."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    turned: Array = points @ np.array([[c, s], [-s, c]])
    return turned


def prepare(points: Array, rotation_invariant: bool) -> Array:
    """A raw stroke (N, 2) in the form templates are stored in: resampled, normalised, and for a
    rotation-invariant template turned to indicative angle 0."""
    shape = normalise(resample(points))
    if rotation_invariant:
        shape = rotate(shape, -indicative_angle(shape))
    return shape


def distance_at_best_angle(candidate: Array, template: Array, limit_rad: float) -> float:
    """Smallest mean distance over rotations of ``candidate`` within +-``limit_rad``.

    Every rotation on a grid of SEARCH_PRECISION_DEG steps is tried in one vectorised pass:
    as precise as $1's golden-section search at this step and, in NumPy, several times faster
    than its sequential evaluations (the recogniser runs in the processing thread).
    """
    steps = max(3, math.ceil(2.0 * math.degrees(limit_rad) / SEARCH_PRECISION_DEG) + 1)
    angles = np.linspace(-limit_rad, limit_rad, steps)
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    x, y = candidate[None, :, 0], candidate[None, :, 1]
    dx = x * c - y * s - template[None, :, 0]
    dy = x * s + y * c - template[None, :, 1]
    return float(np.min(np.mean(np.sqrt(dx * dx + dy * dy), axis=1)))


@dataclass(frozen=True)
class Shape:
    """One gesture's template as the recogniser uses it: its examples and how it may be turned."""

    name: str
    examples: tuple[Array, ...]
    """Prepared examples, each (POINTS, 2)."""
    rotation_invariant: bool
    max_rotation_deg: float
    """For directional templates: how far a stroke may be turned from an example and still match."""


def score_shape(points: Array, shape: Shape) -> float:
    """The best score (0 to 1) of a raw stroke (N, 2) against any example of ``shape``."""
    candidate = prepare(points, shape.rotation_invariant)
    limit = math.radians(INVARIANT_SEARCH_DEG if shape.rotation_invariant else shape.max_rotation_deg)
    best = min(distance_at_best_angle(candidate, example, limit) for example in shape.examples)
    return max(0.0, 1.0 - best / SCORE_SCALE)


def score_all(points: Array, shapes: list[Shape]) -> list[tuple[str, float]]:
    """Every shape's score for a raw stroke (N, 2), best first."""
    scores = [(shape.name, score_shape(points, shape)) for shape in shapes]
    return sorted(scores, key=lambda item: -item[1])
