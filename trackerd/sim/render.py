"""Ray-cast rendering of the room and the pointer through each camera of a rig (report section 4).

Every pixel's colour comes from casting rays through the camera's real lens
model (intrinsics and distortion, :class:`~trackerd.geometry.camera.CameraModel`)
into the scene of :mod:`trackerd.sim.scene`, so the ground truth is exact:

* the static room is rendered once per camera (anti-aliased with
  ``background_supersampling``^2 rays per pixel) and cached in memory and on
  disk (``~/.cache/trackerd/backgrounds``);
* the pointer is rendered per frame with ``supersampling``^2 rays per pixel, only
  in tiles near its image, and composited over the room by coverage;
* the same sub-pixel samples give the truth: the visible area of each ball and
  the centroid of that area, besides the projection of each ball's centre;
* sensor noise (read noise plus shot noise) is added after mosaicing, as a
  camera adds it to the raw values, then values are quantised to 8 bits.
"""

from __future__ import annotations

import hashlib
import math
import os
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from trackerd.config.models import RigConfig
from trackerd.config.rig_geometry import camera_model, wall_frame
from trackerd.geometry.camera import CameraModel
from trackerd.pixelformat import from_rgb
from trackerd.sim.appearance import DEFAULT_LOOK, Look, Occluder
from trackerd.sim.scene import (
    HAND_RADIUS_M,
    HANDLE_LENGTH_FACTOR,
    PointerPose,
    Room,
    build_room,
)

Array = NDArray[np.float64]

RENDER_VERSION = 1
"""Bump when the background rendering changes, so cached backgrounds are not reused."""

TILE_PX = 16
AMBIENT = DEFAULT_LOOK.ambient
DIFFUSE = DEFAULT_LOOK.diffuse

# Primitive ids in the pointer's sample buffers.
_NONE, _RED, _BLUE, _ROD, _HAND, _OCCLUDER = 0, 1, 2, 3, 4, 5


@dataclass(frozen=True)
class ViewTruth:
    """Ground truth of one rendered view, per colour ('red', 'blue')."""

    centre_px: dict[str, Array]
    """Projection of each ball's centre (NaN if behind the camera)."""
    centroid_px: dict[str, Array]
    """Centroid of the ball's visible image region (NaN if fully hidden or off-image)."""
    area_px: dict[str, float]
    """Visible area of the ball's image, in pixels."""
    full_area_px: dict[str, float] = dataclass_field(default_factory=dict)
    """Area the ball's image would have with nothing in front of it and no frame edge (its
    silhouette, projected through the lens), in pixels."""

    def visible_fraction(self, colour: str) -> float:
        """Share of the ball's silhouette that is visible in the frame (0 when hidden or off-image)."""
        full = self.full_area_px.get(colour, 0.0)
        return float(min(1.0, self.area_px[colour] / full)) if full > 0 else 0.0


@dataclass(frozen=True)
class RenderedView:
    image: NDArray[np.uint8]
    """The frame as the camera would deliver it, in ``pixel_format``."""
    pixel_format: str
    truth: ViewTruth


def default_cache_dir() -> Path:
    """$TRACKERD_RENDER_CACHE, else $XDG_CACHE_HOME/trackerd/backgrounds, else ~/.cache/trackerd/backgrounds."""
    explicit = os.environ.get("TRACKERD_RENDER_CACHE")
    if explicit:
        return Path(explicit)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "trackerd" / "backgrounds"


class SceneRenderer:
    """Renders what each camera of a rig sees, with the pointer at any pose."""

    def __init__(
        self,
        rig: RigConfig,
        cameras: list[CameraModel] | None = None,
        *,
        cache_dir: Path | bool | None = True,
        look: Look = DEFAULT_LOOK,
        background_step: int = 1,
        noise_field: bool = False,
    ) -> None:
        """``look``: paints and light (the default is the look every bench was rendered with);
        ``background_step``: render the static room every this many pixels and interpolate (for
        large sensors in randomized scenes, where the room behind the pointer needs no detail);
        ``noise_field``: draw each camera's sensor noise once, a little larger than its frame, and give
        each frame a window of it at a random offset (white noise within a frame, a fraction of the cost
        of drawing millions of values a frame; for benchmarks that render thousands of frames)."""
        self.rig = rig
        self.look = look
        self.background_step = max(1, int(background_step))
        self._display_maps: dict[int, tuple[NDArray[np.float32], NDArray[np.float32], tuple[int, int, int, int]]] = {}
        self._illumination: dict[int, NDArray[np.float32] | None] = {}
        self.noise_field = noise_field
        self._display_lookups: dict[tuple[int, int, int], tuple[NDArray[np.float32], NDArray[np.float32]]] = {}
        self._noise: dict[int, NDArray[np.float32]] = {}
        self.cameras = cameras if cameras is not None else [camera_model(c) for c in rig.cameras]
        self.pixel_formats = [c.pixel_format for c in rig.cameras]
        self.wall = wall_frame(rig.wall)
        self.room: Room = build_room(rig, self.wall)
        self.front_colour = rig.pointer.front_colour
        self._maps: dict[int, NDArray[np.float32]] = {}
        self._backgrounds: dict[int, NDArray[np.float32]] = {}
        self._mosaics: dict[tuple[int, str], NDArray[np.float32]] = {}
        self._last_patch: dict[int, tuple[tuple[bytes, ...], Any]] = {}
        if cache_dir is True:
            self.cache_dir: Path | None = default_cache_dir()
        elif cache_dir is False or cache_dir is None:
            self.cache_dir = None
        else:
            self.cache_dir = Path(cache_dir)

    # ------------------------------------------------------------------ public

    def render(
        self,
        camera_index: int,
        pose: PointerPose | None,
        rng: np.random.Generator,
        *,
        motion_to: PointerPose | None = None,
        motion_steps: int = 6,
        pixel_format: str | None = None,
        noise: bool = True,
        occluders: tuple[Occluder, ...] = (),
        content: NDArray[np.float32] | None = None,
    ) -> RenderedView:
        """Render one camera's view with the pointer at ``pose`` (None: no pointer).

        With ``motion_to``, the pointer moves linearly from ``pose`` to ``motion_to``
        during the exposure, sampled at ``motion_steps`` instants (motion blur);
        the truth is then averaged over the exposure. ``occluders`` stand in front
        of (or behind) the pointer; ``content`` is what the display shows
        (:func:`trackerd.sim.appearance.wall_content`), where the room's own slide is
        shown otherwise.
        """
        fmt = pixel_format or self.pixel_formats[camera_index]
        camera = self.cameras[camera_index]
        # The room, lit and mosaiced, is cached per format; each frame changes only the display's region
        # (its content) and the pointer's, which are composed in RGB, lit and mosaiced on their own.
        mosaic = self._lit_room_in_format(camera_index, fmt).copy()
        display = None
        if content is not None:
            display = self._display_showing(camera_index, content)
            r0, _, c0, _, shown = display
            self._put(mosaic, shown, camera_index, fmt, c0, r0)
        truth_centre = {c: np.full(2, np.nan) for c in ("red", "blue")}
        truth_centroid = {c: np.full(2, np.nan) for c in ("red", "blue")}
        truth_area = {"red": 0.0, "blue": 0.0}
        full_area = {"red": 0.0, "blue": 0.0}
        if pose is not None:
            poses = [pose] if motion_to is None else [
                pose.interpolate(motion_to, f) for f in np.linspace(0.0, 1.0, max(motion_steps, 2))
            ]
            patch = self._pointer_patch(camera_index, poses, occluders)
            if patch is not None:
                x0, y0, rgb, coverage, sums = patch
                h, w = rgb.shape[:2]
                behind = self._background(camera_index)[y0 : y0 + h, x0 : x0 + w]
                if display is not None:
                    behind = _overlay(behind, display, x0, y0)
                blended = rgb + (1.0 - coverage[..., None]) * behind
                self._put(mosaic, blended.astype(np.float32), camera_index, fmt, x0, y0)
                for colour, (count, sx, sy) in sums.items():
                    if count > 0:
                        truth_centroid[colour] = np.array([sx / count, sy / count])
                        truth_area[colour] = count
            mid = poses[len(poses) // 2] if len(poses) % 2 else poses[0].interpolate(poses[-1], 0.5)
            radius = self.rig.pointer.end_diameter_m / 2.0
            for colour in ("red", "blue"):
                centre = mid.centre_of(colour, self.front_colour)
                truth_centre[colour] = camera.project(centre[None])[0]
                full_area[colour] = silhouette_area_px(camera, centre, radius)
        draws = self._noise_window(camera_index, mosaic.shape, rng) if (noise and self.noise_field) else None
        sim = self.rig.simulation
        image = sensor_output(mosaic, rng, sim.noise_sigma, sim.shot_noise, noise, draws)
        return RenderedView(image, fmt, ViewTruth(truth_centre, truth_centroid, truth_area, full_area))

    def _noise_window(self, index: int, shape: tuple[int, ...], rng: np.random.Generator) -> NDArray[np.float32]:
        """A frame's standard normal draws: a window at a random offset in the camera's noise field."""
        margin = 64
        field = self._noise.get(index)
        if field is None:
            field = rng.standard_normal((shape[0] + margin, shape[1] + margin, *shape[2:]), dtype=np.float32)
            self._noise[index] = field
        dy, dx = (int(v) for v in rng.integers(0, margin, size=2))
        return field[dy : dy + shape[0], dx : dx + shape[1]]

    def _put(self, mosaic: NDArray[np.float32], rgb: NDArray[np.float32], index: int, fmt: str, x0: int,
             y0: int) -> None:
        """Write an RGB region at (x0, y0) into a frame's raw values, lit as the rest of the frame."""
        h, w = rgb.shape[:2]
        illumination = self._illumination_map(index)
        if illumination is not None:
            rgb = rgb * illumination[y0 : y0 + h, x0 : x0 + w]
        region = raw_values(rgb, fmt, x0, y0)
        if region.ndim == 2:
            mosaic[y0 : y0 + h, x0 : x0 + w] = region
        else:
            mosaic[y0 : y0 + h, x0 : x0 + w, :] = region

    def _lit_room_in_format(self, index: int, fmt: str) -> NDArray[np.float32]:
        """The empty room as the camera delivers it (lit by the look, in its pixel format), cached."""
        illumination = self._illumination_map(index)
        if illumination is None:
            return self._background_in_format(index, fmt)
        key = (index, "lit-" + fmt)
        cached = self._mosaics.get(key)
        if cached is None:
            cached = raw_values(self._background(index) * illumination, fmt, 0, 0)
            self._mosaics[key] = cached
        return cached

    def background_rgb(self, camera_index: int) -> NDArray[np.float32]:
        """The empty room as camera ``camera_index`` sees it, (H, W, 3) floats in [0, 1]."""
        return self._background(camera_index)

    def _illumination_map(self, index: int) -> NDArray[np.float32] | None:
        if index not in self._illumination:
            cam = self.cameras[index]
            self._illumination[index] = self.look.illumination(cam.width_px, cam.height_px)
        return self._illumination[index]

    def _display_showing(self, index: int, content: NDArray[np.float32]
                         ) -> tuple[int, int, int, int, NDArray[np.float32]]:
        """The room over the display's region (r0, r1, c0, c1) with the display showing ``content`` (a
        texture, row 0 at the top), in RGB."""
        map_x, map_y, (r0, r1, c0, c1) = self._display_map(index)
        room = self._background(index)[r0:r1, c0:c1]
        if r1 <= r0:
            return r0, r1, c0, c1, room
        h, w = content.shape[:2]
        key = (index, h, w)
        scaled = self._display_lookups.get(key)
        if scaled is None:
            scaled = (map_x * np.float32(w) - np.float32(0.5), map_y * np.float32(h) - np.float32(0.5))
            self._display_lookups[key] = scaled
        # A fourth channel of ones says where the texture was sampled: the display's own coverage.
        rgba = np.dstack([content.astype(np.float32), np.ones((h, w), dtype=np.float32)])
        shown = cv2_remap(rgba, *scaled)
        alpha = shown[..., 3:4]
        blended = room * (np.float32(1.0) - alpha)
        blended += shown[..., :3]
        return r0, r1, c0, c1, blended

    def _display_map(
        self, index: int
    ) -> tuple[NDArray[np.float32], NDArray[np.float32], tuple[int, int, int, int]]:
        """Where each pixel's ray meets the display, as fractions of its width (left to right) and
        height (top to bottom), -1 where the room or a ball in it is seen instead; cropped to the
        rows and columns (r0, r1, c0, c1) that see the display, padded by a pixel."""
        cached = self._display_maps.get(index)
        if cached is not None:
            return cached
        cam = self.cameras[index]
        xs = np.arange(cam.width_px, dtype=np.float64)
        map_x = np.full((cam.height_px, cam.width_px), -1.0, dtype=np.float32)
        map_y = np.full((cam.height_px, cam.width_px), -1.0, dtype=np.float32)
        x0, y0, x1, y1 = self.room.display
        rows_per_chunk = max(1, 400_000 // cam.width_px)
        for r0 in range(0, cam.height_px, rows_per_chunk):
            ys = np.arange(r0, min(cam.height_px, r0 + rows_per_chunk), dtype=np.float64)
            gx, gy = np.meshgrid(xs, ys)
            dirs = self._rays(index, gx.ravel(), gy.ravel())
            axis, t, points = room_hits(self.room, cam.centre_m, dirs)
            on_wall = (axis == self.room.faces[0].axis) & np.isclose(points[:, 2], self.room.faces[0].value, atol=1e-6)
            for ball in self.room.balls:
                on_wall &= ~(_ray_sphere(cam.centre_m, dirs, np.asarray(ball.centre_m), ball.radius_m) < t)
            fx = (points[:, 0] - x0) / (x1 - x0)
            fy = (y1 - points[:, 1]) / (y1 - y0)
            inside = on_wall & (fx >= 0) & (fx <= 1) & (fy >= 0) & (fy <= 1)
            block_x = np.where(inside, fx, -1.0).reshape(len(ys), cam.width_px)
            block_y = np.where(inside, fy, -1.0).reshape(len(ys), cam.width_px)
            map_x[r0 : r0 + len(ys)] = block_x
            map_y[r0 : r0 + len(ys)] = block_y
        rows, cols = np.nonzero(map_x >= 0)
        if rows.size:
            box = (max(int(rows.min()) - 1, 0), min(int(rows.max()) + 2, cam.height_px),
                   max(int(cols.min()) - 1, 0), min(int(cols.max()) + 2, cam.width_px))
        else:
            box = (0, 0, 0, 0)
        r0, r1, c0, c1 = box
        cropped = (np.ascontiguousarray(map_x[r0:r1, c0:c1]), np.ascontiguousarray(map_y[r0:r1, c0:c1]), box)
        self._display_maps[index] = cropped
        return cropped

    # ------------------------------------------------------------------ rays

    def _normalized_map(self, index: int) -> NDArray[np.float32]:
        """Undistorted normalised coordinates of every pixel centre, padded by one pixel: (H+2, W+2, 2)."""
        cached = self._maps.get(index)
        if cached is not None:
            return cached
        cam = self.cameras[index]
        xs = np.arange(-1, cam.width_px + 1, dtype=np.float64)
        ys = np.arange(-1, cam.height_px + 1, dtype=np.float64)
        grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
        normalized = _undistort_fast(cam, grid).reshape(len(ys), len(xs), 2).astype(np.float32)
        self._maps[index] = normalized
        return normalized

    def _rays(self, index: int, px: Array, py: Array) -> Array:
        """World ray directions (N, 3) through sub-pixel positions (N,), by bilinear lookup in the map.

        The lens map is smooth, so interpolating between pixel centres is exact to
        far below a thousandth of a pixel, and much cheaper than undistorting
        every sample.
        """
        nmap = self._normalized_map(index)
        height, width = nmap.shape[:2]
        flat = nmap.reshape(-1, 2)  # gathers by one flat index are several times cheaper than by (row, col)
        gx = px + 1.0
        gy = py + 1.0
        ix = np.clip(np.floor(gx).astype(np.int64), 0, width - 2)
        iy = np.clip(np.floor(gy).astype(np.int64), 0, height - 2)
        fx = (gx - ix)[:, None]
        fy = (gy - iy)[:, None]
        k = iy * width + ix
        n00 = flat[k]
        n01 = flat[k + 1]
        n10 = flat[k + width]
        n11 = flat[k + width + 1]
        gx_rest, gy_rest = 1 - fx, 1 - fy
        norm = (n00 * gx_rest + n01 * fx) * gy_rest + (n10 * gx_rest + n11 * fx) * fy
        dirs_cam = np.empty((len(norm), 3))
        dirs_cam[:, :2] = norm
        dirs_cam[:, 2] = 1.0
        length = np.sqrt(norm[:, 0] * norm[:, 0] + norm[:, 1] * norm[:, 1] + 1.0)
        dirs_cam /= length[:, None]
        return dirs_cam @ self.cameras[index].rotation

    # ------------------------------------------------------------------ background

    def _background(self, index: int) -> NDArray[np.float32]:
        cached = self._backgrounds.get(index)
        if cached is not None:
            return cached
        path = self._cache_path(index)
        if path is not None and path.exists():
            try:
                background = np.load(path).astype(np.float32)
                self._backgrounds[index] = background
                return background
            except (OSError, ValueError):
                pass  # a damaged cache file is simply rendered again
        # Stored as float16 on disk, so rounded to it here too: a render must not depend on
        # whether its background came from the cache (the benches' figures moved with it).
        background = self._render_background(index).astype(np.float16).astype(np.float32)
        self._backgrounds[index] = background
        if path is not None:
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                tmp = path.with_suffix(f".tmp{os.getpid()}.npy")
                np.save(tmp, background.astype(np.float16))
                os.replace(tmp, path)
            except OSError:
                pass  # caching is an optimisation; a read-only home must not break rendering
        return background

    def _cache_path(self, index: int) -> Path | None:
        if self.cache_dir is None:
            return None
        cam = self.cameras[index]
        key = repr((
            RENDER_VERSION, self.room.fingerprint, cam.width_px, cam.height_px,
            cam.matrix.round(9).tolist(), cam.distortion.round(12).tolist(),
            cam.rotation.round(12).tolist(), cam.translation_m.round(12).tolist(),
            self.rig.simulation.background_supersampling,
            *(() if self.background_step == 1 else (self.background_step,)),
        ))
        digest = hashlib.sha256(key.encode()).hexdigest()[:24]
        return self.cache_dir / f"bg-{digest}.npy"

    def _render_background(self, index: int) -> NDArray[np.float32]:
        cam = self.cameras[index]
        ss = self.rig.simulation.background_supersampling
        step = self.background_step
        offsets = (np.arange(ss) + 0.5) / ss - 0.5
        # Every step-th pixel (the centre of each step x step block), interpolated between.
        width, height = -(-cam.width_px // step), -(-cam.height_px // step)
        out = np.empty((height, width, 3), dtype=np.float32)
        rows_per_chunk = max(1, 400_000 // (width * ss * ss))
        xs = np.arange(width, dtype=np.float64) * step + (step - 1) / 2.0
        for y0 in range(0, height, rows_per_chunk):
            ys = np.arange(y0, min(height, y0 + rows_per_chunk), dtype=np.float64) * step + (step - 1) / 2.0
            acc = np.zeros((len(ys), width, 3), dtype=np.float64)
            for oy in offsets:
                for ox in offsets:
                    gx, gy = np.meshgrid(xs + ox, ys + oy)
                    dirs = self._rays(index, gx.ravel(), gy.ravel())
                    acc += shade_room(self.room, cam.centre_m, dirs).reshape(len(ys), width, 3)
            out[y0 : y0 + len(ys)] = acc / (ss * ss)
        if step > 1:
            import cv2

            out = cv2.resize(out, (step * width, step * height), interpolation=cv2.INTER_LINEAR)
            out = np.ascontiguousarray(out[: cam.height_px, : cam.width_px])
        return out

    def _background_in_format(self, index: int, fmt: str) -> NDArray[np.float32]:
        key = (index, fmt)
        cached = self._mosaics.get(key)
        if cached is None:
            cached = raw_values(self._background(index), fmt, 0, 0)
            self._mosaics[key] = cached
        return cached

    # ------------------------------------------------------------------ pointer

    def _pointer_patch(self, index: int, poses: list[PointerPose], occluders: tuple[Occluder, ...] = ()):
        """``_render_pointer``, remembered for the last poses of each camera: a pointer held still
        (a presenter asked to hold it there) is ray-cast once; each frame still gets its own noise."""
        key = (tuple(p.front_m.tobytes() + p.back_m.tobytes() for p in poses), occluders)
        last = self._last_patch.get(index)
        if last is not None and last[0] == key:
            return last[1]
        patch = self._render_pointer(index, poses, occluders)
        self._last_patch[index] = (key, patch)
        return patch

    def _render_pointer(
        self, index: int, poses: list[PointerPose], occluders: tuple[Occluder, ...] = ()
    ) -> tuple[int, int, Array, Array, dict[str, tuple[float, float, float]]] | None:
        """Render the pointer alone in the tiles its image touches, averaged over ``poses``.

        Returns (x0, y0, premultiplied rgb (h, w, 3), coverage (h, w), per-colour
        (area, sum x, sum y) of the visible region), or None when nothing is in view.
        """
        cam = self.cameras[index]
        tiles = set()
        for pose in poses:
            tiles |= self._tiles_near_pointer(cam, pose, occluders)
        if not tiles:
            return None
        tx = np.array([t[0] for t in tiles])
        ty = np.array([t[1] for t in tiles])
        x0, y0 = int(tx.min() * TILE_PX), int(ty.min() * TILE_PX)
        x1 = min(cam.width_px, int((tx.max() + 1) * TILE_PX))
        y1 = min(cam.height_px, int((ty.max() + 1) * TILE_PX))
        in_tiles = np.zeros((y1 - y0, x1 - x0), dtype=bool)
        for tile_x, tile_y in tiles:
            in_tiles[tile_y * TILE_PX - y0 : (tile_y + 1) * TILE_PX - y0,
                     tile_x * TILE_PX - x0 : (tile_x + 1) * TILE_PX - x0] = True
        local_y, local_x = np.nonzero(in_tiles)
        centre_dirs = self._rays(index, (local_x + x0).astype(np.float64), (local_y + y0).astype(np.float64))
        rgb = np.zeros((y1 - y0, x1 - x0, 3))
        coverage = np.zeros((y1 - y0, x1 - x0))
        sums = {"red": np.zeros(3), "blue": np.zeros(3)}
        weight = 1.0 / len(poses)
        for pose in poses:
            self._accumulate_pose(index, pose, x0, y0, local_x, local_y, centre_dirs, in_tiles.shape,
                                  weight, rgb, coverage, sums, occluders)
        result = {c: (float(v[0]), float(v[1]), float(v[2])) for c, v in sums.items()}
        return x0, y0, rgb, coverage, result

    def _accumulate_pose(
        self,
        index: int,
        pose: PointerPose,
        x0: int,
        y0: int,
        local_x: NDArray[np.int64],
        local_y: NDArray[np.int64],
        centre_dirs: Array,
        shape: tuple[int, int],
        weight: float,
        rgb: Array,
        coverage: Array,
        sums: dict[str, Array],
        occluders: tuple[Occluder, ...] = (),
    ) -> None:
        """Adaptive supersampling: one ray per pixel, then ss x ss rays where ids change.

        A pixel whose centre and 8 neighbours all hit the same primitive is taken
        as fully covered by it; every other pixel (edges, junctions) gets the full
        grid of sub-pixel rays, so areas and centroids stay exact at the edges
        while most interior pixels cost one ray.
        """
        cam = self.cameras[index]
        ss = self.rig.simulation.supersampling
        ids_c, colours_c = shade_pointer(self, cam.centre_m, centre_dirs, pose, occluders)
        id_grid = np.zeros(shape, dtype=np.int8)
        id_grid[local_y, local_x] = ids_c
        padded = np.pad(id_grid, 1, mode="edge")
        edge = np.zeros(shape, dtype=bool)
        h, w = shape
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                if dx or dy:
                    edge |= padded[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w] != id_grid
        is_edge = edge[local_y, local_x]
        # Interior pixels: one sample stands for the whole pixel.
        interior = ~is_edge & (ids_c != _NONE)
        iy, ix = local_y[interior], local_x[interior]
        coverage[iy, ix] += weight
        rgb[iy, ix] += weight * colours_c[interior]
        for colour, prim in (("red", _RED), ("blue", _BLUE)):
            mask = ids_c[interior] == prim
            if np.any(mask):
                sums[colour] += weight * np.array([mask.sum(), (ix[mask] + x0).sum(), (iy[mask] + y0).sum()])
        if not np.any(is_edge):
            return
        # Edge pixels: the full sub-pixel grid.
        ey, ex = local_y[is_edge], local_x[is_edge]
        offsets = (np.arange(ss) + 0.5) / ss - 0.5
        ox, oy = np.meshgrid(offsets, offsets)
        sample_x = ((ex + x0)[:, None] + ox.ravel()[None, :]).ravel()
        sample_y = ((ey + y0)[:, None] + oy.ravel()[None, :]).ravel()
        ids, colours = shade_pointer(self, cam.centre_m, self._rays(index, sample_x, sample_y), pose, occluders)
        n = ss * ss
        coverage[ey, ex] += weight * (ids != _NONE).reshape(-1, n).sum(axis=1) / n
        rgb[ey, ex] += weight * colours.reshape(-1, n, 3).sum(axis=1) / n
        for colour, prim in (("red", _RED), ("blue", _BLUE)):
            mask = ids == prim
            if np.any(mask):
                sums[colour] += (weight / n) * np.array([mask.sum(), sample_x[mask].sum(), sample_y[mask].sum()])

    def _tiles_near_pointer(
        self, cam: CameraModel, pose: PointerPose, occluders: tuple[Occluder, ...] = ()
    ) -> set[tuple[int, int]]:
        """Tiles whose centre lies within reach of the pointer's (and the occluders') projected outline."""
        pointer = self.rig.pointer
        length = pose.length_m
        handle_end = pose.back_m - HANDLE_LENGTH_FACTOR * length * pose.direction
        hand_centre = handle_end - HAND_RADIUS_M * 0.5 * pose.direction
        axis_points = np.linspace(0.0, 1.0, 24)[:, None]
        points = np.vstack([
            pose.front_m + axis_points * (handle_end - pose.front_m),
            hand_centre[None, :],
        ])
        radius = np.full(len(points), max(pointer.end_diameter_m / 2.0, pointer.rod_diameter_m / 2.0))
        radius[-1] = HAND_RADIUS_M if self.rig.simulation.hand else 0.0
        in_cam = cam.to_camera_frame(points)
        ahead = in_cam[:, 2] > 0.05
        if not np.any(ahead):
            return set()
        projected = cam.project(points[ahead])
        reach = cam.focal_px * radius[ahead] / in_cam[ahead, 2] * 1.3 + 3.0 + TILE_PX * 0.75
        n_tx = (cam.width_px + TILE_PX - 1) // TILE_PX
        n_ty = (cam.height_px + TILE_PX - 1) // TILE_PX
        # Candidate tiles around each projected point and along segments between them.
        dense = []
        for k in range(len(projected) - 1):
            a, b = projected[k], projected[k + 1]
            if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
                continue
            steps = max(2, int(np.linalg.norm(b - a) / (TILE_PX / 2)) + 1)
            for f in np.linspace(0, 1, steps):
                dense.append((a + f * (b - a), reach[k] + f * (reach[k + 1] - reach[k])))
        dense.append((projected[-1], reach[-1]))
        dense += self._occluder_reach(cam, occluders)
        marked = np.zeros((n_ty, n_tx), dtype=bool)
        for centre, r in dense:
            if not np.all(np.isfinite(centre)):
                continue
            lo = np.floor((centre - r) / TILE_PX).astype(int)
            hi = np.floor((centre + r) / TILE_PX).astype(int)
            marked[max(lo[1], 0) : min(hi[1], n_ty - 1) + 1, max(lo[0], 0) : min(hi[0], n_tx - 1) + 1] = True
        rows, cols = np.nonzero(marked)
        return set(zip(cols.tolist(), rows.tolist(), strict=True))


    def _occluder_reach(self, cam: CameraModel, occluders: tuple[Occluder, ...]) -> list[tuple[Array, float]]:
        """(image point, reach in pixels) along each occluder, for the tiles to render."""
        out: list[tuple[Array, float]] = []
        for occ in occluders:
            centre = np.asarray(occ.centre_m, dtype=np.float64)
            if occ.kind == "sphere":
                points = centre[None]
            else:
                steps = max(2, int(occ.height_m / max(occ.radius_m, 0.01)) * 2 + 1)
                points = centre + np.linspace(-0.5, 0.5, steps)[:, None] * np.array([0.0, occ.height_m, 0.0])
            depth = cam.to_camera_frame(points)[:, 2]
            ahead = depth > 0.05
            if not np.any(ahead):
                continue
            projected = cam.project(points[ahead])
            reach = cam.focal_px * occ.radius_m / depth[ahead] * 1.3 + 3.0 + TILE_PX * 0.75
            step_px = TILE_PX / 2
            for k in range(len(projected)):
                out.append((projected[k], float(reach[k])))
                if k + 1 < len(projected):
                    a, b = projected[k], projected[k + 1]
                    if np.all(np.isfinite(a)) and np.all(np.isfinite(b)):
                        n = max(2, int(np.linalg.norm(b - a) / step_px) + 1)
                        for f in np.linspace(0, 1, n)[1:-1]:
                            out.append((a + f * (b - a), float(reach[k] + f * (reach[k + 1] - reach[k]))))
        return out


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


# ----------------------------------------------------------------------------- shading


def shade_pointer(
    renderer: SceneRenderer, origin: Array, dirs: Array, pose: PointerPose, occluders: tuple[Occluder, ...] = ()
) -> tuple[NDArray[np.int8], Array]:
    """Intersect rays (N, 3) from ``origin`` with the pointer (and any occluders); per ray the
    primitive id and shaded colour."""
    pointer = renderer.rig.pointer
    look = renderer.look
    light = np.asarray(renderer.room.light_m)
    length = pose.length_m
    direction = pose.direction
    handle_end = pose.back_m - HANDLE_LENGTH_FACTOR * length * direction
    ball_r = pointer.end_diameter_m / 2.0
    rod_r = pointer.rod_diameter_m / 2.0
    front_rgb = look.red_rgb if renderer.front_colour == "red" else look.blue_rgb
    back_rgb = look.blue_rgb if renderer.front_colour == "red" else look.red_rgb
    front_id = _RED if renderer.front_colour == "red" else _BLUE
    back_id = _BLUE if renderer.front_colour == "red" else _RED

    n = len(dirs)
    best_t = np.full(n, np.inf)
    ids = np.zeros(n, dtype=np.int8)
    normals = np.zeros((n, 3))
    base = np.zeros((n, 3))

    def near(centre: Array, bound_m: float) -> NDArray[np.intp]:
        """The rays that pass within ``bound_m`` of ``centre``: the only ones that can hit what it bounds."""
        offset = centre - origin
        along = dirs @ offset
        miss2 = offset @ offset - along * along
        return np.flatnonzero((miss2 <= bound_m * bound_m) | (offset @ offset <= bound_m * bound_m))

    def consider(rays: NDArray[np.intp], t: Array, normal: Array, prim: int, rgb: tuple[float, float, float]) -> None:
        closer = t < best_t[rays]
        if np.any(closer):
            chosen = rays[closer]
            best_t[chosen] = t[closer]
            ids[chosen] = prim
            normals[chosen] = normal[closer]
            base[chosen] = rgb

    def sphere(centre: Array, radius: float, prim: int, rgb: tuple[float, float, float]) -> None:
        rays = near(centre, radius * 1.001)
        if rays.size:
            sub = dirs[rays]
            t = _ray_sphere(origin, sub, centre, radius)
            consider(rays, t, (origin + t[:, None] * sub - centre) / radius, prim, rgb)

    def cylinder(start: Array, end: Array, radius: float, prim: int, rgb: tuple[float, float, float]) -> None:
        rays = near(0.5 * (start + end), 0.5 * float(np.linalg.norm(end - start)) + radius * 1.001)
        if rays.size:
            t, normal = _ray_cylinder(origin, dirs[rays], start, end, radius)
            consider(rays, t, normal, prim, rgb)

    sphere(pose.front_m, ball_r, front_id, front_rgb)
    sphere(pose.back_m, ball_r, back_id, back_rgb)
    for start, end in ((pose.front_m, pose.back_m), (pose.back_m, handle_end)):
        cylinder(start, end, rod_r, _ROD, look.rod_rgb)
    if renderer.rig.simulation.hand:
        sphere(handle_end - HAND_RADIUS_M * 0.5 * direction, HAND_RADIUS_M, _HAND, look.skin_rgb)
    for occ in occluders:
        centre = np.asarray(occ.centre_m, dtype=np.float64)
        if occ.kind == "sphere":
            sphere(centre, occ.radius_m, _OCCLUDER, occ.rgb)
        else:
            half = np.array([0.0, occ.height_m / 2.0, 0.0])
            cylinder(centre - half, centre + half, occ.radius_m, _OCCLUDER, occ.rgb)

    hit = ids != _NONE
    colours = np.zeros((n, 3))
    if np.any(hit):
        points = origin + best_t[hit, None] * dirs[hit]
        to_light = light - points
        to_light /= np.linalg.norm(to_light, axis=1, keepdims=True)
        lambert = np.clip(np.sum(normals[hit] * to_light, axis=1), 0.0, 1.0)
        colours[hit] = base[hit] * (look.ambient + look.diffuse * lambert)[:, None]
        if look.specular > 0.0:
            # A white Phong highlight on the glossy balls: the light mirrored about the normal, seen along the ray.
            ball = (ids[hit] == _RED) | (ids[hit] == _BLUE)
            n_hit = normals[hit]
            reflected = 2.0 * np.sum(n_hit * to_light, axis=1)[:, None] * n_hit - to_light
            facing = np.clip(-np.sum(reflected * dirs[hit], axis=1), 0.0, 1.0)
            colours[hit] += (ball * look.specular * facing**look.shininess)[:, None]
    return ids, colours


def room_hits(room: Room, origin: Array, dirs: Array) -> tuple[NDArray[np.int64], Array, Array]:
    """Where rays (N, 3) from ``origin`` inside the room box leave it: the axis of the face hit,
    the distance and the point."""
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
        tex = _texture(room, face, u, v)
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
        tb = _ray_sphere(origin, dirs, np.asarray(ball.centre_m), ball.radius_m)
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


def _texture(room: Room, face, u: Array, v: Array) -> Array:
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
                (u >= x0 + fx0 * width) & (u <= x0 + fx1 * width)
                & (v >= y0 + fy0 * height) & (v <= y0 + fy1 * height)
            )
            tex[block] = rgb
    return tex.reshape(n, 3)


def _ray_sphere(origin: Array, dirs: Array, centre: Array, radius: float) -> Array:
    """Distance along unit rays to the first hit of a sphere (inf where missed or behind)."""
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


def _ray_cylinder(origin: Array, dirs: Array, start: Array, end: Array, radius: float) -> tuple[Array, Array]:
    """First hit of unit rays with the side of a finite cylinder (no caps): distances and normals."""
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
    points = origin + np.where(np.isfinite(t), t, 0.0)[:, None] * dirs
    rel = points - start
    normal = rel - (rel @ axis)[:, None] * axis
    norm = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = normal / np.where(norm > 0, norm, 1.0)
    return t, normal


# ----------------------------------------------------------------------------- output


def _overlay(behind: NDArray[np.float32], display: tuple[int, int, int, int, NDArray[np.float32]], x0: int,
             y0: int) -> NDArray[np.float32]:
    """``behind`` (a region at (x0, y0)) with the part the display's region covers taken from it."""
    r0, r1, c0, c1, shown = display
    h, w = behind.shape[:2]
    top, bottom = max(y0, r0), min(y0 + h, r1)
    left, right = max(x0, c0), min(x0 + w, c1)
    if top >= bottom or left >= right:
        return behind
    out = behind.copy()
    out[top - y0 : bottom - y0, left - x0 : right - x0] = shown[top - r0 : bottom - r0, left - c0 : right - c0]
    return out


def cv2_remap(image: NDArray[np.float32], map_x: NDArray[np.float32], map_y: NDArray[np.float32]
              ) -> NDArray[np.float32]:
    """Bilinear lookup of ``image`` at (map_x, map_y) pixel positions, zero outside it."""
    import cv2

    return cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def _undistort_fast(cam: CameraModel, pixels: Array) -> Array:
    """Normalised coordinates of many pixels; OpenCV's default iterations are exact to ~1e-6 px here."""
    import cv2

    if not cam.has_distortion:
        return cam.normalized_from_pixels(pixels)
    out = cv2.undistortPoints(pixels.reshape(-1, 1, 2), cam.matrix, cam.distortion)
    return out.reshape(-1, 2)


def raw_values(rgb: NDArray[np.float32], fmt: str, x0: int, y0: int) -> NDArray[np.float32]:
    """RGB floats (h, w, 3) -> the camera's raw values for a region starting at (x0, y0).

    Every renderer of the simulator (the scene, the calibration board, the hand) goes through
    this and :func:`sensor_output`, so their frames share one sensor model."""
    from trackerd.pixelformat import BAYER_LAYOUTS

    layout = BAYER_LAYOUTS.get(fmt)
    if layout is None:
        if fmt == "RGB8":
            return rgb
        if fmt == "BGR8":
            return np.ascontiguousarray(rgb[..., ::-1])
        return from_rgb(rgb, fmt).astype(np.float32)  # pragma: no cover - other formats
    h, w = rgb.shape[:2]
    out = np.empty((h, w), dtype=np.float32)
    for (row, col), channel in ((layout.red, 0), (layout.green_a, 1), (layout.green_b, 1), (layout.blue, 2)):
        # The Bayer cell is anchored at the image origin, not the region's.
        r0 = (row - y0) % 2
        c0 = (col - x0) % 2
        out[r0::2, c0::2] = rgb[r0::2, c0::2, channel]
    return out


def sensor_output(
    values: NDArray[np.float32], rng: np.random.Generator, read_sigma: float, shot: float, noise: bool,
    draws: NDArray[np.float32] | None = None,
) -> NDArray[np.uint8]:
    """[0, 1] values -> 8-bit sensor output with read and shot noise."""
    grey = values * np.float32(255.0)
    if noise and (read_sigma > 0 or shot > 0):
        # In place (a 1080p frame is 2 M values): the same arithmetic as
        # grey + sqrt(read^2 + shot^2 * max(grey, 0)) * N(0, 1), bit for bit.
        sigma = np.maximum(grey, np.float32(0.0))
        sigma *= np.float32(shot**2)
        sigma += np.float32(read_sigma**2)
        np.sqrt(sigma, out=sigma)
        if draws is None:
            draws = rng.standard_normal(grey.shape, dtype=np.float32)
        sigma *= draws
        draws = sigma
        grey += draws
    np.rint(grey, out=grey)
    np.clip(grey, 0, 255, out=grey)
    return grey.astype(np.uint8)
