"""A camera's lens (intrinsics) and pose (extrinsics) as a rig or calibration file gives them.

Two forms of each: the report's own (a field of view, eq. 14; a pan-tilt pose, eq. 18-21) and
OpenCV's (a calibrated pinhole with distortion; a world-to-camera transform)."""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from trackerd.config.base import ConfigModel, Vec3

# OpenCV accepts these distortion vector lengths (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1..s4 [tx ty]]]]).
OPENCV_DISTORTION_LENGTHS = (0, 4, 5, 8, 12, 14)


# --------------------------------------------------------------------------- intrinsics


class FovIntrinsics(ConfigModel):
    """The report's simple camera model (section 3.4, eq. 14).

    A distortion-free pinhole with its principal point at the image centre, fixed
    by the horizontal field of view: a pixel spans ``f * tan(hfov / 2) / (width / 2)``
    on an image plane at focal length ``f`` (eq. 14), which is a focal length of
    ``(width / 2) / tan(hfov / 2)`` in pixels.
    """

    model: Literal["fov"]
    """Selects this model."""
    horizontal_fov_deg: float = Field(gt=0.0, lt=180.0)
    """Full horizontal angle of view, in degrees."""
    vertical_fov_deg: float | None = Field(default=None, gt=0.0, lt=180.0)
    """Full vertical angle of view; omit for square pixels (then it follows from the aspect ratio)."""
    focal_length_mm: float | None = Field(default=None, gt=0.0)
    """Lens focal length. Does not change any ray (eq. 14 scales out); reported for reference."""


class OpenCVIntrinsics(ConfigModel):
    """A full pinhole model with OpenCV's lens distortion, as `cv2.calibrateCamera` returns it."""

    model: Literal["opencv"]
    """Selects this model."""
    fx_px: float = Field(gt=0.0)
    """Focal length along image x, in pixels."""
    fy_px: float = Field(gt=0.0)
    """Focal length along image y, in pixels."""
    cx_px: float
    """Principal point x, in pixels, measured from the left edge of the first pixel's centre (OpenCV)."""
    cy_px: float
    """Principal point y, in pixels, from the top."""
    distortion: tuple[float, ...] = ()
    """Distortion coefficients in OpenCV order: k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tx ty]]]]."""

    @field_validator("distortion")
    @classmethod
    def _distortion_length(cls, value: tuple[float, ...]) -> tuple[float, ...]:
        if len(value) not in OPENCV_DISTORTION_LENGTHS:
            raise ValueError(
                f"has {len(value)} coefficients; OpenCV takes " + ", ".join(str(n) for n in OPENCV_DISTORTION_LENGTHS)
            )
        return value


Intrinsics = Annotated[FovIntrinsics | OpenCVIntrinsics, Field(discriminator="model")]


# --------------------------------------------------------------------------- extrinsics


class PoseExtrinsics(ConfigModel):
    """Where the camera is and where it looks, as a camera operator would measure it.

    The angles follow the report's pitch, yaw and roll about the camera's x, y and
    z axes (eq. 18-20), composed as a pan-tilt head moves: yaw first, then pitch,
    then roll (eq. 21, docs/geometry.md). With all three at zero the camera is
    level and looks straight at the wall, along the world's -z axis.
    """

    kind: Literal["pose"]
    """Selects this form."""
    position_m: Vec3
    """The camera's optical centre in world coordinates."""
    yaw_deg: float = 0.0
    """Pan: positive turns the camera to its right."""
    pitch_deg: float = 0.0
    """Tilt: positive tilts the camera up."""
    roll_deg: float = 0.0
    """Rotation about the optical axis: positive turns the image content anticlockwise
    (the camera itself turns clockwise, seen from behind)."""


class OpenCVExtrinsics(ConfigModel):
    """World-to-camera transform in OpenCV's convention: ``x_cam = R @ x_world + t``.

    This is what `cv2.solvePnP` and `cv2.stereoCalibrate` produce. Give the rotation
    either as a Rodrigues vector or as a matrix, not both.
    """

    kind: Literal["opencv"]
    """Selects this form."""
    rvec: Vec3 | None = None
    """Rotation as a Rodrigues vector (axis times angle in radians)."""
    rotation_matrix: tuple[Vec3, Vec3, Vec3] | None = None
    """Rotation as a 3x3 matrix, rows first."""
    tvec_m: Vec3
    """Translation t, in metres."""

    @model_validator(mode="after")
    def _one_rotation(self) -> OpenCVExtrinsics:
        if (self.rvec is None) == (self.rotation_matrix is None):
            raise ValueError("give exactly one of rvec or rotation_matrix")
        if self.rotation_matrix is not None:
            import numpy as np

            matrix = np.asarray(self.rotation_matrix, dtype=float)
            if not np.allclose(matrix @ matrix.T, np.eye(3), atol=1e-6) or np.linalg.det(matrix) < 0:
                raise ValueError("rotation_matrix is not a rotation (orthonormal, determinant +1)")
        return self


Extrinsics = Annotated[PoseExtrinsics | OpenCVExtrinsics, Field(discriminator="kind")]


def horizontal_focal_px(intrinsics: FovIntrinsics, width_px: int) -> float:
    """Focal length in pixels implied by a field of view (eq. 14 inverted)."""
    return (width_px / 2.0) / math.tan(math.radians(intrinsics.horizontal_fov_deg) / 2.0)
