"""Looking for a board in one image: the view found, or why the image gives none.

A board's search is the costly part of calibration (0.1 s to a few seconds an image), and one
process may look at the same image more than once (a live session offered an unchanged frame
again, a program that calibrates each camera and then the pair from the same images): the board
found in an image is kept, keyed by the image's content and the board, for the last
:data:`FOUND_CACHE_SIZE` images searched, and judged again under the caller's limits each time.
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict
from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.calibration.board import MIN_EDGE_CONTRAST, BoardSpec, BoardView, edge_sharpness_px, stretched
from trackerd.calibration.chessboard import find_chessboard

MAX_SHARPNESS_PX = 3.0
"""Views whose edges rise over more pixels than this (10 % to 90 %) are rejected as blurred;
OpenCV's guidance for ``estimateChessboardSharpness`` is "below about 3 pixels"."""

MIN_CORNER_FRACTION = 0.5
"""A partial ChArUco view must show at least this fraction of the board's corners."""

MIN_CORNERS = 8
"""And at least this many corners (a homography and a pose need a handful)."""


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
    found = find_board(grey, spec, name)
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


FOUND_CACHE_SIZE = 64
"""How many images' search results are kept (a few hundred bytes each; the images are not kept)."""

_found: OrderedDict[tuple[bytes, tuple[int, ...], str], BoardView | None] = OrderedDict()
_found_lock = threading.Lock()


def find_board(grey: NDArray[np.uint8], spec: BoardSpec, name: str = "") -> BoardView | None:
    """The board as found in a grey image (H, W), complete or not, named ``name``; None when no detector
    finds it. An image searched before for the same board (same pixels) is not searched again."""
    image = np.ascontiguousarray(grey)
    key = (hashlib.blake2b(image.data, digest_size=16).digest(), image.shape, str(spec))
    with _found_lock:
        cached = key in _found
        found = _found.get(key)
        if cached:
            _found.move_to_end(key)
    if not cached:
        found = (find_chessboard if spec.kind == "chessboard" else _find_charuco)(image, spec, "")
        with _found_lock:
            _found[key] = found
            while len(_found) > FOUND_CACHE_SIZE:
                _found.popitem(last=False)
    return None if found is None else replace(found, name=name)


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
