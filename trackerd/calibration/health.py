"""Is the calibration still right? Ray gaps and reprojection errors of the tracked pointer.

With a correct calibration the two cameras' rays through an end of the pointer
nearly meet (about a millimetre on the simulated DataWall: centroid noise, and the
rod hiding part of each ball), and the triangulated ends project back onto the
detected centroids to about half a pixel. A camera that was bumped by a
tenth of a degree makes the rays miss each other by millimetres: the ray gap
(eq. 17's closest approach) jumps, and so does the reprojection error. Both
are measured on every fix, so drift is noticed during normal operation.

:class:`CalibrationHealth` is the daemon's streaming accumulator: O(1) per fix,
a bounded window of recent values, and a summary cheap enough to publish once a
second on the status topic. :func:`health_statistics` computes the same figures
for ``trackerd calibrate check`` over a whole run.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from trackerd.config.models import RigConfig
from trackerd.config.rig_geometry import camera_model
from trackerd.geometry.camera import CameraModel

if TYPE_CHECKING:
    from trackerd.locator import PointerFix

Array = NDArray[np.float64]

GAP_LIMIT_MM = 4.0
"""Median ray gap above which the calibration is suspect. On the simulated DataWall a correct
calibration gives a median of about 1.4 mm (the rod hiding part of each ball shifts its centroid
along the pointer, and the two cameras' shifts do not meet); one camera turned by 0.2 degrees
gives about 9 mm."""
REPROJECTION_LIMIT_PX = 1.5
"""Median reprojection error above which the calibration is suspect (correct: about 0.55 px on
the simulated DataWall; one camera turned by 0.2 degrees: about 3.6 px)."""
MIN_FIXES = 20
"""Fewer fixes than this say nothing either way."""


def ellipse_centre_px(camera: CameraModel, centre_m: Array, radius_m: float) -> Array:
    """Where a ball's image centre falls: the projection of its centre corrected for perspective.

    A sphere at camera coordinates (X, Y, Z) images as an ellipse centred at
    ``(X, Y) Z / (Z^2 - r^2)`` on the normalised image plane (see
    trackerd/geometry/pointer_line.py), not at ``(X, Y) / Z``; the detector
    measures the ellipse. Returns (2,) pixels, NaN when the ball is behind the camera.
    """
    in_cam = camera.to_camera_frame(np.asarray(centre_m, dtype=np.float64)[None])[0]
    if in_cam[2] <= radius_m:
        return np.full(2, np.nan)
    scale = in_cam[2] / (in_cam[2] ** 2 - radius_m**2)
    shifted_cam = np.array([in_cam[0] * scale, in_cam[1] * scale, 1.0])
    world = (shifted_cam - camera.translation_m) @ camera.rotation
    return np.asarray(camera.project(world[None])[0], dtype=np.float64)


def fix_figures(
    fix: PointerFix,
    cameras: Sequence[CameraModel],
    radius_m: float,
    front_colour: str,
    length_m: float | None = None,
    length_tolerance_m: float = 0.05,
) -> tuple[float, float] | None:
    """(worse ray gap in metres, worst reprojection error in pixels) of one locator fix, or None.

    ``fix`` is a :class:`trackerd.locator.PointerFix`; fixes without a line (an end
    not found) give None, and so do lines whose length is not the pointer's
    (``length_m``, when given): those are a wrong blob, not the calibration.
    Fixes rejected for their ray gap still count: a drifted calibration is exactly
    what makes the locator reject by ray gap.
    """
    line = getattr(fix, "line", None)
    if line is None:
        return None
    if length_m is not None and abs(line.length_m - length_m) > length_tolerance_m:
        return None
    back_colour = "blue" if front_colour == "red" else "red"
    worst = 0.0
    for camera, centroids in zip(cameras, fix.centroids_px, strict=True):
        for colour, centre in ((front_colour, line.front_m), (back_colour, line.back_m)):
            measured = centroids.get(colour)
            if measured is None:
                return None
            predicted = ellipse_centre_px(camera, centre, radius_m)
            if not np.all(np.isfinite(predicted)):
                return None
            worst = max(worst, float(np.linalg.norm(np.asarray(measured) - predicted)))
    return float(line.gap_m), worst


@dataclass(frozen=True)
class HealthFigures:
    """The distribution of ray gaps and reprojection errors over some fixes."""

    fixes: int
    gap_p50_mm: float | None
    gap_p95_mm: float | None
    gap_max_mm: float | None
    reprojection_p50_px: float | None
    reprojection_p95_px: float | None
    reprojection_max_px: float | None
    suspect: bool
    """Whether the figures say the calibration has drifted."""
    reason: str | None

    def to_json(self) -> dict[str, object]:
        def r(value: float | None, digits: int) -> float | None:
            return None if value is None else round(value, digits)

        return {
            "fixes": self.fixes,
            "ray_gap_mm": {"p50": r(self.gap_p50_mm, 3), "p95": r(self.gap_p95_mm, 3), "max": r(self.gap_max_mm, 3)},
            "reprojection_px": {
                "p50": r(self.reprojection_p50_px, 3),
                "p95": r(self.reprojection_p95_px, 3),
                "max": r(self.reprojection_max_px, 3),
            },
            "suspect": self.suspect,
            "reason": self.reason,
        }


def health_statistics(
    gaps_m: Iterable[float],
    reprojection_px: Iterable[float],
    *,
    gap_limit_mm: float = GAP_LIMIT_MM,
    reprojection_limit_px: float = REPROJECTION_LIMIT_PX,
    min_fixes: int = MIN_FIXES,
) -> HealthFigures:
    """Percentiles of ray gaps (metres in, millimetres out) and reprojection errors, and a verdict."""
    gaps = np.asarray(list(gaps_m), dtype=np.float64) * 1000.0
    reproj = np.asarray(list(reprojection_px), dtype=np.float64)
    if len(gaps) == 0:
        return HealthFigures(0, None, None, None, None, None, None, False, "no pointer fixes yet")
    g50, g95, gmax = (float(v) for v in (np.median(gaps), np.percentile(gaps, 95), gaps.max()))
    r50, r95, rmax = (float(v) for v in (np.median(reproj), np.percentile(reproj, 95), reproj.max()))
    reasons = []
    if len(gaps) >= min_fixes:
        if g50 > gap_limit_mm:
            reasons.append(f"median ray gap {g50:.2f} mm exceeds {gap_limit_mm:.2f} mm")
        if r50 > reprojection_limit_px:
            reasons.append(f"median reprojection error {r50:.2f} px exceeds {reprojection_limit_px:.2f} px")
    reason = (
        "; ".join(reasons)
        if reasons
        else (None if len(gaps) >= min_fixes else f"only {len(gaps)} fixes (need {min_fixes} to judge)")
    )
    return HealthFigures(len(gaps), g50, g95, gmax, r50, r95, rmax, bool(reasons), reason)


class CalibrationHealth:
    """Streaming ray-gap and reprojection figures for the daemon's status topic.

    Feed every fix with :meth:`add_fix` (or the two numbers with :meth:`add`);
    :meth:`figures` summarises the last ``window`` fixes. Cost per fix: one
    projection per end per camera. Not thread-safe: call from the pipeline thread.
    """

    def __init__(
        self,
        cameras: Sequence[CameraModel],
        ball_radius_m: float,
        front_colour: str = "red",
        *,
        length_m: float | None = None,
        length_tolerance_m: float = 0.05,
        window: int = 600,
        gap_limit_mm: float = GAP_LIMIT_MM,
        reprojection_limit_px: float = REPROJECTION_LIMIT_PX,
        min_fixes: int = MIN_FIXES,
    ) -> None:
        self.cameras = list(cameras)
        self.radius_m = ball_radius_m
        self.front_colour = front_colour
        self.length_m = length_m
        self.length_tolerance_m = length_tolerance_m
        self.gap_limit_mm = gap_limit_mm
        self.reprojection_limit_px = reprojection_limit_px
        self.min_fixes = min_fixes
        self._gaps: deque[float] = deque(maxlen=window)
        self._reprojection: deque[float] = deque(maxlen=window)
        self.total = 0

    @classmethod
    def for_rig(cls, rig: RigConfig, cameras: Sequence[CameraModel] | None = None, **kwargs: Any) -> CalibrationHealth:
        """From a RigConfig (pointer ball size and front colour)."""
        pointer = rig.pointer
        if pointer is None:
            raise ValueError("the rig has no [pointer]: its ball size and colours are needed to judge fixes")
        cams = list(cameras) if cameras is not None else [camera_model(c) for c in rig.cameras]
        kwargs.setdefault("length_m", pointer.length_m)
        kwargs.setdefault("length_tolerance_m", pointer.length_tolerance_m)
        return cls(cams, pointer.end_diameter_m / 2.0, pointer.front_colour, **kwargs)

    def add(self, gap_m: float, reprojection_px: float) -> None:
        self._gaps.append(float(gap_m))
        self._reprojection.append(float(reprojection_px))
        self.total += 1

    def add_fix(self, fix: PointerFix) -> bool:
        """Account for one locator fix; False when it had no line to measure."""
        figures = fix_figures(
            fix, self.cameras, self.radius_m, self.front_colour, self.length_m, self.length_tolerance_m
        )
        if figures is None:
            return False
        self.add(*figures)
        return True

    def reset(self) -> None:
        """Forget the window (after a recalibration)."""
        self._gaps.clear()
        self._reprojection.clear()

    def figures(self) -> HealthFigures:
        return health_statistics(
            self._gaps,
            self._reprojection,
            gap_limit_mm=self.gap_limit_mm,
            reprojection_limit_px=self.reprojection_limit_px,
            min_fixes=self.min_fixes,
        )

    def to_json(self) -> dict[str, object]:
        """The summary for the status topic, plus the total number of fixes measured."""
        return {**self.figures().to_json(), "total_fixes": self.total}
