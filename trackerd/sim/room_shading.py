"""The colour of the room along any ray: its walls' textures, the slide on the display, the posters,
stickers and balls of its clutter (:mod:`trackerd.sim.scene` describes them).

Pure functions of a :class:`~trackerd.sim.scene.Room` and rays ``origin`` (3,), ``dirs`` (N, 3).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from trackerd.sim.appearance import DEFAULT_LOOK
from trackerd.sim.raycast import ray_sphere
from trackerd.sim.scene import Face, Room

Array = NDArray[np.float64]

AMBIENT = DEFAULT_LOOK.ambient
DIFFUSE = DEFAULT_LOOK.diffuse


def room_hits(room: Room, origin: Array, dirs: Array) -> tuple[NDArray[np.int64], Array, Array]:
    """Where rays (N, 3) from ``origin`` inside the room box leave it: the axis of the face hit (N,),
    the distance (N,) and the point (N, 3)."""
    lower = np.asarray(room.lower_m)
    upper = np.asarray(room.upper_m)
    with np.errstate(divide="ignore", invalid="ignore"):
        bounds = np.where(dirs > 0, upper, lower)
        t_axes = (bounds - origin) / dirs
    t_axes[~np.isfinite(t_axes)] = np.inf
    t_axes[t_axes <= 0] = np.inf
    axis = np.argmin(t_axes, axis=1)
    t = t_axes[np.arange(len(dirs)), axis]
    return axis, t, origin + t[:, None] * dirs


def shade_room(room: Room, origin: Array, dirs: Array) -> Array:
    """Colour (N, 3) seen along rays (N, 3) from ``origin`` inside the room box."""
    axis, t, points = room_hits(room, origin, dirs)
    colour = np.zeros((len(dirs), 3))
    for face_index, face in enumerate(room.faces):
        on_face = (axis == face.axis) & (np.isclose(points[:, face.axis], face.value, atol=1e-6))
        if not np.any(on_face):
            continue
        u = points[on_face, face.u_axis]
        v = points[on_face, face.v_axis]
        tex = face_texture(room, face, u, v)
        for patch in room.patches:
            if patch.face != face_index:
                continue
            du = u - patch.centre_uv_m[0]
            dv = v - patch.centre_uv_m[1]
            if patch.shape == "rect":
                inside = (np.abs(du) <= patch.size_uv_m[0] / 2) & (np.abs(dv) <= patch.size_uv_m[1] / 2)
            else:
                inside = du * du + dv * dv <= (patch.size_uv_m[0] / 2) ** 2
            tex[inside] = patch.rgb
        # Soft light falloff so the room is not flat.
        to_light = np.asarray(room.light_m) - points[on_face]
        dist = np.linalg.norm(to_light, axis=1)
        tex *= (0.78 + 0.22 * np.exp(-dist / 4.0))[:, None]
        colour[on_face] = tex
    # Balls standing in the room, in front of the walls.
    for ball in room.balls:
        tb = ray_sphere(origin, dirs, np.asarray(ball.centre_m), ball.radius_m)
        closer = tb < t
        if np.any(closer):
            points_b = origin + tb[closer, None] * dirs[closer]
            normal = (points_b - np.asarray(ball.centre_m)) / ball.radius_m
            to_light = np.asarray(room.light_m) - points_b
            to_light /= np.linalg.norm(to_light, axis=1, keepdims=True)
            lambert = np.clip(np.sum(normal * to_light, axis=1), 0.0, 1.0)
            colour[closer] = np.asarray(ball.rgb) * (AMBIENT + DIFFUSE * lambert)[:, None]
            t = np.where(closer, tb, t)
    return colour


def face_texture(room: Room, face: Face, u: Array, v: Array) -> Array:
    """A face's own colour (N, 3) at its coordinates ``u``, ``v`` (N,) in metres: a gently varying base,
    tile joints, or the display showing the room's muted slide."""
    base = np.asarray(face.base_rgb, dtype=np.float64)
    n = len(u)
    variation = 0.94 + 0.06 * np.sin(1.7 * u + 0.3) * np.cos(1.1 * v + 0.7)
    tex = base[None, :] * variation[:, None]
    if face.texture == "tiles":
        line = (np.abs(((u + 0.25) % 0.5) - 0.25) < 0.006) | (np.abs(((v + 0.25) % 0.5) - 0.25) < 0.006)
        tex[line] *= 0.7
    elif face.texture == "display":
        x0, y0, x1, y1 = room.display
        inside = (u >= x0) & (u <= x1) & (v >= y0) & (v <= y1)
        tex[inside] = (0.10, 0.12, 0.17)
        width, height = x1 - x0, y1 - y0
        rng = np.random.default_rng(room.seed + 101)
        # A slide: a title bar and a few charts in muted colours.
        blocks = [((0.03, 0.82, 0.97, 0.95), (0.55, 0.57, 0.60))]
        for k in range(5):
            bx = 0.05 + 0.18 * k + rng.uniform(0, 0.03)
            bh = rng.uniform(0.2, 0.6)
            hue = [(0.55, 0.35, 0.30), (0.30, 0.38, 0.55), (0.40, 0.50, 0.35)][k % 3]
            blocks.append(((bx, 0.1, bx + 0.1, 0.1 + bh), hue))
        for (fx0, fy0, fx1, fy1), rgb in blocks:
            block = (
                (u >= x0 + fx0 * width) & (u <= x0 + fx1 * width) & (v >= y0 + fy0 * height) & (v <= y0 + fy1 * height)
            )
            tex[block] = rgb
    return tex.reshape(n, 3)
