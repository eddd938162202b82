"""One camera's lens: focal lengths, principal point and distortion from board views.

A wrapper around ``cv2.calibrateCameraExtended`` that says how good the answer
is: the RMS reprojection error over all corners, each view's own RMS (a view
much worse than the rest is an outlier: a board that moved during the
exposure, a misnumbered corner), the standard errors OpenCV estimates for each
parameter, and how much of the image the corners covered.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.calibration import CalibrationError
from trackerd.calibration.board import BoardView
from trackerd.calibration.views import CoverageGrid
from trackerd.config.models import OpenCVIntrinsics
from trackerd.geometry.lens_inverse import invert_lens

Array = NDArray[np.float64]

MIN_VIEWS = 8
"""Fewer views than this leave the distortion poorly determined; 15 to 30 are better."""
MIN_VIEWS_FLOOR = 6
"""Fewer views than this leave a five-term lens poorly pinned (focal length and k3 trade off): the
command asks for --force below it."""

DISTORTION_TERMS = (4, 5, 8)
"""4: k1 k2 p1 p2; 5: and k3 (the default); 8: OpenCV's rational model (wide-angle lenses)."""

_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)


@dataclass(frozen=True)
class IntrinsicsResult:
    """A camera's calibrated lens and the figures that say how far to trust it."""

    matrix: Array
    """3x3 intrinsic matrix K."""
    distortion: Array
    """OpenCV distortion coefficients (4, 5 or 8)."""
    image_size: tuple[int, int]
    rms_px: float
    """RMS reprojection error over every corner of every view used."""
    per_view_rms_px: Array
    """(V,) RMS of each view used."""
    view_names: tuple[str, ...]
    view_detectors: tuple[str, ...]
    """Which detector found the board in each view used ('' where not recorded)."""
    std_matrix_px: Array
    """Standard errors of (fx, fy, cx, cy) estimated by OpenCV, in pixels."""
    std_distortion: Array
    rvecs: Array
    """(V, 3) board-to-camera rotations of the views used."""
    tvecs_m: Array
    """(V, 3) board-to-camera translations."""
    outliers: tuple[int, ...]
    """Indices (into the views used) of views whose error stands out."""
    dropped: tuple[str, ...]
    """Names of views dropped as outliers before this result (with ``drop_outliers``)."""
    coverage: CoverageGrid
    corners: int
    """Corners used in all."""

    @property
    def focal_px(self) -> tuple[float, float]:
        return float(self.matrix[0, 0]), float(self.matrix[1, 1])

    @property
    def principal_point_px(self) -> tuple[float, float]:
        return float(self.matrix[0, 2]), float(self.matrix[1, 2])

    def to_config(self) -> OpenCVIntrinsics:
        return OpenCVIntrinsics(
            model="opencv",
            fx_px=float(self.matrix[0, 0]),
            fy_px=float(self.matrix[1, 1]),
            cx_px=float(self.matrix[0, 2]),
            cy_px=float(self.matrix[1, 2]),
            distortion=tuple(float(d) for d in self.distortion),
        )


def outlier_views(per_view_rms_px: Array) -> tuple[int, ...]:
    """Views whose RMS exceeds both three times the median and the median plus 0.2 px.

    The two conditions together flag a view that is clearly worse than the rest
    without flagging the normal spread of good views (0.05 to 0.15 px) or every
    view of a lens the model fits poorly.
    """
    errors = np.asarray(per_view_rms_px, dtype=np.float64)
    if len(errors) < 4:
        return ()
    median = float(np.median(errors))
    limit = max(3.0 * median, median + 0.2)
    return tuple(int(i) for i in np.nonzero(errors > limit)[0])


def calibrate_intrinsics(
    views: Sequence[BoardView],
    *,
    distortion_terms: int = 5,
    min_views: int = MIN_VIEWS,
    drop_outliers: bool = False,
    initial: tuple[Array, Array] | None = None,
) -> IntrinsicsResult:
    """Calibrate one camera from board views (all of the same image size).

    With ``drop_outliers`` the views flagged by :func:`outlier_views` are removed
    and the calibration repeated once; their names are listed in ``dropped``.
    Raises CalibrationError when there are too few views or OpenCV cannot solve.
    """
    views = list(views)
    if distortion_terms not in DISTORTION_TERMS:
        raise ValueError(f"distortion_terms must be one of {DISTORTION_TERMS}")
    check_views(views, min_views)
    result = _calibrate(views, distortion_terms, initial, ())
    if drop_outliers and result.outliers:
        dropped = tuple(views[i].name or f"view {i + 1}" for i in result.outliers)
        kept = [v for i, v in enumerate(views) if i not in set(result.outliers)]
        check_views(kept, min_views, after=f"dropping {len(dropped)} outlier view(s)")
        result = _calibrate(kept, distortion_terms, initial, dropped)
    return result


def check_views(views: Sequence[BoardView], min_views: int, after: str = "") -> None:
    """Raise CalibrationError for too few views or views of different image sizes."""
    suffix = f" after {after}" if after else ""
    if len(views) < min_views:
        raise CalibrationError(
            f"too few usable views: {len(views)}{suffix}, need at least {min_views}"
            " (15 to 30 views of the board at different places and angles are better)"
        )
    size = views[0].image_size
    for view in views[1:]:
        if view.image_size != size:
            raise CalibrationError(
                f"{view.name or 'a view'}: image is {view.image_size[0]}x{view.image_size[1]},"
                f" but {views[0].name or 'the first view'} is {size[0]}x{size[1]};"
                " all views of one camera must have the same size"
            )


def _calibrate(
    views: list[BoardView], terms: int, initial: tuple[Array, Array] | None, dropped: tuple[str, ...]
) -> IntrinsicsResult:
    size = views[0].image_size
    object_points = [v.object_points_m.astype(np.float32) for v in views]
    image_points = [v.image_points_px.astype(np.float32).reshape(-1, 1, 2) for v in views]
    flags = 0
    if terms == 4:
        flags |= cv2.CALIB_FIX_K3
    elif terms == 8:
        flags |= cv2.CALIB_RATIONAL_MODEL
    if initial is not None:
        matrix0 = np.array(initial[0], dtype=np.float64)
        dist0 = np.zeros(max(terms, 5))
        dist0[: min(len(initial[1]), len(dist0))] = np.asarray(initial[1])[: len(dist0)]
        flags |= cv2.CALIB_USE_INTRINSIC_GUESS
    else:
        matrix0 = np.eye(3)
        dist0 = np.zeros(max(terms, 5))
    try:
        (rms, matrix, dist, rvecs, tvecs, std_intr, _, per_view) = cv2.calibrateCameraExtended(
            object_points, image_points, size, matrix0, dist0, flags=flags, criteria=_CRITERIA
        )
    except cv2.error as err:
        raise CalibrationError(f"OpenCV could not calibrate from these views: {err.err or err}") from err
    dist = np.asarray(dist, dtype=np.float64).ravel()[:terms]
    std = np.asarray(std_intr, dtype=np.float64).ravel()
    per_view = np.asarray(per_view, dtype=np.float64).ravel()
    if not np.isfinite(rms) or not np.all(np.isfinite(matrix)):
        raise CalibrationError("the calibration did not converge; add views with the board tilted")
    coverage = CoverageGrid(*size)
    for view in views:
        coverage.add(view.image_points_px)
    return IntrinsicsResult(
        matrix=np.asarray(matrix, dtype=np.float64),
        distortion=dist,
        image_size=size,
        rms_px=float(rms),
        per_view_rms_px=per_view,
        view_names=tuple(v.name for v in views),
        view_detectors=tuple(v.meta.get("detector", "") for v in views),
        std_matrix_px=std[:4],
        std_distortion=std[4 : 4 + terms],
        rvecs=np.asarray(rvecs, dtype=np.float64).reshape(-1, 3),
        tvecs_m=np.asarray(tvecs, dtype=np.float64).reshape(-1, 3),
        outliers=outlier_views(per_view),
        dropped=dropped,
        coverage=coverage,
        corners=int(sum(len(v.ids) for v in views)),
    )


def lens_model_difference_px(
    matrix_a: Array,
    dist_a: Array,
    matrix_b: Array,
    dist_b: Array,
    image_size: tuple[int, int],
    step_px: int = 40,
) -> tuple[float, float]:
    """RMS and largest disagreement (pixels) between two lens models' rays over the image, up to a rotation.

    Each pixel of a grid is back-projected through both models; the ray bundles
    are aligned by the best rotation (a small rotation of the camera is what a
    principal point shift mostly amounts to, and the extrinsics absorb it), and
    the remaining angle between the two rays of each pixel, times the focal
    length, is how far apart the models put it. This compares whole lens
    models, where comparing distortion coefficients one by one is meaningless
    (they trade off against each other).
    """
    width, height = image_size
    xs, ys = np.meshgrid(
        np.arange(0, width, step_px, dtype=np.float64), np.arange(0, height, step_px, dtype=np.float64)
    )
    pixels = np.column_stack([xs.ravel(), ys.ravel()])
    rays = []
    for matrix, dist in ((matrix_a, dist_a), (matrix_b, dist_b)):
        norm = invert_lens(matrix, dist, pixels)
        ray = np.column_stack([norm, np.ones(len(norm))])
        rays.append(ray / np.linalg.norm(ray, axis=1, keepdims=True))
    u, _, vt = np.linalg.svd(rays[1].T @ rays[0])
    fix = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
    rotation = (u @ fix @ vt).T  # rotation @ b ~ a
    aligned = rays[1] @ rotation.T
    angles = np.arccos(np.clip(np.sum(aligned * rays[0], axis=1), -1.0, 1.0))
    distances = angles * float(matrix_a[0, 0] + matrix_a[1, 1]) / 2.0
    return float(np.sqrt(np.mean(distances**2))), float(np.max(distances))
