"""View selection: coverage of the image, similar views refused, guidance that names what is missing."""

from __future__ import annotations

import dataclasses

import numpy as np
from calibration_frames import INTRINSICS_BOARD

from trackerd.calibration.board import BoardView
from trackerd.calibration.views import CoverageGrid, ViewSelector, board_tilt_deg, view_change

W, H = 1920, 1080


def grid_view(centre_px: tuple[float, float], spacing_px: float, name: str = "", size=(W, H)) -> BoardView:
    """A board seen square-on: its corners on a regular grid around centre_px."""
    cols, rows = INTRINSICS_BOARD.inner_corners
    i, j = np.meshgrid(np.arange(cols) - (cols - 1) / 2, np.arange(rows) - (rows - 1) / 2)
    points = np.column_stack([centre_px[0] + i.ravel() * spacing_px, centre_px[1] + j.ravel() * spacing_px])
    ids = np.arange(cols * rows)
    return BoardView(
        ids, points, INTRINSICS_BOARD.object_points_m.copy(), size, 1.5, INTRINSICS_BOARD.corner_count, name
    )


def test_coverage_grid_counts_cells_and_names_missing_regions_corners_first() -> None:
    grid = CoverageGrid(W, H)
    assert grid.fraction == 0.0
    assert grid.missing_regions()[:4] == [
        "top-left corner",
        "top-right corner",
        "bottom-left corner",
        "bottom-right corner",
    ]
    grid.add(np.array([[0.0, 0.0], [W - 1.0, H - 1.0], [W / 2, H / 2]]))
    assert grid.counts.sum() == 3
    assert grid.counts[0, 0] == 1 and grid.counts[-1, -1] == 1
    assert grid.fraction == 3 / 48
    lines = grid.ascii().splitlines()
    assert lines[0].startswith("#.") and lines[-1].endswith(".#")
    assert "top-left corner" in grid.missing_regions()  # one cell of four is not enough
    grid.add(np.array([[x, y] for x in np.linspace(0, W - 1, 40) for y in np.linspace(0, H - 1, 30)]))
    assert grid.fraction == 1.0 and grid.missing_regions() == []


def test_similar_views_are_refused_and_different_ones_kept() -> None:
    selector = ViewSelector(W, H)
    first = grid_view((960, 540), 60, "a.png")
    assert selector.consider(first).accepted
    nudged = grid_view((975, 545), 60, "b.png")  # 16 px: under 3 % of the 2203 px diagonal
    verdict = selector.consider(nudged)
    assert not verdict.accepted
    assert verdict.reason.startswith("too similar to 'a.png' (corners moved 0.72 % of the diagonal, need 3 %)")
    moved = grid_view((700, 400), 60, "c.png")
    assert selector.consider(moved).accepted
    assert [v.name for v in selector.views] == ["a.png", "c.png"]
    assert view_change(first, moved) > 0.1


def test_views_of_another_size_are_refused() -> None:
    selector = ViewSelector(W, H)
    verdict = selector.consider(grid_view((600, 300), 40, "small.png", size=(1280, 720)))
    assert not verdict.accepted
    assert verdict.reason == "image is 1280x720, the camera's are 1920x1080"


def test_views_sharing_few_corners_are_not_compared() -> None:
    full = grid_view((960, 540), 60)

    def part(view: BoardView, keep: slice) -> BoardView:
        return dataclasses.replace(
            view,
            ids=view.ids[keep],
            image_points_px=view.image_points_px[keep],
            object_points_m=view.object_points_m[keep],
        )

    # Two partial ChArUco views of different ends of the board, at the same place in the image.
    assert view_change(part(full, slice(0, 20)), part(full, slice(17, 40))) is None
    assert view_change(part(full, slice(0, 20)), part(full, slice(5, 25))) == 0.0


def test_guidance_asks_for_the_uncovered_corner_then_tilt(intrinsics_views: dict) -> None:
    selector = ViewSelector(W, H)
    selector.add(grid_view((960, 540), 60))
    assert selector.guidance(20) == "cover the top-left corner of the image with the board"
    for view in intrinsics_views["left"]:
        selector.add(view)
    assert selector.coverage.fraction > 0.8
    # The rendered views are tilted 15 to 50 degrees; the square-on one is not.
    tilts = selector.tilts_deg
    assert tilts[0] < 2.0 and min(tilts[1:]) > 8.0
    assert selector.guidance(len(selector.views)) == "enough views: finish (Ctrl-C) or keep adding views"
    flat = ViewSelector(W, H)
    for x in (300, 960, 1620):
        for y in (180, 540, 900):
            flat.add(grid_view((x, y), 70))
    assert flat.coverage.missing_regions() == []
    assert flat.guidance(20).startswith("tilt the board")


def test_tilt_of_a_square_on_board_is_small() -> None:
    assert board_tilt_deg(grid_view((960, 540), 60)) < 1.0
