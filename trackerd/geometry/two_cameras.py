"""The pointer's line from exactly two cameras, in plain floats: the locator's every-pair case.

The same closed forms as :mod:`trackerd.geometry.pointer_line` (two interpretation
planes meeting in the pointer's line, each end placed on it by its rays' common
perpendicular, eq. 15-17; the rays' gaps, eq. 16), written for two cameras on
Python floats. With three-element vectors NumPy's cost is its calls (about a
microsecond each, some 900 calls a fix), not the arithmetic, so the two-camera
fix that every pair needs runs here at a fraction of that; the NumPy functions
stay the reference (tests/geometry/test_two_cameras.py holds the two to 1e-9)
and the general case for three or more cameras.

Vectors are 3-tuples of floats in world coordinates, metres; rotations are
world-to-camera matrices as 3-tuples of rows (``x_cam = R x_world + t``).
"""

from __future__ import annotations

import math

import numpy as np

from trackerd.errors import GeometryError
from trackerd.geometry.pointer_line import PointerLine

Vec = tuple[float, float, float]
Rows = tuple[Vec, Vec, Vec]


# These functions run several times a pair, so they spell each dot and cross product out on
# unpacked components (a . b as a0 b0 + a1 b1 + a2 b2, a x b as usual) rather than calling
# helpers: about 230 Python calls a fix fewer, the same floats.


def world_ray(rotation: Rows, x_norm: float, y_norm: float) -> Vec:
    """The world direction (not unit) of the camera ray through normalised image point (x, y): R^T (x, y, 1)."""
    r0, r1, r2 = rotation
    return (
        r0[0] * x_norm + r1[0] * y_norm + r2[0],
        r0[1] * x_norm + r1[1] * y_norm + r2[1],
        r0[2] * x_norm + r1[2] * y_norm + r2[2],
    )


def plane_normal(front: Vec, back: Vec) -> Vec:
    """Unit normal of a camera's interpretation plane, spanned by its two end rays."""
    fx, fy, fz = front
    bx, by, bz = back
    nx, ny, nz = fy * bz - fz * by, fz * bx - fx * bz, fx * by - fy * bx  # front x back
    length = math.sqrt(nx * nx + ny * ny + nz * nz)
    if length < 1e-12:
        raise GeometryError("the pointer's two ends coincide in an image: it is seen end-on")
    k = 1.0 / length
    return (nx * k, ny * k, nz * k)


def planes_line(c0: Vec, c1: Vec, n0: Vec, n1: Vec) -> tuple[Vec, Vec, float] | None:
    """Where two planes (through c0 and c1, unit normals n0 and n1) meet: (point, unit direction,
    sine of the angle between the planes), the point nearest the midpoint of c0 and c1; None
    when the planes are parallel. As :func:`pointer_line.two_plane_lines`, with the 3x3 system
    [n0; n1; u] x = [n0.c0, n1.c1, u.m] solved by Cramer's rule in cross products."""
    ax0, ay0, az0 = n0
    ax1, ay1, az1 = n1
    cx, cy, cz = ay0 * az1 - az0 * ay1, az0 * ax1 - ax0 * az1, ax0 * ay1 - ay0 * ax1  # n0 x n1
    conditioning = math.sqrt(cx * cx + cy * cy + cz * cz)
    if conditioning < 1e-12:
        return None
    k = 1.0 / conditioning
    ux, uy, uz = cx * k, cy * k, cz * k
    mx, my, mz = (c0[0] + c1[0]) * 0.5, (c0[1] + c1[1]) * 0.5, (c0[2] + c1[2]) * 0.5
    r0 = ax0 * c0[0] + ay0 * c0[1] + az0 * c0[2]
    r1 = ax1 * c1[0] + ay1 * c1[1] + az1 * c1[2]
    r2 = ux * mx + uy * my + uz * mz
    px, py, pz = ay1 * uz - az1 * uy, az1 * ux - ax1 * uz, ax1 * uy - ay1 * ux  # n1 x u
    qx, qy, qz = uy * az0 - uz * ay0, uz * ax0 - ux * az0, ux * ay0 - uy * ax0  # u x n0
    det = ax0 * px + ay0 * py + az0 * pz
    point = (
        (r0 * px + r1 * qx + r2 * cx) / det,
        (r0 * py + r1 * qy + r2 * cy) / det,
        (r0 * pz + r1 * qz + r2 * cz) / det,
    )
    return point, (ux, uy, uz), conditioning


def _end_on_line(point: Vec, u: Vec, c0: Vec, c1: Vec, d0: Vec, d1: Vec) -> Vec:
    """Where an end's two rays (c_k + t d_k) come closest to the line point + s u, averaged with
    weights sin^2 of each ray's angle to the line (as pointer_line._ends_along_line)."""
    px, py, pz = point
    ux, uy, uz = u
    total = weights = 0.0
    for (ox, oy, oz), (dx, dy, dz) in ((c0, d0), (c1, d1)):
        k = 1.0 / math.sqrt(dx * dx + dy * dy + dz * dz)
        dx, dy, dz = dx * k, dy * k, dz * k  # unit
        rx, ry, rz = px - ox, py - oy, pz - oz
        b = dx * ux + dy * uy + dz * uz
        sin2 = max(1.0 - b * b, 1e-18)
        s = (b * (dx * rx + dy * ry + dz * rz) - (rx * ux + ry * uy + rz * uz)) / sin2
        total += s * sin2
        weights += sin2
    s_mean = total / weights
    return (px + s_mean * ux, py + s_mean * uy, pz + s_mean * uz)


def ray_gap_m(c0: Vec, c1: Vec, d0: Vec, d1: Vec) -> float:
    """How far two rays miss each other: |(c1 - c0) . (d0 x d1)| / |d0 x d1| (eq. 16 measured)."""
    ax, ay, az = d0
    bx, by, bz = d1
    nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx  # d0 x d1
    length = math.sqrt(nx * nx + ny * ny + nz * nz)
    if length <= 1e-12:
        return 0.0
    return abs(nx * (c1[0] - c0[0]) + ny * (c1[1] - c0[1]) + nz * (c1[2] - c0[2])) / length


def pointer_line(
    c0: Vec, c1: Vec, front0: Vec, back0: Vec, front1: Vec, back1: Vec, min_plane_sin: float
) -> PointerLine | None:
    """:func:`pointer_line.estimate_pointer_line` for two cameras (centres c0, c1; world rays
    through each camera's front and back end); None when the planes are too close to parallel
    for their line, where the caller uses the two triangulated points instead."""
    ends = pointer_ends(c0, c1, front0, back0, front1, back1, min_plane_sin)
    return None if ends is None else line_through(c0, c1, front0, back0, front1, back1, ends)


def pointer_ends(
    c0: Vec, c1: Vec, front0: Vec, back0: Vec, front1: Vec, back1: Vec, min_plane_sin: float
) -> tuple[Vec, Vec, float] | None:
    """The ends of :func:`pointer_line` alone, (front, back, sine of the angle between the planes):
    what a first line is needed for when it is corrected for the balls' size."""
    found = planes_line(c0, c1, plane_normal(front0, back0), plane_normal(front1, back1))
    if found is None or found[2] < min_plane_sin:
        return None
    point, u, conditioning = found
    return _end_on_line(point, u, c0, c1, front0, front1), _end_on_line(point, u, c0, c1, back0, back1), conditioning


def line_through(
    c0: Vec, c1: Vec, front0: Vec, back0: Vec, front1: Vec, back1: Vec, ends: tuple[Vec, Vec, float]
) -> PointerLine:
    """The :class:`PointerLine` of :func:`pointer_ends`' ``ends`` for those rays, with the rays' gaps."""
    front, back, conditioning = ends
    return PointerLine(
        np.array(front),
        np.array(back),
        ray_gap_m(c0, c1, front0, front1),
        ray_gap_m(c0, c1, back0, back1),
        "planes",
        conditioning,
    )


def plane_line_hits(
    c0: Vec,
    c1: Vec,
    rotations: tuple[Rows, Rows],
    variants: list[tuple[float, ...]],
    wall_normal: Vec,
    wall_offset_m: float,
) -> list[Vec]:
    """Where the interpretation planes' line meets the wall plane, for sets of normalised end
    coordinates (x0f, y0f, x0b, y0b, x1f, y1f, x1b, y1b): the batched path of the locator's
    uncertainty (:func:`trackerd.geometry.camera_set.hit_uncertainty_reference_m`). The wall plane is
    n . x + offset = 0 (eq. 23).

    Raises GeometryError when the line of a set is parallel to the wall or the planes are parallel.
    """
    hits = []
    wx, wy, wz = wall_normal
    # A perturbation moves one camera's ends only (the uncertainty's variants): the other
    # camera's plane is the measured one again, computed once.
    normals: list[dict[tuple[float, ...], Vec]] = [{}, {}]

    def normal_of(camera: int, ends: tuple[float, float, float, float]) -> Vec:
        known = normals[camera].get(ends)
        if known is None:
            rows = rotations[camera]
            known = normals[camera][ends] = plane_normal(
                world_ray(rows, ends[0], ends[1]), world_ray(rows, ends[2], ends[3])
            )
        return known

    for x0f, y0f, x0b, y0b, x1f, y1f, x1b, y1b in variants:
        n0 = normal_of(0, (x0f, y0f, x0b, y0b))
        n1 = normal_of(1, (x1f, y1f, x1b, y1b))
        found = planes_line(c0, c1, n0, n1)
        if found is None:
            raise GeometryError("the cameras' planes through the pointer are parallel: no line")
        (px, py, pz), (ux, uy, uz), _ = found
        denominator = ux * wx + uy * wy + uz * wz
        if abs(denominator) < 1e-9:
            raise GeometryError("the pointer is parallel to the wall")
        t = (wx * px + wy * py + wz * pz + wall_offset_m) / denominator
        hits.append((px - t * ux, py - t * uy, pz - t * uz))
    return hits
