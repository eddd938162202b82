"""Rendering calibration boards into the simulated room, through each camera's real lens model.

A board is a flat plate (a white margin around the printed squares) placed in
the room at any pose. Its image is ray-cast like the rest of the simulator: the
rays come from :meth:`SceneRenderer._rays`, so the camera's intrinsics and
distortion are those of the rig, and calibrating from these images is a true
test of calibration. The pattern is evaluated analytically (squares, and for
ChArUco the marker bits from OpenCV's dictionary), so an edge lies exactly where
the board's geometry puts it at any resolution. Pixels near an edge are
supersampled (``supersampling``^2 rays); the others take one ray.

The truth of a view is the projection of every inner corner through the same
camera model.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.acquisition.frame import Frame, FramePair
from trackerd.acquisition.source import PairSource
from trackerd.acquisition.status import SourceStatus
from trackerd.calibration.board import BoardSpec
from trackerd.geometry.rotation import rotation_about_x, rotation_about_y, rotation_about_z
from trackerd.sim.render import AMBIENT, DIFFUSE, SceneRenderer, raw_values, sensor_output

Array = NDArray[np.float64]

WHITE_ALBEDO = 0.82
BLACK_ALBEDO = 0.05
BACK_ALBEDO = 0.45
"""The plate's unprinted back, seen when a camera looks at the board from behind."""

# Sample labels: which part of the scene a ray sees.
_ROOM, _WHITE, _BLACK, _BACK = 0, 1, 2, 3


@dataclass(frozen=True)
class BoardPose:
    """Where the board is: its origin (top-left corner of the squares) and its axes, in world metres.

    ``rotation`` is world-from-board: its columns are the board's x (along the
    columns), y (down the rows) and z (into the board, away from its printed face).
    """

    origin_m: Array
    rotation: Array

    def __post_init__(self) -> None:
        object.__setattr__(self, "origin_m", np.asarray(self.origin_m, dtype=np.float64).reshape(3))
        object.__setattr__(self, "rotation", np.asarray(self.rotation, dtype=np.float64).reshape(3, 3))

    def to_world(self, points_board_m: Array) -> Array:
        """Board coordinates (N, 3) -> world (N, 3)."""
        return np.asarray(points_board_m, dtype=np.float64).reshape(-1, 3) @ self.rotation.T + self.origin_m

    @classmethod
    def centred(cls, spec: BoardSpec, centre_m: Array, rotation: Array) -> BoardPose:
        """The pose whose squared area is centred on ``centre_m``."""
        rotation = np.asarray(rotation, dtype=np.float64)
        width, height = spec.size_m
        origin = np.asarray(centre_m, dtype=np.float64) - rotation @ np.array([width / 2, height / 2, 0.0])
        return cls(origin, rotation)


@dataclass(frozen=True)
class RenderedBoard:
    image: NDArray[np.uint8]
    """The frame as the camera delivers it, in ``pixel_format``."""
    pixel_format: str
    corners_px: Array
    """(N, 2) true projection of every inner corner, by corner id (NaN when behind the camera)."""
    visible: NDArray[np.bool_]
    """(N,) corners inside the image and on the face the camera sees."""


class BoardRenderer:
    """Renders a board at any pose into the views of a :class:`SceneRenderer`'s cameras."""

    def __init__(
        self, scene: SceneRenderer, spec: BoardSpec, *, margin_squares: float = 0.75, supersampling: int = 4
    ) -> None:
        self.scene = scene
        self.spec = spec
        self.margin_m = margin_squares * spec.square_m
        self.supersampling = supersampling

    def render(
        self,
        camera_index: int,
        pose: BoardPose,
        rng: np.random.Generator,
        *,
        blur_px: float = 0.0,
        noise: bool = True,
        pixel_format: str | None = None,
    ) -> RenderedBoard:
        """One camera's view of the room with the board at ``pose``.

        ``blur_px`` smooths the board's image with a Gaussian of that standard
        deviation (a defocused or moving board) before noise is added.
        """
        camera = self.scene.cameras[camera_index]
        fmt = pixel_format or self.scene.pixel_formats[camera_index]
        rgb = self.scene.background_rgb(camera_index).copy()
        box = self._bounding_box(camera_index, pose)
        if box is not None:
            x0, y0, x1, y1 = box
            region = rgb[y0:y1, x0:x1]
            colour, coverage = self._render_region(camera_index, pose, x0, y0, x1, y1)
            region[...] = colour + (1.0 - coverage[..., None]) * region
            if blur_px > 0:
                pad = int(np.ceil(3 * blur_px))
                bx0, by0 = max(0, x0 - pad), max(0, y0 - pad)
                bx1, by1 = min(camera.width_px, x1 + pad), min(camera.height_px, y1 + pad)
                rgb[by0:by1, bx0:bx1] = cv2.GaussianBlur(rgb[by0:by1, bx0:bx1], (0, 0), blur_px)
        values = raw_values(rgb.astype(np.float32), fmt, 0, 0)
        sim = self.scene.rig.simulation
        image = sensor_output(values, rng, sim.noise_sigma, sim.shot_noise, noise)
        corners_world = pose.to_world(self.spec.object_points_m)
        corners_px = camera.project(corners_world)
        facing = float((camera.centre_m - pose.origin_m) @ pose.rotation[:, 2]) < 0.0
        visible = (
            np.all(np.isfinite(corners_px), axis=1) & camera.contains(np.nan_to_num(corners_px, nan=-1e9)) & facing
        )
        return RenderedBoard(image, fmt, corners_px, visible)

    # ------------------------------------------------------------------ geometry

    def _outline_m(self) -> Array:
        """(4, 3) corners of the plate (squares plus margin) in board coordinates."""
        width, height = self.spec.size_m
        m = self.margin_m
        return np.array([[-m, -m, 0.0], [width + m, -m, 0.0], [width + m, height + m, 0.0], [-m, height + m, 0.0]])

    def _bounding_box(self, index: int, pose: BoardPose) -> tuple[int, int, int, int] | None:
        """Pixel box (x0, y0, x1, y1) holding the plate's image, or None when it is out of view."""
        camera = self.scene.cameras[index]
        outline = self._outline_m()
        edge = np.linspace(0.0, 1.0, 33)[:, None]
        points = np.vstack([outline[k] + edge * (outline[(k + 1) % 4] - outline[k]) for k in range(4)])
        world = pose.to_world(points)
        depth = camera.to_camera_frame(world)[:, 2]
        if np.any(depth <= 0.05):
            raise ValueError("the board reaches behind the camera; place it in front")
        px = camera.project(world)
        x0 = int(np.floor(px[:, 0].min())) - 2
        y0 = int(np.floor(px[:, 1].min())) - 2
        x1 = int(np.ceil(px[:, 0].max())) + 3
        y1 = int(np.ceil(px[:, 1].max())) + 3
        x0, y0 = max(0, x0), max(0, y0)
        x1, y1 = min(camera.width_px, x1), min(camera.height_px, y1)
        if x0 >= x1 or y0 >= y1:
            return None
        return x0, y0, x1, y1

    def _render_region(self, index: int, pose: BoardPose, x0: int, y0: int, x1: int, y1: int) -> tuple[Array, Array]:
        """Premultiplied board colour (h, w, 3) and coverage (h, w) over a pixel box.

        One ray per pixel centre first; every pixel whose 3 x 3 neighbourhood sees
        more than one label (room, white, black, back) is then covered by the full
        ``supersampling``^2 grid of rays.
        """
        h, w = y1 - y0, x1 - x0
        ys, xs = np.mgrid[y0:y1, x0:x1]
        px = xs.ravel().astype(np.float64)
        py = ys.ravel().astype(np.float64)
        labels, colours = self._shade(index, pose, px, py)
        label_grid = labels.reshape(h, w)
        padded = np.pad(label_grid, 1, mode="edge")
        edge = np.zeros((h, w), dtype=bool)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                if dx or dy:
                    edge |= padded[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w] != label_grid
        coverage = (label_grid != _ROOM).astype(np.float64)
        colour = colours.reshape(h, w, 3)
        ey, ex = np.nonzero(edge)
        if len(ey):
            ss = self.supersampling
            offsets = (np.arange(ss) + 0.5) / ss - 0.5
            ox, oy = np.meshgrid(offsets, offsets)
            n = ss * ss
            # In chunks, to bound memory on boards that fill the view.
            chunk = max(1, 400_000 // n)
            for start in range(0, len(ey), chunk):
                cy, cx = ey[start : start + chunk], ex[start : start + chunk]
                sx = ((cx + x0)[:, None] + ox.ravel()[None, :]).ravel()
                sy = ((cy + y0)[:, None] + oy.ravel()[None, :]).ravel()
                sub_labels, sub_colours = self._shade(index, pose, sx, sy)
                coverage[cy, cx] = (sub_labels != _ROOM).reshape(-1, n).mean(axis=1)
                colour[cy, cx] = sub_colours.reshape(-1, n, 3).mean(axis=1)
        return colour, coverage

    def _shade(self, index: int, pose: BoardPose, px: Array, py: Array) -> tuple[NDArray[np.int8], Array]:
        """Per sample: the label it sees and the board's colour there (zero where it sees the room)."""
        camera = self.scene.cameras[index]
        dirs = self.scene._rays(index, px, py)
        normal = pose.rotation[:, 2]
        centre = camera.centre_m
        denominator = dirs @ normal
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((pose.origin_m - centre) @ normal) / denominator
        hit = np.isfinite(t) & (t > 0)
        points = centre + np.where(hit, t, 0.0)[:, None] * dirs
        rel = points - pose.origin_m
        u = rel @ pose.rotation[:, 0]
        v = rel @ pose.rotation[:, 1]
        width, height = self.spec.size_m
        m = self.margin_m
        on_plate = hit & (u >= -m) & (u <= width + m) & (v >= -m) & (v <= height + m)
        labels = np.zeros(len(px), dtype=np.int8)
        front = float((centre - pose.origin_m) @ normal) < 0.0
        if front:
            black = board_black(self.spec, u, v)
            labels[on_plate] = np.where(black[on_plate], _BLACK, _WHITE)
        else:
            labels[on_plate] = _BACK
        albedo = np.select(
            [labels == _WHITE, labels == _BLACK, labels == _BACK], [WHITE_ALBEDO, BLACK_ALBEDO, BACK_ALBEDO], 0.0
        )
        light = np.asarray(self.scene.room.light_m) - points
        light /= np.maximum(np.linalg.norm(light, axis=1, keepdims=True), 1e-12)
        facing_normal = -normal if front else normal
        lambert = np.clip(light @ facing_normal, 0.0, 1.0)
        shade = albedo * (AMBIENT + DIFFUSE * lambert)
        return labels, np.repeat(shade[:, None], 3, axis=1)


def board_black(spec: BoardSpec, u_m: Array, v_m: Array) -> NDArray[np.bool_]:
    """Whether board points (u, v) (N,) are printed black: the squares, and ChArUco's marker bits."""
    s = spec.square_m
    col = np.floor(u_m / s).astype(np.int64)
    row = np.floor(v_m / s).astype(np.int64)
    inside = (col >= 0) & (col < spec.squares_x) & (row >= 0) & (row < spec.squares_y)
    black = inside & spec.black_square(col, row)
    for _, corners, bits in spec.markers:
        top_left = corners[0, :2]
        side = float(corners[1, 0] - corners[0, 0])
        cells = bits.shape[0] + 2  # one border cell on each side
        mu = (u_m - top_left[0]) / side
        mv = (v_m - top_left[1]) / side
        in_marker = (mu >= 0) & (mu < 1) & (mv >= 0) & (mv < 1)
        if not np.any(in_marker):
            continue
        cu = np.floor(mu[in_marker] * cells).astype(np.int64)
        cv = np.floor(mv[in_marker] * cells).astype(np.int64)
        border = (cu == 0) | (cv == 0) | (cu == cells - 1) | (cv == cells - 1)
        inner_bit = bits[np.clip(cv - 1, 0, cells - 3), np.clip(cu - 1, 0, cells - 3)]
        black[np.nonzero(in_marker)[0]] = border | (inner_bit == 0)
    return black


# --------------------------------------------------------------------------- poses


def facing_rotation(
    view_dir: Array, tilt_x_deg: float, tilt_y_deg: float, spin_deg: float, up: Array | None = None
) -> Array:
    """World-from-board rotation of a board facing along ``view_dir`` (from the viewer to the board).

    The board's z (into the board) starts along ``view_dir`` with its y as close
    to world down as possible, then turns by ``spin_deg`` about z (in its plane),
    ``tilt_x_deg`` about its x and ``tilt_y_deg`` about its y.
    """
    z = np.asarray(view_dir, dtype=np.float64)
    z = z / np.linalg.norm(z)
    down = np.array([0.0, -1.0, 0.0]) if up is None else -np.asarray(up, dtype=np.float64)
    y = down - (down @ z) * z
    if np.linalg.norm(y) < 1e-6:
        y = np.array([0.0, 0.0, 1.0]) - z[2] * z
    y /= np.linalg.norm(y)
    x = np.cross(y, z)
    base = np.column_stack([x, y, z])
    turn = (
        rotation_about_z(np.radians(spin_deg))
        @ rotation_about_x(np.radians(tilt_x_deg))
        @ rotation_about_y(np.radians(tilt_y_deg))
    )
    return base @ turn


def poses_for_camera(
    scene: SceneRenderer,
    spec: BoardSpec,
    camera_index: int,
    count: int,
    rng: np.random.Generator,
    *,
    distance_m: tuple[float, float] = (0.8, 2.0),
    tilt_deg: tuple[float, float] = (15.0, 50.0),
    margin_px: float = 12.0,
    candidates: int = 12,
    max_tries: int = 20000,
) -> list[BoardPose]:
    """Varied poses of the whole board in one camera's view, as a careful operator holds it.

    Candidate poses put the board's centre on the ray through a random pixel, at
    a random distance, turned toward the camera and then tilted by an angle in
    ``tilt_deg`` about a random axis in its plane (a board facing the camera
    squarely says little about the focal length). From ``candidates`` times
    ``count`` of them, poses are
    chosen one by one to cover the image cells (of an 8 x 6 grid) that earlier
    poses left empty, the image's corners and edges most of all, since that is
    where distortion is measured; ties go to the more tilted pose.
    """
    camera = scene.cameras[camera_index]
    width, height = camera.width_px, camera.height_px
    pool: list[tuple[BoardPose, set[tuple[int, int]], float]] = []
    for _ in range(max_tries):
        if len(pool) >= candidates * count:
            break
        target = rng.uniform([0.0, 0.0], [width, height])
        distance = rng.uniform(*distance_m)
        _, dirs = camera.pixel_to_ray(target[None])
        centre = camera.centre_m + distance * dirs[0]
        tilt = rng.uniform(*tilt_deg)
        axis = rng.uniform(0.0, 2.0 * np.pi)
        tilt_x, tilt_y = tilt * np.cos(axis), tilt * np.sin(axis)
        spin = rng.uniform(-25.0, 25.0)
        view_dir = centre - camera.centre_m
        pose = BoardPose.centred(spec, centre, facing_rotation(view_dir, tilt_x, tilt_y, spin, up=-camera.rotation[1]))
        if board_in_view(scene, spec, pose, [camera_index], margin_px):
            px = camera.project(pose.to_world(spec.object_points_m))
            cells = {(int(x / width * 8), int(y / height * 6)) for x, y in px}
            pool.append((pose, cells, float(np.hypot(tilt_x, tilt_y))))
    if len(pool) < count:
        raise RuntimeError(f"found only {len(pool)} of {count} board poses in view of camera {camera_index}")
    weight = {(c, r): 1.0 + 2.0 * (c in (0, 7)) + 1.5 * (r in (0, 5)) for c in range(8) for r in range(6)}
    seen: dict[tuple[int, int], int] = {}
    chosen: list[BoardPose] = []
    for _ in range(count):

        def gain(item: tuple[BoardPose, set[tuple[int, int]], float]) -> float:
            return sum(weight[c] / (1.0 + seen.get(c, 0)) for c in item[1]) + 0.01 * item[2]

        best = max(range(len(pool)), key=lambda i: gain(pool[i]))
        pose, cells, _ = pool.pop(best)
        chosen.append(pose)
        for cell in cells:
            seen[cell] = seen.get(cell, 0) + 1
    return chosen


def poses_for_pair(
    scene: SceneRenderer,
    spec: BoardSpec,
    count: int,
    rng: np.random.Generator,
    *,
    region_m: tuple[Array, Array] | None = None,
    facing: Array | None = None,
    max_tilt_deg: float = 25.0,
    max_turn_deg: float = 8.0,
    max_obliquity_deg: float = 70.0,
    margin_px: float = 12.0,
    max_tries: int = 4000,
) -> list[BoardPose]:
    """Poses of the whole board seen by the first two cameras at once (stereo pairs).

    The board faces ``facing`` (default: the mean of the directions from the
    board's centre to the two cameras, so both see its printed face), tipped
    forward or back by up to ``max_tilt_deg`` and turned left or right by up to
    ``max_turn_deg`` (cameras that converge from the two sides each see the board
    at a steep angle already; turning it further hides it from one of them),
    centred anywhere in ``region_m`` (default: the presenter's area in front of
    the wall, from the rig's simulation settings).
    """
    cams = scene.cameras[:2]
    if region_m is None:
        sim = scene.rig.simulation
        wall = scene.wall
        low = wall.origin_m + 0.2 * wall.width_m * wall.x_axis + sim.presenter_distance_m[0] * wall.normal
        high = wall.origin_m + 0.8 * wall.width_m * wall.x_axis + sim.presenter_distance_m[1] * wall.normal
        floor = float(wall.corners_m[:, 1].min()) - sim.display_height_above_floor_m
        low = np.array([low[0], floor + sim.hand_height_m[0], low[2]])
        high = np.array([high[0], floor + sim.hand_height_m[1] + 0.2, high[2]])
        region_m = (np.minimum(low, high), np.maximum(low, high))
    lo, hi = (np.asarray(r, dtype=np.float64) for r in region_m)
    poses: list[BoardPose] = []
    for _ in range(max_tries):
        if len(poses) == count:
            break
        centre = rng.uniform(lo, hi)
        if facing is None:
            towards = np.asarray(
                sum((c.centre_m - centre) / np.linalg.norm(c.centre_m - centre) for c in cams), dtype=np.float64
            )
        else:
            towards = np.asarray(facing, dtype=np.float64)
        tilt_x = rng.uniform(-max_tilt_deg, max_tilt_deg)
        tilt_y = rng.uniform(-max_turn_deg, max_turn_deg)
        spin = rng.uniform(-15.0, 15.0)
        pose = BoardPose.centred(spec, centre, facing_rotation(-towards, tilt_x, tilt_y, spin))
        if board_in_view(scene, spec, pose, [0, 1], margin_px, max_obliquity_deg):
            poses.append(pose)
    if len(poses) < count:
        raise RuntimeError(f"found only {len(poses)} of {count} board poses seen by both cameras")
    return poses


def board_in_view(
    scene: SceneRenderer,
    spec: BoardSpec,
    pose: BoardPose,
    camera_indices: list[int],
    margin_px: float,
    max_obliquity_deg: float = 75.0,
) -> bool:
    """Every inner corner and the plate's outline inside each camera's image, printed face towards it,
    seen no more than ``max_obliquity_deg`` away from the board's normal."""
    width, height = spec.size_m
    m = 0.5 * spec.square_m
    outline = np.array([[-m, -m, 0.0], [width + m, -m, 0.0], [width + m, height + m, 0.0], [-m, height + m, 0.0]])
    points = pose.to_world(np.vstack([spec.object_points_m, outline]))
    centre = pose.to_world(np.array([[width / 2, height / 2, 0.0]]))[0]
    for index in camera_indices:
        camera = scene.cameras[index]
        to_camera = camera.centre_m - centre
        cos_obliquity = float(-(to_camera @ pose.rotation[:, 2]) / np.linalg.norm(to_camera))
        if cos_obliquity <= np.cos(np.radians(max_obliquity_deg)):
            return False
        if np.any(camera.to_camera_frame(points)[:, 2] <= 0.1):
            return False
        px = camera.project(points)
        if not np.all(np.isfinite(px)) or not np.all(camera.contains(px, margin_px)):
            return False
    return True


# --------------------------------------------------------------------------- a pair source


class RenderedPairSource(PairSource):
    """A :class:`PairSource` that renders each pair when it is asked for one (tests and demos).

    ``render(k)`` returns the k-th pair's images, one per camera in rig order;
    after ``count`` pairs the source stops. There is no real-time backlog, so a
    consumer should take pairs one by one rather than skip to the newest.
    """

    def __init__(
        self,
        camera_ids: list[str],
        pixel_formats: list[str],
        render: Callable[[int], list[NDArray[np.uint8]]],
        count: int,
        *,
        period_ns: int = 33_333_333,
        skew_ns: int = 0,
    ) -> None:
        self.camera_ids = camera_ids
        self.pixel_formats = pixel_formats
        self._render = render
        self.count = count
        self.period_ns = period_ns
        self.skew_ns = skew_ns
        self._index = 0
        self._running = False

    def start(self) -> None:
        self._running = True

    def stop(self) -> None:
        self._running = False

    def next_pair(self, timeout_s: float) -> FramePair | None:
        if not self._running:
            return None
        if self._index >= self.count:
            self._running = False
            return None
        k = self._index
        self._index += 1
        images = self._render(k)
        stamp = k * self.period_ns
        frames = tuple(
            Frame(cam_id, k, stamp, stamp, fmt, image)
            for cam_id, fmt, image in zip(self.camera_ids, self.pixel_formats, images, strict=True)
        )
        return FramePair(frames, stamp, self.skew_ns, k)

    def status(self) -> SourceStatus:
        return SourceStatus(
            running=self._running, trigger="software", pairing="rendered", pairs=self._index, delivered=self._index
        )


def board_pair_source(
    board: BoardRenderer, poses: list[BoardPose], rng: np.random.Generator, blur_px: float = 0.5
) -> RenderedPairSource:
    """Every camera's view of the board at each pose in turn, as a pair source."""
    scene = board.scene
    ids = [cam.camera_id for cam in scene.cameras]

    def render(k: int) -> list[NDArray[np.uint8]]:
        return [board.render(i, poses[k], rng, blur_px=blur_px).image for i in range(len(ids))]

    return RenderedPairSource(ids, list(scene.pixel_formats), render, len(poses))
