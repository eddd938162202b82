"""Rendered hands showing 0 to 5 extended fingers, for the hand-pose detector (trackerd/interaction/hand.py).

A hand is a few solids in its own frame (centimetres below; x across the palm
towards the little finger, y along the fingers, z out of the palm):

* the palm: an ellipsoid 8.5 x 10 x 3 cm;
* four fingers on the palm's top edge, fanned out, and a thumb on its side:
  capsules 1.7-2.0 cm thick. An extended finger is a capsule 6-8 cm long along
  its direction; a folded one lies curled over the front of the palm, leaving a
  knuckle's bump on the outline;
* a wrist (a capsule 5.6 cm thick) and a dark sleeve.

The hand faces the camera (palm normal towards the camera's centre, tilted by
up to ``tilt_deg``), is turned about that normal by ``roll_deg`` and scaled by
``scale``, and stands ``distance_m`` from the camera along the ray through a
chosen image point. It is ray-cast through the camera's real lens model
(:meth:`SceneRenderer.rays`), anti-aliased with ``SUPERSAMPLING``^2 rays per
pixel, shaded by the room's light, composited over the empty room, mosaiced
into the camera's pixel format and given the same sensor noise as the
pointer's renders.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.sim.render import SceneRenderer
from trackerd.sim.room_shading import AMBIENT, DIFFUSE
from trackerd.sim.scene import SKIN_RGB
from trackerd.sim.sensor import raw_values, sensor_output

Array = NDArray[np.float64]

SUPERSAMPLING = 2
SLEEVE_RGB = (0.16, 0.16, 0.18)
CM = 0.01

# (name, base on the palm (x, y) cm, direction in the palm plane (deg from +y, towards +x), length cm, radius cm)
DIGITS = (
    ("thumb", (-3.6, -0.5), -58.0, 6.0, 1.0),
    ("index", (-2.9, 4.4), -12.0, 7.2, 0.9),
    ("middle", (-0.95, 4.8), -3.0, 8.0, 0.9),
    ("ring", (0.95, 4.6), 6.0, 7.5, 0.85),
    ("little", (2.8, 4.0), 16.0, 6.0, 0.8),
)
EXTENDED = {
    0: ((),),
    1: (("index",), ("middle",)),
    2: (("index", "middle"), ("thumb", "index")),
    3: (("index", "middle", "ring"), ("thumb", "index", "middle")),
    4: (("index", "middle", "ring", "little"),),
    5: (("thumb", "index", "middle", "ring", "little"),),
}
"""Which digits are out for each count (one of the variants is picked at random)."""


@dataclass(frozen=True)
class HandPose:
    """Where the hand is and what it shows."""

    fingers: int
    extended: tuple[str, ...]
    centre_px: tuple[float, float]
    """Image point (in the rendering camera) the palm's centre projects to."""
    distance_m: float
    roll_deg: float
    """Turn about the palm's normal: 0 has the fingers up in the image."""
    tilt_deg: tuple[float, float]
    """Turn of the palm away from facing the camera, about the image's x and y axes."""
    scale: float
    skin_rgb: tuple[float, float, float]


@dataclass(frozen=True)
class RenderedHand:
    image: NDArray[np.uint8]
    pixel_format: str
    pose: HandPose
    palm_px: tuple[float, float]
    """Projection of the palm's centre."""
    box_px: tuple[int, int, int, int]
    """x0, y0, x1, y1 of the region the hand covers."""
    area_px: float
    """Pixels covered by the hand (skin only, not the sleeve)."""


def random_hand_pose(
    fingers: int, rng: np.random.Generator, width_px: int, height_px: int, distance_m: tuple[float, float] = (1.5, 3.0)
) -> HandPose:
    """A hand showing ``fingers`` fingers somewhere in the middle of the image, turned and scaled at random."""
    variants = EXTENDED[fingers]
    extended = variants[int(rng.integers(len(variants)))]
    tone = rng.uniform(0.85, 1.1)
    skin = tuple(float(np.clip(c * tone + rng.normal(0, 0.02), 0, 1)) for c in SKIN_RGB)
    return HandPose(
        fingers=fingers,
        extended=extended,
        centre_px=(float(rng.uniform(0.25, 0.75) * width_px), float(rng.uniform(0.3, 0.7) * height_px)),
        distance_m=float(rng.uniform(*distance_m)),
        roll_deg=float(rng.uniform(-70.0, 70.0)),
        tilt_deg=(float(rng.uniform(-20.0, 20.0)), float(rng.uniform(-20.0, 20.0))),
        scale=float(rng.uniform(0.85, 1.15)),
        skin_rgb=skin,  # type: ignore[arg-type]
    )


def _rotation(axis: int, angle_rad: float) -> Array:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m = np.eye(3)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


@dataclass(frozen=True)
class _Capsule:
    a: Array
    b: Array
    radius: float
    skin: bool


def hand_solids(pose: HandPose) -> tuple[Array, list[_Capsule]]:
    """Palm semi-axes (3,) and the capsules of the hand in its own frame, metres."""
    k = pose.scale * CM
    palm = np.array([4.25, 5.0, 1.5]) * k
    capsules = []
    for name, (bx, by), angle_deg, length, radius in DIGITS:
        base = np.array([bx, by, 0.0]) * k
        if name in pose.extended:
            direction = np.array([math.sin(math.radians(angle_deg)), math.cos(math.radians(angle_deg)), 0.0])
            tip = base + direction * length * k
        elif name == "thumb":
            tip = np.array([-1.2, 1.2, 1.8]) * k  # across the front of the palm
        else:
            tip = base + np.array([0.0, -2.0, 1.9]) * k  # curled over the front of the palm
            base = base + np.array([0.0, 0.4, 0.3]) * k
        capsules.append(_Capsule(base, tip, radius * k, True))
    capsules.append(_Capsule(np.array([0.0, -4.0, 0.0]) * k, np.array([0.0, -10.0, 0.0]) * k, 2.8 * k, True))
    capsules.append(_Capsule(np.array([0.0, -10.0, 0.0]) * k, np.array([0.0, -16.0, 0.0]) * k, 4.0 * k, False))
    return palm, capsules


def _ray_ellipsoid(origin: Array, dirs: Array, semi_axes: Array) -> tuple[Array, Array]:
    """Distances and normals of unit rays (N, 3) from ``origin`` hitting an origin-centred ellipsoid."""
    o, d = origin / semi_axes, dirs / semi_axes
    a = np.sum(d * d, axis=1)
    b = 2.0 * (d @ o)
    c = float(o @ o) - 1.0
    disc = b * b - 4 * a * c
    t = np.full(len(dirs), np.inf)
    ok = disc >= 0
    near = (-b - np.sqrt(np.where(ok, disc, 0.0))) / (2 * a)
    t[ok & (near > 0)] = near[ok & (near > 0)]
    points = origin + np.where(np.isfinite(t), t, 0.0)[:, None] * dirs
    normals = points / (semi_axes**2)
    return t, normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)


def _ray_capsule(origin: Array, dirs: Array, capsule: _Capsule) -> Array:
    """Distances along unit rays (N, 3) from ``origin`` to a capsule (segment a-b, radius r); inf: missed."""
    axis = capsule.b - capsule.a
    length = float(np.linalg.norm(axis))
    axis = axis / length
    r = capsule.radius
    t = np.full(len(dirs), np.inf)
    # Side: the infinite cylinder, kept where the hit lies between the ends.
    w = origin - capsule.a
    d_par = dirs @ axis
    d_perp = dirs - d_par[:, None] * axis
    w_perp = w - float(w @ axis) * axis
    a = np.sum(d_perp * d_perp, axis=1)
    b = 2.0 * (d_perp @ w_perp)
    c = float(w_perp @ w_perp) - r * r
    disc = b * b - 4 * a * c
    ok = (disc >= 0) & (a > 1e-15)
    near = (-b - np.sqrt(np.where(ok, disc, 0.0))) / np.where(ok, 2 * a, 1.0)
    along = float(w @ axis) + near * d_par
    side = ok & (near > 0) & (along >= 0) & (along <= length)
    t[side] = near[side]
    # Ends: spheres.
    for centre in (capsule.a, capsule.b):
        oc = origin - centre
        bb = dirs @ oc
        cc = float(oc @ oc) - r * r
        dd = bb * bb - cc
        hit = dd >= 0
        tt = -bb - np.sqrt(np.where(hit, dd, 0.0))
        closer = hit & (tt > 0) & (tt < t)
        t[closer] = tt[closer]
    return t


def _capsule_normals(points: Array, capsule: _Capsule) -> Array:
    """Outward unit normals (N, 3) of a capsule at surface points (N, 3)."""
    axis = capsule.b - capsule.a
    length = float(np.linalg.norm(axis))
    s = np.clip((points - capsule.a) @ (axis / length), 0.0, length)
    normals = points - (capsule.a + s[:, None] * (axis / length))
    unit: Array = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    return unit


class HandRenderer:
    """Renders hands into one camera's view of a rig's room (the pointer is not in these frames)."""

    def __init__(self, renderer: SceneRenderer, camera_index: int = 0) -> None:
        self.renderer = renderer
        self.index = camera_index
        self.camera = renderer.cameras[camera_index]
        self.pixel_format = renderer.pixel_formats[camera_index]
        self._background = renderer.background_rgb(camera_index)
        self._formatted: NDArray[np.float32] | None = None

    def _frame_values(self) -> NDArray[np.float32]:
        if self._formatted is None:
            self._formatted = raw_values(self._background, self.pixel_format, 0, 0)
        return self._formatted

    def empty(self, rng: np.random.Generator) -> NDArray[np.uint8]:
        """The room without a hand, with sensor noise."""
        sim = self.renderer.rig.simulation
        return sensor_output(self._frame_values().copy(), rng, sim.noise_sigma, sim.shot_noise, True)

    def placement(self, pose: HandPose) -> tuple[Array, Array]:
        """The hand's frame in the world: (rotation (3, 3) whose columns are its axes, centre (3,))."""
        cam = self.camera
        ray = self.renderer.rays(self.index, np.array([pose.centre_px[0]]), np.array([pose.centre_px[1]]))[0]
        centre = cam.centre_m + pose.distance_m * ray
        # Camera axes in the world: rows of the world-to-camera rotation.
        right, down = cam.rotation[0], cam.rotation[1]
        towards_camera = -ray
        up = -(down - (down @ towards_camera) * towards_camera)
        up /= np.linalg.norm(up)
        across = np.cross(up, towards_camera)
        base = np.column_stack([across, up, towards_camera])  # hand x, y, z in world, upright and facing
        if right @ across < 0:
            base[:, 0] = -base[:, 0]
        local = (
            _rotation(2, math.radians(pose.roll_deg))
            @ _rotation(0, math.radians(pose.tilt_deg[0]))
            @ _rotation(1, math.radians(pose.tilt_deg[1]))
        )
        return base @ local, centre

    def render(self, pose: HandPose, rng: np.random.Generator, *, noise: bool = True) -> RenderedHand:
        cam = self.camera
        rotation, centre = self.placement(pose)
        palm, capsules = hand_solids(pose)
        # The region: every solid's points projected, with a margin.
        points = [centre + rotation @ p for c in capsules for p in (c.a, c.b)]
        reach = max(c.radius for c in capsules) + 0.02
        projected = cam.project(np.array(points))
        scale_px = cam.focal_px * reach / pose.distance_m
        x0 = int(max(0, math.floor(np.nanmin(projected[:, 0]) - scale_px)))
        y0 = int(max(0, math.floor(np.nanmin(projected[:, 1]) - scale_px)))
        x1 = int(min(cam.width_px, math.ceil(np.nanmax(projected[:, 0]) + scale_px)))
        y1 = int(min(cam.height_px, math.ceil(np.nanmax(projected[:, 1]) + scale_px)))
        ys, xs = np.mgrid[y0:y1, x0:x1]
        offsets = (np.arange(SUPERSAMPLING) + 0.5) / SUPERSAMPLING - 0.5
        ox, oy = np.meshgrid(offsets, offsets)
        sample_x = (xs.reshape(-1, 1) + ox.reshape(1, -1)).ravel()
        sample_y = (ys.reshape(-1, 1) + oy.reshape(1, -1)).ravel()
        dirs_world = self.renderer.rays(self.index, sample_x, sample_y)
        origin = rotation.T @ (cam.centre_m - centre)
        dirs = dirs_world @ rotation  # into the hand's frame
        best, normal = _ray_ellipsoid(origin, dirs, palm)
        which = np.where(np.isfinite(best), -1, -2)
        for index, capsule in enumerate(capsules):
            t = _ray_capsule(origin, dirs, capsule)
            closer = t < best
            best[closer], which[closer] = t[closer], index
        hit = np.isfinite(best)
        points_local = origin + np.where(hit, best, 0.0)[:, None] * dirs
        skin = which == -1
        for index, capsule in enumerate(capsules):
            on = which == index
            normal[on] = _capsule_normals(points_local[on], capsule)
            skin[on] = capsule.skin
        light = rotation.T @ (np.asarray(self.renderer.room.light_m) - centre)
        to_light = light - points_local
        to_light /= np.linalg.norm(to_light, axis=1, keepdims=True)
        lambert = np.clip(np.sum(normal * to_light, axis=1), 0.0, 1.0)
        base = np.where(skin[:, None], np.asarray(pose.skin_rgb), np.asarray(SLEEVE_RGB))
        colour = np.where(hit[:, None], base * (AMBIENT + DIFFUSE * lambert)[:, None], 0.0)
        n = SUPERSAMPLING * SUPERSAMPLING
        h, w = y1 - y0, x1 - x0
        coverage = hit.reshape(h, w, n).mean(axis=2)
        premultiplied = colour.reshape(h, w, n, 3).mean(axis=2)
        blended = premultiplied + (1.0 - coverage[..., None]) * self._background[y0:y1, x0:x1]
        values = self._frame_values().copy()
        region = raw_values(blended.astype(np.float32), self.pixel_format, x0, y0)
        values[y0:y1, x0:x1] = region
        sim = self.renderer.rig.simulation
        image = sensor_output(values, rng, sim.noise_sigma, sim.shot_noise, noise)
        palm_px = cam.project(centre[None])[0]
        area = float((hit & skin).reshape(h, w, n).mean(axis=2).sum())
        return RenderedHand(
            image, self.pixel_format, pose, (float(palm_px[0]), float(palm_px[1])), (x0, y0, x1, y1), area
        )
