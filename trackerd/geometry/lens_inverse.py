"""Pixels back to undistorted normalised coordinates: OpenCV's inverse of the lens, and Newton's method
where that does not converge.

OpenCV's ``undistortPoints`` iterates a fixed point, x <- (x_distorted - tangential) / radial
factor, which converges only where the radial map is steep enough: near the corners of
a strongly distorted wide lens (k1 = -0.34 with k2 = +0.06, whose radial map flattens
without folding) it does not converge in any number of iterations, and with its default
5 it leaves tens of pixels there. Newton's method converges in 4-8 steps wherever the map
does not fold: OpenCV's 5-term model is written out here (fast enough for every pixel of
an image), any other model is projected by OpenCV with its derivatives.
:class:`trackerd.geometry.camera.CameraModel` chooses once per camera, calibration's checks
per call (:func:`invert_lens`), and the simulator's lens maps use Newton's method for every
pixel (:mod:`trackerd.sim.lens_rays`).
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

FIXED_POINT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-14)
"""OpenCV's fixed point iterated to convergence (its default 5 iterations leave a tenth of a pixel
near the corners of a strongly distorted lens, and tens of pixels near a flattening one)."""

FIXED_POINT_TOLERANCE_PX = 1e-4
"""How far a pixel taken through OpenCV's inverse and projected back may land from itself before
Newton's method takes over."""

CHUNK = 32_768
"""Pixels inverted together: small enough that the arrays of one Newton step stay in cache."""

MAX_STEPS = 30
TOLERANCE = 1e-13
"""Newton stops when no pixel of a chunk moves more than this (normalised units, ~1e-10 px)."""


def fixed_point_undistort(matrix: Array, distortion: Array, pixels_px: Array) -> Array:
    """OpenCV's inverse of the lens, iterated to convergence: normalised (x, y) (N, 2) of pixels (N, 2)."""
    out = cv2.undistortPoints(pixels_px.reshape(-1, 1, 2), matrix, distortion, criteria=FIXED_POINT_CRITERIA)
    return np.asarray(out, dtype=np.float64).reshape(-1, 2)  # float64 already: typed, not copied


def fixed_point_miss_px(matrix: Array, distortion: Array, pixels_px: Array) -> Array:
    """How far each pixel (N, 2), taken through :func:`fixed_point_undistort` and projected back,
    lands from itself (N,)."""
    return _projection_miss_px(matrix, distortion, fixed_point_undistort(matrix, distortion, pixels_px), pixels_px)


def _projection_miss_px(matrix: Array, distortion: Array, normalised: Array, pixels_px: Array) -> Array:
    """Distance (N,) from each pixel (N, 2) to where its normalised coordinates (N, 2) project."""
    in_cam = np.column_stack([normalised, np.ones(len(normalised))])
    back, _ = cv2.projectPoints(in_cam.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), matrix, distortion)
    miss: Array = np.linalg.norm(back.reshape(-1, 2) - pixels_px, axis=1)
    return miss


def invert_lens(matrix: Array, distortion: Array, pixels_px: Array) -> Array:
    """Normalised (x, y) (N, 2) of pixels (N, 2) through any OpenCV lens: OpenCV's fixed point,
    and Newton's method where that has not converged (checked by projecting back). For
    calibration's checks; :class:`CameraModel` decides once per camera instead."""
    pixels_px = np.asarray(pixels_px, dtype=np.float64).reshape(-1, 2)
    matrix = np.asarray(matrix, dtype=np.float64)
    distortion = np.asarray(distortion, dtype=np.float64).ravel()
    fixed = fixed_point_undistort(matrix, distortion, pixels_px)
    if np.all(_projection_miss_px(matrix, distortion, fixed, pixels_px) <= FIXED_POINT_TOLERANCE_PX):
        return fixed
    solved = newton_undistort(matrix, distortion, pixels_px)
    return fixed if solved is None else solved


def is_five_term(distortion: Array) -> bool:
    """Whether a distortion vector is OpenCV's k1 k2 p1 p2 [k3] (longer ones with only zeros after)."""
    return distortion.size <= 5 or not np.any(distortion[5:] != 0.0)


def newton_undistort(matrix: Array, distortion: Array, pixels_px: Array) -> Array | None:
    """Undistorted normalised (x, y) (N, 2) of pixels (N, 2), or None if some pixel has no converged
    inverse (the lens folds before reaching it). OpenCV's 5-term lens (``is_five_term``) is written
    out here; any other is projected by OpenCV, with its derivatives (slower: for a frame's pixels, or
    a camera's border, not a whole image). A pixel given as NaN (an end a camera did not see) comes
    back as NaN without holding up the others."""
    solve = _newton_chunk if is_five_term(distortion) else _newton_chunk_any
    finite = np.all(np.isfinite(pixels_px), axis=1)
    given = pixels_px if bool(np.all(finite)) else pixels_px[finite]
    solved_all = np.empty((len(given), 2))
    for start in range(0, len(given), CHUNK):
        solved = solve(matrix, distortion, given[start : start + CHUNK])
        if solved is None:
            return None
        solved_all[start : start + CHUNK] = solved
    if len(given) == len(pixels_px):
        return solved_all
    out = np.full((len(pixels_px), 2), np.nan)
    out[finite] = solved_all
    return out


def _newton_chunk(matrix: Array, distortion: Array, pixels: Array) -> Array | None:
    """Undistorted normalised (x, y) (N, 2) whose OpenCV 5-term distortion (k1 k2 p1 p2 k3) lands on
    ``pixels``, by Newton's method from the distorted position; None if it has not converged."""
    k1, k2, p1, p2, k3 = np.concatenate([distortion, np.zeros(5)])[:5]
    xd, yd = _distorted_normalised(matrix, pixels)

    def miss_and_jacobian(x: Array, y: Array) -> tuple[Array, Array, Array, Array, Array, Array]:
        xx, yy, xy = x * x, y * y, x * y
        r2 = xx + yy
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        # d(radial)/d(r2), doubled: the radial factor's share of each partial derivative.
        slope2 = 2.0 * (k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2))
        miss_x = x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * xx) - xd
        miss_y = y * radial + p1 * (r2 + 2.0 * yy) + 2.0 * p2 * xy - yd
        dxx = radial + slope2 * xx + 2.0 * p1 * y + 6.0 * p2 * x
        dxy = slope2 * xy + 2.0 * p1 * x + 2.0 * p2 * y  # the Jacobian is symmetric
        dyy = radial + slope2 * yy + 6.0 * p1 * y + 2.0 * p2 * x
        return miss_x, miss_y, dxx, dxy, dxy, dyy

    return _newton(xd, yd, miss_and_jacobian)


def _newton_chunk_any(matrix: Array, distortion: Array, pixels: Array) -> Array | None:
    """As :func:`_newton_chunk` for any OpenCV lens model: each step projects the estimate with
    ``cv2.projectPoints``, whose derivatives with respect to the translation are, for a point at
    depth 1 with no rotation, those with respect to its normalised x and y."""

    def miss_and_jacobian(x: Array, y: Array) -> tuple[Array, Array, Array, Array, Array, Array]:
        in_cam = np.column_stack([x, y, np.ones(len(x))])
        projected, jacobian = cv2.projectPoints(in_cam.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), matrix, distortion)
        miss = projected.reshape(-1, 2) - pixels
        # Rows 2i and 2i+1 are point i's u and v; columns 3 and 4 the translation's x and y. (float64 already:
        # typed, not copied.)
        d: Array = np.asarray(jacobian, dtype=np.float64)
        return miss[:, 0], miss[:, 1], d[0::2, 3], d[0::2, 4], d[1::2, 3], d[1::2, 4]

    return _newton(*_distorted_normalised(matrix, pixels), miss_and_jacobian)


def _distorted_normalised(matrix: Array, pixels: Array) -> tuple[Array, Array]:
    """Pixels (N, 2) through the inverse intrinsic matrix alone: (x, y) before undistortion."""
    yd = (pixels[:, 1] - matrix[1, 2]) / matrix[1, 1]
    xd = (pixels[:, 0] - matrix[0, 2] - matrix[0, 1] * yd) / matrix[0, 0]
    return xd, yd


def _newton(
    xd: Array, yd: Array, miss_and_jacobian: Callable[[Array, Array], tuple[Array, Array, Array, Array, Array, Array]]
) -> Array | None:
    """Newton's method from (xd, yd) on a residual (its x and y, and the 2x2 Jacobian a b / c d, per
    point); (N, 2) once no point moves more than TOLERANCE, None if that does not happen."""
    x, y = xd.copy(), yd.copy()
    # A lens model that does not invert (a typo in its coefficients) overflows here: the finite check below
    # reports that, in one line, without NumPy's warnings before it.
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for _ in range(MAX_STEPS):
            miss_x, miss_y, a, b, c, d = miss_and_jacobian(x, y)
            det = a * d - b * c
            step_x = (d * miss_x - b * miss_y) / det
            step_y = (a * miss_y - c * miss_x) / det
            x -= step_x
            y -= step_y
            # np.max, not max(): a NaN in either step must not pass for convergence.
            moved = float(np.max([np.abs(step_x).max(), np.abs(step_y).max()]))
            if not np.isfinite(moved):
                return None
            if moved < TOLERANCE:
                return np.column_stack([x, y])
    return None
