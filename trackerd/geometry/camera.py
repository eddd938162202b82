"""A calibrated camera: projection of world points and back-projection of pixels to rays.

The model is OpenCV's pinhole with lens distortion, which contains the report's
simple model (eq. 1-2 and 14) as the special case of no distortion and a
principal point at the image centre. Pixel coordinates follow OpenCV: the centre
of the top-left pixel is (0, 0), x to the right, y down.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.geometry.lens_inverse import (
    FIXED_POINT_TOLERANCE_PX,
    fixed_point_miss_px,
    fixed_point_undistort,
    newton_undistort,
)

Array = NDArray[np.float64]


def border_pixels(width_px: int, height_px: int, per_side: int = 65) -> Array:
    """Pixels along the image's border (the outer edges of the outer pixels), per_side per side."""
    w, h = width_px - 0.5, height_px - 0.5
    steps = np.linspace(0.0, 1.0, per_side)
    xs, ys = -0.5 + steps * (w + 0.5), -0.5 + steps * (h + 0.5)
    near = np.full(per_side, -0.5)
    return np.vstack(
        [
            np.column_stack([xs, near]),
            np.column_stack([xs, np.full(per_side, h)]),
            np.column_stack([near, ys]),
            np.column_stack([np.full(per_side, w), ys]),
        ]
    )


@dataclass(frozen=True, eq=False)
class CameraModel:
    """Intrinsics, distortion and pose of one camera.

    ``rotation`` and ``translation_m`` are OpenCV's world-to-camera transform,
    ``x_cam = rotation @ x_world + translation_m``.
    """

    camera_id: str
    width_px: int
    height_px: int
    matrix: Array
    """3x3 intrinsic matrix K."""
    distortion: Array
    """OpenCV distortion coefficients, shape (0,), (4,), (5,), (8,), (12,) or (14,)."""
    rotation: Array
    """3x3 world-to-camera rotation."""
    translation_m: Array
    """World-to-camera translation, shape (3,)."""
    centre_m: Array = field(init=False)
    """Optical centre in world coordinates, shape (3,)."""

    def __post_init__(self) -> None:
        for name in ("matrix", "distortion", "rotation", "translation_m"):
            value = np.array(getattr(self, name), dtype=np.float64)
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        centre = -self.rotation.T @ self.translation_m
        centre.setflags(write=False)
        object.__setattr__(self, "centre_m", centre)

    # ----------------------------------------------------------------- construction

    @classmethod
    def from_pose(
        cls,
        camera_id: str,
        width_px: int,
        height_px: int,
        matrix: Array,
        distortion: Array,
        position_m: Array,
        world_from_cam: Array,
    ) -> CameraModel:
        """Build from a camera position and a world-from-camera rotation."""
        rotation = np.asarray(world_from_cam, dtype=float).T
        translation = -rotation @ np.asarray(position_m, dtype=float)
        return cls(camera_id, width_px, height_px, matrix, distortion, rotation, translation)

    # ----------------------------------------------------------------- properties

    @property
    def world_from_camera(self) -> Array:
        """3x3 rotation taking camera-frame directions to world directions (eq. 22)."""
        return self.rotation.T

    @cached_property
    def has_distortion(self) -> bool:
        # Asked for every pair (normalized_from_pixels); the model is frozen, so once is enough.
        return bool(self.distortion.size and np.any(self.distortion != 0.0))

    @cached_property
    def focal_px(self) -> float:
        """Mean focal length in pixels, a scale for converting angles to pixels (asked for every pair:
        the model is frozen, so computed once)."""
        return float((self.matrix[0, 0] + self.matrix[1, 1]) / 2.0)

    def with_intrinsics(self, matrix: Array, distortion: Array) -> CameraModel:
        """The same camera pose with other intrinsics (for calibration studies)."""
        return CameraModel(
            self.camera_id,
            self.width_px,
            self.height_px,
            matrix,
            distortion,
            self.rotation,
            self.translation_m,
        )

    # ----------------------------------------------------------------- projection

    def to_camera_frame(self, points_world_m: Array) -> Array:
        """World points (N, 3) -> the same points in the camera frame (N, 3)."""
        pts = np.asarray(points_world_m, dtype=np.float64).reshape(-1, 3)
        return pts @ self.rotation.T + self.translation_m

    def project(self, points_world_m: Array) -> Array:
        """World points (N, 3) -> pixel coordinates (N, 2), distortion applied (eq. 1-2).

        Points on or behind the camera plane project to NaN.
        """
        pts = np.asarray(points_world_m, dtype=np.float64).reshape(-1, 3)
        in_cam = self.to_camera_frame(pts)
        pixels = np.full((len(pts), 2), np.nan)
        ahead = in_cam[:, 2] > 1e-12
        if np.any(ahead):
            projected, _ = cv2.projectPoints(
                in_cam[ahead].reshape(-1, 1, 3), np.zeros(3), np.zeros(3), self.matrix, self._dist_or_none()
            )
            pixels[ahead] = projected.reshape(-1, 2)
        return pixels

    def normalized_from_pixels(self, pixels_px: Array) -> Array:
        """Pixels (N, 2) -> undistorted normalised image coordinates (N, 2), i.e. x/z and y/z."""
        pix = np.asarray(pixels_px, dtype=np.float64).reshape(-1, 2)
        if not self.has_distortion:
            fx, fy = self.matrix[0, 0], self.matrix[1, 1]
            cx, cy = self.matrix[0, 2], self.matrix[1, 2]
            skew = self.matrix[0, 1]
            y = (pix[:, 1] - cy) / fy
            x = (pix[:, 0] - cx - skew * y) / fx
            plain: Array = np.column_stack([x, y])
            return plain
        if self._fixed_point_fails:
            solved = newton_undistort(self.matrix, self.distortion, pix)
            if solved is not None:
                return solved
        return fixed_point_undistort(self.matrix, self.distortion, pix)

    @cached_property
    def _fixed_point_fails(self) -> bool:
        """Whether OpenCV's fixed point leaves pixels of this camera's border (where it converges
        slowest) more than FIXED_POINT_TOLERANCE_PX off, where Newton's method
        (trackerd.geometry.lens_inverse) brings them back: a wide lens whose radial map flattens
        near the corners. Asked once per camera; other lenses keep OpenCV's (faster on the few
        pixels of a frame)."""
        if not self.has_distortion:
            return False
        border = border_pixels(self.width_px, self.height_px)
        miss = fixed_point_miss_px(self.matrix, self.distortion, border)
        return not bool(np.all(miss <= FIXED_POINT_TOLERANCE_PX))

    def rays_camera(self, pixels_px: Array) -> Array:
        """Pixels (N, 2) -> unit ray directions in the camera frame (N, 3)."""
        norm = self.normalized_from_pixels(pixels_px)
        dirs = np.column_stack([norm, np.ones(len(norm))])
        unit: Array = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
        return unit

    def pixel_to_ray(self, pixels_px: Array) -> tuple[Array, Array]:
        """Pixels (N, 2) -> rays in world coordinates: origins (N, 3) and unit directions (N, 3).

        Every ray starts at the optical centre (the report's C in eq. 15-17) and
        passes through the undistorted image point (its P).
        """
        dirs = self.rays_camera(pixels_px) @ self.rotation  # (R^T d^T)^T
        origins = np.broadcast_to(self.centre_m, dirs.shape).copy()
        return origins, dirs

    def contains(self, pixels_px: Array, margin_px: float = 0.0) -> NDArray[np.bool_]:
        """Whether pixel coordinates (N, 2) fall inside the image, at least margin_px from its edge."""
        pix = np.asarray(pixels_px, dtype=np.float64).reshape(-1, 2)
        return (
            (pix[:, 0] >= -0.5 + margin_px)
            & (pix[:, 0] <= self.width_px - 0.5 - margin_px)
            & (pix[:, 1] >= -0.5 + margin_px)
            & (pix[:, 1] <= self.height_px - 0.5 - margin_px)
        )

    def _dist_or_none(self) -> Array | None:
        return self.distortion if self.distortion.size else None


def report_pixel_pitch(focal_length: float, horizontal_fov_deg: float, width_px: int) -> float:
    """Size of one pixel on the image plane at focal length ``focal_length`` (eq. 14).

    ``x distance per pixel = f * tan(half view angle) / (image width in pixels / 2)``;
    the result is in the unit of ``focal_length``.
    """
    return focal_length * float(np.tan(np.radians(horizontal_fov_deg) / 2.0)) / (width_px / 2.0)
