"""Calibration results as text an operator reads, and as JSON a script reads.

Each report leads with the figure that says whether to trust the result, then
the details that say why not: per-view errors with outliers marked, the image
coverage grid, rejected frames with their reasons, per-observation residuals.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from typing import Any

import numpy as np

from trackerd.calibration.health import HealthFigures
from trackerd.calibration.intrinsics import IntrinsicsResult
from trackerd.calibration.stereo import StereoResult
from trackerd.calibration.wall import WallFit
from trackerd.geometry.wall import WallFrame

GOOD_RMS_PX = 0.5
"""Above this RMS reprojection error a calibration deserves a second look."""
GOOD_COVERAGE = 0.6


def _r(value: float, digits: int = 4) -> float:
    return round(float(value), digits)


def reason_kind(reason: str) -> str:
    """The kind of a rejection, without its particulars: 'too similar to an accepted view'."""
    kind = reason.split(":")[0].split(" (")[0]
    return "too similar to an accepted view" if kind.startswith("too similar") else kind


def rejections_summary(rejected: Sequence[tuple[str, str]]) -> list[str]:
    """Rejected frames grouped by kind of reason: ``12 x no whole board found by any detector``."""
    kinds = Counter(reason_kind(reason) for _, reason in rejected)
    return [f"{count} x {kind}" for kind, count in kinds.most_common()]


# --------------------------------------------------------------------------- intrinsics


def intrinsics_json(
    result: IntrinsicsResult, rejected: Sequence[tuple[str, str]], warnings: Sequence[str] = ()
) -> dict[str, Any]:
    fx, fy = result.focal_px
    cx, cy = result.principal_point_px
    return {
        "rms_px": _r(result.rms_px),
        "views": [
            {"name": name, "rms_px": _r(err), "outlier": i in result.outliers, "detector": detector}
            for i, (name, err, detector) in enumerate(
                zip(result.view_names, result.per_view_rms_px, result.view_detectors, strict=True)
            )
        ],
        "dropped": list(result.dropped),
        "corners": result.corners,
        "fx_px": _r(fx, 3),
        "fy_px": _r(fy, 3),
        "cx_px": _r(cx, 3),
        "cy_px": _r(cy, 3),
        "distortion": [float(d) for d in result.distortion],
        "std_px": {
            "fx": _r(result.std_matrix_px[0], 3),
            "fy": _r(result.std_matrix_px[1], 3),
            "cx": _r(result.std_matrix_px[2], 3),
            "cy": _r(result.std_matrix_px[3], 3),
        },
        "coverage": result.coverage.to_json(),
        "rejected": [{"name": n, "reason": r} for n, r in rejected],
        "warnings": [*quality_warnings(result.rms_px, result.coverage.fraction), *warnings],
    }


def intrinsics_text(
    camera_id: str, result: IntrinsicsResult, rejected: Sequence[tuple[str, str]], warnings: Sequence[str] = ()
) -> str:
    fx, fy = result.focal_px
    cx, cy = result.principal_point_px
    sd = result.std_matrix_px
    lines = [
        f"camera {camera_id}: RMS reprojection error {result.rms_px:.3f} px over {result.corners} corners"
        f" in {len(result.view_names)} views",
        f"  focal length fx {fx:.2f} +- {sd[0]:.2f} px, fy {fy:.2f} +- {sd[1]:.2f} px;"
        f" principal point ({cx:.2f} +- {sd[2]:.2f}, {cy:.2f} +- {sd[3]:.2f}) px",
        "  distortion " + " ".join(f"{d:+.6f}" for d in result.distortion) + "  (k1 k2 p1 p2 [k3 ...])",
        "  per-view RMS (px):",
    ]
    views = zip(result.view_names, result.per_view_rms_px, result.view_detectors, strict=True)
    for i, (name, err, detector) in enumerate(views):
        found_by = f"  ({detector})" if detector else ""
        flag = "  <- outlier: retake or drop it (--drop-outliers)" if i in result.outliers else ""
        lines.append(f"    {name or f'view {i + 1}':<28} {err:.3f}{found_by}{flag}")
    if result.dropped:
        lines.append(f"  dropped as outliers: {', '.join(result.dropped)}")
    lines.append(f"  image coverage {result.coverage.fraction * 100:.0f} % ('#' = corners seen):")
    lines += [f"    {row}" for row in result.coverage.ascii().splitlines()]
    missing = result.coverage.missing_regions()
    if missing:
        lines.append(f"  not covered: {', '.join(missing)}; distortion there is extrapolated")
    if rejected:
        lines.append(f"  rejected frames: {'; '.join(rejections_summary(rejected))}")
    found = quality_warnings(result.rms_px, result.coverage.fraction)
    lines += [f"  WARNING: {warning}" for warning in (*found, *warnings)]
    return "\n".join(lines)


def quality_warnings(rms_px: float, coverage: float = 1.0) -> list[str]:
    """What about a result is worth a second look (the text report prefixes each with WARNING;
    ``--json`` lists them as ``warnings``)."""
    out = []
    if rms_px > GOOD_RMS_PX:
        out.append(
            f"RMS {rms_px:.2f} px is high (expect 0.1 to 0.3 px): check the board"
            " spec, focus, motion blur and outlier views"
        )
    if coverage < GOOD_COVERAGE:
        out.append(
            f"the corners cover only {coverage * 100:.0f} % of the image; add views"
            " with the board near the edges and corners"
        )
    return out


# --------------------------------------------------------------------------- stereo


def stereo_json(result: StereoResult, rejected: Sequence[tuple[str, str]], world_frame: str) -> dict[str, Any]:
    yaw, pitch, roll = result.relative_ypr_deg
    return {
        "rms_px": _r(result.rms_px),
        "epipolar_rms_px": _r(result.epipolar_rms_px),
        "baseline_m": _r(result.baseline_m, 6),
        "rotation_deg": _r(result.rotation_deg),
        "relative_yaw_pitch_roll_deg": [_r(yaw), _r(pitch), _r(roll)],
        "camera2_centre_in_camera1_m": [_r(v, 6) for v in result.camera2_centre_m],
        "pairs": [
            {"name": name, "rms_px": _r(err), "epipolar_px": _r(epi), "outlier": i in result.outliers}
            for i, (name, err, epi) in enumerate(
                zip(result.pair_names, result.per_pair_rms_px, result.per_pair_epipolar_px, strict=True)
            )
        ],
        "rejected": [{"name": n, "reason": r} for n, r in (*result.rejected, *rejected)],
        "world_frame": world_frame,
    }


def stereo_text(
    ids: tuple[str, str],
    result: StereoResult,
    rejected: Sequence[tuple[str, str]],
    world_frame: str,
    warnings: Sequence[str] = (),
) -> str:
    yaw, pitch, roll = result.relative_ypr_deg
    c = result.camera2_centre_m
    lines = [
        f"stereo {ids[0]} -> {ids[1]}: RMS reprojection error {result.rms_px:.3f} px, epipolar error"
        f" {result.epipolar_rms_px:.3f} px (RMS) over {len(result.pair_names)} pairs",
        f"  baseline {result.baseline_m:.4f} m; {ids[1]} at ({c[0]:+.4f}, {c[1]:+.4f}, {c[2]:+.4f}) m"
        f" in {ids[0]}'s frame",
        f"  relative rotation {result.rotation_deg:.3f} deg: yaw {yaw:+.3f}, pitch {pitch:+.3f}, roll {roll:+.3f} deg"
        f" ({ids[1]}'s axes seen from {ids[0]}, eq. 18-21)",
        "  per-pair RMS / epipolar error (px):",
    ]
    for i, (name, err, epi) in enumerate(
        zip(result.pair_names, result.per_pair_rms_px, result.per_pair_epipolar_px, strict=True)
    ):
        flag = "  <- outlier" if i in result.outliers else ""
        lines.append(f"    {name:<24} {err:.3f} / {epi:.3f}{flag}")
    for name, reason in result.rejected:
        lines.append(f"  left out {name}: {reason}")
    if rejected:
        lines.append(f"  rejected frames: {'; '.join(rejections_summary(rejected))}")
    lines.append(f"  world frame: {world_frame}")
    lines += [f"  WARNING: {warning}" for warning in (*quality_warnings(result.rms_px), *warnings)]
    return "\n".join(lines)


# --------------------------------------------------------------------------- wall


def wall_fit_json(fit: WallFit, nominal_size_m: tuple[float, float]) -> dict[str, Any]:
    return {
        "rms_mm": _r(fit.rms_mm, 3),
        "size_m": [_r(fit.width_m, 5), _r(fit.height_m, 5)],
        "size_fitted": fit.size_fitted,
        "implied_size_m": None if fit.implied_size_m is None else [_r(v, 5) for v in fit.implied_size_m],
        "nominal_size_m": [_r(v, 5) for v in nominal_size_m],
        "origin_m": [_r(v, 5) for v in fit.origin_m],
        "normal": [_r(v, 6) for v in fit.rotation[:, 2]],
        "residuals": [
            {
                "label": r.label,
                "kind": r.kind,
                "plane_mm": None if r.plane_mm is None else _r(r.plane_mm, 2),
                "in_plane_mm": None if r.in_plane_mm is None else _r(r.in_plane_mm, 2),
                "miss_mm": None if r.miss_mm is None else _r(r.miss_mm, 2),
                "used": r.used,
            }
            for r in fit.residuals
        ],
    }


def wall_fit_text(fit: WallFit, nominal_size_m: tuple[float, float], flag_mm: float = 10.0) -> str:
    w, h = fit.width_m, fit.height_m
    nw, nh = nominal_size_m
    o = fit.origin_m
    lines = [
        f"wall: RMS residual {fit.rms_mm:.2f} mm over {sum(r.used for r in fit.residuals)} observations"
        + (
            f" ({sum(not r.used for r in fit.residuals)} left out as outliers)"
            if not all(r.used for r in fit.residuals)
            else ""
        ),
        f"  size {w:.4f} x {h:.4f} m"
        + (" (solved for)" if fit.size_fitted else " (as configured)")
        + (
            f"; the targets imply {fit.implied_size_m[0]:.4f} x {fit.implied_size_m[1]:.4f} m"
            f" ({(fit.implied_size_m[0] - nw) * 1000:+.1f} / {(fit.implied_size_m[1] - nh) * 1000:+.1f} mm"
            f" from the configured {nw:.4f} x {nh:.4f} m)"
            if fit.implied_size_m is not None
            else ""
        ),
        f"  bottom-left corner at ({o[0]:+.4f}, {o[1]:+.4f}, {o[2]:+.4f}) m in the cameras' frame so far",
        "  residuals (mm): plane = distance from the fitted plane, in-plane = from the target's place,"
        " miss = pointer line to target",
    ]
    for r in fit.residuals:
        parts = []
        if r.plane_mm is not None:
            parts.append(f"plane {r.plane_mm:+7.2f}")
        if r.in_plane_mm is not None:
            parts.append(f"in-plane {r.in_plane_mm:6.2f}")
        if r.miss_mm is not None:
            parts.append(f"miss {r.miss_mm:6.2f}")
        flag = "  <- left out as an outlier" if not r.used else "  <- check this one" if r.worst_mm > flag_mm else ""
        lines.append(f"    {r.kind:<8} {r.label:<12} {', '.join(parts)}{flag}")
    implied = fit.implied_size_m
    if implied is not None and (abs(implied[0] - nw) > 0.02 or abs(implied[1] - nh) > 0.02):
        lines.append(
            "  WARNING: the implied size differs from the configured one by more than 20 mm:"
            " a target touched in the wrong place, or the display is not where it is said to be"
        )
    return "\n".join(lines)


def measured_wall_text(frame: WallFrame, points: np.ndarray) -> str:
    residuals = frame.fit_residuals_m if frame.fit_residuals_m is not None else np.zeros(len(points))
    lines = [
        f"wall from {len(points)} measured points: plane normal ({', '.join(f'{v:+.4f}' for v in frame.normal)}),"
        f" size {frame.width_m:.4f} x {frame.height_m:.4f} m",
        "  distance of each point from the fitted plane (mm): " + ", ".join(f"{r * 1000:+.2f}" for r in residuals),
    ]
    if len(points) == 3:
        lines.append("  (three points fix the plane exactly: measure a fourth to check them)")
    return "\n".join(lines)


# --------------------------------------------------------------------------- health


def health_text(figures: HealthFigures, frames: int) -> str:
    if figures.fixes == 0:
        return f"check: no pointer fixes in {frames} frame pairs (is the pointer in view of both cameras?)"
    verdict = (
        "SUSPECT: " + (figures.reason or "")
        if figures.suspect
        else ("OK" if figures.reason is None else f"undecided: {figures.reason}")
    )
    return "\n".join(
        [
            f"check: {figures.fixes} pointer fixes from {frames} frame pairs: {verdict}",
            f"  ray gap (how far the cameras' rays through an end miss each other): median {figures.gap_p50_mm:.2f} mm,"
            f" p95 {figures.gap_p95_mm:.2f} mm, max {figures.gap_max_mm:.2f} mm",
            f"  reprojection error of the triangulated ends: median {figures.reprojection_p50_px:.2f} px,"
            f" p95 {figures.reprojection_p95_px:.2f} px, max {figures.reprojection_max_px:.2f} px",
        ]
    )
