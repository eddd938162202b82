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


def ray_cylinder(origin: Array, dirs: Array, start: Array, end: Array, radius: float) -> tuple[Array, Array]:
    """First hit of unit rays with the side of a finite cylinder (no caps): distances (N,) and outward unit
    normals (N, 3), zero where a ray misses."""
    axis = end - start
    length = float(np.linalg.norm(axis))
    axis = axis / length
    w = origin - start
    d_par = dirs @ axis
    d_perp = dirs - d_par[:, None] * axis
    w_par = w @ axis
    w_perp = w - w_par * axis
    a = np.sum(d_perp * d_perp, axis=1)
    b = 2.0 * (d_perp @ w_perp)
    c = w_perp @ w_perp - radius * radius
    disc = b * b - 4 * a * c
    t = np.full(len(dirs), np.inf)
    ok = (disc >= 0) & (a > 1e-15)
    root = np.sqrt(np.where(ok, disc, 0.0))
    near = (-b - root) / np.where(ok, 2 * a, 1.0)
    along = w_par + near * d_par
    valid = ok & (near > 1e-9) & (along >= 0) & (along <= length)
    t[valid] = near[valid]
    # Normals only where a ray hits: most rays near a thin rod miss it.
    normal = np.zeros((len(dirs), 3))
    rel = origin + near[valid, None] * dirs[valid] - start
    outward = rel - (rel @ axis)[:, None] * axis
    norm = np.linalg.norm(outward, axis=1, keepdims=True)
    normal[valid] = outward / np.where(norm > 0, norm, 1.0)
    return t, normal
