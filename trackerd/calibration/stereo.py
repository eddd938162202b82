"""Camera 2 relative to camera 1, from synchronized pairs of board views.

The report's world frame is camera 1's (section 3.1): camera 2 is "obtained
from the former through rotation and translations". ``cv2.stereoCalibrate``
finds that rotation R and translation T (``x_cam2 = R x_cam1 + T``) with each
camera's intrinsics held fixed by default (they come from the intrinsics step,
where close-up views pin them far better than a few stereo pairs can).

Before solving, every pair is checked for being in sync: from each camera's
own view of the board (``solvePnP``) a pair implies a relative pose, and a pair
whose relative pose disagrees with the others' had its two frames taken at
different instants (or of different boards). After solving, the figures are the
stereo RMS reprojection error, the baseline length, the relative rotation as
angles, and the epipolar error of the pairs: how far each corner in one image
lies from the epipolar line of its partner, which is what triangulation feels.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.calibration import CalibrationError
from trackerd.calibration.board import BoardView
from trackerd.calibration.intrinsics import outlier_views
from trackerd.geometry.lens_inverse import invert_lens
from trackerd.geometry.rotation import rotation_angle_deg, rotation_from_rvec, rvec_from_rotation

Array = NDArray[np.float64]

MIN_PAIRS = 5
"""Fewer pairs than this give a relative pose that a single bad pair can move."""
MIN_PAIRS_FLOOR = 3
"""Fewer pairs than this leave no way to tell a pair out of sync from the others (check_sync needs 3)."""

MIN_SHARED_CORNERS = 8

SYNC_TRANSLATION_M = 0.005
SYNC_ROTATION_DEG = 0.1
"""A pair's implied relative pose may differ from the median by five times the typical
difference, and at least by these, before it is called out of sync."""

SYNC_SPREAD_M = 0.02
SYNC_SPREAD_DEG = 0.5
"""When the typical pair differs from the median pose by more than these, most pairs are out of
sync and no majority can be trusted (pairs in sync agree within about a millimetre and 0.02
degrees on the simulated DataWall)."""

_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)


@dataclass(frozen=True)
class Lens:
    """One camera's intrinsics: K (3, 3) and OpenCV distortion coefficients."""

    matrix: Array
    distortion: Array

    @property
    def focal_px(self) -> float:
        return float((self.matrix[0, 0] + self.matrix[1, 1]) / 2.0)


@dataclass(frozen=True)
class StereoPair:
    """The corners both cameras saw in one synchronized pair."""

    name: str
    ids: NDArray[np.int64]
    object_points_m: Array
    """(N, 3) board coordinates."""
    points1_px: Array
    """(N, 2) in camera 1."""
    points2_px: Array
    """(N, 2) in camera 2."""


def match_views(view1: BoardView, view2: BoardView, name: str = "") -> StereoPair | None:
    """The corners two views of one board share, or None when fewer than MIN_SHARED_CORNERS."""
    common, i1, i2 = np.intersect1d(view1.ids, view2.ids, return_indices=True)
    if len(common) < MIN_SHARED_CORNERS:
        return None
    return StereoPair(
        name or view1.name, common, view1.object_points_m[i1], view1.image_points_px[i1], view2.image_points_px[i2]
    )


@dataclass(frozen=True)
class SyncCheck:
    """Which pairs agree on the relative pose, and the median pose they agree on."""

    kept: tuple[StereoPair, ...]
    rejected: tuple[tuple[str, str], ...]
    """(pair name, reason) for pairs out of sync."""
    rotation: Array
    translation_m: Array


def board_pose(pair_points: Array, object_points: Array, lens: Lens) -> tuple[Array, Array]:
    """Board-to-camera rotation (3, 3) and translation (3,) from one view's corners."""
    ok, rvec, tvec = cv2.solvePnP(
        object_points.astype(np.float64),
        pair_points.astype(np.float64),
        lens.matrix,
        lens.distortion,
        flags=cv2.SOLVEPNP_IPPE,
    )
    if not ok:
        ok, rvec, tvec = cv2.solvePnP(
            object_points.astype(np.float64), pair_points.astype(np.float64), lens.matrix, lens.distortion
        )
    if not ok:
        raise CalibrationError("solvePnP failed on a board view")
    rvec, tvec = cv2.solvePnPRefineLM(
        object_points.astype(np.float64), pair_points.astype(np.float64), lens.matrix, lens.distortion, rvec, tvec
    )
    return rotation_from_rvec(np.asarray(rvec, dtype=np.float64).ravel()), np.asarray(tvec, dtype=np.float64).ravel()


def check_sync(pairs: Sequence[StereoPair], lens1: Lens, lens2: Lens) -> SyncCheck:
    """Split pairs into those whose two views agree with the others on the cameras' relative pose.

    Raises CalibrationError when most pairs disagree (the two cameras' images do
    not belong together at all).
    """
    if len(pairs) < 3:
        raise CalibrationError(f"need at least 3 pairs to check they are in sync, got {len(pairs)}")
    rotations, translations = [], []
    for pair in pairs:
        r1, t1 = board_pose(pair.points1_px, pair.object_points_m, lens1)
        r2, t2 = board_pose(pair.points2_px, pair.object_points_m, lens2)
        relative = r2 @ r1.T
        rotations.append(relative)
        translations.append(t2 - relative @ t1)
    translations_arr = np.array(translations)
    median_t = np.median(translations_arr, axis=0)
    median_r = rotation_from_rvec(np.median(np.array([rvec_from_rotation(r) for r in rotations]), axis=0))
    dt = np.linalg.norm(translations_arr - median_t, axis=1)
    dr = np.array([rotation_angle_deg(r @ median_r.T) for r in rotations])
    if float(np.median(dt)) > SYNC_SPREAD_M or float(np.median(dr)) > SYNC_SPREAD_DEG:
        raise CalibrationError(
            f"pairs out of sync: the pairs disagree on where the cameras are (typically by"
            f" {float(np.median(dt)) * 1000:.0f} mm and {float(np.median(dr)):.1f} degrees; in-sync pairs agree"
            " within a few mm and a few hundredths of a degree): were both images of each pair taken at the"
            " same instant, of the same board?"
        )
    limit_t = max(5.0 * float(np.median(dt)), SYNC_TRANSLATION_M)
    limit_r = max(5.0 * float(np.median(dr)), SYNC_ROTATION_DEG)
    kept, rejected = [], []
    for pair, t_off, r_off in zip(pairs, dt, dr, strict=True):
        if t_off > limit_t or r_off > limit_r:
            rejected.append(
                (
                    pair.name,
                    f"out of sync: its two views put the cameras {t_off * 1000:.0f} mm and"
                    f" {r_off:.2f} degrees away from where the other pairs do",
                )
            )
        else:
            kept.append(pair)
    if len(kept) < len(pairs) / 2:
        raise CalibrationError(
            f"pairs out of sync: {len(rejected)} of {len(pairs)} pairs disagree on where the cameras are"
            " (were both images of each pair taken at the same instant, of the same board?)"
        )
    return SyncCheck(tuple(kept), tuple(rejected), median_r, median_t)


@dataclass(frozen=True)
class StereoResult:
    """Camera 2's pose in camera 1's frame, and how well the pairs support it."""

    rotation: Array
    """R: camera-1 coordinates to camera-2 coordinates (``x2 = R x1 + T``)."""
    translation_m: Array
    """T, (3,)."""
    rms_px: float
    """Stereo RMS reprojection error over both cameras' corners."""
    per_pair_rms_px: Array
    """(P,) RMS of each pair used (both cameras)."""
    pair_names: tuple[str, ...]
    epipolar_rms_px: float
    """RMS distance of corners from their partners' epipolar lines (both directions)."""
    per_pair_epipolar_px: Array
    outliers: tuple[int, ...]
    rejected: tuple[tuple[str, str], ...]
    """Pairs left out before solving, with the reason."""
    lens1: Lens
    lens2: Lens
    corners: int

    @property
    def baseline_m(self) -> float:
        """Distance between the two optical centres."""
        return float(np.linalg.norm(self.translation_m))

    @property
    def rotation_deg(self) -> float:
        """Total angle between the two cameras' orientations."""
        return rotation_angle_deg(self.rotation)

    @property
    def camera2_centre_m(self) -> Array:
        """Camera 2's optical centre in camera 1's frame."""
        return -self.rotation.T @ self.translation_m

    @property
    def relative_ypr_deg(self) -> tuple[float, float, float]:
        """Camera 2's orientation seen from camera 1: yaw (about y), pitch (about x), roll (about z).

        Composed as the report's pan-tilt head turns (eq. 18-21): camera 2's axes
        in camera 1's frame are ``Ry(yaw) Rx(pitch) Rz(roll)``.
        """
        return ypr_from_matrix(self.rotation.T)


BASELINE_TOLERANCE = 0.03
"""A calibrated baseline further than this fraction from the one the rig already states is
warned about: the board's scale is the baseline's scale, and a wrong square size is the usual
cause (a 60 mm board declared as 100 mm gives a baseline 40 % short)."""


def baseline_warning(
    calibrated_m: float, stated_m: float, square_mm: float, tolerance: float = BASELINE_TOLERANCE
) -> str | None:
    """A warning when ``calibrated_m`` differs from the rig's ``stated_m`` by more than ``tolerance``
    (a fraction), with the square size that would reconcile them; None when they agree."""
    if stated_m <= 0 or not np.isfinite(calibrated_m):
        return None
    ratio = calibrated_m / stated_m
    if abs(ratio - 1.0) <= tolerance:
        return None
    return (
        f"the calibrated baseline {calibrated_m:.4f} m differs from the rig's {stated_m:.4f} m"
        f" by {(ratio - 1.0) * 100:+.1f} % (more than {tolerance * 100:.0f} %). The board's square size sets"
        f" the baseline's scale: with the rig's baseline the squares would be {square_mm / ratio:.1f} mm, not"
        f" {square_mm:g} mm. Check --board against the printed board; if the cameras were moved, ignore this"
    )


def ypr_from_matrix(m: Array) -> tuple[float, float, float]:
    """Angles (degrees) of ``m = Ry(yaw) Rx(pitch) Rz(roll)`` (eq. 18-21, about the camera's own axes)."""
    pitch = np.arcsin(np.clip(-m[1, 2], -1.0, 1.0))
    if abs(np.cos(pitch)) < 1e-9:
        return float(np.degrees(np.arctan2(-m[2, 0], m[0, 0]))), float(np.degrees(pitch)), 0.0
    yaw = np.arctan2(m[0, 2], m[2, 2])
    roll = np.arctan2(m[1, 0], m[1, 1])
    return float(np.degrees(yaw)), float(np.degrees(pitch)), float(np.degrees(roll))


def calibrate_stereo(
    pairs: Sequence[StereoPair],
    lens1: Lens,
    lens2: Lens,
    image_size: tuple[int, int],
    *,
    refine_intrinsics: bool = False,
    min_pairs: int = MIN_PAIRS,
) -> StereoResult:
    """Solve camera 2's pose relative to camera 1 from synchronized pairs.

    Pairs out of sync are left out (listed in ``rejected``); intrinsics stay fixed
    unless ``refine_intrinsics``. Raises CalibrationError for too few pairs.
    """
    pairs = list(pairs)
    if len(pairs) < min_pairs:
        raise CalibrationError(
            f"too few pairs with the board seen by both cameras: {len(pairs)}, need at least {min_pairs}"
            " (10 to 20 pairs across the shared view are better)"
        )
    sync = check_sync(pairs, lens1, lens2)
    kept = list(sync.kept)
    if len(kept) < min_pairs:
        raise CalibrationError(
            f"too few pairs in sync: {len(kept)} of {len(pairs)}, need at least {min_pairs}; "
            + "; ".join(f"{name}: {reason}" for name, reason in sync.rejected[:3])
        )
    object_points = [p.object_points_m.astype(np.float32) for p in kept]
    points1 = [p.points1_px.astype(np.float32).reshape(-1, 1, 2) for p in kept]
    points2 = [p.points2_px.astype(np.float32).reshape(-1, 1, 2) for p in kept]
    flags = cv2.CALIB_USE_EXTRINSIC_GUESS
    flags |= cv2.CALIB_USE_INTRINSIC_GUESS if refine_intrinsics else cv2.CALIB_FIX_INTRINSIC
    try:
        out = cv2.stereoCalibrateExtended(
            object_points,
            points1,
            points2,
            lens1.matrix.copy(),
            lens1.distortion.copy(),
            lens2.matrix.copy(),
            lens2.distortion.copy(),
            image_size,
            sync.rotation.copy(),
            sync.translation_m.reshape(3, 1).copy(),
            flags=flags,
            criteria=_CRITERIA,
        )
    except cv2.error as err:
        raise CalibrationError(f"OpenCV could not solve the stereo pose: {err.err or err}") from err
    rms, k1, d1, k2, d2, rotation_cv, translation_cv = out[:7]
    per_view = np.asarray(out[11], dtype=np.float64).reshape(len(kept), -1)
    per_pair = np.sqrt(np.mean(per_view**2, axis=1))
    lens1 = Lens(np.asarray(k1, dtype=np.float64), np.asarray(d1, dtype=np.float64).ravel())
    lens2 = Lens(np.asarray(k2, dtype=np.float64), np.asarray(d2, dtype=np.float64).ravel())
    rotation = np.asarray(rotation_cv, dtype=np.float64)
    translation = np.asarray(translation_cv, dtype=np.float64).ravel()
    epipolar = [epipolar_distances_px(p.points1_px, p.points2_px, lens1, lens2, rotation, translation) for p in kept]
    all_epipolar = np.concatenate(epipolar)
    return StereoResult(
        rotation=rotation,
        translation_m=translation,
        rms_px=float(rms),
        per_pair_rms_px=per_pair,
        pair_names=tuple(p.name for p in kept),
        epipolar_rms_px=float(np.sqrt(np.mean(all_epipolar**2))),
        per_pair_epipolar_px=np.array([float(np.sqrt(np.mean(e**2))) for e in epipolar]),
        outliers=outlier_views(per_pair),
        rejected=sync.rejected,
        lens1=lens1,
        lens2=lens2,
        corners=int(sum(len(p.ids) for p in kept)),
    )


def epipolar_distances_px(
    points1_px: Array, points2_px: Array, lens1: Lens, lens2: Lens, rotation: Array, translation_m: Array
) -> Array:
    """Symmetric epipolar distance of each correspondence (N,), in pixels.

    With undistorted normalised coordinates x1, x2 and the essential matrix
    ``E = [T]x R``, the epipolar line of x1 in image 2 is ``E x1``; the distance
    of x2 from it, scaled by camera 2's focal length, and the same the other way
    round, are averaged.
    """
    x1 = _normalised_h(points1_px, lens1)
    x2 = _normalised_h(points2_px, lens2)
    t = np.asarray(translation_m, dtype=np.float64)
    skew = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
    essential = skew @ rotation
    lines2 = x1 @ essential.T
    lines1 = x2 @ essential
    residual = np.sum(x2 * lines2, axis=1)
    d2 = np.abs(residual) / np.hypot(lines2[:, 0], lines2[:, 1]) * lens2.focal_px
    d1 = np.abs(residual) / np.hypot(lines1[:, 0], lines1[:, 1]) * lens1.focal_px
    return np.asarray((d1 + d2) / 2.0, dtype=np.float64)


def _normalised_h(points_px: Array, lens: Lens) -> Array:
    norm = invert_lens(lens.matrix, lens.distortion, points_px)
    return np.column_stack([norm, np.ones(len(norm))])
