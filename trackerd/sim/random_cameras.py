"""Cameras for randomized installations: placed by family, aimed at the presenter's area, with a lens
drawn to take it in, and written as a rig file (:mod:`trackerd.sim.randomized` draws the rest).

World frame as in the example rigs: x along the wall, y up, z out of the wall (the wall is z = 0).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from trackerd.config.models import RigConfig
from trackerd.geometry.camera import CameraModel

Array = NDArray[np.float64]

RESOLUTIONS = ((1280, 720), (1920, 1080), (1920, 1200), (2448, 2048), (3840, 2160))

CORNER_MARGIN = 1.05
"""A drawn lens's radial map must keep growing to this factor beyond its farthest image corner."""


def build_rig(
    name: str,
    cameras: list[tuple[CameraModel, str]],
    wall_width_m: float,
    wall_height_m: float,
    above_floor_m: float,
    pointer: dict[str, Any],
    simulation: dict[str, Any] | None = None,
) -> RigConfig:
    """A rig file for cameras (their true models and pixel formats) in front of a wall in the plane z = 0,
    from (0, 0) to (width, height), its display's bottom edge ``above_floor_m`` over the floor."""
    corners = [[0.0, 0.0, 0.0], [wall_width_m, 0.0, 0.0], [wall_width_m, wall_height_m, 0.0], [0.0, wall_height_m, 0.0]]
    return RigConfig.model_validate(
        {
            "name": name,
            "cameras": [camera_config(model, fmt) for model, fmt in cameras],
            "wall": {
                "corners_m": corners,
                "display_width_px": 3840,
                "display_height_px": int(3840 * wall_height_m / wall_width_m),
            },
            "pointer": pointer,
            "simulation": {
                "supersampling": 2,
                "background_supersampling": 1,
                "display_height_above_floor_m": above_floor_m,
                "room_depth_m": 7.0,
                "hand_height_m": (1.0, 1.8),
                **(simulation or {}),
            },
        }
    )


def aimed_camera(
    camera_id: str,
    position: Array,
    target: Array,
    width_px: int,
    height_px: int,
    hfov_deg: float,
    distortion: Array | None = None,
    roll_deg: float = 0.0,
) -> CameraModel:
    """A camera at ``position`` looking at ``target`` (image y down, world y up), with a horizontal field
    of view and the principal point at the image's centre."""
    forward = np.asarray(target, dtype=np.float64) - np.asarray(position, dtype=np.float64)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    roll = math.radians(roll_deg)
    right, down = (math.cos(roll) * right + math.sin(roll) * down, -math.sin(roll) * right + math.cos(roll) * down)
    focal = (width_px / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
    matrix = np.array([[focal, 0.0, (width_px - 1) / 2.0], [0.0, focal, (height_px - 1) / 2.0], [0.0, 0.0, 1.0]])
    return CameraModel.from_pose(
        camera_id,
        width_px,
        height_px,
        matrix,
        np.zeros(5) if distortion is None else np.asarray(distortion, dtype=np.float64),
        np.asarray(position, dtype=np.float64),
        np.column_stack([right, down, forward]),
    )


def camera_positions(
    rng: np.random.Generator, placement: str, count: int, width: float, floor: float, centre: Array
) -> list[Array]:
    """Positions of ``count`` cameras for a placement family (world: x along the wall, y up, z out of it)."""

    def side(k: int) -> Array:
        x = -rng.uniform(0.2, 1.2) if k % 2 == 0 else width + rng.uniform(0.2, 1.2)
        return np.array([x, floor + rng.uniform(1.8, 2.6), rng.uniform(2.3, 3.6)])

    def behind(k: int, high: bool) -> Array:
        spread = rng.uniform(0.6, 2.2) * (1 if k % 2 == 0 else -1) + rng.uniform(-0.3, 0.3)
        y = floor + (rng.uniform(2.2, 2.9) if high else rng.uniform(0.7, 1.3))
        return np.array([width / 2.0 + spread, y, rng.uniform(4.5, 6.5)])

    def ceiling(k: int) -> Array:
        # Under the ceiling over the back of the presenter's area, looking steeply down past them.
        spread = rng.uniform(0.4, 1.6) * (1 if k % 2 == 0 else -1)
        return np.array([width / 2.0 + spread, floor + rng.uniform(2.75, 2.95), rng.uniform(3.2, 4.4)])

    families = {
        "side-on": lambda k: side(k),
        "behind high": lambda k: behind(k, True),
        "behind low": lambda k: behind(k, False),
        "ceiling": ceiling,
    }
    if placement in families:
        return [families[placement](k) for k in range(count)]
    if placement == "asymmetric":
        kinds = list(rng.permutation(list(families)))
        return [families[kinds[k % len(kinds)]](k) for k in range(count)]
    # close / far: side-on or behind, moved towards or away from the presenter's area.
    base = side if rng.uniform() < 0.5 else (lambda k: behind(k, rng.uniform() < 0.5))
    scale = rng.uniform(0.55, 0.75) if placement == "close" else rng.uniform(1.3, 1.6)
    out = []
    for k in range(count):
        position = centre + scale * (base(k) - centre)
        position[1] = min(max(position[1], floor + 0.4), floor + 2.95)
        out.append(position)
    return out


def draw_aimed_camera(
    rng: np.random.Generator, camera_id: str, position: Array, target: Array, box: Array
) -> tuple[CameraModel, str] | None:
    """A camera at ``position`` looking at ``target``, with a lens that takes in the presenter's area."""
    width_px, height_px = RESOLUTIONS[int(rng.choice(len(RESOLUTIONS), p=[0.3, 0.4, 0.17, 0.08, 0.05]))]
    aim = target + rng.normal(0.0, 0.15, size=3)
    forward = aim - position
    forward /= np.linalg.norm(forward)
    up = np.array([0.0, 1.0, 0.0])
    right = np.cross(forward, up)
    if np.linalg.norm(right) < 1e-6:
        return None
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    roll = math.radians(float(rng.uniform(-8.0, 8.0)))
    right, down = (math.cos(roll) * right + math.sin(roll) * down, -math.sin(roll) * right + math.cos(roll) * down)
    world_from_cam = np.column_stack([right, down, forward])
    # The field of view the presenter's area needs from here, then a lens a little wider or narrower.
    in_cam = (box - position) @ world_from_cam
    if np.any(in_cam[:, 2] <= 0.3):
        return None
    need_x = float(np.max(np.abs(in_cam[:, 0] / in_cam[:, 2])))
    need_y = float(np.max(np.abs(in_cam[:, 1] / in_cam[:, 2])))
    tan_half = max(need_x, need_y * width_px / height_px) * float(rng.uniform(1.0, 1.35))
    hfov = 2.0 * math.degrees(math.atan(tan_half))
    if not 30.0 <= hfov <= 120.0:
        return None
    focal = (width_px / 2.0) / tan_half * float(rng.uniform(0.995, 1.005))
    cx = (width_px - 1) / 2.0 + float(rng.uniform(-0.02, 0.02)) * width_px
    cy = (height_px - 1) / 2.0 + float(rng.uniform(-0.02, 0.02)) * height_px
    matrix = np.array([[focal, 0.0, cx], [0.0, focal * float(rng.uniform(0.998, 1.002)), cy], [0.0, 0.0, 1.0]])
    # Wide lenses are distorted more; keep the radial map monotonic out to the corners.
    strength = min(1.0, hfov / 100.0)
    k1 = float(rng.uniform(-0.35, 0.05)) * strength
    k2 = float(rng.uniform(-0.02, 0.12)) * strength
    corner_r2 = ((width_px / 2.0) ** 2 + (height_px / 2.0) ** 2) / focal**2 * 1.1
    r2 = np.linspace(0.0, corner_r2, 200)
    if np.any(np.diff(np.sqrt(r2) * (1.0 + k1 * r2 + k2 * r2 * r2)) <= 0):
        k1, k2 = k1 / 3.0, 0.0
    # The test above looks at the *undistorted* radius out to the corner's distorted one, which a
    # barrel lens reaches well before its corner: it let lenses through that fold inside the image
    # (no ray at all for the corners' pixels; trackerd's loader refuses such a rig). Weaken until
    # the map reaches past the farthest corner (no random draw here: the rest of the scene stays).
    reach = _farthest_corner_radius(width_px, height_px, matrix) * CORNER_MARGIN
    while _folds_within(k1, k2, reach):
        k1, k2 = k1 / 2.0, k2 / 2.0
    distortion = np.array([k1, k2, float(rng.uniform(-5e-4, 5e-4)), float(rng.uniform(-5e-4, 5e-4)), 0.0])
    fmt = str(rng.choice(["BayerRG8", "BayerRG8", "BayerBG8", "BayerGR8", "BayerGB8", "RGB8"]))
    model = CameraModel.from_pose(camera_id, width_px, height_px, matrix, distortion, position, world_from_cam)
    return model, fmt


def _farthest_corner_radius(width_px: int, height_px: int, matrix: Array) -> float:
    """Distorted normalised radius of the image corner farthest from the principal point."""
    xs = (np.array([-0.5, width_px - 0.5]) - matrix[0, 2]) / matrix[0, 0]
    ys = (np.array([-0.5, height_px - 0.5]) - matrix[1, 2]) / matrix[1, 1]
    return float(math.hypot(np.abs(xs).max(), np.abs(ys).max()))


def _folds_within(k1: float, k2: float, reach: float) -> bool:
    """Whether the radial map r -> r (1 + k1 r^2 + k2 r^4) stops growing before it reaches ``reach``.

    Such a lens images nothing beyond the fold's radius, and pixels out there have no ray;
    inverting the map near the fold is also ill-conditioned (a ball there is squashed to a sliver).
    """
    r = np.linspace(0.0, 4.0 * reach, 4001)
    distorted = r * (1.0 + k1 * r * r + k2 * r**4)
    falls = np.nonzero(np.diff(distorted) <= 0.0)[0]
    grows_to = distorted[: falls[0] + 1] if len(falls) else distorted
    return bool(grows_to.max() < reach)


def camera_config(model: CameraModel, pixel_format: str) -> dict[str, Any]:
    """The rig file's [[cameras]] entry for a camera's true model."""
    k = model.matrix
    return {
        "id": model.camera_id,
        "serial": f"RND-{model.camera_id}",
        "width_px": model.width_px,
        "height_px": model.height_px,
        "pixel_format": pixel_format,
        "intrinsics": {
            "model": "opencv",
            "fx_px": float(k[0, 0]),
            "fy_px": float(k[1, 1]),
            "cx_px": float(k[0, 2]),
            "cy_px": float(k[1, 2]),
            "distortion": [float(v) for v in model.distortion],
        },
        "extrinsics": {
            "kind": "opencv",
            "rotation_matrix": model.rotation.tolist(),
            "tvec_m": model.translation_m.tolist(),
        },
    }
