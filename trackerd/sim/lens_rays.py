"""World rays through any sub-pixel position of a camera, through its real lens (report section 4).

Undistorting every sample of every frame would dominate rendering; instead each
camera's pixel centres are undistorted once into a map, and a sample's ray is
interpolated from it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from trackerd.geometry.camera import CameraModel
from trackerd.geometry.lens_inverse import is_five_term, newton_undistort
from trackerd.sim.shared_maps import SHARED_MAPS_BYTES, SharedMaps, lens_key

Array = NDArray[np.float64]


def undistort_pixels(cam: CameraModel, pixels: Array) -> Array:
    """Normalised coordinates (N, 2) of many pixels (N, 2), exact to ~1e-9 px at any distortion.

    The renderer draws every sample along the ray this gives, and the truth it reports
    projects forward through the same lens (``cv2.projectPoints``): the two agree only if
    the inversion has converged. OpenCV's ``undistortPoints`` with its default 5 fixed-point
    iterations had not, near the corners of a strongly distorted lens (31 px off on a 2448 x
    2048 camera with k1 = -0.23, where trackerd's own geometry, iterated to convergence, was
    right), so the scene drawn there was not the scene the rig describes. Newton's method
    (trackerd.geometry.lens_inverse) converges in 4-8 steps at the cost of those 5
    iterations; other lens models go through the camera's own (converged, slower) inverse.
    """
    if cam.has_distortion and is_five_term(cam.distortion):
        solved = newton_undistort(cam.matrix, cam.distortion, pixels)
        if solved is not None:
            return solved
    return cam.normalized_from_pixels(pixels)


def _normalized_planes(cam: CameraModel) -> NDArray[np.float32]:
    """Undistorted normalised x and y of every pixel centre, padded by one pixel: (2, H+2, W+2)."""
    xs = np.arange(-1, cam.width_px + 1, dtype=np.float64)
    ys = np.arange(-1, cam.height_px + 1, dtype=np.float64)
    grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    normalized = undistort_pixels(cam, grid).reshape(len(ys), len(xs), 2).astype(np.float32)
    # One plane per coordinate: a gather from a plane is a contiguous column, and NumPy works on
    # whole columns several times faster than on rows of two.
    planes = np.ascontiguousarray(normalized.transpose(2, 0, 1))
    planes.setflags(write=False)  # shared between renderers
    return planes


_SHARED: SharedMaps[NDArray[np.float32]] = SharedMaps(SHARED_MAPS_BYTES, lambda planes: planes.nbytes)


class LensRays:
    """Rays through sub-pixel positions of each of a rig's cameras, from a per-camera map built on first use
    (and shared with every other renderer of a camera with the same intrinsics)."""

    def __init__(self, cameras: list[CameraModel]) -> None:
        self.cameras = cameras
        self._maps: dict[int, NDArray[np.float32]] = {}

    def normalized_map(self, index: int) -> NDArray[np.float32]:
        """Undistorted normalised x and y of every pixel centre, padded by one pixel: (2, H+2, W+2)."""
        cached = self._maps.get(index)
        if cached is None:
            cam = self.cameras[index]
            cached = self._maps[index] = _SHARED.get(lens_key(cam), lambda: _normalized_planes(cam))
        return cached

    def rays(self, index: int, px: Array, py: Array) -> Array:
        """World ray directions (N, 3) through sub-pixel positions (N,), by bilinear lookup in the map.

        The lens map is smooth, so interpolating between pixel centres is exact to
        far below a thousandth of a pixel, and much cheaper than undistorting
        every sample.
        """
        planes = self.normalized_map(index)
        height, width = planes.shape[1:]
        gx = px + 1.0
        gy = py + 1.0
        ix = np.clip(np.floor(gx).astype(np.int64), 0, width - 2)
        iy = np.clip(np.floor(gy).astype(np.int64), 0, height - 2)
        fx = gx - ix
        fy = gy - iy
        gx_rest, gy_rest = 1 - fx, 1 - fy
        k = iy * width + ix
        norm = []
        for plane in planes.reshape(2, -1):
            # Gathers by one flat index are several times cheaper than by (row, col).
            n00 = np.take(plane, k)
            n01 = np.take(plane, k + 1)
            n10 = np.take(plane, k + width)
            n11 = np.take(plane, k + width + 1)
            norm.append((n00 * gx_rest + n01 * fx) * gy_rest + (n10 * gx_rest + n11 * fx) * fy)
        return self._world(index, norm[0], norm[1])

    def pixel_rays(self, index: int, xs: NDArray[np.intp], ys: NDArray[np.intp]) -> Array:
        """World ray directions (N, 3) through whole pixel centres (N,) inside the frame: :meth:`rays`
        of the same positions bit for bit, without the interpolation (its weights are 1 and 0 there, and
        x * 1 + y * 0 is x exactly), so a third of the cost."""
        planes = self.normalized_map(index)
        k = (ys + 1) * planes.shape[2] + (xs + 1)
        x, y = (np.take(plane, k).astype(np.float64) for plane in planes.reshape(2, -1))
        return self._world(index, x, y)

    def _world(self, index: int, x: Array, y: Array) -> Array:
        """Unit world directions (N, 3) of normalised image coordinates (N,) of camera ``index``."""
        # Column by column: the same arithmetic as on (N, 3) rows, without NumPy's slow broadcasting
        # of one value per row over three columns.
        length = np.sqrt(x * x + y * y + 1.0)
        dirs_cam = np.empty((3, len(x)))
        np.divide(x, length, out=dirs_cam[0])
        np.divide(y, length, out=dirs_cam[1])
        np.divide(1.0, length, out=dirs_cam[2])
        world: Array = dirs_cam.T @ self.cameras[index].rotation
        return world
