"""Calibration boards: what they look like, and what a view of one holds.

Finding a board is :mod:`trackerd.calibration.detection` (and, for chessboards,
:mod:`trackerd.calibration.chessboard`); this module holds the board's description,
the grey image the finders search, and the measures of a view they share.

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
from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.pixelformat import BAYER_LAYOUTS

Array = NDArray[np.float64]

DEFAULT_DICTIONARY = "5X5_100"

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
        kind: Literal["chessboard", "charuco"] = "charuco" if match["kind"] == "charuco" else "chessboard"
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
        text = f"{self.kind}:{self.squares_x}x{self.squares_y}:{format_mm(self.square_m)}"
        if self.kind == "charuco":
            text += f":{format_mm(self.marker_m or 0.0)}:{self.dictionary}"
        return text

    def describe(self) -> str:
        """For humans: ``chessboard, 10 x 7 squares of 60 mm (54 inner corners)``."""
        text = (
            f"{self.kind}, {self.squares_x} x {self.squares_y} squares of {format_mm(self.square_m)} mm"
            f" ({self.corner_count} inner corners"
        )
        if self.kind == "charuco":
            text += f", {format_mm(self.marker_m or 0.0)} mm markers from {self.dictionary}"
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
        return np.asarray(parity == self._black_parity, dtype=np.bool_)

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
            bits = cv2.aruco.Dictionary.getBitsFromByteList(byte_list, dictionary.markerSize)
            out.append(
                (int(marker_id), np.asarray(corners, dtype=np.float64).reshape(4, 3), np.asarray(bits, dtype=np.uint8))
            )
        return tuple(out)


def format_mm(value_m: float) -> str:
    """A length in metres as millimetres, the way --board gives them (``0.025`` -> ``25``)."""
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
        return np.asarray(cv2.cvtColor(np.ascontiguousarray(frame), code), dtype=np.uint8)
    if pixel_format not in BAYER_LAYOUTS:
        return np.ascontiguousarray(frame)
    out = frame.astype(np.float32)
    levels = [float(np.percentile(frame[r::2, c::2][::4, ::4], 95)) for r in (0, 1) for c in (0, 1)]
    target = float(np.mean(levels))
    for (r, c), level in zip(((0, 0), (0, 1), (1, 0), (1, 1)), levels, strict=True):
        if level > 0:
            out[r::2, c::2] *= target / level
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


# --------------------------------------------------------------------------- views


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


def stretched(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """The image's 1st to 99th percentile of grey spread over 0-255 (a dim, low-contrast photo)."""
    low, high = (float(v) for v in np.percentile(image[::2, ::2], (1, 99)))
    if high - low < 1.0:
        return image
    return np.asarray(np.clip((image.astype(np.float32) - low) * (255.0 / (high - low)), 0, 255), dtype=np.uint8)


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
