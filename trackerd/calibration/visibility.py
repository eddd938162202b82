"""Which wall targets can be touched in view: the tip ball held against the wall, seen by every camera.

Touching (``calibrate wall --touch``) needs both cameras to see the tip ball at
the target. On the DataWall the cameras converge from the two sides and share
only a strip of the display (x from about 1.2 to 2.4 m of its 3.66 m, narrowing
toward the top), so its corners cannot be touched in view. These functions say
which targets can, and find a rectangle of targets that can, from the current
calibration. They are pure: camera models and the wall frame in, arrays out.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from trackerd.calibration.wall import Target
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.wall import WallFrame

Array = NDArray[np.float64]

TOUCH_MARGIN_PX = 30.0
"""The tip ball's centre must project this far inside each image: the ball itself (about 20 px
across at 4 m) and the hand around it must be in view too."""

VIEW_TARGET_LABELS = ("view-bl", "view-br", "view-tr", "view-tl", "view-centre")
"""The targets :func:`view_targets` makes: the corners and centre of a rectangle both cameras see."""


def touch_seen(
    cameras: Sequence[CameraModel],
    wall: WallFrame,
    wall_xy_m: Array,
    tip_radius_m: float,
    margin_px: float = TOUCH_MARGIN_PX,
) -> NDArray[np.bool_]:
    """(N, cameras): whether each camera sees the tip ball touching the wall at ``wall_xy_m`` (N, 2)."""
    xy = np.asarray(wall_xy_m, dtype=np.float64).reshape(-1, 2)
    points = wall.from_wall_m(xy) + tip_radius_m * wall.normal
    out = np.zeros((len(xy), len(cameras)), dtype=bool)
    for k, camera in enumerate(cameras):
        in_front = camera.to_camera_frame(points)[:, 2] > 0.1
        px = camera.project(points)
        finite = np.all(np.isfinite(px), axis=1)
        out[:, k] = in_front & finite & camera.contains(np.nan_to_num(px, nan=-1e9), margin_px)
    return out


def common_view_rectangle(
    cameras: Sequence[CameraModel],
    wall: WallFrame,
    tip_radius_m: float,
    *,
    step_m: float = 0.01,
    edge_m: float = 0.05,
    inset_m: float = 0.05,
    min_side_m: float = 0.2,
) -> tuple[float, float, float, float] | None:
    """The largest display-aligned rectangle (x0, y0, x1, y1) in wall metres that every camera sees.

    The display is sampled every ``step_m``, ``edge_m`` in from its edges (a target must be on the
    display); the rectangle is then shrunk by ``inset_m`` on each side, since before the wall is
    calibrated the wall's place is known only roughly. None when no rectangle of at least
    ``min_side_m`` on each side is left.
    """
    xs = np.arange(edge_m, wall.width_m - edge_m + 1e-9, step_m)
    ys = np.arange(edge_m, wall.height_m - edge_m + 1e-9, step_m)
    if len(xs) == 0 or len(ys) == 0:
        return None
    grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    seen = touch_seen(cameras, wall, grid, tip_radius_m).all(axis=1).reshape(len(ys), len(xs))
    # Each row's longest run of seen samples (the common view of two cameras is convex, up to the
    # lenses' distortion, so one run per row).
    runs: list[tuple[int, int] | None] = []
    for row in seen:
        best: tuple[int, int] | None = None
        start = None
        for i, value in enumerate(np.append(row, False)):
            if value and start is None:
                start = i
            elif not value and start is not None:
                if best is None or i - start > best[1] - best[0]:
                    best = (start, i - 1)
                start = None
        runs.append(best)
    area_best = 0.0
    found: tuple[float, float, float, float] | None = None
    for i in range(len(ys)):
        lo, hi = -1, len(xs)
        for j in range(i, len(ys)):
            run = runs[j]
            if run is None:
                break
            lo, hi = max(lo, run[0]), min(hi, run[1])
            if hi <= lo:
                break
            area = (xs[hi] - xs[lo]) * (ys[j] - ys[i])
            if area > area_best:
                area_best = area
                found = (float(xs[lo]), float(ys[i]), float(xs[hi]), float(ys[j]))
    if found is None:
        return None
    x0, y0, x1, y1 = found[0] + inset_m, found[1] + inset_m, found[2] - inset_m, found[3] - inset_m
    if x1 - x0 < min_side_m or y1 - y0 < min_side_m:
        return None
    # Whole centimetres: marks an operator can measure and tape.
    return (
        float(np.ceil(x0 * 100) / 100),
        float(np.ceil(y0 * 100) / 100),
        float(np.floor(x1 * 100) / 100),
        float(np.floor(y1 * 100) / 100),
    )


def view_targets(rectangle: tuple[float, float, float, float]) -> dict[str, Target]:
    """The corners and centre of ``rectangle`` (x0, y0, x1, y1, wall metres) as targets
    ``view-bl``, ``view-br``, ``view-tr``, ``view-tl`` and ``view-centre``.

    They are places on the display (shown there as crosses, or taped), so they scale with the
    display's size like its corners do.
    """
    x0, y0, x1, y1 = rectangle
    places = ((x0, y0), (x1, y0), (x1, y1), (x0, y1), ((x0 + x1) / 2, (y0 + y1) / 2))
    return {
        label: Target(label, np.array([x, y], dtype=np.float64), True)
        for label, (x, y) in zip(VIEW_TARGET_LABELS, places, strict=True)
    }
