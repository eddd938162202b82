"""The pointer's solids along rays: its two balls, the rod and handle, the hand holding it and anything
standing in front of it, and how they are lit (a Lambert term and, for glossy balls, a Phong highlight).

Also the exact outline of a ball's image (:func:`silhouette_area_px`), for the truth of how much of a
ball a view shows.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.config.models import RigConfig
from trackerd.geometry.camera import CameraModel
from trackerd.sim.appearance import Look, Occluder
from trackerd.sim.raycast import points_along, ray_cylinder, ray_sphere, row_dots
from trackerd.sim.scene import HAND_RADIUS_M, HANDLE_LENGTH_FACTOR, PointerPose, Room, scene_pointer

Array = NDArray[np.float64]
RGB = tuple[float, float, float]

# Primitive ids in the pointer's sample buffers.
NOTHING, RED_BALL, BLUE_BALL, ROD, HAND, OCCLUDER = 0, 1, 2, 3, 4, 5


@dataclass(frozen=True)
class PointerLook:
    """What the pointer is made of and how it is lit: all :func:`shade_pointer` needs of a scene."""

    end_diameter_m: float
    rod_diameter_m: float
    front_colour: str
    """'red' or 'blue': the colour of the ball at the tip."""
    hand: bool
    """Whether a hand holds the handle."""
    light_m: tuple[float, float, float]
    look: Look

    @classmethod
    def of(cls, rig: RigConfig, room: Room, look: Look) -> PointerLook:
        pointer = scene_pointer(rig)
        return cls(
            pointer.end_diameter_m,
            pointer.rod_diameter_m,
            pointer.front_colour,
            rig.simulation.hand,
            room.light_m,
            look,
        )


def shade_pointer(
    scene: PointerLook, origin: Array, dirs: Array, pose: PointerPose, occluders: tuple[Occluder, ...] = ()
) -> tuple[NDArray[np.int8], Array]:
    """Intersect rays (N, 3) from ``origin`` with the pointer (and any occluders); per ray the
    primitive id (N,) and shaded colour (N, 3)."""
    look = scene.look
    light = np.asarray(scene.light_m)
    length = pose.length_m
    direction = pose.direction
    handle_end = pose.back_m - HANDLE_LENGTH_FACTOR * length * direction
    ball_r = scene.end_diameter_m / 2.0
    rod_r = scene.rod_diameter_m / 2.0
    front_rgb = look.red_rgb if scene.front_colour == "red" else look.blue_rgb
    back_rgb = look.blue_rgb if scene.front_colour == "red" else look.red_rgb
    front_id = RED_BALL if scene.front_colour == "red" else BLUE_BALL
    back_id = BLUE_BALL if scene.front_colour == "red" else RED_BALL

    n = len(dirs)
    best_t = np.full(n, np.inf)
    ids = np.zeros(n, dtype=np.int8)
    normals = np.zeros((n, 3))
    # Each ray's paint as an index into ``paints``: filled in once at the end, not a row per hit solid.
    paints: list[RGB] = [(0.0, 0.0, 0.0)]
    paint = np.zeros(n, dtype=np.intp)

    def near(centre: Array, bound_m: float) -> NDArray[np.intp]:
        """The rays that pass within ``bound_m`` of ``centre``: the only ones that can hit what it bounds."""
        offset = centre - origin
        along = dirs @ offset
        miss2 = offset @ offset - along * along
        return np.flatnonzero((miss2 <= bound_m * bound_m) | (offset @ offset <= bound_m * bound_m))

    def consider(
        rays: NDArray[np.intp], t: Array, normal_of: Callable[[NDArray[np.intp]], Array], prim: int, rgb: RGB
    ) -> None:
        """Take the rays ``rays`` whose hit ``t`` is nearer than any before; ``normal_of`` gives the
        normals of some of them (indices into ``rays``)."""
        closer = np.flatnonzero(t < best_t[rays])
        if closer.size:
            chosen = rays[closer]
            best_t[chosen] = t[closer]
            ids[chosen] = prim
            normals[chosen] = normal_of(closer)
            paint[chosen] = len(paints)
            paints.append(rgb)

    def sphere(centre: Array, radius: float, prim: int, rgb: RGB) -> None:
        rays = near(centre, radius * 1.001)
        if rays.size:
            sub = dirs[rays]
            t = ray_sphere(origin, sub, centre, radius)

            def normal_of(closer: NDArray[np.intp]) -> Array:
                normal = points_along(origin, sub[closer], t[closer])
                normal -= centre
                normal /= radius
                return normal

            consider(rays, t, normal_of, prim, rgb)

    def cylinder(start: Array, end: Array, radius: float, prim: int, rgb: RGB) -> None:
        rays = near(0.5 * (start + end), 0.5 * float(np.linalg.norm(end - start)) + radius * 1.001)
        if rays.size:
            t, normal = ray_cylinder(origin, dirs[rays], start, end, radius)
            consider(rays, t, lambda closer: normal[closer], prim, rgb)

    sphere(pose.front_m, ball_r, front_id, front_rgb)
    sphere(pose.back_m, ball_r, back_id, back_rgb)
    for start, end in ((pose.front_m, pose.back_m), (pose.back_m, handle_end)):
        cylinder(start, end, rod_r, ROD, look.rod_rgb)
    if scene.hand:
        sphere(handle_end - HAND_RADIUS_M * 0.5 * direction, HAND_RADIUS_M, HAND, look.skin_rgb)
    for occ in occluders:
        centre = np.asarray(occ.centre_m, dtype=np.float64)
        if occ.kind == "sphere":
            sphere(centre, occ.radius_m, OCCLUDER, occ.rgb)
        else:
            half = np.array([0.0, occ.height_m / 2.0, 0.0])
            cylinder(centre - half, centre + half, occ.radius_m, OCCLUDER, occ.rgb)

    colours = np.zeros((n, 3))
    hit = np.flatnonzero(ids != NOTHING)
    if hit.size:
        ray = dirs[hit]
        normal = normals[hit]
        to_light = points_along(origin, ray, best_t[hit])
        np.subtract(light, to_light, out=to_light)
        distance = np.sqrt(row_dots(to_light, to_light))
        for k in range(3):
            to_light[:, k] /= distance
        facing_light = row_dots(normal, to_light)
        brightness = look.ambient + look.diffuse * np.clip(facing_light, 0.0, 1.0)
        base = np.asarray(paints)[paint[hit]]
        shaded = np.empty_like(base)
        for k in range(3):
            np.multiply(base[:, k], brightness, out=shaded[:, k])
        if look.specular > 0.0:
            # A white Phong highlight on the glossy balls: the light mirrored about the normal, seen along the ray.
            ball = (ids[hit] == RED_BALL) | (ids[hit] == BLUE_BALL)
            twice = 2.0 * facing_light
            reflected = np.empty_like(normal)
            for k in range(3):
                np.multiply(twice, normal[:, k], out=reflected[:, k])
            reflected -= to_light
            highlight = ball * look.specular * np.clip(-row_dots(reflected, ray), 0.0, 1.0) ** look.shininess
            for k in range(3):
                shaded[:, k] += highlight
        colours[hit] = shaded
    return ids, colours


def silhouette_area_px(camera: CameraModel, centre_m: Array, radius_m: float, points: int = 48) -> float:
    """Area of a ball's image with nothing in front of it, unclipped: its outline projected through the lens.

    The rays that graze a sphere touch it on a circle centred at ``c - (r^2 / d) u``
    with radius ``r sqrt(1 - r^2 / d^2)``, in the plane perpendicular to the
    viewing direction ``u`` (``d`` the distance to the centre); projecting that
    circle gives the outline, whose polygon area is the image's area.
    """
    offset = np.asarray(centre_m, dtype=np.float64) - camera.centre_m
    distance = float(np.linalg.norm(offset))
    if distance <= radius_m or camera.to_camera_frame(np.asarray(centre_m, dtype=np.float64)[None])[0, 2] <= radius_m:
        return 0.0
    u = offset / distance
    helper = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(u, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    ring_radius = radius_m * math.sqrt(1.0 - (radius_m / distance) ** 2)
    ring_centre = np.asarray(centre_m, dtype=np.float64) - (radius_m**2 / distance) * u
    angles = np.linspace(0.0, 2.0 * math.pi, points, endpoint=False)
    ring = ring_centre + ring_radius * (np.cos(angles)[:, None] * e1 + np.sin(angles)[:, None] * e2)
    px = camera.project(ring)
    if not np.all(np.isfinite(px)):
        return 0.0
    x, y = px[:, 0], px[:, 1]
    return float(0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
