"""Finding a chessboard's inner corners in a grey image, and naming the board a wrong --board missed.

OpenCV's sector-based detector (``cv2.findChessboardCornersSB``) finds a board quickly
(about 0.2 s on a 640 x 480 photo) but takes five times as long to conclude that a board
of the size asked for is not there, so the searches are arranged to fail rarely:

* the first search may return a board larger than asked (``CALIB_CB_LARGER``, at no extra
  cost); when it does and that board is a true grid of squares, the image shows a board of
  another size and the other detectors are not run (they would fail too, about a second each);
* the hint for a wrong --board asks the same once with the smallest neighbouring size, which
  names the board the image shows, instead of a failed search for every larger neighbour.

Corners are then refined at full resolution with ``cv2.cornerSubPix`` and numbered the same
way from any viewpoint (:func:`_canonical_order`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.calibration.board import BoardSpec, BoardView, edge_sharpness_px, format_mm, stretched

Array = NDArray[np.float64]

_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 100, 1e-4)


def find_chessboard(grey: NDArray[np.uint8], spec: BoardSpec, name: str) -> BoardView | None:
    cols, rows = spec.inner_corners
    corners = None
    # Half resolution first: four times faster, and enough to find a board that is not
    # tiny. Where its squares are small (a distant or steeply tilted board) the
    # half-resolution corners can be pixels off, so the board is found again at full
    # resolution in a window around it; the corners are refined below either way.
    finder = ""
    if min(grey.shape[:2]) >= 720:
        small = np.asarray(cv2.resize(grey, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA), dtype=np.uint8)
        found = _sector_corners(small, cols, rows)
        if found is not None:
            # Pixel centres sit at integers in both images: x_full = (x_small + 0.5) * 2 - 0.5.
            corners, finder = (found[0] + 0.5) * 2.0 - 0.5, found[1] + ", half resolution"
            if _shortest_spacing_px(corners.reshape(rows, cols, 2)) < 40.0:
                corners = _sector_corners_near(grey, corners, cols, rows, found[1])
                finder = found[1] + ", again near it"
    if corners is None:
        # Every detector was tried at half resolution; at full resolution only the first is, as before
        # the others existed (the quad detector and OpenCV's quick check can take 20 s on a cluttered
        # 1080p frame, and a frame without a board should cost what it did).
        found = _sector_corners(grey, cols, rows, only=None if min(grey.shape[:2]) < 720 else BOARD_FINDERS[0][0])
        if found is None:
            return None
        corners, finder = found
    grid = corners.reshape(rows, cols, 2)
    # The sector-based detector is robust but noisy (about 0.15 px on a noisy image);
    # gradient refinement over a window scaled to the squares brings it to about 0.06 px.
    # On a steeply tilted board the squares are thin diamonds whose corners nearly touch
    # along one diagonal, so the window follows the shortest spacing, diagonals included,
    # and a corner the refinement carried off toward a neighbour keeps its first position.
    square = _square_px(grid)
    spacing = _shortest_spacing_px(grid)
    half = int(np.clip(round(0.2 * spacing), 2, 9))
    start = grid.reshape(-1, 2)
    refined = (
        cv2.cornerSubPix(grey, start.reshape(-1, 1, 2).astype(np.float32), (half, half), (-1, -1), _SUBPIX_CRITERIA)
        .reshape(-1, 2)
        .astype(np.float64)
    )
    moved = np.linalg.norm(refined - start, axis=1) > max(1.0, 0.15 * spacing)
    refined[moved] = start[moved]
    grid = refined.reshape(rows, cols, 2)
    grid = _canonical_order(grey, grid, spec)
    points = grid.reshape(-1, 2)
    ids = np.arange(cols * rows)
    height, width = grey.shape[:2]
    return BoardView(
        ids,
        points,
        spec.object_points_m.copy(),
        (width, height),
        edge_sharpness_px(grey, points, square),
        spec.corner_count,
        name,
        {"detector": finder},
    )


def _sb(image: NDArray[np.uint8], cols: int, rows: int, flags: int) -> Array | None:
    ok, found = cv2.findChessboardCornersSB(image, (cols, rows), flags=flags)
    if not ok or found is None or len(found) != cols * rows:
        return None
    return found.reshape(-1, 2).astype(np.float64)


def _classic(image: NDArray[np.uint8], cols: int, rows: int) -> Array | None:
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_FILTER_QUADS
    ok, found = cv2.findChessboardCorners(image, (cols, rows), flags=flags)
    if not ok or found is None or len(found) != cols * rows:
        return None
    return found.reshape(-1, 2).astype(np.float64)


BOARD_FINDERS: tuple[tuple[str, Callable[[NDArray[np.uint8], int, int], Array | None]], ...] = (
    ("sector, normalised", lambda image, c, r: _sb(image, c, r, cv2.CALIB_CB_NORMALIZE_IMAGE)),
    ("sector", lambda image, c, r: _sb(image, c, r, 0)),
    ("sector, contrast stretched", lambda image, c, r: _sb(stretched(image), c, r, 0)),
    ("quads, adaptive threshold", _classic),
)
"""The chessboard detectors tried in turn, most exact first, until one finds the whole board:
OpenCV's sector-based detector with its normalisation and without (which finds the boards of some dim
photos that normalising loses), the same on a contrast-stretched copy, and the classic quad detector
with adaptive thresholding. Corners are refined the same way whichever found them."""


def _sector_corners(
    image: NDArray[np.uint8], cols: int, rows: int, only: str | None = None
) -> tuple[Array, str] | None:
    """The board's corners by the first detector that finds them all (and passes the junction check),
    and that detector's name.

    The first detector is tried on every image; the others only where OpenCV's quick check for a board
    (about 10 ms on a 960 x 540 image) says there may be one, on the image or its contrast-stretched
    copy, so that the many frames without a board (live capture, a recording) do not pay for four
    detectors. ``only`` names the one detector to try, without the quick check: on a large cluttered
    image the quick check and the quad detector can take tens of seconds.
    """
    finders = BOARD_FINDERS if only is None else tuple((n, f) for n, f in BOARD_FINDERS if n == only)
    for k, (name, find) in enumerate(finders):
        if k == 0 and only is None:
            first = _first_search(image, cols, rows)
            if isinstance(first, str):
                return None  # a larger board: the other detectors would not find this size either
            corners = first
            if corners is not None and corners_are_junctions(image, corners.reshape(rows, cols, 2)):
                return corners, name
            continue
        if k == 1 and not (_board_likely(image, cols, rows) or _board_likely(stretched(image), cols, rows)):
            return None
        corners = find(image, cols, rows)
        if corners is not None and corners_are_junctions(image, corners.reshape(rows, cols, 2)):
            return corners, name
    return None


def _first_search(image: NDArray[np.uint8], cols: int, rows: int) -> Array | Literal["larger board"] | None:
    """The first detector (sector-based, normalised), allowed to return a larger board than asked.

    Corners (cols * rows, 2) when it finds the board asked for (the same corners as without
    ``CALIB_CB_LARGER``), ``"larger board"`` when it finds a larger one that passes the junction check
    (the image shows a board of another size, so a failed search by each other detector, a second
    each, is spared), and None when it finds neither. A larger grid that fails the junction check
    (one run onto the printed margin) says nothing, so the detector is run again as asked.
    """
    ok, found, meta = cv2.findChessboardCornersSBWithMeta(
        image, (cols, rows), flags=cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_LARGER
    )
    if not ok or found is None:
        return None
    corners = np.asarray(found, dtype=np.float64).reshape(-1, 2)
    if len(corners) == cols * rows:
        return corners
    if _larger_board_shown(image, corners, np.asarray(meta).shape):
        return "larger board"
    return _sb(image, cols, rows, cv2.CALIB_CB_NORMALIZE_IMAGE)


def _larger_board_shown(image: NDArray[np.uint8], corners: Array, grid_shape: tuple[int, ...]) -> bool:
    """Whether corners (N, 2) that OpenCV returned as a grid of ``grid_shape`` (rows, cols) sit where
    four squares meet."""
    if len(grid_shape) != 2 or grid_shape[0] * grid_shape[1] != len(corners):
        return False
    return corners_are_junctions(image, corners.reshape(grid_shape[0], grid_shape[1], 2))


MIN_JUNCTION_SHARE = 0.3
"""A corner with an edge between two of its four squares weaker than this share of the board's typical
edge is not a corner between four squares (see :func:`corners_are_junctions`)."""


def corners_are_junctions(image: NDArray[np.uint8], grid: Array) -> bool:
    """Whether every corner of a found grid (rows, cols, 2) sits where four squares meet, dark and
    light alternating in the pattern the grid's numbering implies.

    OpenCV's detectors can return a grid shifted by a row or a column onto the board's printed edge
    (the white margin then stands in for a row of squares), most often in dim, glared photos; along
    that edge the two outer "squares" are both margin. Each corner's four squares are sampled a third
    of the way to the next corners, and each of the four edges between them must have the sign the
    chessboard's parity gives and at least MIN_JUNCTION_SHARE of the board's median edge.
    """
    rows, cols = grid.shape[:2]
    if rows < 2 or cols < 2:
        return True
    # Vectors to the next corner along a row (u) and a column (v), and to the previous one (the first
    # row and column mirror the next); the outer squares of a tilted board are smaller, so samples
    # stay well inside a square.
    u = np.diff(grid, axis=1)
    u_ahead = np.concatenate([u, u[:, -1:]], axis=1)
    u_back = np.concatenate([u[:, :1], u], axis=1)
    v = np.diff(grid, axis=0)
    v_ahead = np.concatenate([v, v[-1:]], axis=0)
    v_back = np.concatenate([v[:1], v], axis=0)
    spacing = float(np.median(np.hypot(*u.reshape(-1, 2).T)))
    radius = max(1, round(0.1 * spacing))
    blurred = cv2.blur(image, (2 * radius + 1, 2 * radius + 1)).astype(np.float32)
    h, w = blurred.shape[:2]

    def level(offset: Array) -> Array:
        at = np.rint(grid + 0.35 * offset).astype(np.int64)
        inside = (at[..., 0] >= 0) & (at[..., 0] < w) & (at[..., 1] >= 0) & (at[..., 1] < h)
        values = blurred[np.clip(at[..., 1], 0, h - 1), np.clip(at[..., 0], 0, w - 1)]
        return np.where(inside, values, np.nan)

    # a and b are the squares on one diagonal, c and d on the other.
    a, b = level(u_ahead + v_ahead), level(-u_back - v_back)
    c, d = level(u_ahead - v_back), level(-u_back + v_ahead)
    parity = np.where((np.add.outer(np.arange(rows), np.arange(cols)) % 2) == 0, 1.0, -1.0)
    edges = np.stack([a - c, a - d, b - c, b - d], axis=-1) * parity[..., None]
    # A corner whose outer squares leave the image cannot be judged; the rest must all pass.
    judged = edges[np.all(np.isfinite(edges), axis=-1)]
    if len(judged) < 4:
        return True
    judged = judged * np.sign(np.median(judged))
    typical = float(np.median(judged))
    return typical > 0 and bool(np.all(judged >= MIN_JUNCTION_SHARE * typical))


def _board_likely(image: NDArray[np.uint8], cols: int, rows: int) -> bool:
    flags = cv2.CALIB_CB_FAST_CHECK | cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    ok, _ = cv2.findChessboardCorners(image, (cols, rows), flags=flags)
    return bool(ok)


def board_size_hint(grey: NDArray[np.uint8], spec: BoardSpec) -> str | None:
    """The board of another size that is in the image (one more or one fewer inner corner each way,
    either way round), as the --board to give; None when none is. For when no image shows the board.

    OpenCV's detector also finds part of a larger board (5 x 8 inner corners inside a 9 x 6 one), so
    the largest neighbouring size found is named, the way round the user gave. One search for the
    smallest neighbour that may return a larger board (``CALIB_CB_LARGER``) names the board in view;
    that size is confirmed as any other would be. Only when it names no neighbouring size is every
    neighbour tried, largest first (a failed search costs about a second on a 640 x 480 photo).
    """
    if spec.kind != "chessboard":
        return None
    cols, rows = spec.inner_corners
    if min(grey.shape[:2]) >= 720:
        grey = np.asarray(cv2.resize(grey, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA), dtype=np.uint8)
    candidates: list[tuple[int, bool, int, int]] = []
    tried = {(cols, rows), (rows, cols)}  # the size given, either way round, is what was not found
    for dc in (-1, 0, 1):
        for dr in (-1, 0, 1):
            for swapped, (c, r) in ((False, (cols + dc, rows + dr)), (True, (rows + dr, cols + dc))):
                if (c, r) in tried or min(c, r) < 2:
                    continue
                tried.add((c, r))
                candidates.append((c * r, not swapped, c, r))
    # The largest first, the way round the user gave before the other: the first found is the
    # answer, and the failed searches are not run for the smaller ones.
    ordered = [(c, r) for _, _, c, r in sorted(candidates, reverse=True)]
    # One search names the board in view (1-3 s); trying the largest neighbour first would save it
    # for a board one square larger each way, and cost a failed search (several seconds) otherwise.
    shown = _board_shown(grey, max(2, cols - 1), max(2, rows - 1))
    named = [(c, r) for c, r in ordered if shown is not None and sorted((c, r)) == shown]
    for c, r in dict.fromkeys(named[:1] + ordered):  # the named size first, each searched once
        if _is_board_of_size(grey, c, r):
            return f"chessboard:{c + 1}x{r + 1}:{format_mm(spec.square_m)}"
    return None


def _board_shown(grey: NDArray[np.uint8], cols: int, rows: int) -> list[int] | None:
    """The inner corners (sorted) of the largest board OpenCV finds containing cols x rows, or None."""
    ok, found, meta = cv2.findChessboardCornersSBWithMeta(
        grey, (cols, rows), flags=cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_LARGER
    )
    if not ok or found is None or meta is None or np.asarray(meta).ndim != 2:
        return None
    return sorted(np.asarray(meta).shape)


def _is_board_of_size(grey: NDArray[np.uint8], cols: int, rows: int) -> bool:
    """Whether the sector-based detector, normalised or not, finds a cols x rows grid of true corners
    (a grid that runs onto the printed margin is not a board of that size)."""
    for flags in (cv2.CALIB_CB_NORMALIZE_IMAGE, 0):
        corners = _sb(grey, cols, rows, flags)
        if corners is not None and corners_are_junctions(grey, corners.reshape(rows, cols, 2)):
            return True
    return False


def _sector_corners_near(grey: NDArray[np.uint8], rough: Array, cols: int, rows: int, finder: str) -> Array | None:
    """Find the board again at full resolution, in a window around rough corner positions, with the
    detector that found it at half resolution."""
    pad = 2.0 * _square_px(rough.reshape(rows, cols, 2)) + 8.0
    h, w = grey.shape[:2]
    x0, y0 = max(0, int(rough[:, 0].min() - pad)), max(0, int(rough[:, 1].min() - pad))
    x1, y1 = min(w, int(rough[:, 0].max() + pad) + 1), min(h, int(rough[:, 1].max() + pad) + 1)
    found = _sector_corners(np.ascontiguousarray(grey[y0:y1, x0:x1]), cols, rows, only=finder)
    return None if found is None else found[0] + np.array([x0, y0], dtype=np.float64)


def _canonical_order(grey: NDArray[np.uint8], grid: Array, spec: BoardSpec) -> Array:
    """Renumber a chessboard's corner grid (rows, cols, 2) the same way from any viewpoint.

    The detector may start at any of the board's four outer corners. Board x
    cross board y must point into the image (the printed face is seen from the
    front, which keeps orientation), and the square diagonally outside corner 0
    must be black; for a board without 180-degree symmetry this fixes the order.
    """
    a = grid[0, 1] - grid[0, 0]
    b = grid[1, 0] - grid[0, 0]
    if a[0] * b[1] - a[1] * b[0] < 0:
        grid = grid[:, ::-1]
    if spec.symmetric:
        return grid
    # Centres of the outer square at corner 0 and of its neighbour along the first row.
    step_x = grid[0, 1] - grid[0, 0]
    step_y = grid[1, 0] - grid[0, 0]
    outer = grid[0, 0] - 0.5 * step_x - 0.5 * step_y
    neighbour = grid[0, 0] + 0.5 * step_x - 0.5 * step_y
    if _mean_around(grey, outer) > _mean_around(grey, neighbour):
        grid = grid[::-1, ::-1]
    return grid


def _mean_around(grey: NDArray[np.uint8], point: Array, radius: int = 2) -> float:
    x, y = int(np.rint(point[0])), int(np.rint(point[1]))
    h, w = grey.shape[:2]
    patch = grey[max(0, y - radius) : min(h, y + radius + 1), max(0, x - radius) : min(w, x + radius + 1)]
    return float(patch.mean()) if patch.size else 128.0


def _shortest_spacing_px(grid: Array) -> float:
    """Median over corners of the distance to the nearest neighbouring corner, diagonals included."""
    rows, cols = grid.shape[:2]
    best = np.full((rows, cols), np.inf)
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
        a = grid[max(0, -dy) : rows - max(0, dy), max(0, -dx) : cols - max(0, dx)]
        b = grid[max(0, dy) :, max(0, dx) : cols + min(0, dx) or None]
        b = b[: a.shape[0], : a.shape[1]]
        d = np.linalg.norm(a - b, axis=2)
        ya, xa = max(0, -dy), max(0, -dx)
        best[ya : ya + d.shape[0], xa : xa + d.shape[1]] = np.minimum(
            best[ya : ya + d.shape[0], xa : xa + d.shape[1]], d
        )
        yb, xb = max(0, dy), max(0, dx)
        best[yb : yb + d.shape[0], xb : xb + d.shape[1]] = np.minimum(
            best[yb : yb + d.shape[0], xb : xb + d.shape[1]], d
        )
    return float(np.median(best))


def _square_px(grid: Array) -> float:
    """Typical side of a square in the image along its more foreshortened direction, in pixels."""
    dx = np.linalg.norm(np.diff(grid, axis=1), axis=2)
    dy = np.linalg.norm(np.diff(grid, axis=0), axis=2)
    return float(min(np.median(dx), np.median(dy)))
