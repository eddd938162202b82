"""The chessboard search's shortcuts give what the full search gives, on OpenCV's real sample photos:
a board larger than the one asked for ends the search early with no board, and the wrong-board hint
named from one search for a larger board is the one every neighbouring size, tried in turn, names."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from trackerd.calibration import chessboard
from trackerd.calibration.board import BoardSpec
from trackerd.calibration.chessboard import board_size_hint, find_chessboard

PHOTOS = Path(__file__).resolve().parents[1] / "data" / "opencv-stereo-chessboard"


def _photo(name: str) -> np.ndarray:
    image = cv2.imread(str(PHOTOS / name), cv2.IMREAD_GRAYSCALE)
    assert image is not None, name
    return image


def test_a_board_larger_than_asked_ends_the_search_without_the_other_detectors(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # left01 shows 9 x 6 inner corners; asked for 8 x 5 (--board 9x6 counting corners as squares),
    # the first search returns the whole board, a true grid, and no other detector runs.
    image = _photo("left01.jpg")
    later: list[str] = []
    monkeypatch.setattr(chessboard, "_board_likely", lambda *args: later.append("quick check") or True)
    assert chessboard._first_search(image, 8, 5) == "larger board"
    assert find_chessboard(image, BoardSpec.parse("chessboard:9x6:25"), "left01") is None
    assert later == []
    # The board asked for is found as before, by the first detector.
    view = find_chessboard(image, BoardSpec.parse("chessboard:10x7:25"), "left01")
    assert view is not None and view.meta["detector"] == "sector, normalised" and len(view.ids) == 54


@pytest.mark.parametrize(("given", "named"), [("9x6", "10x7"), ("6x9", "7x10")])
def test_the_hint_from_one_search_is_the_hint_from_every_neighbour(
    given: str, named: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    image = _photo("left01.jpg")
    spec = BoardSpec.parse(f"chessboard:{given}:25")
    assert board_size_hint(image, spec) == f"chessboard:{named}:25"
    # Without the search for a larger board, every neighbouring size is tried, largest first.
    monkeypatch.setattr(chessboard, "_board_shown", lambda *args: None)
    assert board_size_hint(image, spec) == f"chessboard:{named}:25"


def test_an_image_without_a_board_has_no_hint() -> None:
    blank = np.full((240, 320), 128, np.uint8)
    assert board_size_hint(blank, BoardSpec.parse("chessboard:10x7:25")) is None
