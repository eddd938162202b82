"""A ball's centre direction from its outline: the cone of rays that graze a sphere.

The rays from a camera's centre that touch a sphere of radius r whose centre is
at distance d along the unit direction c form a circular cone about c with
half-angle alpha, sin(alpha) = r / d. Every unit ray u through the ball's
outline (its rim in the image, undistorted) satisfies u . c = cos(alpha), which
is linear in a = c / cos(alpha): u . a = 1. So three or more rim rays give c and
alpha by linear least squares, exactly, whatever the perspective (a sphere
images as an ellipse whose centre is not the projection of its centre) and the
lens distortion: the rim points are undistorted one by one before the fit.

This replaces, for fitted outlines, the (1 - r^2 / Z^2) correction of a
centroid (trackerd/geometry/pointer_line.py, ``sphere_centre_scale``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from trackerd.geometry.camera import CameraModel

Array = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class SphereDirection:
    """A ball's centre as seen from one camera."""

    normalised: Array
    """(x/z, y/z) of the ball's centre in the camera's undistorted normalised image plane."""
    half_angle_rad: float
    """Half the angle the ball subtends: its distance is radius / sin(half_angle)."""
    covariance: Array
    """2x2 covariance of ``normalised``."""


def fit_sphere_direction(
    rim_normalised: Array, weights: Array | None = None, rim_sigma_normalised: float | None = None
) -> SphereDirection | None:
    """The cone through rim points given in normalised undistorted coordinates (N, 2).

    ``rim_sigma_normalised`` is one rim point's standard error across the rim, in
    normalised units; the covariance follows from it (or from the fit's own scatter
    when it is None). None when the points do not determine a cone (fewer than three,
    or all on a line).
    """
    points = np.asarray(rim_normalised, dtype=np.float64).reshape(-1, 2)
    n = len(points)
    if n < 3:
        return None
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=np.float64)
    rays = np.column_stack([points, np.ones(n)])
    rays /= np.sqrt(np.sum(rays * rays, axis=1, keepdims=True))
    sw = np.sqrt(w)
    lhs = rays * sw[:, None]
    rhs = sw
    try:
        a, *_ = np.linalg.lstsq(lhs, rhs, rcond=None)
    except np.linalg.LinAlgError:
        return None
    norm = float(np.linalg.norm(a))
    if not norm > 1.0 or a[2] <= 0:
        return None
    cos_alpha = 1.0 / norm
    alpha = math.acos(min(1.0, cos_alpha))
    normalised = a[:2] / a[2]
    # Covariance of a from the normal equations, then of a[:2] / a[2].
    normal = lhs.T @ lhs
    try:
        inverse = np.linalg.inv(normal)
    except np.linalg.LinAlgError:
        return None
    if rim_sigma_normalised is None:
        residual = lhs @ a - rhs
        dof = max(n - 3, 1)
        variance = float(residual @ residual) / dof
    else:
        # A rim point moved by s across the rim changes u . a by about s * sin(alpha) * |a|.
        variance = (rim_sigma_normalised * math.sin(alpha) * norm) ** 2
    cov_a = variance * inverse
    jac = np.array([[1.0 / a[2], 0.0, -a[0] / a[2] ** 2], [0.0, 1.0 / a[2], -a[1] / a[2] ** 2]])
    return SphereDirection(normalised, alpha, jac @ cov_a @ jac.T)


def view_map(camera: CameraModel, at_px: Array, step_px: float = 1.0) -> Array:
    """The 2x2 map from image offsets near pixel ``at_px`` to the focal length times the angles they make
    with the ray through it (on the plane at right angles to that ray), lens distortion included.

    A ball's grazing rays are a circular cone, so in these units its outline is a circle of radius
    ``focal * tan(half-angle)`` wherever it is in the image. In pixels it is not: seen at an angle theta
    off the optical axis it is stretched away from the axis by about 1 / cos(theta) (its image is an
    ellipse), 1.27 at 38 degrees, where a wide lens sees a ball held close to it. Near the axis the map
    is the identity to within the lens's aspect ratio."""
    centre = np.asarray(at_px, dtype=np.float64).reshape(2)
    h = float(step_px)
    around = centre + np.array([[0.0, 0.0], [h, 0.0], [-h, 0.0], [0.0, h], [0.0, -h]])
    rays = camera.rays_camera(around)
    axis = rays[0]
    # An orthonormal basis of the plane at right angles to the ray, as close to the image's x and y as
    # can be (the identity on the optical axis).
    first = np.array([1.0, 0.0, 0.0]) - axis * axis[0]
    first /= np.linalg.norm(first)
    second = np.cross(axis, first)
    # Gnomonic coordinates on that plane: where each ray meets it.
    on_plane = rays / (rays @ axis)[:, None] - axis
    coords = np.column_stack([on_plane @ first, on_plane @ second])
    jacobian = np.column_stack([coords[1] - coords[2], coords[3] - coords[4]]) / (2.0 * h)
    mapped: Array = camera.focal_px * jacobian
    return mapped
