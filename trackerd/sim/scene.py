"""What the simulator renders: the room, its clutter, and the pointer's pose (report section 4).

The report rendered its test scenes in 3ds Max; here the scene is described by
plain data built from the rig configuration, so every render is reproducible
from the rig file and a seed, and the ground truth is exact:

* the room is a box: the display wall in the plane z = 0 (the example rigs'
  world frame), a floor, a ceiling, two side walls and a back wall, each with a
  procedural texture;
* clutter: posters and stickers painted on the room's surfaces and balls
  standing in the room, some red or blue like the pointer's ends, seeded;
* the pointer: a dark rod with a ball at each end and a handle behind the back
  ball, held by a skin-coloured hand (skin is reddish, a realistic distractor).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from trackerd.config.models import PointerConfig, RigConfig, WallConfig
from trackerd.config.rig_geometry import camera_model, wall_frame
from trackerd.errors import ConfigError, GeometryError
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.wall import WallFrame, intersect_line_plane

Array = NDArray[np.float64]

# Linear-ish display values in [0, 1] (times 255 gives the 8-bit value before noise).
RED_BALL_RGB = (0.86, 0.10, 0.08)
BLUE_BALL_RGB = (0.10, 0.20, 0.86)
ROD_RGB = (0.10, 0.10, 0.11)
SKIN_RGB = (0.80, 0.58, 0.47)

HANDLE_LENGTH_FACTOR = 0.25
"""Handle behind the back ball, as a fraction of the pointer length."""
HAND_RADIUS_M = 0.045


def scene_pointer(rig: RigConfig) -> PointerConfig:
    """The rig's pointer, which every simulated scene shows (a rig file may leave it out)."""
    if rig.pointer is None:
        raise ConfigError(f"rig '{rig.name}': the simulator needs the [pointer] it is to render")
    return rig.pointer


def scene_wall(rig: RigConfig) -> WallConfig:
    """The rig's wall, which every simulated room is built around (a rig file may leave it out)."""
    if rig.wall is None:
        raise ConfigError(f"rig '{rig.name}': the simulator needs the [wall] its room is built around")
    return rig.wall


@dataclass(frozen=True)
class PointerPose:
    """Where the pointer is: the centres of its front (tip) ball and its back ball, world metres."""

    front_m: Array
    back_m: Array

    def __post_init__(self) -> None:
        object.__setattr__(self, "front_m", np.asarray(self.front_m, dtype=np.float64).reshape(3))
        object.__setattr__(self, "back_m", np.asarray(self.back_m, dtype=np.float64).reshape(3))

    @property
    def direction(self) -> Array:
        """Unit vector from the back ball to the front ball: where the pointer points."""
        axis = self.front_m - self.back_m
        return axis / np.linalg.norm(axis)

    @property
    def length_m(self) -> float:
        return float(np.linalg.norm(self.front_m - self.back_m))

    def interpolate(self, other: PointerPose, fraction: float) -> PointerPose:
        """Pose a fraction of the way to ``other`` (both ends moved linearly), for motion blur."""
        return PointerPose(
            self.front_m + fraction * (other.front_m - self.front_m),
            self.back_m + fraction * (other.back_m - self.back_m),
        )

    def centre_of(self, colour: str, front_colour: str) -> Array:
        """Centre of the ball of the given colour."""
        return self.front_m if colour == front_colour else self.back_m

    def to_json(self) -> dict[str, list[float]]:
        return {"front_m": self.front_m.tolist(), "back_m": self.back_m.tolist()}


def pose_aimed_at(tip_m: Array, target_m: Array, length_m: float) -> PointerPose:
    """A pointer whose front ball is at ``tip_m`` and whose line passes through ``target_m``."""
    tip = np.asarray(tip_m, dtype=np.float64)
    direction = np.asarray(target_m, dtype=np.float64) - tip
    direction /= np.linalg.norm(direction)
    return PointerPose(tip, tip - length_m * direction)


@dataclass(frozen=True)
class WallHitTruth:
    """Where the pointer's line truly meets the wall."""

    wall_xy_m: Array | None
    """Hit in the wall's 2D frame, or None if the pointer is parallel to or points away from the wall."""
    world_m: Array | None
    on_wall: bool


def true_wall_hit(pose: PointerPose, wall: WallFrame) -> WallHitTruth:
    """Exact hit of the pointer's line on the wall plane (eq. 26-28 on the true ends)."""
    try:
        hit = intersect_line_plane(pose.back_m, pose.front_m, wall.plane)
    except GeometryError:
        return WallHitTruth(None, None, False)
    if float(hit.u) <= 0.0:
        return WallHitTruth(None, None, False)
    xy = wall.to_wall_m(hit.point_m)
    return WallHitTruth(xy, hit.point_m, bool(wall.on_wall(xy)))


# ----------------------------------------------------------------------------- room


@dataclass(frozen=True)
class Patch:
    """A flat coloured shape painted on one face of the room: a poster (rectangle) or a sticker (disc)."""

    face: int
    """Index into Room.faces."""
    shape: str
    """'rect' or 'disc'."""
    centre_uv_m: tuple[float, float]
    size_uv_m: tuple[float, float]
    """Rectangle width/height, or disc diameter twice."""
    rgb: tuple[float, float, float]


@dataclass(frozen=True)
class Ball:
    """A sphere standing in the room (clutter)."""

    centre_m: tuple[float, float, float]
    radius_m: float
    rgb: tuple[float, float, float]


@dataclass(frozen=True)
class Face:
    """One face of the room box: the plane ``axis`` = ``value``, textured in (u, v) metres."""

    name: str
    axis: int
    value: float
    u_axis: int
    v_axis: int
    base_rgb: tuple[float, float, float]
    texture: str
    """'plain', 'tiles', 'display' or 'wood'."""


@dataclass(frozen=True)
class Room:
    """The room box around the wall and what is in it."""

    lower_m: tuple[float, float, float]
    upper_m: tuple[float, float, float]
    faces: tuple[Face, ...]
    patches: tuple[Patch, ...] = ()
    balls: tuple[Ball, ...] = ()
    display: tuple[float, float, float, float] = (0.0, 0.0, 1.0, 1.0)
    """x0, y0, x1, y1 of the display area on the wall face, for its texture."""
    light_m: tuple[float, float, float] = (0.0, 2.0, 3.0)
    """A point light near the ceiling, for the shading of balls and the pointer."""
    seed: int = 0
    fingerprint: str = field(default="")


def build_room(rig: RigConfig, wall: WallFrame) -> Room:
    """The room for a rig: the box around its wall, with seeded clutter (rig.simulation)."""
    sim = rig.simulation
    corners = wall.corners_m
    margin = sim.room_margin_m
    x0 = float(corners[:, 0].min()) - margin
    x1 = float(corners[:, 0].max()) + margin
    floor = float(corners[:, 1].min()) - sim.display_height_above_floor_m
    ceiling = floor + sim.room_height_m
    depth = sim.room_depth_m
    # Keep every camera inside the box.
    for cam in rig.cameras:
        pos = camera_model(cam).centre_m
        x0, x1 = min(x0, pos[0] - 0.3), max(x1, pos[0] + 0.3)
        floor, ceiling = min(floor, pos[1] - 0.3), max(ceiling, pos[1] + 0.3)
        depth = max(depth, pos[2] + 0.3)
    faces = (
        Face("wall", 2, 0.0, 0, 1, (0.72, 0.70, 0.66), "display"),
        Face("back", 2, depth, 0, 1, (0.62, 0.64, 0.66), "plain"),
        Face("left", 0, x0, 2, 1, (0.70, 0.68, 0.63), "plain"),
        Face("right", 0, x1, 2, 1, (0.66, 0.68, 0.70), "plain"),
        Face("floor", 1, floor, 0, 2, (0.36, 0.33, 0.30), "tiles"),
        Face("ceiling", 1, ceiling, 0, 2, (0.85, 0.85, 0.83), "tiles"),
    )
    rng = np.random.default_rng(sim.seed)
    patches: list[Patch] = []
    balls: list[Ball] = []
    lower = (x0, floor, 0.0)
    upper = (x1, ceiling, depth)
    ball_r = scene_pointer(rig).end_diameter_m / 2.0
    for index in range(sim.clutter):
        kind = index % 4
        colour = _clutter_colour(rng, index)
        face_index = int(rng.choice([1, 2, 3, 4]))
        face = faces[face_index]
        lo_u, hi_u = lower[face.u_axis], upper[face.u_axis]
        lo_v, hi_v = lower[face.v_axis], upper[face.v_axis]
        centre = (float(rng.uniform(lo_u + 0.3, hi_u - 0.3)), float(rng.uniform(lo_v + 0.3, hi_v - 0.3)))
        if kind == 0:  # poster
            size = (float(rng.uniform(0.3, 0.9)), float(rng.uniform(0.3, 0.9)))
            patches.append(Patch(face_index, "rect", centre, size, colour))
        elif kind == 1:  # sticker about the size of a pointer end: the hard case
            diameter = float(rng.uniform(0.5, 1.5)) * 2 * ball_r
            patches.append(Patch(face_index, "disc", centre, (diameter, diameter), colour))
        elif kind == 2:  # a strip (cable, tape) that is coloured but far from round
            length = float(rng.uniform(0.4, 1.2))
            patches.append(Patch(face_index, "rect", centre, (length, float(rng.uniform(0.02, 0.05))), colour))
        else:  # a ball on the floor near the walls
            radius = float(rng.uniform(0.6, 3.0)) * ball_r
            side = rng.choice([x0 + 0.4, x1 - 0.4])
            balls.append(Ball((float(side), floor + radius, float(rng.uniform(0.5, depth - 0.5))), radius, colour))
    display = (
        float(corners[:, 0].min()),
        float(corners[:, 1].min()),
        float(corners[:, 0].max()),
        float(corners[:, 1].max()),
    )
    light = ((x0 + x1) / 2.0, ceiling - 0.2, depth * 0.6)
    fingerprint = repr((lower, upper, patches, balls, display, light, faces))
    return Room(lower, upper, faces, tuple(patches), tuple(balls), display, light, sim.seed, fingerprint)


def _clutter_colour(rng: np.random.Generator, index: int) -> tuple[float, float, float]:
    """Every third object red-ish, every third blue-ish, the rest neutral or other hues."""
    choice = index % 3
    if choice == 0:
        return (float(rng.uniform(0.7, 0.95)), float(rng.uniform(0.05, 0.3)), float(rng.uniform(0.05, 0.3)))
    if choice == 1:
        return (float(rng.uniform(0.05, 0.3)), float(rng.uniform(0.1, 0.35)), float(rng.uniform(0.65, 0.95)))
    grey = float(rng.uniform(0.2, 0.9))
    tint = rng.uniform(-0.1, 0.1, size=3)
    return tuple(float(np.clip(grey + t, 0, 1)) for t in tint)  # type: ignore[return-value]


# ----------------------------------------------------------------------------- poses


def random_pose(
    rig: RigConfig,
    rng: np.random.Generator,
    cameras: list[CameraModel] | None = None,
    wall: WallFrame | None = None,
    on_wall_fraction: float = 0.9,
    margin_px: float = 40.0,
    max_tries: int = 1000,
) -> PointerPose:
    """A random pointer pose in the presenter's area, aimed at the wall, with both balls in every view.

    The front ball is placed between ``rig.simulation.presenter_distance_m`` from
    the wall, at a hand's height, and aimed at a random point of the display
    (or, with probability ``1 - on_wall_fraction``, at a point just beyond its edge).
    """
    wall = wall or wall_frame(scene_wall(rig))
    cameras = cameras or [camera_model(c) for c in rig.cameras]
    sim = rig.simulation
    near, far = sim.presenter_distance_m
    low, high = sim.hand_height_m
    length = scene_pointer(rig).length_m
    floor_y = float(wall.corners_m[:, 1].min()) - sim.display_height_above_floor_m
    for _ in range(max_tries):
        if rng.uniform() < on_wall_fraction:
            target_xy = rng.uniform([0.0, 0.0], [wall.width_m, wall.height_m])
        else:
            target_xy = rng.uniform([-0.4, -0.3], [wall.width_m + 0.4, wall.height_m + 0.3])
        target = wall.from_wall_m(target_xy)
        distance = rng.uniform(near, far)
        along = rng.uniform(0.15, 0.85) * wall.width_m
        height = rng.uniform(low, high)
        tip = wall.origin_m + along * wall.x_axis + distance * wall.normal
        tip = tip + (floor_y + height - tip[1]) * np.array([0.0, 1.0, 0.0])
        pose = pose_aimed_at(tip, target, length)
        if pose_visible(pose, cameras, margin_px):
            return pose
    raise RuntimeError("could not find a pointer pose visible to every camera; check the rig")


def pose_visible(pose: PointerPose, cameras: list[CameraModel], margin_px: float = 40.0) -> bool:
    """Both ball centres project inside every camera's image, at least margin_px from the edge."""
    pts = np.stack([pose.front_m, pose.back_m])
    for cam in cameras:
        px = cam.project(pts)
        if not np.all(np.isfinite(px)) or not np.all(cam.contains(px, margin_px)):
            return False
    return True
