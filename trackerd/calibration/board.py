"""Calibration boards: what they look like, how to find their corners, and whether a view is usable.

Two kinds, both printed on a flat, rigid plate:

* ``chessboard:COLSxROWS:SQUARE_MM`` an OpenCV chessboard of COLS x ROWS squares
  (so (COLS-1) x (ROWS-1) inner corners), found with ``cv2.findChessboardCornersSB``;
  the whole board must be in view. For stereo use one with an odd number of squares
  on one side and an even number on the other, so that it has no 180-degree symmetry
  and both cameras number its corners alike.
* ``charuco:COLSxROWS:SQUARE_MM:MARKER_MM[:DICT]`` an OpenCV ChArUco board (ArUco
  markers in the white squares, dictionary default ``5X5_100``), found with
  ``cv2.aruco.CharucoDetector``; partial views work because every corner has an id.

Board coordinates (OpenCV's): origin at the top-left corner of the squares, x along
the columns, y down the rows, z into the board (away from a viewer of its printed
face), in metres. Inner corner (i, j) (i-th column, j-th row) is at
``((i + 1) s, (j + 1) s, 0)`` and has id ``j (COLS - 1) + i``, as in
``cv2.aruco.CharucoBoard.getChessboardCorners``.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.pixelformat import BAYER_LAYOUTS

Array = NDArray[np.float64]

DEFAULT_DICTIONARY = "5X5_100"

MAX_SHARPNESS_PX = 3.0
"""Views whose edges rise over more pixels than this (10 % to 90 %) are rejected as blurred;
OpenCV's guidance for ``estimateChessboardSharpness`` is "below about 3 pixels"."""

MIN_CORNER_FRACTION = 0.5
"""A partial ChArUco view must show at least this fraction of the board's corners."""

MIN_CORNERS = 8
"""And at least this many corners (a homography and a pose need a handful)."""


_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 100, 1e-4)

_SPEC = re.compile(
    r"^(?P<kind>chessboard|chess|charuco):(?P<cols>\d+)x(?P<rows>\d+):(?P<square>[0-9.]+)"
    r"(?::(?P<marker>[0-9.]+))?(?::(?P<dict>[A-Za-z0-9_]+))?$"
)


@dataclass(frozen=True)
class BoardSpec:
    """A calibration board: kind, size in squares, square size, and for ChArUco the markers."""

    kind: Literal["chessboard", "charuco"]
    squares_x: int
    """Squares along the board's x (columns)."""
    squares_y: int
    """Squares along y (rows)."""
    square_m: float
    marker_m: float | None = None
    dictionary: str | None = None
    """ArUco dictionary name without the ``DICT_`` prefix, e.g. ``5X5_100``."""

    def __post_init__(self) -> None:
        if self.squares_x < 3 or self.squares_y < 3:
            raise ValueError("a board needs at least 3 x 3 squares")
        if self.square_m <= 0:
            raise ValueError("the square size must be positive")
        if self.kind == "chessboard" and self.squares_x == self.squares_y:
            raise ValueError("a square chessboard has no orientation; use different numbers of rows and columns")
        if self.kind == "charuco":
            if self.marker_m is None or not 0 < self.marker_m < self.square_m:
                raise ValueError("a ChArUco marker must be smaller than its square")
            name = f"DICT_{self.dictionary}"
            if not hasattr(cv2.aruco, name):
                raise ValueError(f"unknown ArUco dictionary '{self.dictionary}' (e.g. 5X5_100, 6X6_250)")
            needed = (self.squares_x * self.squares_y) // 2
            available = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name)).bytesList.shape[0]
            if needed > available:
                raise ValueError(f"the board needs {needed} markers; {self.dictionary} has {available}")

    # ------------------------------------------------------------------ text form

    @classmethod
    def parse(cls, text: str) -> BoardSpec:
        """``chessboard:10x7:60`` or ``charuco:10x7:60:45[:5X5_100]`` (sizes in millimetres)."""
        match = _SPEC.match(text.strip())
        if match is None:
            raise ValueError(
                f"board '{text}': expected chessboard:COLSxROWS:SQUARE_MM or"
                " charuco:COLSxROWS:SQUARE_MM:MARKER_MM[:DICT], counting squares (e.g. chessboard:10x7:60)"
            )
        kind = "charuco" if match["kind"] == "charuco" else "chessboard"
        marker = match["marker"]
        if kind == "chessboard" and (marker or match["dict"]):
            raise ValueError(f"board '{text}': a chessboard has no markers")
        if kind == "charuco" and not marker:
            raise ValueError(f"board '{text}': a ChArUco board needs the marker size, charuco:10x7:60:45")
        dictionary = (match["dict"] or DEFAULT_DICTIONARY).upper().removeprefix("DICT_")
        try:
            return cls(
                kind,
                int(match["cols"]),
                int(match["rows"]),
                float(match["square"]) / 1000.0,
                float(marker) / 1000.0 if marker else None,
                dictionary if kind == "charuco" else None,
            )
        except ValueError as err:
            raise ValueError(f"board '{text}': {err}") from err

    def __str__(self) -> str:
        text = f"{self.kind}:{self.squares_x}x{self.squares_y}:{_mm(self.square_m)}"
        if self.kind == "charuco":
            text += f":{_mm(self.marker_m or 0.0)}:{self.dictionary}"
        return text

    def describe(self) -> str:
        """For humans: ``chessboard, 10 x 7 squares of 60 mm (54 inner corners)``."""
        text = (
            f"{self.kind}, {self.squares_x} x {self.squares_y} squares of {_mm(self.square_m)} mm"
            f" ({self.corner_count} inner corners"
        )
        if self.kind == "charuco":
            text += f", {_mm(self.marker_m or 0.0)} mm markers from {self.dictionary}"
        return text + ")"

    # ------------------------------------------------------------------ geometry

    @property
    def inner_corners(self) -> tuple[int, int]:
        """(columns, rows) of inner corners, OpenCV's ``patternSize``."""
        return self.squares_x - 1, self.squares_y - 1

    @property
    def corner_count(self) -> int:
        cols, rows = self.inner_corners
        return cols * rows

    @property
    def size_m(self) -> tuple[float, float]:
        """Width and height of the squared area."""
        return self.squares_x * self.square_m, self.squares_y * self.square_m

    @property
    def symmetric(self) -> bool:
        """Whether a chessboard looks the same turned by 180 degrees (then its corner order is ambiguous)."""
        return self.kind == "chessboard" and (self.squares_x + self.squares_y) % 2 == 0

    @cached_property
    def object_points_m(self) -> Array:
        """(N, 3) board coordinates of every inner corner, indexed by corner id."""
        cols, rows = self.inner_corners
        i, j = np.meshgrid(np.arange(cols), np.arange(rows))
        return np.column_stack(
            [(i.ravel() + 1) * self.square_m, (j.ravel() + 1) * self.square_m, np.zeros(cols * rows)]
        )

    def black_square(self, col: NDArray[np.int64], row: NDArray[np.int64]) -> NDArray[np.bool_]:
        """Whether squares (col, row) are black. A chessboard's top-left square is black; a ChArUco
        board's colouring follows OpenCV's (markers sit in the white squares)."""
        parity = (np.asarray(col) + np.asarray(row)) % 2
        return parity == self._black_parity

    @cached_property
    def _black_parity(self) -> int:
        if self.kind == "chessboard":
            return 0
        first = np.asarray(self.cv_board.getObjPoints()[0]).reshape(4, 3)
        centre = first.mean(axis=0) / self.square_m
        return 1 - int(np.floor(centre[0]) + np.floor(centre[1])) % 2

    # ------------------------------------------------------------------ OpenCV objects

    @cached_property
    def cv_dictionary(self) -> cv2.aruco.Dictionary:
        if self.kind != "charuco":
            raise ValueError("a chessboard has no ArUco dictionary")
        return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, f"DICT_{self.dictionary}"))

    @cached_property
    def cv_board(self) -> cv2.aruco.CharucoBoard:
        if self.kind != "charuco":
            raise ValueError("a chessboard has no ChArUco board object")
        return cv2.aruco.CharucoBoard(
            (self.squares_x, self.squares_y), self.square_m, float(self.marker_m or 0.0), self.cv_dictionary
        )

    @cached_property
    def markers(self) -> tuple[tuple[int, Array, NDArray[np.uint8]], ...]:
        """ChArUco markers as (id, corners (4, 3) in board metres clockwise from top-left, bits (n, n))."""
        if self.kind != "charuco":
            return ()
        board = self.cv_board
        dictionary = self.cv_dictionary
        out = []
        for marker_id, corners in zip(np.asarray(board.getIds()).ravel(), board.getObjPoints(), strict=True):
            byte_list = dictionary.bytesList[int(marker_id) : int(marker_id) + 1]
            bits = cv2.aruco.Dictionary_getBitsFromByteList(byte_list, dictionary.markerSize)
            out.append(
                (int(marker_id), np.asarray(corners, dtype=np.float64).reshape(4, 3), np.asarray(bits, dtype=np.uint8))
            )
        return tuple(out)


def _mm(value_m: float) -> str:
    return f"{value_m * 1000:g}"


# --------------------------------------------------------------------------- images


def grey_for_calibration(frame: NDArray[np.uint8], pixel_format: str) -> NDArray[np.uint8]:
    """A full-resolution grey image of a frame, without demosaicing a Bayer mosaic.

    A calibration board is black and white, so under roughly white light every
    Bayer site sees the same pattern, only with its channel's gain. Equalising the
    four sites' gains (by their bright levels) gives a grey image at full
    resolution, where bilinear demosaicing would soften and shift the edges that
    the corner finder measures. Shapes: (H, W) or (H, W, 3) -> (H, W).
    """
    if frame.ndim == 3:
        code = cv2.COLOR_RGB2GRAY if pixel_format == "RGB8" else cv2.COLOR_BGR2GRAY
        return cv2.cvtColor(np.ascontiguousarray(frame), code)
    if pixel_format not in BAYER_LAYOUTS:
        return np.ascontiguousarray(frame)
    out = frame.astype(np.float32)
    levels = [float(np.percentile(frame[r::2, c::2][::4, ::4], 95)) for r in (0, 1) for c in (0, 1)]
    target = float(np.mean(levels))
    for (r, c), level in zip(((0, 0), (0, 1), (1, 0), (1, 1)), levels, strict=True):
        if level > 0:
            out[r::2, c::2] *= target / level
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


# --------------------------------------------------------------------------- detection


@dataclass(frozen=True)
class BoardView:
    """A board found in one image: which corners, where, and how sharp."""

    ids: NDArray[np.int64]
    """(N,) corner ids (see the module docstring)."""
    image_points_px: Array
    """(N, 2) sub-pixel corner positions, OpenCV pixel coordinates."""
    object_points_m: Array
    """(N, 3) the same corners in board coordinates."""
    image_size: tuple[int, int]
    """(width, height) of the image."""
    sharpness_px: float
    """Median 10-90 % rise distance of the board's edges near its corners (smaller is sharper)."""
    corner_count: int
    """Corners the whole board has."""
    name: str = ""
    """Where the view came from (a file name, a frame number)."""
    meta: dict[str, str] = field(default_factory=dict)
    """``detector``: which detector found the board (BOARD_FINDERS)."""

    @property
    def complete(self) -> bool:
        return len(self.ids) == self.corner_count

    @property
    def fraction(self) -> float:
        return len(self.ids) / self.corner_count


@dataclass(frozen=True)
class Detection:
    """The outcome of looking for a board in one image: a usable view, or why not."""

    view: BoardView | None
    reason: str | None = None
    """Why the image gives no usable view: 'no whole board found by any detector', 'blurred (...)',
    'partial (...)', 'too little contrast (...)'."""
    found: BoardView | None = None
    """The board as found even when rejected (for showing it), else None."""


@dataclass(frozen=True)
class Quality:
    """Limits a view must meet."""

    max_sharpness_px: float = MAX_SHARPNESS_PX
    min_corner_fraction: float = MIN_CORNER_FRACTION
    min_corners: int = MIN_CORNERS


def detect_board(grey: NDArray[np.uint8], spec: BoardSpec, name: str = "", quality: Quality | None = None) -> Detection:
    """Find the board's corners in a grey image (H, W) and judge the view's quality."""
    quality = quality or Quality()
    find = _find_chessboard if spec.kind == "chessboard" else _find_charuco
    found = find(grey, spec, name)
    if found is None:
        what = "board" if spec.kind == "charuco" else "whole board"
        return Detection(None, f"no {what} found by any detector")
    if len(found.ids) < quality.min_corners or found.fraction < quality.min_corner_fraction:
        return Detection(None, f"partial: {len(found.ids)} of {spec.corner_count} corners in view", found)
    if not np.isfinite(found.sharpness_px):
        return Detection(
            None,
            f"too little contrast between the squares (under {MIN_EDGE_CONTRAST} grey levels near most corners)"
            " to judge the focus; more light or a longer exposure",
            found,
        )
    if found.sharpness_px > quality.max_sharpness_px:
        return Detection(
            None,
            f"blurred: edges rise over {found.sharpness_px:.1f} px"
            f" (limit {quality.max_sharpness_px:.1f}); hold the board still or shorten the exposure",
            found,
        )
    return Detection(found)


def _find_chessboard(grey: NDArray[np.uint8], spec: BoardSpec, name: str) -> BoardView | None:
    cols, rows = spec.inner_corners
    corners = None
    # Half resolution first: four times faster, and enough to find a board that is not
    # tiny. Where its squares are small (a distant or steeply tilted board) the
    # half-resolution corners can be pixels off, so the board is found again at full
    # resolution in a window around it; the corners are refined below either way.
    finder = ""
    if min(grey.shape[:2]) >= 720:
        small = cv2.resize(grey, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
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


def stretched(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """The image's 1st to 99th percentile of grey spread over 0-255 (a dim, low-contrast photo)."""
    low, high = (float(v) for v in np.percentile(image[::2, ::2], (1, 99)))
    if high - low < 1.0:
        return image
    return np.clip((image.astype(np.float32) - low) * (255.0 / (high - low)), 0, 255).astype(np.uint8)


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
        if k == 1 and not (_board_likely(image, cols, rows) or _board_likely(stretched(image), cols, rows)):
            return None
        corners = find(image, cols, rows)
        if corners is not None and corners_are_junctions(image, corners.reshape(rows, cols, 2)):
            return corners, name
    return None


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
    every neighbouring size is tried and the largest found is named, the way round the user gave.
    """
    if spec.kind != "chessboard":
        return None
    cols, rows = spec.inner_corners
    if min(grey.shape[:2]) >= 720:
        grey = cv2.resize(grey, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
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
    # answer, and a failed search (about 0.3 s on a 640 x 480 photo) is not run for the smaller ones.
    for _, _, c, r in sorted(candidates, reverse=True):
        for flags in (cv2.CALIB_CB_NORMALIZE_IMAGE, 0):
            corners = _sb(grey, c, r, flags)
            # A grid that runs onto the printed margin is not a board of that size.
            if corners is not None and corners_are_junctions(grey, corners.reshape(r, c, 2)):
                return f"chessboard:{c + 1}x{r + 1}:{_mm(spec.square_m)}"
    return None


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


def _find_charuco(grey: NDArray[np.uint8], spec: BoardSpec, name: str) -> BoardView | None:
    detector = _charuco_detector(spec)
    # A dim photo's markers can fall below the marker detector's thresholds; a contrast-stretched
    # copy is the second try.
    finder = "charuco"
    corners, ids, _, _ = detector.detectBoard(grey)
    if ids is None or corners is None or len(ids) < 4:
        finder = "charuco, contrast stretched"
        corners, ids, _, _ = detector.detectBoard(stretched(grey))
        if ids is None or corners is None or len(ids) < 4:
            return None
    ids = np.asarray(ids, dtype=np.int64).ravel()
    points = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    order = np.argsort(ids)
    ids, points = ids[order], points[order]
    height, width = grey.shape[:2]
    cols, _ = spec.inner_corners
    # Image size of a square from neighbouring corners along rows.
    neighbours = [
        float(np.linalg.norm(points[k + 1] - points[k]))
        for k in range(len(ids) - 1)
        if ids[k + 1] == ids[k] + 1 and ids[k] % cols != cols - 1
    ]
    square = float(np.median(neighbours)) if neighbours else 20.0
    return BoardView(
        ids,
        points,
        spec.object_points_m[ids].copy(),
        (width, height),
        edge_sharpness_px(grey, points, square),
        spec.corner_count,
        name,
        {"detector": finder},
    )


_DETECTORS: dict[str, cv2.aruco.CharucoDetector] = {}


def _charuco_detector(spec: BoardSpec) -> cv2.aruco.CharucoDetector:
    key = str(spec)
    detector = _DETECTORS.get(key)
    if detector is None:
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
        charuco = cv2.aruco.CharucoParameters()
        charuco.tryRefineMarkers = True
        detector = cv2.aruco.CharucoDetector(spec.cv_board, charuco, params)
        _DETECTORS[key] = detector
    return detector


MIN_EDGE_CONTRAST = 8
"""Corners whose black and white squares differ by fewer grey levels are not used to judge sharpness
(noise would decide). A dim photo of a board may have 15-30 levels of contrast and still be sharp."""


def edge_sharpness_px(grey: NDArray[np.uint8], points_px: Array, square_px: float) -> float:
    """Median 10-90 % rise distance of the edges around corners (N, 2), in pixels.

    Around each corner, the steepest gradient of the black-to-white step relates
    to its contrast as ``rise = 0.8 * contrast / max gradient`` for a linear ramp; a
    sharp, anti-aliased edge gives about 1 px, a blurred one several. The same
    measure serves both board kinds (OpenCV's estimateChessboardSharpness needs a
    complete chessboard).
    """
    radius = int(np.clip(0.35 * square_px, 3, 12))
    h, w = grey.shape[:2]
    gx = cv2.Sobel(grey, cv2.CV_32F, 1, 0, ksize=3) / 8.0
    gy = cv2.Sobel(grey, cv2.CV_32F, 0, 1, ksize=3) / 8.0
    magnitude = np.sqrt(gx * gx + gy * gy)
    rises = []
    step = max(1, len(points_px) // 40)
    for x, y in np.asarray(points_px)[::step]:
        xi, yi = int(np.rint(x)), int(np.rint(y))
        x0, x1 = max(0, xi - radius), min(w, xi + radius + 1)
        y0, y1 = max(0, yi - radius), min(h, yi + radius + 1)
        patch = grey[y0:y1, x0:x1]
        if patch.size < 9:
            continue
        contrast = float(np.percentile(patch, 95) - np.percentile(patch, 5))
        steepest = float(np.max(magnitude[y0:y1, x0:x1]))
        if contrast < MIN_EDGE_CONTRAST or steepest <= 0:
            continue
        rises.append(0.8 * contrast / steepest)
    return float(np.median(rises)) if rises else float("inf")
