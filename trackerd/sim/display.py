"""The wall's display showing content (pictures, slides, video frames) in each camera's view.

Where each pixel's ray meets the display is found once per camera (a map of
texture coordinates, cropped to the rows and columns that see the display); a
frame's content is then drawn into the view by a bilinear lookup in it, over
the empty room.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from trackerd.geometry.camera import CameraModel
from trackerd.sim.lens_rays import LensRays
from trackerd.sim.raycast import ray_sphere
from trackerd.sim.room_shading import room_hits
from trackerd.sim.scene import Room
from trackerd.sim.shared_maps import SHARED_MAPS_BYTES, SharedMaps, camera_key

FloatImage = NDArray[np.float32]


class DisplayMap(NamedTuple):
    """Texture coordinates of the display seen at each pixel of a crop of a camera's view."""

    map_x: FloatImage
    """Fraction of the display's width (left to right), -1 where the room or a ball in it is seen."""
    map_y: FloatImage
    """Fraction of the display's height (top to bottom), -1 likewise."""
    box: tuple[int, int, int, int]
    """Rows and columns (r0, r1, c0, c1) of the view the crop covers: those that see the display,
    padded by a pixel; all 0 when the camera does not see it."""


class ShownDisplay(NamedTuple):
    """The room over the display's region (r0, r1, c0, c1) of a view, the display showing content."""

    r0: int
    r1: int
    c0: int
    c1: int
    rgb: FloatImage
    """(r1 - r0, c1 - c0, 3) RGB."""


class _Lookup(NamedTuple):
    x: FloatImage
    """Texture column sampled at each pixel of the display's crop (-1 and below: not the display)."""
    y: FloatImage
    """Texture row likewise."""
    room_seen: FloatImage
    """The room behind the crop times the share of each pixel the display leaves uncovered."""


def cv2_remap(image: FloatImage, map_x: FloatImage, map_y: FloatImage) -> FloatImage:
    """Bilinear lookup of ``image`` at (map_x, map_y) pixel positions, zero outside it."""
    import cv2

    # OpenCV's stubs type its results loosely; a float32 image in is float32 out (np.asarray copies nothing).
    out = cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return np.asarray(out, dtype=np.float32)


def overlay(behind: FloatImage, display: ShownDisplay, x0: int, y0: int) -> FloatImage:
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


class DisplayScreen:
    """The display in each camera's view: where it is seen, and what it shows in a frame."""

    def __init__(self, cameras: list[CameraModel], room: Room, lens: LensRays) -> None:
        self.cameras = cameras
        self.room = room
        self.lens = lens
        self._maps: dict[int, DisplayMap] = {}
        self._lookups: dict[tuple[int, int, int], _Lookup] = {}

    def showing(self, index: int, content: FloatImage, room_rgb: FloatImage) -> ShownDisplay:
        """Camera ``index``'s view of the display showing ``content`` (a texture, row 0 at the top) over
        ``room_rgb`` (the camera's view of the empty room, (H, W, 3); the same array on every call for
        a camera: what of it the display leaves seen is kept)."""
        r0, r1, c0, c1 = self.map(index).box
        if r1 <= r0:
            return ShownDisplay(r0, r1, c0, c1, room_rgb[r0:r1, c0:c1])
        h, w = content.shape[:2]
        lookup = self._lookups.get((index, h, w))
        if lookup is None:
            lookup = self._lookup(index, h, w, room_rgb[r0:r1, c0:c1])
            self._lookups[(index, h, w)] = lookup
        shown = cv2_remap(np.ascontiguousarray(content, dtype=np.float32), lookup.x, lookup.y)
        shown += lookup.room_seen
        return ShownDisplay(r0, r1, c0, c1, shown)

    def _lookup(self, index: int, h: int, w: int, room: FloatImage) -> _Lookup:
        """The display map in pixels of an (h, w) texture, and the room behind the display weighted by
        how much of each pixel the display leaves uncovered: the same for every frame of a camera, so
        a frame costs one remap and one addition."""
        map_x, map_y, _ = self.map(index)
        x = map_x * np.float32(w) - np.float32(0.5)
        y = map_y * np.float32(h) - np.float32(0.5)
        # Where the texture is sampled, and how much: the display's own coverage of each pixel.
        coverage = cv2_remap(np.ones((h, w), dtype=np.float32), x, y)
        room_seen = room * (np.float32(1.0) - coverage)[..., None]
        return _Lookup(x, y, room_seen)

    def map(self, index: int) -> DisplayMap:
        """Where each pixel's ray meets the display (see :class:`DisplayMap`), computed once per camera
        (and shared with every renderer of the same camera in the same room, by its fingerprint)."""
        cached = self._maps.get(index)
        if cached is None:
            cam = self.cameras[index]
            if self.room.fingerprint:
                key = camera_key(cam) + self.room.fingerprint.encode()
                cached = _SHARED.get(key, lambda: self._solve_map(index))
            else:
                cached = self._solve_map(index)
            self._maps[index] = cached
        return cached

    def _solve_map(self, index: int) -> DisplayMap:
        cam = self.cameras[index]
        xs = np.arange(cam.width_px)
        map_x = np.full((cam.height_px, cam.width_px), -1.0, dtype=np.float32)
        map_y = np.full((cam.height_px, cam.width_px), -1.0, dtype=np.float32)
        x0, y0, x1, y1 = self.room.display
        rows_per_chunk = max(1, 400_000 // cam.width_px)
        for r0 in range(0, cam.height_px, rows_per_chunk):
            ys = np.arange(r0, min(cam.height_px, r0 + rows_per_chunk))
            gx, gy = np.meshgrid(xs, ys)
            dirs = self.lens.pixel_rays(index, gx.ravel(), gy.ravel())
            axis, t, points = room_hits(self.room, cam.centre_m, dirs)
            on_wall = (axis == self.room.faces[0].axis) & np.isclose(points[:, 2], self.room.faces[0].value, atol=1e-6)
            for ball in self.room.balls:
                on_wall &= ~(ray_sphere(cam.centre_m, dirs, np.asarray(ball.centre_m), ball.radius_m) < t)
            fx = (points[:, 0] - x0) / (x1 - x0)
            fy = (y1 - points[:, 1]) / (y1 - y0)
            inside = on_wall & (fx >= 0) & (fx <= 1) & (fy >= 0) & (fy <= 1)
            block_x = np.where(inside, fx, -1.0).reshape(len(ys), cam.width_px)
            block_y = np.where(inside, fy, -1.0).reshape(len(ys), cam.width_px)
            map_x[r0 : r0 + len(ys)] = block_x
            map_y[r0 : r0 + len(ys)] = block_y
        rows, cols = np.nonzero(map_x >= 0)
        if rows.size:
            box = (
                max(int(rows.min()) - 1, 0),
                min(int(rows.max()) + 2, cam.height_px),
                max(int(cols.min()) - 1, 0),
                min(int(cols.max()) + 2, cam.width_px),
            )
        else:
            box = (0, 0, 0, 0)
        r0, r1, c0, c1 = box
        cropped = DisplayMap(np.ascontiguousarray(map_x[r0:r1, c0:c1]), np.ascontiguousarray(map_y[r0:r1, c0:c1]), box)
        for plane in (cropped.map_x, cropped.map_y):
            plane.setflags(write=False)  # shared between renderers
        return cropped


_SHARED: SharedMaps[DisplayMap] = SharedMaps(SHARED_MAPS_BYTES, lambda m: m.map_x.nbytes + m.map_y.nbytes)
