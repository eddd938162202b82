"""Per-camera maps the simulator solves once and shares between renderers of a process.

A renderer solves, for each camera, where every pixel's ray goes: through the lens (the undistortion
map, a quarter of a second for a 1080p camera) and onto the display (a few tenths more). Renderers of the
same cameras are many: `bench accuracy` builds one per variant, `bench robustness` one for an
installation's shots, one for its colour learning and one for its followed sequence, and tests render the
same installations again. Without sharing, most of their time went to solving the same maps again.

The maps are kept by what they depend on (the caller's key, bytes), least recently used first out, within
a memory budget; they are read-only, so a renderer cannot change another's.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable
from typing import Generic, TypeVar

import numpy as np

from trackerd.geometry.camera import CameraModel

Value = TypeVar("Value")

SHARED_MAPS_BYTES = 384 * 1024 * 1024
"""What each kind of shared map may hold in memory (a 1080p lens map is 17 MB, a 4K one 66 MB)."""


def lens_key(cam: CameraModel) -> bytes:
    """What a camera's lens map depends on: its size, K and distortion (not where it stands)."""
    size = np.array([cam.width_px, cam.height_px], dtype=np.int64)
    return size.tobytes() + cam.matrix.tobytes() + cam.distortion.tobytes()


def camera_key(cam: CameraModel) -> bytes:
    """A camera's lens and its pose."""
    return lens_key(cam) + cam.rotation.tobytes() + cam.translation_m.tobytes()


class SharedMaps(Generic[Value]):
    """Maps by key, the least recently used dropped first while they hold more than ``limit_bytes``
    (the newest is always kept). Safe to use from several threads: a map two threads ask for at once may
    be built twice, and neither waits for the other."""

    def __init__(self, limit_bytes: int, size_bytes: Callable[[Value], int]) -> None:
        self.limit_bytes = limit_bytes
        self._size_bytes = size_bytes
        self._maps: OrderedDict[bytes, Value] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: bytes, build: Callable[[], Value]) -> Value:
        """The map kept under ``key``, or ``build()``'s, kept."""
        with self._lock:
            cached = self._maps.get(key)
            if cached is not None:
                self._maps.move_to_end(key)
                return cached
        built = build()
        with self._lock:
            self._maps[key] = built
            self._maps.move_to_end(key)
            while len(self._maps) > 1 and sum(self._size_bytes(m) for m in self._maps.values()) > self.limit_bytes:
                self._maps.popitem(last=False)
        return built
