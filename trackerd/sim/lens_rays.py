"""World rays through any sub-pixel position of a camera, through its real lens (report section 4).

Undistorting every sample of every frame would dominate rendering; instead each
camera's pixel centres are undistorted once into a map, and a sample's ray is
interpolated from it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from trackerd.geometry.camera import CameraModel

Array = NDArray[np.float64]


def undistort_pixels(cam: CameraModel, pixels: Array) -> Array:
    """Normalised coordinates (N, 2) of many pixels (N, 2); OpenCV's default iterations are exact to
    ~1e-6 px here."""
    import cv2

    if not cam.has_distortion:
        return cam.normalized_from_pixels(pixels)
    # OpenCV's stubs type its results loosely; float64 points in are float64 out (np.asarray copies nothing).
    out = np.asarray(cv2.undistortPoints(pixels.reshape(-1, 1, 2), cam.matrix, cam.distortion), dtype=np.float64)
    return out.reshape(-1, 2)


class LensRays:
    """Rays through sub-pixel positions of each of a rig's cameras, from a per-camera map built on first use."""

    def __init__(self, cameras: list[CameraModel]) -> None:
        self.cameras = cameras
        self._maps: dict[int, NDArray[np.float32]] = {}

    def normalized_map(self, index: int) -> NDArray[np.float32]:
        """Undistorted normalised coordinates of every pixel centre, padded by one pixel: (H+2, W+2, 2)."""
        cached = self._maps.get(index)
        if cached is not None:
            return cached
        cam = self.cameras[index]
        xs = np.arange(-1, cam.width_px + 1, dtype=np.float64)
        ys = np.arange(-1, cam.height_px + 1, dtype=np.float64)
        grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
        normalized = undistort_pixels(cam, grid).reshape(len(ys), len(xs), 2).astype(np.float32)
        self._maps[index] = normalized
        return normalized

    def rays(self, index: int, px: Array, py: Array) -> Array:
        """World ray directions (N, 3) through sub-pixel positions (N,), by bilinear lookup in the map.

        The lens map is smooth, so interpolating between pixel centres is exact to
        far below a thousandth of a pixel, and much cheaper than undistorting
        every sample.
        """
        nmap = self.normalized_map(index)
        height, width = nmap.shape[:2]
        # Gathers by one flat index are several times cheaper than by (row, col), and np.take of whole rows
        # several times cheaper again than fancy indexing (the same values, so the same rays bit for bit).
        flat = nmap.reshape(-1, 2)
        gx = px + 1.0
        gy = py + 1.0
        ix = np.clip(np.floor(gx).astype(np.int64), 0, width - 2)
        iy = np.clip(np.floor(gy).astype(np.int64), 0, height - 2)
        fx = (gx - ix)[:, None]
        fy = (gy - iy)[:, None]
        k = iy * width + ix
        n00 = np.take(flat, k, axis=0)
        n01 = np.take(flat, k + 1, axis=0)
        n10 = np.take(flat, k + width, axis=0)
        n11 = np.take(flat, k + width + 1, axis=0)
        gx_rest, gy_rest = 1 - fx, 1 - fy
        norm = (n00 * gx_rest + n01 * fx) * gy_rest + (n10 * gx_rest + n11 * fx) * fy
        return self._world(index, norm)

    def pixel_rays(self, index: int, xs: NDArray[np.intp], ys: NDArray[np.intp]) -> Array:
        """World ray directions (N, 3) through whole pixel centres (N,) inside the frame: :meth:`rays`
        of the same positions bit for bit, without the interpolation (its weights are 1 and 0 there, and
        x * 1 + y * 0 is x exactly), so a third of the cost."""
        nmap = self.normalized_map(index)
        width = nmap.shape[1]
        norm = np.take(nmap.reshape(-1, 2), (ys + 1) * width + (xs + 1), axis=0).astype(np.float64)
        return self._world(index, norm)

    def _world(self, index: int, norm: Array) -> Array:
        """Unit world directions (N, 3) of normalised image coordinates (N, 2) of camera ``index``."""
        dirs_cam = np.empty((len(norm), 3))
        dirs_cam[:, :2] = norm
        dirs_cam[:, 2] = 1.0
        length = np.sqrt(norm[:, 0] * norm[:, 0] + norm[:, 1] * norm[:, 1] + 1.0)
        dirs_cam /= length[:, None]
        world: Array = dirs_cam @ self.cameras[index].rotation
        return world
