"""Randomized rigs and scenes, drawn from wide distributions, seeded and reproducible.

The simulator's own rig (config/simulated.toml) always has two cameras at the
sides of the wall, one lighting, one pair of paints and a muted slide on the
display: a detector tuned there can be brittle anywhere else. This module draws
everything that differs between real installations instead:

* **placement** of 2 to 4 cameras: side-on, behind the presenter (high and low),
  on the ceiling, a mix of those (asymmetric), close and far;
* **lenses**: 720p to 4K sensors, wide to narrow fields of view, strong barrel
  distortion, any Bayer layout or RGB;
* **lighting**: dim to bright, warm to cold white balance, a spotlight, uneven
  shading and vignetting, glossy balls with specular highlights, sensor noise
  that grows with gain;
* **paint** and **pointer**: darker, brighter, orange-red, crimson, navy and
  cyan-blue paints; balls of 20-50 mm, rods of 6-16 mm, pointers of 0.3-0.6 m;
* per frame: what the **display shows** (a photo, saturated blocks near the
  paints' colours, a slide with red text, a dark slide, nothing), **motion
  blur** (speed times exposure) and **occlusion** (a hand over part of a ball,
  the presenter's body between one camera and an end; the rod over a ball comes
  with the placement).

The cameras are placed, aimed and given lenses by :mod:`trackerd.sim.random_cameras`.
Every rig and shot carries the factor levels it was drawn with, so a benchmark
can report per factor (:mod:`trackerd.bench.robustness`). A rig is a plain
:class:`~trackerd.config.models.RigConfig` with the detector's and locator's
defaults: what an operator would start from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.config.models import RigConfig
from trackerd.config.rig_geometry import wall_frame
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.wall import WallFrame
from trackerd.sim.appearance import CONTENT_KINDS, Look, Occluder
from trackerd.sim.random_cameras import RESOLUTIONS, aimed_camera, build_rig, camera_positions, draw_aimed_camera
from trackerd.sim.scene import PointerPose, pose_aimed_at, scene_pointer, scene_wall, true_wall_hit

Array = NDArray[np.float64]

__all__ = [
    "LIGHTINGS",
    "OCCLUSIONS",
    "OCCLUSION_ODDS",
    "PAINTS",
    "PLACEMENTS",
    "RESOLUTIONS",
    "RandomRig",
    "RandomShot",
    "aimed_camera",
    "build_rig",
    "random_rig",
    "random_shot",
]
"""The drawing of installations and shots, and the camera helpers (:mod:`trackerd.sim.random_cameras`)
the tests' rooms build rigs with, imported from here."""

PLACEMENTS = ("side-on", "behind high", "behind low", "ceiling", "asymmetric", "close", "far")
LIGHTINGS = ("standard", "dim", "bright", "warm", "cold", "spotlight", "uneven", "glossy")
PAINTS = ("standard", "dark", "orange-red", "crimson and navy", "bright and cyan")
OCCLUSIONS = ("none", "hand", "body")
OCCLUSION_ODDS = (0.55, 0.25, 0.2)
"""How often a shot (or a followed sequence) has each of OCCLUSIONS."""

_PAINT_RGB: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "standard": ((0.86, 0.10, 0.08), (0.10, 0.20, 0.86)),
    "dark": ((0.52, 0.07, 0.05), (0.06, 0.10, 0.48)),
    "orange-red": ((0.95, 0.32, 0.08), (0.16, 0.36, 0.92)),
    "crimson and navy": ((0.72, 0.05, 0.20), (0.08, 0.08, 0.42)),
    "bright and cyan": ((1.00, 0.20, 0.26), (0.05, 0.48, 0.95)),
}

CLOTHES_RGB = ((0.12, 0.12, 0.14), (0.10, 0.12, 0.30), (0.35, 0.08, 0.10), (0.55, 0.55, 0.52), (0.20, 0.30, 0.20))

MIN_BALL_DIAMETER_PX = 10.0
"""A drawn rig is kept only if the balls image at least this wide (at the presenter area's
far side) in every camera: a smaller ball is below what the detector's full search is set
to find, which an installer would fix by choosing the lens."""


@dataclass(frozen=True)
class RandomRig:
    """A drawn installation: its rig file, the cameras' true models, the scene's look, and the
    factor levels it was drawn with."""

    rig: RigConfig
    cameras: tuple[CameraModel, ...]
    look: Look
    factors: dict[str, str]
    presenter_box_m: tuple[tuple[float, float, float], tuple[float, float, float]]
    """Where the pointer's tip may be: (x, y, z) lower and upper corners, world metres."""


@dataclass(frozen=True)
class RandomShot:
    """One frame's pointer and what else differs per frame."""

    pose: PointerPose
    motion_to: PointerPose | None
    """Where the pointer is at the end of the exposure (None: held still)."""
    occluders: tuple[Occluder, ...]
    content_kind: str
    factors: dict[str, str]
    motion_steps: int = 2
    """Instants the exposure is sampled at: enough that the pointer moves at most about 2 px between
    them, and no more than four (a rendering cost; the blur's extent, not its smoothness, is what
    tests the detector)."""


# ----------------------------------------------------------------------------- rigs


def random_rig(rng: np.random.Generator, name: str = "random", placement: str | None = None) -> RandomRig:
    """Draw an installation (camera placement, lenses, wall, pointer, light and paint)."""
    for _ in range(200):
        drawn = _try_rig(rng, name, placement)
        if drawn is not None:
            return drawn
    raise RuntimeError("could not draw a rig whose cameras see the presenter's area")  # pragma: no cover


def _try_rig(rng: np.random.Generator, name: str, placement: str | None) -> RandomRig | None:
    placement = placement or str(rng.choice(PLACEMENTS))
    width = float(rng.uniform(2.4, 4.8))
    height = float(rng.uniform(0.9, 1.8))
    above_floor = float(rng.uniform(0.7, 1.1))
    floor = -above_floor
    lower = (0.12 * width, floor + 1.0, 1.0)
    upper = (0.88 * width, floor + 1.8, 2.8)
    centre = np.array([(lower[i] + upper[i]) / 2.0 for i in range(3)])
    count = int(rng.choice([2, 2, 2, 3, 3, 4]))
    positions = camera_positions(rng, placement, count, width, floor, centre)
    ball_d = float(rng.uniform(0.02, 0.05))
    rod_d = float(min(rng.uniform(0.006, 0.016), 0.6 * ball_d))
    length = float(rng.uniform(0.3, 0.6))
    cameras = []
    formats = []
    # Each camera's lens takes in the middle of the presenter's area (as an installer aims it); a pose
    # nearer an edge counts when two cameras see it (random_shot).
    core_x = (0.3 * width, 0.7 * width)
    core_z = (1.3, 2.4)
    box = np.array([[x, y, z] for x in core_x for y in (lower[1], upper[1]) for z in core_z])
    for index, position in enumerate(positions):
        camera = draw_aimed_camera(rng, f"cam{index}", position, centre, box)
        if camera is None:
            return None
        model, fmt = camera
        # Ball image size at the far corner of the presenter's area, by the focal length.
        far = float(np.max(np.linalg.norm(box - model.centre_m, axis=1)))
        if model.focal_px * ball_d / far < MIN_BALL_DIAMETER_PX:
            return None
        cameras.append(model)
        formats.append(fmt)
    lighting = str(rng.choice(LIGHTINGS))
    paint = str(rng.choice(PAINTS))
    look, noise_sigma, shot_noise = _look(rng, lighting, paint)
    rig = build_rig(
        name,
        list(zip(cameras, formats, strict=True)),
        width,
        height,
        above_floor,
        {
            "length_m": length,
            "end_diameter_m": ball_d,
            "rod_diameter_m": rod_d,
            "front_colour": str(rng.choice(["red", "red", "blue"])),
        },
        {
            "seed": int(rng.integers(0, 2**31)),
            "clutter": int(rng.integers(4, 16)),
            "noise_sigma": noise_sigma,
            "shot_noise": shot_noise,
            "presenter_distance_m": (lower[2], upper[2]),
        },
    )
    widest = max(c.width_px for c in cameras)
    factors = {
        "placement": placement,
        "lighting": lighting,
        "paint": paint,
        "cameras": str(count),
        "resolution": "4K-class" if widest > 2000 else ("1080p-class" if widest > 1300 else "720p"),
    }
    return RandomRig(rig, tuple(cameras), look, factors, (lower, upper))


def _look(rng: np.random.Generator, lighting: str, paint: str) -> tuple[Look, float, float]:
    """The scene's look, read noise and shot noise for a lighting and a paint."""
    red, blue = (tuple(float(np.clip(c * rng.uniform(0.9, 1.1), 0.0, 1.0)) for c in rgb) for rgb in _PAINT_RGB[paint])
    values: dict = {"red_rgb": red, "blue_rgb": blue}
    noise, shot = float(rng.uniform(0.6, 1.5)), float(rng.uniform(0.15, 0.3))
    if lighting == "dim":
        gain = float(rng.uniform(0.35, 0.6))
        values["gain"] = gain
        # The camera's gain that makes up for the light amplifies the read noise with the signal.
        noise, shot = noise / gain * 0.6, shot / math.sqrt(gain)
    elif lighting == "bright":
        values["gain"] = float(rng.uniform(1.2, 1.55))
    elif lighting == "warm":
        values["white_balance"] = (float(rng.uniform(1.1, 1.25)), 1.0, float(rng.uniform(0.65, 0.85)))
    elif lighting == "cold":
        values["white_balance"] = (float(rng.uniform(0.75, 0.9)), 1.0, float(rng.uniform(1.1, 1.25)))
    elif lighting == "spotlight":
        values["gain"] = float(rng.uniform(0.6, 0.8))
        values["spot"] = (
            float(rng.uniform(0.2, 0.8)),
            float(rng.uniform(0.2, 0.8)),
            float(rng.uniform(0.1, 0.3)),
            float(rng.uniform(0.5, 1.2)),
        )
    elif lighting == "uneven":
        values["gradient"] = (float(rng.uniform(-0.5, 0.5)), float(rng.uniform(-0.5, 0.5)))
        values["vignetting"] = float(rng.uniform(0.2, 0.5))
    elif lighting == "glossy":
        values["specular"] = float(rng.uniform(0.3, 0.8))
        values["shininess"] = float(rng.uniform(15.0, 80.0))
    return Look(**values), noise, shot


# ----------------------------------------------------------------------------- shots


def random_shot(drawn: RandomRig, rng: np.random.Generator, wall: WallFrame | None = None) -> RandomShot:
    """A pointer pose aimed at the wall from the presenter's area, seen by at least two cameras, with
    its motion during the exposure, occluders and what the display shows."""
    wall = wall or wall_frame(scene_wall(drawn.rig))
    pointer = scene_pointer(drawn.rig)
    lower, upper = (np.asarray(v) for v in drawn.presenter_box_m)
    for _ in range(2000):
        tip = rng.uniform(lower, upper)
        target_xy = rng.uniform([0.0, 0.0], [wall.width_m, wall.height_m])
        if rng.uniform() < 0.1:
            target_xy = rng.uniform([-0.4, -0.3], [wall.width_m + 0.4, wall.height_m + 0.3])
        pose = pose_aimed_at(tip, wall.from_wall_m(target_xy), pointer.length_m)
        if true_wall_hit(pose, wall).wall_xy_m is None or _seen_by(pose, drawn.cameras) < 2:
            continue
        motion_to, blur_px = _motion(rng, pose, drawn.cameras)
        occlusion = str(rng.choice(OCCLUSIONS, p=list(OCCLUSION_ODDS)))
        occluders = _occluders(rng, occlusion, pose, drawn)
        if occluders is None:
            continue
        content = str(rng.choice(CONTENT_KINDS))
        blur = "none" if blur_px < 1.0 else ("some" if blur_px < 4.0 else "strong")
        steps = int(min(4, max(2, math.ceil(blur_px / 2.0) + 1)))
        return RandomShot(
            pose, motion_to, occluders, content, {"content": content, "occlusion": occlusion, "blur": blur}, steps
        )
    raise RuntimeError("could not draw a pointer pose two cameras see")  # pragma: no cover


def _seen_by(pose: PointerPose, cameras: tuple[CameraModel, ...], margin_px: float = 30.0) -> int:
    """How many cameras have both ball centres inside their image, ``margin_px`` from its edge."""
    points = np.stack([pose.front_m, pose.back_m])
    seen = 0
    for cam in cameras:
        if np.any(cam.to_camera_frame(points)[:, 2] <= 0.2):
            continue
        px = cam.project(points)
        if np.all(np.isfinite(px)) and np.all(cam.contains(px, margin_px)):
            seen += 1
    return seen


def _motion(
    rng: np.random.Generator, pose: PointerPose, cameras: tuple[CameraModel, ...]
) -> tuple[PointerPose | None, float]:
    """The pose at the end of the exposure (a sweep about the hand), and the tip's largest image motion."""
    if rng.uniform() < 0.4:
        return None, 0.0
    speed = float(rng.uniform(0.2, 2.0))  # tip speed, m/s
    exposure = float(rng.uniform(0.002, 0.010))
    sideways = np.cross(pose.direction, rng.normal(size=3))
    sideways /= np.linalg.norm(sideways)
    step = speed * exposure * sideways
    # The hand holds the back end: the tip moves most, the back end a third as far.
    moved = PointerPose(pose.front_m + step, pose.back_m + step / 3.0)
    points = np.stack([pose.front_m, moved.front_m])
    blur = 0.0
    for cam in cameras:
        px = cam.project(points)
        if np.all(np.isfinite(px)):
            blur = max(blur, float(np.linalg.norm(px[1] - px[0])))
    return moved, blur


def _occluders(
    rng: np.random.Generator, occlusion: str, pose: PointerPose, drawn: RandomRig
) -> tuple[Occluder, ...] | None:
    """What stands in front of the pointer for an occlusion level; None when it cannot be placed."""
    if occlusion == "none":
        return ()
    ball_r = scene_pointer(drawn.rig).end_diameter_m / 2.0
    if occlusion == "hand":
        # A finger or thumb against one ball, from the side.
        ball = pose.front_m if rng.uniform() < 0.5 else pose.back_m
        side = np.cross(pose.direction, rng.normal(size=3))
        side /= np.linalg.norm(side)
        radius = ball_r * float(rng.uniform(0.45, 0.8))
        place = ball + side * (ball_r + radius * float(rng.uniform(0.2, 0.7)))
        red, green, blue = (float(c) for c in np.clip(np.array([0.80, 0.58, 0.47]) * rng.uniform(0.7, 1.1), 0, 1))
        x, y, z = (float(v) for v in place)
        return (Occluder("sphere", (x, y, z), radius, (red, green, blue), label="hand"),)
    # The presenter's body between one camera and one end, partly or wholly hiding it there.
    camera = drawn.cameras[int(rng.integers(0, len(drawn.cameras)))]
    end = pose.front_m if rng.uniform() < 0.5 else pose.back_m
    radius = float(rng.uniform(0.1, 0.18))
    for _ in range(20):
        along = float(rng.uniform(0.25, 0.6))
        point = end + along * (camera.centre_m - end)
        to_camera = camera.centre_m - end
        across = np.cross(to_camera, [0.0, 1.0, 0.0])
        if np.linalg.norm(across) < 1e-6:
            return None
        across /= np.linalg.norm(across)
        point = point + across * radius * float(rng.uniform(-1.3, 1.3))
        centre = (float(point[0]), float(point[1] - 0.1), float(point[2]))
        if clear_of_pointer(np.asarray(centre), radius, 0.4, pose, ball_r):
            clothes = CLOTHES_RGB[int(rng.integers(0, len(CLOTHES_RGB)))]
            return (Occluder("cylinder", centre, radius, clothes, height_m=0.4, label="body"),)
    return None


def clear_of_pointer(centre: Array, radius: float, height: float, pose: PointerPose, ball_r: float) -> bool:
    """Whether an upright cylinder stays clear of the pointer (both balls and the rod between)."""
    for f in np.linspace(0.0, 1.0, 12):
        p = pose.back_m + f * (pose.front_m - pose.back_m)
        horizontal = math.hypot(p[0] - centre[0], p[2] - centre[2])
        within_height = abs(p[1] - centre[1]) <= height / 2.0 + ball_r
        if within_height and horizontal < radius + ball_r + 0.02:
            return False
    return True
