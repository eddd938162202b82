"""The centre from every pixel of the rim, one end at a time, written plainly: the reference.

This is the first implementation of :mod:`trackerd.detect.coverage` (2-D arrays,
one end per call, about 45 NumPy calls), with the unsolved pixels' estimate
since steepened (BESIDE_SLOPE). The detector now measures both ends at once on
flat arrays (:mod:`trackerd.detect.flat`), which is faster and much harder to
read; the tests check that it computes the same thing as this.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from trackerd.detect.colour import SampleGrid
from trackerd.detect.coverage import BESIDE_SLOPE, DARK_FRACTION, MIN_CONTRAST, MIX_SLACK, Rim


def rim_centre(frame: NDArray[np.uint8], grid: SampleGrid, end: Rim) -> tuple[float, float, float] | None:
    """Centre (x, y) and area of an end from the coverage of every pixel, full-resolution pixels.

    ``end.strong`` should hold every thresholded sample of the end with a cell
    of margin (measure's box does, unless the end reaches its window's border).
    None when it does not, when the cells and a ring around them do not fit in
    the frame, or when nothing is covered: keep the own samples' estimate then.
    """
    h, w = end.strong.shape
    r0, c0 = end.origin
    if r0 < 1 or c0 < 1 or r0 + h + 1 > grid.rows or c0 + w + 1 > grid.cols:
        return None
    edge = end.strong[0].any() or end.strong[-1].any() or end.strong[:, 0].any()
    if edge or end.strong[:, -1].any():
        return None  # part of the rim would be outside the arrays
    dr, dc = grid.offset(end.colour)
    # The cells and a ring of cells around them, the end's own colour at each cell's top-left
    # pixel. Red and blue are diagonal in every Bayer layout, so the other colour is then
    # bottom-right and the greens are right of and below the own sample, for either end.
    patch = frame[2 * r0 - 2 + dr : 2 * (r0 + h) + 2 + dr, 2 * c0 - 2 + dc : 2 * (c0 + w) + 2 + dc]
    # One copy: the four samples of each cell as four planes (own, right, below, diagonal).
    planes = patch.reshape(h + 2, 2, w + 2, 2).transpose(1, 3, 0, 2).astype(np.float32)
    planes = planes.reshape(4, h + 2, w + 2)
    others = planes[1:]

    # Each other sample against the pair of its channel's samples two pixels to either side,
    # along the row or the column, whichever differ more.
    value = others[:, 1:-1, 1:-1]
    left, right = others[:, 1:-1, :-2], others[:, 1:-1, 2:]
    above, below = others[:, :-2, 1:-1], others[:, 2:, 1:-1]
    ball_h = np.minimum(left, right)
    back_h = np.maximum(left, right)
    ball_v = np.minimum(above, below)
    back_v = np.maximum(above, below)
    contrast_h = back_h - ball_h
    contrast_v = back_v - ball_v
    across_row = contrast_h >= contrast_v
    ball = np.where(across_row, ball_h, ball_v)
    back = np.where(across_row, back_h, back_v)
    contrast = np.maximum(contrast_h, contrast_v)
    solved = contrast >= MIN_CONTRAST
    slack = contrast * MIX_SLACK
    solved &= value >= ball - slack
    solved &= value <= back + slack
    # The own samples next to a cell's other pixels: its own, right, below and diagonal.
    dark = planes[0] <= DARK_FRACTION * end.own_level
    near_dark = dark[1:-1, 1:-1] | dark[1:-1, 2:]
    near_dark |= dark[2:, 1:-1]
    near_dark |= dark[2:, 2:]
    solved &= ~near_dark
    mixed = back - value
    mixed /= np.maximum(contrast, 1.0)
    np.minimum(mixed, 1.0, out=mixed)
    np.maximum(mixed, 0.0, out=mixed)

    # Unsolved: the mean of the own samples beside (the green right of the own sample has one
    # left and one right of it, the green below one above and one below, the other colour four
    # at the diagonals).
    own = np.zeros((h + 1, w + 1), dtype=np.float32)
    own[:-1, :-1] = end.cover
    beside = np.empty_like(value)
    np.add(own[:-1, :-1], own[:-1, 1:], out=beside[0])
    np.add(own[:-1, :-1], own[1:, :-1], out=beside[1])
    np.add(beside[0], own[1:, :-1], out=beside[2])
    beside[2] += own[1:, 1:]
    beside[:2] *= 0.5
    beside[2] *= 0.25
    beside = np.clip(0.5 + BESIDE_SLOPE * (beside - 0.5), 0.0, 1.0)
    cover = np.where(solved, mixed, beside)  # own-sample coverage is in [0, 1], so is beside

    # Per cell: its four pixels' coverage, and how much of it lies one pixel right or down.
    strong = np.zeros((h + 2, w + 2), dtype=np.float32)
    strong[1:-1, 1:-1] = end.strong
    near = _box3(strong)
    per_cell = cover.sum(axis=0)
    per_cell += end.cover
    right_px = cover[0] + cover[2]
    down_px = cover[1] + cover[2]
    inside = near >= 9.0
    per_cell[inside] = 4.0
    right_px[inside] = 2.0
    down_px[inside] = 2.0
    empty = near == 0.0
    per_cell[empty] = 0.0
    right_px[empty] = 0.0
    down_px[empty] = 0.0
    total = float(per_cell.sum())
    if not total > 0.0:
        return None
    x = 2.0 * float(per_cell.sum(axis=0) @ _ramp(w)) + float(right_px.sum())
    y = 2.0 * float(per_cell.sum(axis=1) @ _ramp(h)) + float(down_px.sum())
    return x / total + 2 * c0 + dc, y / total + 2 * r0 + dr, total


def _box3(values: NDArray[np.float32]) -> NDArray[np.float32]:
    """Sum over the 3x3 neighbourhood of every element not on the border: shape (h-2, w-2)."""
    rows = values[:, :-2] + values[:, 1:-1]
    rows += values[:, 2:]
    out = rows[:-2] + rows[1:-1]
    out += rows[2:]
    return out


_RAMPS: dict[int, NDArray[np.float32]] = {}


def _ramp(n: int) -> NDArray[np.float32]:
    """0, 1, ..., n - 1 as float32 (cached: boxes come in few sizes)."""
    ramp = _RAMPS.get(n)
    if ramp is None:
        ramp = np.arange(n, dtype=np.float32)
        ramp.setflags(write=False)
        if len(_RAMPS) < 4096:
            _RAMPS[n] = ramp
    return ramp
