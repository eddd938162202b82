"""The pointer's 3D line from its two ends seen by two or more cameras.

The report triangulates each end separately (eq. 15-17) and passes a line through
the two points (eq. 26). That is sensitive to errors *along* the pointer's image,
and those are the common ones: the rod hides part of the far ball, a hand or motion
blur smears an end, which moves its centroid along the pointer's image line but
not across it (the rod and ball silhouettes are symmetric about the plane through
the camera centre and the pointer's axis). Small end errors are then magnified on
the wall by the ratio of wall distance to pointer length.

So the line is estimated from what each camera sees *across* the pointer: the
image line through a camera's two end centroids back-projects to a plane through
the camera centre that contains the pointer (the "interpretation plane"), and
the planes of two or more cameras meet in the pointer's line. The positions of
the ends along that line then come from each end's rays. When the planes are
nearly parallel (the pointer lies close to a plane containing the cameras'
baseline) their intersection is ill-conditioned and the line through the two
triangulated ends is used instead.

All functions are pure: NumPy arrays in, dataclasses of arrays out. Those on
planes and rays take leading dimensions, sets of measurements computed together:
the locator puts one pair's measurement and the moved copies of it that its
uncertainty needs through one call of each (trackerd/geometry/camera_set.py), since
with three-element vectors NumPy's cost is its calls, not the arithmetic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np
from numpy.typing import NDArray

from trackerd.errors import GeometryError
from trackerd.geometry.triangulation import closest_approach, triangulate_least_squares

Array = NDArray[np.float64]

MIN_PLANE_ANGLE_SIN = 0.08
"""Below this sine of the angle between two interpretation planes (about 4.6 degrees),
their intersection is too ill-conditioned and the two-point line is used."""

PARALLEL_PLANES_SIN = 1e-6
"""Planes closer to parallel than this (sine of their angle) have no common line: the angle comes from the
eigenvalues of sum n n^T, which hold it squared, so below about 1e-8 it is rounding (and the line is
already ill-conditioned far above, at MIN_PLANE_ANGLE_SIN)."""


@dataclass(frozen=True)
class PointerLine:
    """The pointer in 3D: its two end centres, which lie on the estimated line."""

    front_m: Array
    """Centre of the front (tip) end, (3,)."""
    back_m: Array
    """Centre of the back end, (3,)."""
    front_gap_m: float
    """How far the cameras' rays through the front end miss each other (eq. 17's closest
    approach; for more than two cameras the largest of the pairs' gaps, or with method 'points'
    twice the largest distance from their least-squares point). The quality signal: a wrong blob
    in one camera gives rays that do not meet."""
    back_gap_m: float
    """Same for the back end."""
    method: str
    """'planes' (interpretation planes) or 'points' (the report's two triangulated points)."""
    plane_angle_sin: float
    """Sine of the angle between the cameras' interpretation planes (conditioning)."""

    # Computed once, on first use: the judging and the messages of a pair read them several times.
    @cached_property
    def length_m(self) -> float:
        return math.sqrt(float(np.sum((self.front_m - self.back_m) ** 2)))

    @cached_property
    def direction(self) -> Array:
        """Unit vector from the back end to the front end (NaN when the ends coincide)."""
        length = self.length_m
        direction = (self.front_m - self.back_m) / length if length > 0.0 else np.full(3, np.nan)
        direction.flags.writeable = False  # one array for every caller
        return direction

    @property
    def gap_m(self) -> float:
        """The worse of the two ends' ray gaps."""
        return max(self.front_gap_m, self.back_gap_m)


_NEXT = np.array([1, 2, 0])
_PREV = np.array([2, 0, 1])
_FIRST = np.array([1.0, 0.0, 0.0])


def cross3(a: Array, b: Array) -> Array:
    """Cross product of (..., 3) arrays; np.cross costs twice as much for the handful of vectors used here."""
    product: Array = a[..., _NEXT] * b[..., _PREV] - a[..., _PREV] * b[..., _NEXT]
    return product


def world_rays(normalised: Array, rotations: Array) -> Array:
    """World directions (not unit) of the rays through normalised image points: ``R^T (x, y, 1)`` (eq. 14).

    Shapes: normalised coordinates (..., C, E, 2) of E points in each of C cameras,
    world-to-camera rotations (C, 3, 3) -> (..., C, E, 3).
    """
    # As rows: (x, y, 1) @ R = x R[0] + y R[1] + R[2].
    rays: Array = normalised @ rotations[:, :2, :] + rotations[:, 2:, :]
    return rays


def interpretation_plane_normals(front_dirs: Array, back_dirs: Array) -> Array:
    """Unit normals (..., C, 3) of the planes spanned by each camera's two end rays (..., C, 3) and (..., C, 3)."""
    normals = cross3(front_dirs, back_dirs)
    norms = np.sqrt((normals * normals).sum(axis=-1))[..., None]
    if not (norms >= 1e-12).all():
        raise GeometryError("the pointer's two ends coincide in an image: it is seen end-on")
    unit: Array = normals / norms
    return unit


def lines_from_planes(centres_m: Array, normals: Array) -> tuple[Array, Array, Array]:
    """Least-squares lines common to C >= 2 planes through ``centres_m`` (C, 3), for sets of unit normals (..., C, 3).

    Returns (points (..., 3), unit directions (..., 3), conditioning (...,)): each
    direction is the vector most nearly perpendicular to all of its set's normals, and
    conditioning is the sine of the angle that separates the planes (0 when they are
    parallel; then the point is NaN). For two planes the line is where they meet; the
    point is the one nearest the mean of the centres.
    """
    transposed = np.swapaxes(normals, -1, -2)
    scatter = transposed @ normals
    eigenvalues, eigenvectors = np.linalg.eigh(scatter)
    direction = eigenvectors[..., :, 0]
    # Two planes whose normals are theta apart give eigenvalues 0, 1 - cos, 1 + cos,
    # so sqrt(l1 * l2) is sin(theta); dividing by C / 2 extends that to C planes.
    cameras = normals.shape[-2]
    conditioning = np.sqrt(np.maximum(eigenvalues[..., 1], 0.0) * eigenvalues[..., 2]) * (2.0 / cameras)
    # The point: least squares on n_i . x = n_i . c_i, with its place along the line fixed
    # at the centres' mean, i.e. (scatter + u u^T) x = N^T offsets + u (u . mean). In the
    # scatter's eigenvectors V that matrix is V diag(l0 + 1, l1, l2) V^T: no solve needed.
    offsets = (normals * centres_m).sum(axis=-1)
    along = direction @ (centres_m.sum(axis=0) / cameras)
    rhs = (transposed @ offsets[..., None])[..., 0] + direction * along[..., None]
    scale = eigenvalues + _FIRST
    parallel = not (conditioning >= PARALLEL_PLANES_SIN).all()
    if parallel:
        scale = np.where(conditioning[..., None] >= PARALLEL_PLANES_SIN, scale, 1.0)
    coefficients = (np.swapaxes(eigenvectors, -1, -2) @ rhs[..., None]) / scale[..., None]
    points = (eigenvectors @ coefficients)[..., 0]
    if parallel:
        points = np.where(conditioning[..., None] >= PARALLEL_PLANES_SIN, points, np.nan)
    return points, direction, conditioning


def ends_along_line(points_m: Array, directions: Array, origins_m: Array, rays: Array) -> Array:
    """Where each end's rays come closest to its line: one point on the line per end.

    Shapes: line points and unit directions (..., 3), ray origins (C, 3), rays
    (..., E, C, 3) -> (..., E, 3). For the line p + s u and a unit ray o + t d, the
    closest point has s = (b e - d1) / (1 - b^2) with b = u.d, d1 = u.(p - o),
    e = d.(p - o) (the common perpendicular of eq. 17); the cameras' s are averaged
    with weights 1 - b^2, since a ray nearly parallel to the line fixes the position
    along it poorly (so the weighted sum of s is that of b e - d1).
    """
    unit = rays / np.sqrt((rays * rays).sum(axis=-1))[..., None]
    line_dir = directions[..., None, None, :]
    relative = points_m[..., None, None, :] - origins_m  # (..., 1, C, 3)
    b = (unit * line_dir).sum(axis=-1)
    d1 = (relative * line_dir).sum(axis=-1)
    e = (unit * relative).sum(axis=-1)
    s_mean = (b * e - d1).sum(axis=-1) / np.maximum(1.0 - b * b, 1e-18).sum(axis=-1)  # (..., E)
    placed: Array = points_m[..., None, :] + s_mean[..., None] * directions[..., None, :]
    return placed


@lru_cache(maxsize=8)
def _camera_pairs(cameras: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    first, second = np.triu_indices(cameras, 1)
    first.flags.writeable = second.flags.writeable = False  # one pair of arrays for every caller
    return first, second


def ray_gaps_m(origins_m: Array, directions: Array) -> Array:
    """How far rays through one point miss each other: the largest pairwise closest-approach distance.

    Shapes: ray origins (C, 3), rays (..., E, C, 3) for E points -> (..., E). For two
    rays this is the length of their common perpendicular (eq. 16 is the case where it
    is zero): ``|(C2 - C1) . (A x B)| / |A x B|``.
    """
    first, second = _camera_pairs(origins_m.shape[0])
    normals = cross3(directions[..., first, :], directions[..., second, :])  # (..., E, pairs, 3)
    norms = np.sqrt((normals * normals).sum(axis=-1))
    offsets = np.abs((normals * (origins_m[second] - origins_m[first])).sum(axis=-1))
    gaps = np.where(norms > 1e-12, offsets / np.maximum(norms, 1e-300), 0.0)
    worst: Array = gaps.max(axis=-1)
    return worst


def line_on_planes(
    centres_m: Array, rays: Array, point_m: Array, direction: Array, conditioning: float, min_plane_sin: float
) -> PointerLine:
    """The pointer for one set of world rays (2 ends (front, back), C, 3) and its planes' line
    (:func:`lines_from_planes`): each end placed on that line by its rays, or, where the planes
    are too close to parallel (``conditioning`` below ``min_plane_sin``), the two triangulated ends."""
    if not conditioning >= min_plane_sin:
        return _line_from_points(centres_m, rays[0], rays[1], conditioning)
    front, back = ends_along_line(point_m, direction, centres_m, rays)
    # The planes fix the line; the ends' own rays fix where on it they are. The
    # gaps are those of the ends' rays, which the line cannot hide.
    front_gap, back_gap = ray_gaps_m(centres_m, rays).tolist()
    return PointerLine(front, back, front_gap, back_gap, "planes", conditioning)


def estimate_pointer_line(
    centres_m: Array,
    front_dirs: Array,
    back_dirs: Array,
    min_plane_sin: float = MIN_PLANE_ANGLE_SIN,
) -> PointerLine:
    """The pointer's line and end centres from C >= 2 cameras.

    Shapes: camera centres (C, 3); world ray directions through each camera's
    front-end and back-end centroids (C, 3) and (C, 3).
    """
    centres = np.asarray(centres_m, dtype=np.float64).reshape(-1, 3)
    front_dirs = np.asarray(front_dirs, dtype=np.float64).reshape(-1, 3)
    back_dirs = np.asarray(back_dirs, dtype=np.float64).reshape(-1, 3)
    if len(centres) < 2:
        raise GeometryError("the pointer needs to be seen by two or more cameras")
    if not (np.all(np.isfinite(front_dirs)) and np.all(np.isfinite(back_dirs))):
        raise GeometryError("an end's ray is undefined (NaN): every camera must see both ends")
    normals = interpretation_plane_normals(front_dirs, back_dirs)
    point, direction, conditioning = lines_from_planes(centres, normals)
    return line_on_planes(
        centres, np.stack([front_dirs, back_dirs]), point, direction, float(conditioning), min_plane_sin
    )


def _line_from_points(centres: Array, front_dirs: Array, back_dirs: Array, conditioning: float) -> PointerLine:
    """The report's way: triangulate each end (eq. 15-17) and join the two points (eq. 26)."""
    if len(centres) == 2:
        front = closest_approach(centres[0], front_dirs[0], centres[1], front_dirs[1])
        back = closest_approach(centres[0], back_dirs[0], centres[1], back_dirs[1])
        return PointerLine(
            front.midpoint_m, back.midpoint_m, float(front.gap_m), float(back.gap_m), "points", conditioning
        )
    front_m, front_d = triangulate_least_squares(centres, front_dirs)
    back_m, back_d = triangulate_least_squares(centres, back_dirs)
    return PointerLine(front_m, back_m, float(2 * front_d.max()), float(2 * back_d.max()), "points", conditioning)


def pointer_from_points(centres_m: Array, front_dirs: Array, back_dirs: Array) -> PointerLine:
    """The report's method only (two triangulated points), for comparison and benchmarks."""
    centres = np.asarray(centres_m, dtype=np.float64).reshape(-1, 3)
    front_dirs = np.asarray(front_dirs, dtype=np.float64).reshape(-1, 3)
    back_dirs = np.asarray(back_dirs, dtype=np.float64).reshape(-1, 3)
    conditioning = float(np.linalg.norm(cross3(*interpretation_plane_normals(front_dirs, back_dirs)[:2])))
    return _line_from_points(centres, front_dirs, back_dirs, conditioning)


def sphere_centre_scale(depth_m: Array, radius_m: float) -> Array:
    """How much to scale a ball's normalised image coordinates to move its centroid onto the
    projection of its centre, for balls at camera depths ``depth_m`` (any shape, same shape out).

    Under perspective a sphere images as an ellipse whose centre is not the
    projection of the sphere's centre: with the sphere at camera coordinates
    (X, Y, Z) and radius r, the ellipse centre is at (X, Y) Z / (Z^2 - r^2) on
    the normalised image plane, against (X, Y) / Z for the centre (the image of
    the tangent cone, whose gradient vanishes there). So the normalised
    coordinates shrink by (1 - r^2 / Z^2).
    """
    scale: Array = 1.0 - (radius_m / np.asarray(depth_m, dtype=np.float64)) ** 2
    return scale
