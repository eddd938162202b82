"""The empty room as each camera sees it, rendered once and cached in memory and on disk.

The static room is anti-aliased with ``background_supersampling``^2 rays per
pixel; at 1080p that takes seconds, so it is kept under
``~/.cache/trackerd/backgrounds`` (keyed by everything it depends on) and in
memory, besides its raw values in each pixel format a frame asks for.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from trackerd.config.models import RigConfig
from trackerd.geometry.camera import CameraModel
from trackerd.sim.lens_rays import LensRays
from trackerd.sim.room_shading import shade_room
from trackerd.sim.scene import Room
from trackerd.sim.sensor import raw_values

RENDER_VERSION = 2
"""Bump when the background rendering changes, so cached backgrounds are not reused."""


def user_cache_dir(variable: str, name: str) -> Path:
    """$``variable``, else $XDG_CACHE_HOME/trackerd/``name``, else ~/.cache/trackerd/``name``: where the
    simulator keeps what it renders once (backgrounds here, loops in :mod:`trackerd.sim.loops`)."""
    explicit = os.environ.get(variable)
    if explicit:
        return Path(explicit)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "trackerd" / name


def default_cache_dir() -> Path:
    """$TRACKERD_RENDER_CACHE, else $XDG_CACHE_HOME/trackerd/backgrounds, else ~/.cache/trackerd/backgrounds."""
    return user_cache_dir("TRACKERD_RENDER_CACHE", "backgrounds")


class RoomBackgrounds:
    """Each camera's view of the empty room: (H, W, 3) float32 RGB in [0, 1], and its raw values."""

    def __init__(
        self,
        rig: RigConfig,
        cameras: list[CameraModel],
        room: Room,
        lens: LensRays,
        *,
        cache_dir: Path | None,
        step: int = 1,
    ) -> None:
        """``step``: render every this many pixels and interpolate (for large sensors in randomized
        scenes, where the room behind the pointer needs no detail); ``cache_dir`` None: memory only."""
        self.rig = rig
        self.cameras = cameras
        self.room = room
        self.lens = lens
        self.cache_dir = cache_dir
        self.step = max(1, int(step))
        self._rgb: dict[int, NDArray[np.float32]] = {}
        self._raw: dict[tuple[int, str], NDArray[np.float32]] = {}

    def rgb(self, index: int) -> NDArray[np.float32]:
        """Camera ``index``'s view of the empty room, from memory, the disk cache or rendered now."""
        cached = self._rgb.get(index)
        if cached is not None:
            return cached
        path = self.cache_path(index)
        if path is not None and path.exists():
            try:
                background: NDArray[np.float32] = np.load(path).astype(np.float32)
                self._rgb[index] = background
                return background
            except (OSError, ValueError):
                pass  # a damaged cache file is simply rendered again
        # Stored as float16 on disk, so rounded to it here too: a render must not depend on
        # whether its background came from the cache (the benches' figures moved with it).
        background = self._render(index).astype(np.float16).astype(np.float32)
        self._rgb[index] = background
        if path is not None:
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                tmp = path.with_suffix(f".tmp{os.getpid()}.npy")
                np.save(tmp, background.astype(np.float16))
                os.replace(tmp, path)
            except OSError:
                pass  # caching is an optimisation; a read-only home must not break rendering
        return background

    def in_format(self, index: int, fmt: str) -> NDArray[np.float32]:
        """The empty room as raw values in pixel format ``fmt`` (unlit by any look), cached."""
        key = (index, fmt)
        cached = self._raw.get(key)
        if cached is None:
            cached = raw_values(self.rgb(index), fmt, 0, 0)
            self._raw[key] = cached
        return cached

    def lit_in_format(self, index: int, fmt: str, illumination: NDArray[np.float32] | None) -> NDArray[np.float32]:
        """The empty room lit by a look's ``illumination`` (H, W, 3), as raw values in ``fmt``, cached
        (one look per renderer, so the format is the key)."""
        if illumination is None:
            return self.in_format(index, fmt)
        key = (index, "lit-" + fmt)
        cached = self._raw.get(key)
        if cached is None:
            cached = raw_values(self.rgb(index) * illumination, fmt, 0, 0)
            self._raw[key] = cached
        return cached

    def cache_path(self, index: int) -> Path | None:
        """The file camera ``index``'s background is kept in: a hash of all it depends on."""
        if self.cache_dir is None:
            return None
        cam = self.cameras[index]
        key = repr(
            (
                RENDER_VERSION,
                self.room.fingerprint,
                cam.width_px,
                cam.height_px,
                cam.matrix.round(9).tolist(),
                cam.distortion.round(12).tolist(),
                cam.rotation.round(12).tolist(),
                cam.translation_m.round(12).tolist(),
                self.rig.simulation.background_supersampling,
                *(() if self.step == 1 else (self.step,)),
            )
        )
        digest = hashlib.sha256(key.encode()).hexdigest()[:24]
        return self.cache_dir / f"bg-{digest}.npy"

    def _render(self, index: int) -> NDArray[np.float32]:
        cam = self.cameras[index]
        ss = self.rig.simulation.background_supersampling
        step = self.step
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
                    dirs = self.lens.rays(index, gx.ravel(), gy.ravel())
                    acc += shade_room(self.room, cam.centre_m, dirs).reshape(len(ys), width, 3)
            out[y0 : y0 + len(ys)] = acc / (ss * ss)
        if step > 1:
            import cv2

            # np.asarray: OpenCV's stubs type its results loosely; float32 in is float32 out (no copy).
            out = np.asarray(
                cv2.resize(out, (step * width, step * height), interpolation=cv2.INTER_LINEAR), dtype=np.float32
            )
            out = np.ascontiguousarray(out[: cam.height_px, : cam.width_px])
        return out
