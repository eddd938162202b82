"""Inverting the lens (trackerd/geometry/lens_inverse.py): Newton's method agrees with OpenCV where
OpenCV converges, inverts where it does not, and says so where nothing can."""

from __future__ import annotations

import cv2
import numpy as np

from trackerd.geometry.camera import border_pixels
from trackerd.geometry.lens_inverse import fixed_point_miss_px, fixed_point_undistort, invert_lens, newton_undistort

# 100 degrees across (1920 x 1080); the radial map's slope falls to 0.12 near the corners but stays positive.
FLATTENING = (
    np.array([[799.68, 0.0, 931.23], [0.0, 798.50, 525.12], [0.0, 0.0, 1.0]]),
    np.array([-0.33781, 0.057999, -0.00017266, 0.000020395, 0.0]),
)


def _grid(width_px: int, height_px: int, steps: int = 41) -> np.ndarray:
    xs, ys = np.meshgrid(np.linspace(-0.5, width_px - 0.5, steps), np.linspace(-0.5, height_px - 0.5, steps))
    return np.column_stack([xs.ravel(), ys.ravel()])


def test_newton_agrees_with_opencv_where_opencv_converges() -> None:
    matrix = np.array([[1000.0, 0.0, 962.5], [0.0, 1001.0, 538.0], [0.0, 0.0, 1.0]])
    distortion = np.array([-0.3, 0.15, 0.001, -0.001, -0.02])  # 88 degrees across, strong barrel
    pixels = _grid(1920, 1080)
    assert np.max(fixed_point_miss_px(matrix, distortion, pixels)) < 1e-6
    newton = newton_undistort(matrix, distortion, pixels)
    assert newton is not None
    np.testing.assert_allclose(newton, fixed_point_undistort(matrix, distortion, pixels), atol=1e-11)


def test_a_lens_that_flattens_is_inverted_where_opencv_is_not() -> None:
    matrix, distortion = FLATTENING
    border = border_pixels(1920, 1080)
    assert np.max(fixed_point_miss_px(matrix, distortion, border)) > 0.1
    normalised = invert_lens(matrix, distortion, border)
    in_cam = np.column_stack([normalised, np.ones(len(border))])
    back, _ = cv2.projectPoints(in_cam.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), matrix, distortion)
    assert np.max(np.linalg.norm(back.reshape(-1, 2) - border, axis=1)) < 1e-6


def test_no_inverse_beyond_a_fold() -> None:
    # This lens's distorted radius peaks at 0.742 (normalised) and falls after: the image's
    # corners, at 0.92, are no pixel's image. Newton's method does not converge and says so;
    # invert_lens falls back to OpenCV's answer, which the rig loader's lens check refuses.
    matrix = np.array([[1166.5, 0.0, 996.6], [0.0, 1167.5, 528.7], [0.0, 0.0, 1.0]])
    distortion = np.array([-0.26358, -0.0048419, 0.0, 0.0, 0.0])
    assert newton_undistort(matrix, distortion, np.array([[1919.5, 1079.5]])) is None
    inside = np.array([[1200.0, 600.0]])
    solved = newton_undistort(matrix, distortion, inside)
    assert solved is not None
    np.testing.assert_allclose(solved, fixed_point_undistort(matrix, distortion, inside), atol=1e-12)


def test_a_pixel_given_as_nan_comes_back_nan_and_the_others_are_inverted() -> None:
    # The locator passes NaN for an end a camera did not see, in the same call as the ends it saw.
    matrix, distortion = FLATTENING
    pixels = np.array([[np.nan, np.nan], [329.5, -0.5], [960.0, 540.0]])
    solved = newton_undistort(matrix, distortion, pixels)
    assert solved is not None
    assert np.all(np.isnan(solved[0]))
    np.testing.assert_allclose(solved[1:], newton_undistort(matrix, distortion, pixels[1:]), atol=0)
    assert np.max(fixed_point_miss_px(matrix, distortion, pixels[1:2])) > 0.01  # a pixel only Newton inverts
