"""Camera orientation: the report's pitch, yaw and roll (section 3.5, eq. 18-22).

Conventions (docs/geometry.md):

* Camera frame: OpenCV's. x to the right of the image, y down the image, z along
  the optical axis, out of the lens.
* World frame of the pose form: y up, z out of the wall into the room. A camera
  at rest (all angles zero) is level and looks at the wall, so its axes are the
  world's with y and z flipped: ``R_REST = diag(1, -1, -1)``.
* Elementary rotations about the camera's own axes, right-handed (eq. 18-20):
  pitch about x, yaw about y, roll about z.
* Composition (eq. 21): yaw, then pitch about the yawed x axis, then roll about
  the resulting optical axis, the way a pan-tilt head moves. The report writes
  the product as P*Y*R; its figure with the exact order is lost, and pan before
  tilt is what installers measure.
* Eq. 22 maps camera coordinates to world: ``x_world = R_world_from_cam @ x_cam + C``.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

R_REST = np.diag([1.0, -1.0, -1.0])
"""World-from-camera rotation of a level camera looking at the wall (-z)."""


def rotation_about_x(angle_rad: float) -> NDArray[np.float64]:
    """Pitch rotation matrix (eq. 18). Positive pitch tilts the optical axis toward -y (up)."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rotation_about_y(angle_rad: float) -> NDArray[np.float64]:
    """Yaw rotation matrix (eq. 19). Positive yaw turns the optical axis toward +x (right)."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotation_about_z(angle_rad: float) -> NDArray[np.float64]:
    """Roll rotation matrix (eq. 20). Positive roll turns the x axis toward +y (clockwise from behind)."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def world_from_camera_ypr(yaw_deg: float, pitch_deg: float, roll_deg: float) -> NDArray[np.float64]:
    """World-from-camera rotation of a camera with the given pan, tilt and roll (eq. 21-22).

    Returns a 3x3 matrix whose columns are the camera's x, y, z axes in world coordinates.
    """
    yaw, pitch, roll = np.radians([yaw_deg, pitch_deg, roll_deg])
    return R_REST @ rotation_about_y(yaw) @ rotation_about_x(pitch) @ rotation_about_z(roll)


def ypr_from_world_from_camera(rotation: NDArray[np.float64]) -> tuple[float, float, float]:
    """Inverse of :func:`world_from_camera_ypr`: (yaw_deg, pitch_deg, roll_deg).

    Pitch is kept in [-90, 90]; at exactly +-90 degrees yaw and roll are not
    separable and the roll is reported as zero.
    """
    m = R_REST.T @ np.asarray(rotation, dtype=float)
    # m = Ry(yaw) Rx(pitch) Rz(roll); its last row/column give the angles directly.
    pitch = np.arcsin(np.clip(-m[1, 2], -1.0, 1.0))
    if abs(np.cos(pitch)) < 1e-9:
        yaw = np.arctan2(-m[2, 0], m[0, 0])
        roll = 0.0
    else:
        yaw = np.arctan2(m[0, 2], m[2, 2])
        roll = np.arctan2(m[1, 0], m[1, 1])
    return float(np.degrees(yaw)), float(np.degrees(pitch)), float(np.degrees(roll))


def rotation_from_rvec(rvec: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rodrigues vector (axis * angle, radians) -> 3x3 rotation matrix."""
    matrix, _ = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3, 1))
    return np.asarray(matrix, dtype=np.float64)  # float64 already: typed, not copied


def rvec_from_rotation(rotation: NDArray[np.float64]) -> NDArray[np.float64]:
    """3x3 rotation matrix -> Rodrigues vector, shape (3,)."""
    rvec, _ = cv2.Rodrigues(np.asarray(rotation, dtype=np.float64))
    return np.asarray(rvec, dtype=np.float64).reshape(3)  # float64 already: typed, not copied


def rotation_angle_deg(rotation: NDArray[np.float64]) -> float:
    """The angle of a rotation matrix, in degrees (0 for the identity)."""
    cos_angle = (np.trace(rotation) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(cos_angle, -1.0, 1.0))))
