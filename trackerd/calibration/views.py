"""Which board views to keep, how much of the image they cover, and what to do next.

A calibration is only as good as the spread of its views: corners near the
image's edges and corners pin the distortion, tilted views pin the focal length,
and many near-identical views add nothing but weight. :class:`ViewSelector`
accepts a view only when it differs enough from every view accepted so far, and
keeps a :class:`CoverageGrid` of where in the image corners have been seen.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.calibration.board import BoardView

Array = NDArray[np.float64]

MIN_VIEW_CHANGE = 0.03
"""A view whose corners moved on average less than this fraction of the image diagonal
from an accepted view's is 'too similar' to it."""

REGIONS = (
    ("top-left corner", 0, 0),
    ("top edge", 1, 0),
    ("top-right corner", 2, 0),
    ("left edge", 0, 1),
    ("centre", 1, 1),
    ("right edge", 2, 1),
    ("bottom-left corner", 0, 2),
    ("bottom edge", 1, 2),
    ("bottom-right corner", 2, 2),
)
"""The image's nine regions, (name, column third, row third), corners first in the guidance order below."""

_GUIDANCE_ORDER = (0, 2, 6, 8, 1, 3, 5, 7, 4)


@dataclass
class CoverageGrid:
    """Counts of board corners seen in each cell of a coarse grid over the image."""

    width_px: int
    height_px: int
    cols: int = 8
    rows: int = 6
    counts: NDArray[np.int64] = field(init=False)

    def __post_init__(self) -> None:
        self.counts = np.zeros((self.rows, self.cols), dtype=np.int64)

    def add(self, points_px: Array) -> None:
        """Count corners (N, 2) into their cells."""
        pts = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
        col = np.clip((pts[:, 0] + 0.5) / self.width_px * self.cols, 0, self.cols - 1).astype(int)
        row = np.clip((pts[:, 1] + 0.5) / self.height_px * self.rows, 0, self.rows - 1).astype(int)
        np.add.at(self.counts, (row, col), 1)

    @property
    def covered(self) -> NDArray[np.bool_]:
        return self.counts > 0

    @property
    def fraction(self) -> float:
        """Share of cells with at least one corner."""
        return float(self.covered.mean())

    def region_fraction(self, col_third: int, row_third: int) -> float:
        """Share of covered cells in one of the image's nine regions."""
        cols = _third(self.cols, col_third)
        rows = _third(self.rows, row_third)
        return float(self.covered[rows, cols].mean())

    def missing_regions(self, below: float = 0.5) -> list[str]:
        """Regions less than ``below`` covered, image corners first (they matter most for distortion)."""
        out = []
        for index in _GUIDANCE_ORDER:
            name, c, r = REGIONS[index]
            if self.region_fraction(c, r) < below:
                out.append(name)
        return out

    def ascii(self) -> str:
        """The grid as text: '#' covered, '.' not, one line per row."""
        return "\n".join("".join("#" if c else "." for c in row) for row in self.covered)

    def to_json(self) -> dict[str, object]:
        return {
            "cols": self.cols,
            "rows": self.rows,
            "fraction": round(self.fraction, 3),
            "covered": self.ascii().splitlines(),
        }


def _third(n: int, index: int) -> slice:
    edges = [0, round(n / 3), round(2 * n / 3), n]
    return slice(edges[index], max(edges[index + 1], edges[index] + 1))


def view_change(a: BoardView, b: BoardView) -> float | None:
    """Mean movement of the corners two views share, as a fraction of the image diagonal.

    None when they share too few corners to compare (then they are not similar).
    """
    common, ia, ib = np.intersect1d(a.ids, b.ids, return_indices=True)
    if len(common) < 4 or len(common) < 0.5 * min(len(a.ids), len(b.ids)):
        return None
    diagonal = float(np.hypot(*a.image_size))
    return float(np.mean(np.linalg.norm(a.image_points_px[ia] - b.image_points_px[ib], axis=1)) / diagonal)


def board_tilt_deg(view: BoardView) -> float:
    """How far the board is turned from facing the camera, from the homography alone (no intrinsics).

    With a rough pinhole (focal length = image width, principal point at the
    centre) the homography gives the board's normal; the angle is a coarse
    guide for the operator, not a measurement.
    """
    width, height = view.image_size
    focal = float(width)
    matrix = np.array([[focal, 0, (width - 1) / 2], [0, focal, (height - 1) / 2], [0, 0, 1.0]])
    homography, _ = cv2.findHomography(view.object_points_m[:, :2], view.image_points_px)
    if homography is None:
        return 0.0
    h = np.linalg.inv(matrix) @ homography
    r1, r2 = h[:, 0], h[:, 1]
    scale = 2.0 / (np.linalg.norm(r1) + np.linalg.norm(r2))
    normal = np.cross(r1 * scale, r2 * scale)
    normal /= np.linalg.norm(normal)
    return float(np.degrees(np.arccos(min(1.0, abs(normal[2])))))


def board_area_fraction(view: BoardView) -> float:
    """Share of the image the detected corners' convex hull covers."""
    hull = cv2.convexHull(view.image_points_px.astype(np.float32))
    width, height = view.image_size
    return float(cv2.contourArea(hull)) / float(width * height)


@dataclass(frozen=True)
class Verdict:
    accepted: bool
    reason: str | None = None
    """Why a view was rejected ('too similar to view 3 (corners moved 1.2 % of the diagonal)')."""


class ViewSelector:
    """Accepts views that add something: different enough from every view kept so far.

    Not thread-safe; one per calibration run.
    """

    def __init__(self, width_px: int, height_px: int, min_change: float = MIN_VIEW_CHANGE) -> None:
        self.width_px = width_px
        self.height_px = height_px
        self.min_change = min_change
        self.views: list[BoardView] = []
        self.coverage = CoverageGrid(width_px, height_px)
        self.tilts_deg: list[float] = []
        self.areas: list[float] = []

    def consider(self, view: BoardView) -> Verdict:
        """Accept ``view`` unless its size differs from the camera's or it repeats an accepted view."""
        if view.image_size != (self.width_px, self.height_px):
            w, h = view.image_size
            return Verdict(False, f"image is {w}x{h}, the camera's are {self.width_px}x{self.height_px}")
        for index, kept in enumerate(self.views):
            change = view_change(view, kept)
            if change is not None and change < self.min_change:
                label = f"'{kept.name}'" if kept.name else f"view {index + 1}"
                return Verdict(
                    False,
                    f"too similar to {label} (corners moved {change * 100:.2f} % of the"
                    f" diagonal, need {self.min_change * 100:.0f} %); move or tilt the board",
                )
        self.add(view)
        return Verdict(True)

    def add(self, view: BoardView) -> None:
        """Keep a view without the similarity test."""
        self.views.append(view)
        self.coverage.add(view.image_points_px)
        self.tilts_deg.append(board_tilt_deg(view))
        self.areas.append(board_area_fraction(view))

    def guidance(self, wanted_views: int) -> str:
        """What the operator should do next, in one sentence."""
        missing = self.coverage.missing_regions()
        if self.views and missing:
            return f"cover the {missing[0]} of the image with the board"
        tilted = sum(t >= 20.0 for t in self.tilts_deg)
        if len(self.views) >= 3 and tilted < max(2, len(self.views) // 3):
            return "tilt the board (20 to 45 degrees) to the left, right, up and down"
        if self.areas and max(self.areas) < 0.06:
            return "bring the board closer so that it fills more of the image"
        if len(self.views) < wanted_views:
            return "keep moving the board to new places and angles"
        return "enough views: finish (Ctrl-C) or keep adding views"
