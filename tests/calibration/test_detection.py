"""An image searched again for the same board is not searched twice: the board found is kept by the
image's content, named as each caller names it, and judged under each caller's limits."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from trackerd.calibration import detection
from trackerd.calibration.board import BoardSpec, BoardView
from trackerd.calibration.detection import Quality, detect_board

PHOTO = Path(__file__).resolve().parents[1] / "data" / "opencv-stereo-chessboard" / "right03.jpg"
SPEC = BoardSpec.parse("chessboard:10x7:25")


def test_the_same_image_is_searched_once_and_judged_each_time(monkeypatch: pytest.MonkeyPatch) -> None:
    image = cv2.imread(str(PHOTO), cv2.IMREAD_GRAYSCALE)
    assert image is not None
    searches: list[tuple[int, ...]] = []
    search = detection.find_chessboard

    def counted(grey: np.ndarray, spec: BoardSpec, name: str) -> BoardView | None:
        searches.append(grey.shape)
        return search(grey, spec, name)

    monkeypatch.setattr(detection, "find_chessboard", counted)
    monkeypatch.setattr(detection, "_found", type(detection._found)())
    first = detect_board(image, SPEC, "first")
    again = detect_board(image.copy(), SPEC, "again", Quality(max_sharpness_px=0.1))
    assert len(searches) == 1
    assert first.view is not None and first.view.name == "first"
    assert again.view is None and again.found is not None and again.found.name == "again"
    assert again.reason is not None and again.reason.startswith("blurred")
    np.testing.assert_array_equal(again.found.image_points_px, first.view.image_points_px)
    # One pixel changed is another image, and another board size another search.
    changed = image.copy()
    changed[0, 0] ^= 1
    detect_board(changed, SPEC)
    detect_board(image, BoardSpec.parse("chessboard:9x6:25"))
    assert len(searches) == 3


def test_only_the_last_images_are_kept(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(detection, "_found", type(detection._found)())
    monkeypatch.setattr(detection, "FOUND_CACHE_SIZE", 3)
    for level in range(5):
        detect_board(np.full((60, 80), 40 * level, np.uint8), SPEC)
    assert len(detection._found) == 3
