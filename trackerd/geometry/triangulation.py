"""Triangulation: where rays from two or more cameras meet (report section 3.3-3.4).

The report intersects two rays, each through a camera centre C and an image point
P, assuming they meet (eq. 16). Measured rays never quite do, so here the
*closest approach* of two skew rays is used (eq. 17 gives its parameter s): the
answer is the midpoint of the shortest segment joining them, and the length of
that segment, the *gap*, says how well the two observations agree.

For N >= 2 cameras, :func:`triangulate_least_squares` finds the point nearest to
all rays in the least-squares sense; with two rays it is the same midpoint.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.errors import GeometryError

Array = NDArray[np.float64]

MIN_RAY_ANGLE_RAD = 1e-6
"""Rays closer to parallel than this (about 0.2 arc seconds) have no usable intersection."""


@dataclass(frozen=True)
class ClosestApproach:
    """Result of intersecting two rays: shapes are those of the inputs' leading dimensions."""

    midpoint_m: Array
    """Midpoint of the shortest segment between the rays, (..., 3)."""
    gap_m: Array
    """Length of that segment, (...): zero when the rays truly intersect (eq. 16 holds)."""
    s: Array
    """Parameter along the first ray, in units of its direction vector (eq. 17)."""
    t: Array
    """Parameter along the second ray."""


def closest_approach(
    origin_a_m: Array,
    direction_a: Array,
    origin_b_m: Array,
    direction_b: Array,
    min_angle_rad: float = MIN_RAY_ANGLE_RAD,
) -> ClosestApproach:
    """Closest approach of ray ``C1 + s A`` and ray ``C2 + t B`` (eq. 15-17, for skew rays).

    Shapes: origins and directions (..., 3); directions need not be unit length.
    The report's parameter for coplanar rays is ``s = ((C2 - C1) x B) . (A x B) / |A x B|^2``
    (eq. 17); the same expression, and its twin for ``t``, give the feet of the
    common perpendicular when the rays are skew.

    Raises GeometryError if any pair of rays is closer to parallel than min_angle_rad.
    """
    c1 = np.asarray(origin_a_m, dtype=np.float64)
    c2 = np.asarray(origin_b_m, dtype=np.float64)
    a = np.asarray(direction_a, dtype=np.float64)
    b = np.asarray(direction_b, dtype=np.float64)
    for name, value in (("origin", c1), ("direction", a), ("origin", c2), ("direction", b)):
        if not np.all(np.isfinite(value)):
            raise GeometryError(f"a ray's {name} is not finite: nothing to triangulate")
    a_cross_b = np.cross(a, b)
    denom = np.einsum("...i,...i->...", a_cross_b, a_cross_b)
    norms = np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1)
    sin_angle = np.sqrt(denom) / np.where(norms > 0, norms, np.inf)
    if np.any(~(sin_angle >= np.sin(min_angle_rad))):
        worst = float(np.degrees(np.arcsin(np.clip(np.nanmin(sin_angle), 0.0, 1.0))))
        raise GeometryError(f"rays are parallel within {worst:.2g} degrees: the cameras cannot triangulate this point")
    baseline = c2 - c1
    s = np.einsum("...i,...i->...", np.cross(baseline, b), a_cross_b) / denom
    t = np.einsum("...i,...i->...", np.cross(baseline, a), a_cross_b) / denom
    foot_a = c1 + s[..., None] * a
    foot_b = c2 + t[..., None] * b
    midpoint = (foot_a + foot_b) / 2.0
    gap = np.linalg.norm(foot_a - foot_b, axis=-1)
    return ClosestApproach(midpoint, gap, s, t)


def triangulate_least_squares(origins_m: Array, directions: Array) -> tuple[Array, Array]:
    """The point nearest to N >= 2 rays, and each ray's distance from it.

    Shapes: origins (N, 3), directions (N, 3) -> point (3,), distances (N,).
    Minimises the sum of squared perpendicular distances, which for unit
    directions solves ``sum_i (I - d_i d_i^T) (x - o_i) = 0``. NaN rows (a camera
    that did not see the point) are ignored.
    """
    origins = np.asarray(origins_m, dtype=np.float64).reshape(-1, 3)
    dirs = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    valid = np.all(np.isfinite(origins), axis=1) & np.all(np.isfinite(dirs), axis=1)
    origins, dirs = origins[valid], dirs[valid]
    if len(origins) < 2:
        raise GeometryError(f"need rays from two or more cameras, got {len(origins)}")
    lengths = np.linalg.norm(dirs, axis=1, keepdims=True)
    if np.any(lengths < 1e-12):
        raise GeometryError("a ray's direction has no length: nothing to triangulate")
    dirs = dirs / lengths
    lhs, rhs = _normal_equations(origins, dirs)
    # The smallest eigenvalue of lhs measures how far from parallel the rays are.
    if np.linalg.eigvalsh(lhs)[0] < np.sin(MIN_RAY_ANGLE_RAD) ** 2:
        raise GeometryError("rays are parallel: the cameras cannot triangulate this point")
    point = np.asarray(np.linalg.solve(lhs, rhs)[..., 0], dtype=np.float64)
    offsets = point - origins
    perpendicular = offsets - np.sum(offsets * dirs, axis=1, keepdims=True) * dirs
    return point, np.linalg.norm(perpendicular, axis=1)


def nearest_points_m(origins_m: Array, directions: Array) -> Array:
    """:func:`triangulate_least_squares` for many points at once, without its checks: the point nearest
    the rays of each set. Shapes: origins (C, 3), directions (..., C, 3), not necessarily unit -> (..., 3).

    Raises numpy.linalg.LinAlgError when a set's rays are all parallel.
    """
    unit: Array = directions / np.sqrt((directions * directions).sum(axis=-1))[..., None]
    lhs, rhs = _normal_equations(origins_m, unit)
    points = np.asarray(np.linalg.solve(lhs, rhs)[..., 0], dtype=np.float64)
    return points


def _normal_equations(origins_m: Array, unit_directions: Array) -> tuple[Array, Array]:
    """``sum_i (I - d_i d_i^T) x = sum_i (I - d_i d_i^T) o_i``, the least-squares point of rays with unit
    directions (..., C, 3) from origins (C, 3): (lhs (..., 3, 3), rhs (..., 3, 1))."""
    projectors = np.eye(3) - unit_directions[..., :, None] * unit_directions[..., None, :]  # (..., C, 3, 3)
    rhs: Array = (projectors @ origins_m[..., None]).sum(axis=-3)
    return projectors.sum(axis=-3), rhs


def triangulate_pixels(cameras: list, pixels_px: Array) -> tuple[Array, Array]:
    """Triangulate one point seen at ``pixels_px[i]`` (C, 2) by ``cameras[i]`` -> (point (3,), ray distances (C,))."""
    pix = np.asarray(pixels_px, dtype=np.float64).reshape(-1, 2)
    origins, dirs = [], []
    for camera, pixel in zip(cameras, pix, strict=True):
        if not np.all(np.isfinite(pixel)):
            continue
        o, d = camera.pixel_to_ray(pixel[None, :])
        origins.append(o[0])
        dirs.append(d[0])
    return triangulate_least_squares(np.array(origins), np.array(dirs))
