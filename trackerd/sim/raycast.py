"""Where unit rays first meet a sphere or a finite cylinder: the solids the simulator's scenes are made of.

Pure functions on arrays: ``origin`` (3,), ``dirs`` (N, 3) unit directions; a
distance of ``inf`` means the ray misses (or the solid is behind its origin).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def ray_sphere(origin: Array, dirs: Array, centre: Array, radius: float) -> Array:
    """Distance (N,) along unit rays to the first hit of a sphere (inf where missed or behind)."""
    oc = origin - centre
    b = dirs @ oc
    c = oc @ oc - radius * radius
    disc = b * b - c
    t = np.full(len(dirs), np.inf)
    ok = disc >= 0
    root = np.sqrt(np.where(ok, disc, 0.0))
    near = -b - root
    valid = ok & (near > 1e-9)
    t[valid] = near[valid]
    return t


def points_along(origin: Array, dirs: Array, t: Array) -> Array:
    """Points (N, 3) at distances ``t`` (N,) along rays from ``origin``: ``origin + t[:, None] * dirs``
    computed column by column (the same values; NumPy broadcasts one value a row over three columns
    several times slower than it works on whole columns)."""
    points = np.empty((len(t), 3))
    for k in range(3):
        np.multiply(t, dirs[:, k], out=points[:, k])
        points[:, k] += origin[k]
    return points


def without_axis(vectors: Array, along: Array, axis: Array) -> Array:
    """``vectors - along[:, None] * axis`` column by column: the part of each row across ``axis``."""
    out = np.empty_like(vectors)
    for k in range(3):
        np.subtract(vectors[:, k], along * axis[k], out=out[:, k])
    return out


def row_dots(a: Array, b: Array) -> Array:
    """Row-wise dot products of (N, 3) arrays: ``np.sum(a * b, axis=1)`` term for term, at less cost."""
    out = a[:, 0] * b[:, 0]
    out += a[:, 1] * b[:, 1]
    out += a[:, 2] * b[:, 2]
    return out


def ray_cylinder(origin: Array, dirs: Array, start: Array, end: Array, radius: float) -> tuple[Array, Array]:
    """First hit of unit rays with the side of a finite cylinder (no caps): distances (N,) and outward unit
    normals (N, 3), zero where a ray misses."""
    axis = end - start
    length = float(np.linalg.norm(axis))
    axis = axis / length
    w = origin - start
    d_par = dirs @ axis
    d_perp = without_axis(dirs, d_par, axis)
    w_par = w @ axis
    w_perp = w - w_par * axis
    a = row_dots(d_perp, d_perp)
    b = d_perp @ w_perp
    b *= 2.0
    c = w_perp @ w_perp - radius * radius
    disc = b * b - 4 * a * c
    # Only the rays that meet the infinite cylinder go on (most near a thin rod miss it).
    meets = np.flatnonzero((disc >= 0) & (a > 1e-15))
    near = (-b[meets] - np.sqrt(disc[meets])) / (2 * a[meets])
    along = w_par + near * d_par[meets]
    on_side = (near > 1e-9) & (along >= 0) & (along <= length)
    hits = meets[on_side]
    near = near[on_side]
    t = np.full(len(dirs), np.inf)
    t[hits] = near
    rel = points_along(origin, dirs[hits], near)
    rel -= start
    outward = without_axis(rel, rel @ axis, axis)
    norm = np.sqrt(row_dots(outward, outward))
    outward /= np.where(norm > 0, norm, 1.0)[:, None]
    normal = np.zeros((len(dirs), 3))
    normal[hits] = outward
    return t, normal
