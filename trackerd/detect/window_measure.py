"""Both ends measured at once in small windows where tracking expects them (Bayer frames).

While the pointer is tracked, each end is almost always where its
motion says: one round blob in a small window around the prediction. This
measures the ends' windows together, in one set of flat arrays
(:mod:`trackerd.detect.flat`), all the way to the centre from every pixel:

1. the symmetric colour test (as :func:`trackerd.detect.colour.excess_window`:
   each own sample against the greens and the other colour interpolated at its
   own position) and the threshold, in every cell of both windows;
2. each end's thresholded box, area, fill and box aspect; an end that reaches
   its window's border or is not round and full enough ends the attempt here;
3. the coverage of the end's own samples, in its box grown by a cell (as
   :func:`trackerd.detect.centroid.measure`);
4. every pixel's coverage and the centre (:func:`trackerd.detect.coverage.solve`),
   or the centre of the own samples' coverage alone.

It computes what the end-by-end path computes (tests compare them); about 80
NumPy calls for both ends instead of about 170.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.detect.centroid import COVERAGE_FLOOR, COVERAGE_FULL, Measurement
from trackerd.detect.colour import EXCESS_SCALE, Region, SampleGrid, Threshold
from trackerd.detect.coverage import solve
from trackerd.detect.flat import Ops, Workspace, WorkspaceCache, run


@dataclass(frozen=True, slots=True)
class BlobShape:
    """What a blob must be for the quick measurement to stand: round and full."""

    max_elongation: float
    """Longer side of the thresholded box over its shorter."""
    min_fill: float
    """Thresholded samples over the box's samples."""


ANY_SHAPE = BlobShape(float("inf"), 0.0)

WindowOrigin = tuple[int, int, int, int]
"""Where a window lies: (r0, c0, dr, dc), the frame cell of its first cell (ring included) and
the end's colour offset in a cell (:func:`window_origin`)."""


def measure_windows(
    frame: NDArray[np.uint8] | Sequence[NDArray[np.uint8]],
    grid: SampleGrid,
    ends: list[tuple[str, float, float]],
    half_cells: int,
    thresholds: dict[str, Threshold],
    shape: BlobShape,
    cache: WorkspaceCache,
    within: list[Region] | None = None,
    every_pixel: bool = True,
    origins: Sequence[WindowOrigin | None] | None = None,
) -> list[Measurement] | None:
    """Each (colour, x_px, y_px) end measured in the cells within ``half_cells`` of that point.

    ``frame`` is the frame of every end, or a sequence of one frame per end (the
    ends of several cameras measured together: their frames must share ``grid``'s
    layout). Returns one measurement per end (centre and area from every pixel, or with
    ``every_pixel=False`` from the own samples alone), or None as soon as one end
    is not clearly there: nothing of its colour, touching the window's border,
    not of ``shape``, outside its region of ``within`` (frame cells, one per end),
    or the window not fitting in the frame. ``origins`` gives, per end, the
    :func:`window_origin` of its window where the caller has it already (None
    where not).
    """
    n = len(ends)
    size = 2 * half_cells + 1
    ws = cache.get(n, size + 2, size + 2, "window")
    placed = _gather(frame, grid, ends, half_cells, ws, origins)
    if placed is None:
        return None
    if _set_thresholds(ws, [thresholds[colour] for colour, _, _ in ends]):
        run(ws.ops("excess and value", _excess_ops))
    else:
        run(ws.ops("excess", _excess_ops_no_value))

    # Boxes and shapes (rows and columns of the window with its ring: 1 .. size).
    # (Array methods, not np.flatnonzero and np.searchsorted: the same calls without their Python wrappers.)
    found = ws.strong.nonzero()[0]
    cuts = found.searchsorted(ws.window_starts).tolist()
    counts = [cuts[e + 1] - cuts[e] for e in range(n)]
    if not all(counts):
        return None
    firsts = cuts[:-1]
    first_last = found[firsts + [c - 1 for c in cuts[1:]]].tolist()
    columns = found % ws.cols
    left = np.minimum.reduceat(columns, firsts).tolist()
    right = np.maximum.reduceat(columns, firsts).tolist()
    boxes = []
    for e in range(n):
        i0 = (first_last[e] - e * ws.cells) // ws.cols
        i1 = (first_last[n + e] - e * ws.cells) // ws.cols
        j0, j1 = left[e], right[e]
        if i0 == 1 or j0 == 1 or i1 == size or j1 == size:
            return None  # on the window's border: may be cut, or something else is there
        if within is not None:
            # Window cell (i, j) is frame cell (r0 + i - 1, c0 + j - 1).
            r0, c0, _, _ = placed[e]
            top, bottom, first, last = within[e]
            if not (top <= r0 + i0 - 1 and r0 + i1 - 1 < bottom):
                return None
            if not (first <= c0 + j0 - 1 and c0 + j1 - 1 < last):
                return None
        tall, wide = i1 - i0 + 1, j1 - j0 + 1
        elongation = max(tall, wide) / min(tall, wide)
        fill = counts[e] / (tall * wide)
        if elongation > shape.max_elongation or fill < shape.min_fill:
            return None
        boxes.append((i0, i1, j0, j1, elongation, fill))

    # The own samples' coverage in each blob's box grown by a cell (the rest of the window is
    # background, whose faint colour must not count).
    ws.box.fill(0.0)
    for e, (i0, i1, j0, j1, _, _) in enumerate(boxes):
        ws.box_3d[e, i0 - 1 : i1 + 2, j0 - 1 : j1 + 2] = 1.0
    own_sums, excess_sums = np.vecdot(ws.own_and_excess, ws.strong_2d).tolist()
    # One assignment for all windows (each cast to float32 as a window's own assignment would be).
    ws.level_2d[...] = np.array([[0.5 * excess_sums[e] / counts[e]] for e in range(n)])
    run(ws.ops("own coverage", _own_coverage_ops))

    if every_pixel:
        sums = solve(ws, [own_sums[e] / counts[e] for e in range(n)])
    else:
        # The own samples alone, as trackerd.detect.centroid.measure: each at its own pixel,
        # a cell's worth of area (four pixels) each.
        moments = ws.cover.reshape(n, ws.cells).dot(ws.moments).tolist()
        sums = [(4.0 * total, 4.0 * x, 4.0 * y) for total, x, y in moments]
    out = []
    for (r0, c0, dr, dc), (i0, i1, j0, j1, elongation, fill), (total, x_sum, y_sum) in zip(
        placed, boxes, sums, strict=True
    ):
        if not total > 0.0:
            return None
        # Window cell (i, j) is frame cell (r0 + i - 1, c0 + j - 1).
        x0, y0 = 2 * c0 + dc, 2 * r0 + dr
        bbox = (x0 + 2 * (j0 - 1), y0 + 2 * (i0 - 1), x0 + 2 * (j1 - 1), y0 + 2 * (i1 - 1))
        centre = (x_sum / total + x0, y_sum / total + y0)
        out.append(Measurement(*centre, total, bbox, False, elongation, fill))
    return out


def _gather(
    frames: NDArray[np.uint8] | Sequence[NDArray[np.uint8]],
    grid: SampleGrid,
    ends: list[tuple[str, float, float]],
    half_cells: int,
    ws: Workspace,
    known: Sequence[WindowOrigin | None] | None = None,
) -> list[WindowOrigin] | None:
    """Copy each end's window and ring into the workspace's planes; (r0, c0, dr, dc) per end.

    (r0, c0) is the frame cell of the window's first cell, (dr, dc) the end's
    colour offset in the cell (:func:`window_origin`, or ``known``'s where it
    has one). None if a window does not fit in the frame.
    """
    rows, cols = ws.rows, ws.cols
    origins = []
    for e, (colour, x_px, y_px) in enumerate(ends):
        frame = frames if isinstance(frames, np.ndarray) else frames[e]
        origin = None if known is None else known[e]
        if origin is None:
            origin = window_origin(frame.shape, grid, colour, x_px, y_px, half_cells)
            if origin is None:
                return None
        r0, c0, dr, dc = origin
        y, x = 2 * r0 - 2 + dr, 2 * c0 - 2 + dc
        ws.pixels[e] = frame[y : y + 2 * rows, x : x + 2 * cols]
        origins.append(origin)
    np.copyto(ws.planes_5d, ws.pixels_as_planes)
    return origins


def window_origin(
    frame_shape: tuple[int, ...], grid: SampleGrid, colour: str, x_px: float, y_px: float, half_cells: int
) -> WindowOrigin | None:
    """Where :func:`measure_windows` puts the window of ``half_cells`` around an end: (r0, c0, dr, dc),
    the frame cell of its first cell and the colour's offset in a cell; None if it does not fit."""
    height_px, width_px = frame_shape[0], frame_shape[1]
    rows = cols = 2 * half_cells + 3  # the window and its ring
    dr, dc = grid.red if colour == "red" else grid.blue
    r0 = round((y_px - dr) / 2.0) - half_cells
    c0 = round((x_px - dc) / 2.0) - half_cells
    # Slide a window that would leave the frame back in (its ring included). Several times a
    # pair for each end: comparisons rather than min() and max() calls.
    last_row, last_col = (height_px - dr) // 2 - rows + 1, (width_px - dc) // 2 - cols + 1
    r0 = r0 if r0 < last_row else last_row
    r0 = r0 if r0 > 1 else 1
    c0 = c0 if c0 < last_col else last_col
    c0 = c0 if c0 > 1 else 1
    if 2 * r0 - 2 + dr + 2 * rows > height_px or 2 * c0 - 2 + dc + 2 * cols > width_px:
        return None
    return r0, c0, dr, dc


def window_interior(
    frame_shape: tuple[int, ...], grid: SampleGrid, colour: str, x_px: float, y_px: float, half_cells: int
) -> Region | None:
    """The frame cells of that window off its border: a blob measured in it lies there, or it is not
    measured (it touches the border). None if the window does not fit in the frame."""
    origin = window_origin(frame_shape, grid, colour, x_px, y_px, half_cells)
    return None if origin is None else interior_of(origin, half_cells)


def interior_of(origin: WindowOrigin, half_cells: int) -> Region:
    """:func:`window_interior` of the window at ``origin`` (:func:`window_origin`'s)."""
    r0, c0, _, _ = origin
    size = 2 * half_cells + 1
    return (r0 + 1, r0 + size - 1, c0 + 1, c0 + size - 1)


def _set_thresholds(ws: Workspace, thresholds: list[Threshold]) -> bool:
    """Per cell, the excess and the own value a sample must reach (never, on the ring).

    Returns whether the own value needs testing: not when ``min_value`` is at most
    ``min_excess`` (an own value at least ``min_excess`` above the others is that high).
    """
    key = tuple((t.min_excess, t.min_value) for t in thresholds)
    needs_value = any(value > excess for excess, value in key)
    if key == ws.thresholds:
        return needs_value
    excess = ws.excess_min.reshape(ws.n, ws.rows, ws.cols)
    value = ws.value_min.reshape(ws.n, ws.rows, ws.cols)
    excess[...] = np.inf
    for e, t in enumerate(thresholds):
        excess[e, 1:-1, 1:-1] = EXCESS_SCALE * t.min_excess
        value[e] = t.min_value
    ws.thresholds = key
    return needs_value


def _excess_ops(ws: Workspace) -> Ops:
    """EXCESS_SCALE x (own sample - larger of the greens and the other colour at its position),
    and the threshold (``ws.strong``).

    The four greens around an own sample are the right-hand green of its cell and
    of the cell to its left, the lower green of its cell and of the cell above;
    the four diagonal neighbours are the other colour of its cell and of the cells
    left, above and above-left.
    """
    lo, hi, s = ws.lo, ws.hi, ws.cols
    planes, excess, strong = ws.planes, ws.excess[lo:hi], ws.strong[lo:hi]
    greens, diagonal, bright = ws.cell[0:3]
    return [
        (np.add, planes[1, lo - 1 : hi], planes[1, lo - 2 : hi - 1], greens[lo - 1 : hi]),
        (np.add, greens[lo:hi], planes[2, lo:hi], greens[lo:hi]),
        (np.add, greens[lo:hi], planes[2, lo - s : hi - s], greens[lo:hi]),
        (np.add, planes[3, 1:hi], planes[3, : hi - 1], diagonal[1:hi]),
        (np.add, diagonal[lo:hi], diagonal[lo - s : hi - s], diagonal[lo:hi]),
        (np.maximum, greens[lo:hi], diagonal[lo:hi], greens[lo:hi]),
        (np.multiply, planes[0, lo:hi], float(EXCESS_SCALE), excess),
        (np.subtract, excess, greens[lo:hi], excess),
        (np.greater_equal, excess, ws.excess_min[lo:hi], strong),
        (np.greater_equal, planes[0, lo:hi], ws.value_min[lo:hi], bright[lo:hi]),
        (np.multiply, strong, bright[lo:hi], strong),
    ]


def _excess_ops_no_value(ws: Workspace) -> Ops:
    """:func:`_excess_ops` without the test of the own value."""
    return _excess_ops(ws)[:-2]


def _own_coverage_ops(ws: Workspace) -> Ops:
    """``ws.cover`` from ``ws.excess`` in the boxes (``ws.box``), as centroid's ``_coverage``.

    Each sample's excess over the largest in its 3x3 neighbourhood (at least half
    the end's mean excess, ``ws.level``), mapped linearly from 0 at
    COVERAGE_FLOOR to 1 at COVERAGE_FULL; 0 outside the boxes.
    """
    lo, hi, s = ws.lo, ws.hi, ws.cols
    masked, across, local = ws.cell[3:6]
    cover, n_cells = ws.cover[lo:hi], hi - lo
    return [
        (np.multiply, ws.excess, ws.box, masked),
        (np.maximum, masked[:-2], masked[1:-1], across[1:-1]),
        (np.maximum, across[1:-1], masked[2:], across[1:-1]),
        (np.maximum, across[lo - s : hi - s], across[lo:hi], local[lo:hi]),
        (np.maximum, local[lo:hi], across[lo + s : hi + s], local[lo:hi]),
        (np.maximum, local[lo:hi], ws.level[lo:hi], local[lo:hi]),
        (np.multiply, local[lo:hi], COVERAGE_FULL - COVERAGE_FLOOR, local[lo:hi]),
        (np.divide, masked[lo:hi], local[lo:hi], cover),
        (np.subtract, cover, COVERAGE_FLOOR / (COVERAGE_FULL - COVERAGE_FLOOR), cover),
        (np.minimum, cover, ws.ones[:n_cells], cover),
        (np.maximum, cover, ws.zeros[:n_cells], cover),
    ]
