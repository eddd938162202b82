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

All functions are pure: NumPy arrays in, dataclasses of arrays out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from trackerd.errors import GeometryError
from trackerd.geometry.triangulation import closest_approach, triangulate_least_squares

Array = NDArray[np.float64]

MIN_PLANE_ANGLE_SIN = 0.08
"""Below this sine of the angle between two interpretation planes (about 4.6 degrees),
their intersection is too ill-conditioned and the two-point line is used."""


@dataclass(frozen=True)
class PointerLine:
    """The pointer in 3D: its two end centres, which lie on the estimated line."""

    front_m: Array
    """Centre of the front (tip) end, (3,)."""
    back_m: Array
    """Centre of the back end, (3,)."""
    front_gap_m: float
    """How far the cameras' rays through the front end miss each other (eq. 17's closest
    approach; for more than two cameras twice the largest distance from their least-squares
    point). The quality signal: a wrong blob in one camera gives rays that do not meet."""
    back_gap_m: float
    """Same for the back end."""
    method: str
    """'planes' (interpretation planes) or 'points' (the report's two triangulated points)."""
    plane_angle_sin: float
    """Sine of the angle between the cameras' interpretation planes (conditioning)."""

    # Computed once, on first use: the judging and the messages of a pair read them several times.
    @cached_property
    def front_floats(self) -> tuple[float, float, float]:
        """:attr:`front_m` as plain floats."""
        x, y, z = self.front_m.tolist()
        return x, y, z

    @cached_property
    def back_floats(self) -> tuple[float, float, float]:
        """:attr:`back_m` as plain floats."""
        x, y, z = self.back_m.tolist()
        return x, y, z

    @cached_property
    def direction(self) -> Array:
        """Unit vector from the back end to the front end."""
        (fx, fy, fz), (bx, by, bz) = self.front_floats, self.back_floats
        length = self.length_m
        direction = (
            np.full(3, np.nan)
            if not length > 0.0  # coincident ends: no direction
            else np.array([(fx - bx) / length, (fy - by) / length, (fz - bz) / length])
        )
        direction.flags.writeable = False  # one array for every caller
        return direction

    @cached_property
    def length_m(self) -> float:
        (fx, fy, fz), (bx, by, bz) = self.front_floats, self.back_floats
        return math.sqrt((fx - bx) ** 2 + (fy - by) ** 2 + (fz - bz) ** 2)

    @property
    def gap_m(self) -> float:
        """The worse of the two ends' ray gaps."""
        return max(self.front_gap_m, self.back_gap_m)


def cross3(a: Array, b: Array) -> Array:
    """Cross product of (..., 3) arrays; np.cross is slow for the handful of vectors used here."""
    return np.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )


def interpretation_plane_normals(front_dirs: Array, back_dirs: Array) -> Array:
    """Unit normals (C, 3) of the planes spanned by each camera's two end rays (C, 3) and (C, 3)."""
    normals = cross3(front_dirs, back_dirs)
    norms = np.sqrt(np.sum(normals * normals, axis=1, keepdims=True))
    if np.any(norms < 1e-12):
        raise GeometryError("the pointer's two ends coincide in an image: it is seen end-on")
    unit: Array = normals / norms
    return unit


def line_from_planes(centres_m: Array, normals: Array) -> tuple[Array, Array, float]:
    """Least-squares line common to planes through ``centres_m`` (C, 3) with unit ``normals`` (C, 3).

    Returns (point (3,), unit direction (3,), conditioning): the direction is the
    vector most nearly perpendicular to every normal, and conditioning is the sine
    of the angle that separates the planes (0 when they are parallel). Raises
    GeometryError when the planes are parallel.
    """
    if len(normals) == 2:
        points, directions, conditionings = two_plane_lines(centres_m, normals[None])
        return points[0], directions[0], float(conditionings[0])
    scatter = normals.T @ normals
    eigenvalues, eigenvectors = np.linalg.eigh(scatter)
    direction = eigenvectors[:, 0]
    # Two planes whose normals are theta apart give eigenvalues 0, 1 - cos, 1 + cos,
    # so sqrt(l1 * l2) is sin(theta); dividing by C / 2 extends that to C planes.
    conditioning = float(np.sqrt(max(eigenvalues[1], 0.0) * eigenvalues[2]) / (len(normals) / 2.0))
    if conditioning < 1e-12:
        raise GeometryError("the cameras' planes through the pointer are parallel: no line")
    # Point: least squares on n_i . x = n_i . c_i, regularised along the free direction.
    offsets = np.sum(normals * centres_m, axis=1)
    lhs = scatter + np.outer(direction, direction)
    rhs = normals.T @ offsets + direction * (direction @ centres_m.mean(axis=0))
    point: Array = np.linalg.solve(lhs, rhs)
    return point, np.asarray(direction, dtype=np.float64), conditioning


def two_plane_lines(centres_m: Array, normals: Array) -> tuple[Array, Array, Array]:
    """Lines where pairs of planes meet, in closed form, for B pairs at once.

    Shapes: plane points (2, 3), unit normals (B, 2, 3) -> points (B, 3), unit
    directions (B, 3), conditioning (B,) = |n0 x n1|, the sine of the angle
    between the planes. The point is the one nearest the two plane points' midpoint.
    """
    n0, n1 = normals[:, 0], normals[:, 1]
    cross = cross3(n0, n1)
    conditioning = np.sqrt(np.sum(cross * cross, axis=1))
    if np.any(conditioning < 1e-12):
        raise GeometryError("the cameras' planes through the pointer are parallel: no line")
    direction = cross / conditioning[:, None]
    middle = 0.5 * (centres_m[0] + centres_m[1])
    lhs = np.stack([n0, n1, direction], axis=1)
    rhs = np.stack([n0 @ centres_m[0], n1 @ centres_m[1], direction @ middle], axis=1)
    return np.linalg.solve(lhs, rhs[..., None])[..., 0], direction, conditioning


def _ends_along_line(point: Array, direction: Array, origins: Array, dirs: Array) -> Array:
    """Where each end's rays come closest to a line: one point on the line per end.

    Shapes: line point and unit direction (3,), ray origins (C, 3), rays (E, C, 3)
    -> (E, 3). For the line p + s u and a unit ray o + t d, the closest point has
    s = (b e - d1) / (1 - b^2) with b = u.d, d1 = u.(p - o), e = d.(p - o) (the
    common perpendicular of eq. 17); the cameras' s are averaged with weights
    1 - b^2, since a ray nearly parallel to the line fixes the position along it poorly.
    """
    unit = dirs / np.sqrt(np.sum(dirs * dirs, axis=-1, keepdims=True))
    rel = point - origins
    b = unit @ direction
    d1 = rel @ direction
    e = np.sum(unit * rel, axis=-1)
    sin2 = np.maximum(1.0 - b * b, 1e-18)
    s = (b * e - d1) / sin2
    s_mean = np.sum(s * sin2, axis=-1) / np.sum(sin2, axis=-1)
    placed: Array = point + s_mean[:, None] * direction
    return placed


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
    try:
        point, direction, conditioning = line_from_planes(centres, normals)
    except GeometryError:
        conditioning = 0.0
    if conditioning < min_plane_sin:
        return _line_from_points(centres, front_dirs, back_dirs, conditioning)
    ends = np.stack([front_dirs, back_dirs])
    front, back = _ends_along_line(point, direction, centres, ends)
    # The planes fix the line; the ends' own rays fix where on it they are. The
    # gaps are those of the ends' rays, which the line cannot hide.
    gaps = ray_gaps_m(centres, ends)
    return PointerLine(front, back, float(gaps[0]), float(gaps[1]), "planes", conditioning)


def ray_gaps_m(origins_m: Array, directions: Array) -> Array:
    """How far rays through one point miss each other: the largest pairwise closest-approach distance.

    Shapes: ray origins (C, 3), rays (E, C, 3) for E points -> (E,). For two rays
    this is the length of their common perpendicular (eq. 16 is the case where it
    is zero): ``|(C2 - C1) . (A x B)| / |A x B|``.
    """
    worst = np.zeros(directions.shape[0])
    n = origins_m.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            normals = cross3(directions[:, i], directions[:, j])
            norms = np.sqrt(np.sum(normals * normals, axis=-1))
            offsets = np.abs(normals @ (origins_m[j] - origins_m[i]))
            gap = np.where(norms > 1e-12, offsets / np.maximum(norms, 1e-300), 0.0)
            worst = np.maximum(worst, gap)
    return worst


def ray_gap_m(origins_m: Array, directions: Array) -> float:
    """:func:`ray_gaps_m` for the rays (C, 3) of a single point."""
    return float(ray_gaps_m(np.asarray(origins_m, float), np.asarray(directions, float)[None])[0])


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


def sphere_centre_direction(centroid_dirs_cam: Array, depth_m: Array, radius_m: float) -> Array:
    """Correct the ray through a ball's image centroid to the ray through its centre.

    Under perspective a sphere images as an ellipse whose centre is not the
    projection of the sphere's centre: with the sphere at camera coordinates
    (X, Y, Z) and radius r, the ellipse centre is at (X, Y) Z / (Z^2 - r^2) on
    the normalised image plane, against (X, Y) / Z for the centre (the image of
    the tangent cone, whose gradient vanishes there). So the normalised
    coordinates shrink by (1 - r^2 / Z^2).

    Shapes: (N, 3) camera-frame directions through the centroids, (N,) depths -> (N, 3) unit directions.
    """
    dirs = np.asarray(centroid_dirs_cam, dtype=np.float64).reshape(-1, 3)
    normalised = dirs[:, :2] / dirs[:, 2:3]
    scale = 1.0 - (radius_m / np.asarray(depth_m, dtype=np.float64)) ** 2
    corrected = np.column_stack([normalised * scale[:, None], np.ones(len(dirs))])
    unit: Array = corrected / np.linalg.norm(corrected, axis=1, keepdims=True)
    return unit
