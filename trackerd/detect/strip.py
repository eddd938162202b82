"""Many small windows of a frame packed into one small image, to measure them all at once.

A search ends with a handful of windows, each a few hundred cells. Measuring
them one by one costs some sixty NumPy calls per window, and at this size each
call's fixed overhead (about a microsecond) is the whole cost. Copying the
windows into one *strip* first (one slice assignment each) and measuring the
strip with one set of calls takes a frame's refinement from milliseconds to a
fraction of one.

Windows stay aligned to the Bayer cell, so the strip is itself a valid mosaic,
and are separated by a gap of one black cell, so no blob can run from one
window into the next (black is no colour). They are packed in shelves, tallest
first, in one zone per colour (each zone gets only its own colour's test).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.detect.colour import Region, SampleGrid

LARGE_WINDOW_CELLS = 1600
"""Windows with more cells than this are copied at half (or quarter) resolution."""


@dataclass(frozen=True, slots=True)
class Strip:
    """Windows of a frame copied into one image; positions in cells of the same grid."""

    image: NDArray[np.uint8]
    grid: SampleGrid
    """The frame's sample layout, resized to the strip."""
    rows: list[int]
    """Strip cell row of each window's first cell (parallel to the jobs)."""
    cols: list[int]
    """Strip cell column of each window's first cell."""
    zones: list[tuple[str, int, int]]
    """(colour, first row, end row) of each colour's zone."""
    shelf_tops: NDArray[np.int64]
    """First row of each shelf, increasing."""
    shelf_jobs: NDArray[np.int32]
    """(shelves, width): the window index of each column of each shelf (-1 in gaps)."""
    scales: list[int]
    """Each window keeps every ``scale``-th cell along both axes (1: all)."""
    shapes: list[tuple[int, int]]
    """(rows, cols) of each window in the strip."""

    def jobs_at(self, rows: NDArray[np.int64], cols: NDArray[np.int64]) -> list[int]:
        """Index of the window holding each strip cell (rows[i], cols[i]) (each inside a window)."""
        shelf = self.shelf_tops.searchsorted(rows, side="right") - 1
        jobs: list[int] = self.shelf_jobs[shelf, cols].tolist()
        return jobs

    def origin(self, job: int, window: Region) -> tuple[int, int]:
        """(row, col) such that strip cell c of window ``job`` is frame cell origin + scale * c."""
        k = self.scales[job]
        return window[0] - k * self.rows[job], window[2] - k * self.cols[job]


def scale_for(window: Region) -> int:
    """Cells kept along each axis of a window: every one, or every 2nd or 4th of a large window.

    A window larger than LARGE_WINDOW_CELLS holds either a ball close to the camera,
    large enough to classify from a quarter of its cells, or a large surface of
    the colour, often speckled where its colour is near the threshold, whose
    hundreds of specks would cost far more to label at full resolution than the
    ball does. (The chosen end is measured at full resolution in the frame.)
    """
    cells = (window[1] - window[0]) * (window[3] - window[2])
    scale = 1
    while cells > LARGE_WINDOW_CELLS and scale < 4:
        cells //= 4
        scale *= 2
    return scale


def pack(frame: NDArray[np.uint8], grid: SampleGrid, jobs: list[tuple[str, Region]]) -> Strip:
    """Copy each (colour, window) job's window into a strip, a black cell between windows.

    The strip's first and last columns are always black.
    """
    # The windows' sizes in one plain loop (a frame has a handful: Python steps, not
    # arithmetic, are the cost here).
    scales: list[int] = []
    shapes: list[tuple[int, int]] = []
    boxes: list[tuple[int, int]] = []
    tall: list[int] = []
    mine: dict[str, list[int]] = {"red": [], "blue": []}
    area = widest = 0
    for j, (colour, region) in enumerate(jobs):
        k = scale_for(region)
        h, w = -(-(region[1] - region[0]) // k), -(-(region[3] - region[2]) // k)
        scales.append(k)
        shapes.append((h, w))
        boxes.append((h + 1, w + 1))  # with the gap after
        tall.append(h + 1)
        mine[colour].append(j)
        area += (h + 1) * (w + 1)
        widest = w + 1 if w + 1 > widest else widest
    width = max(widest, math.isqrt(area) + 1) + 1
    rows = [0] * len(jobs)
    cols = [0] * len(jobs)
    zones = []
    shelf_tops: list[int] = []
    shelf_of = [0] * len(jobs)
    height = 1
    for colour in ("red", "blue"):
        if not mine[colour]:
            continue
        top = height
        x = width  # forces a new shelf
        shelf = 0
        # Tallest first (reverse keeps the jobs' order among equal heights).
        for j in sorted(mine[colour], key=tall.__getitem__, reverse=True):
            h, w = boxes[j]
            if x + w > width:
                height, x, shelf = height + shelf, 1, 0
                shelf_tops.append(height)
            rows[j], cols[j] = height, x
            shelf_of[j] = len(shelf_tops) - 1
            x += w
            shelf = max(shelf, h)
        height += shelf
        zones.append((colour, top, height))
    s = grid.cell_px
    image = np.zeros((s * height, s * width, *frame.shape[2:]), dtype=np.uint8)
    shelf_jobs = np.full((len(shelf_tops), width), -1, dtype=np.int32)
    for j, (_, (r0, r1, c0, c1)) in enumerate(jobs):
        y, x = rows[j], cols[j]
        h, w = shapes[j]
        window = frame[s * r0 : s * r1, s * c0 : s * c1]
        target = image[s * y : s * (y + h), s * x : s * (x + w)]
        k = scales[j]
        if k > 1:
            # Every k-th cell, whole (a Bayer cell's 2x2 samples stay together), copied once.
            cells = window.reshape(r1 - r0, s, c1 - c0, s, *frame.shape[2:])[::k, :, ::k, :]
            blocks = target.view()
            blocks.shape = (h, s, w, s, *frame.shape[2:])  # a view, never a silent copy
            blocks[...] = cells
        else:
            target[...] = window
        shelf_jobs[shelf_of[j], x : x + w] = j
    # (Not dataclasses.replace: it costs more than the rest of this function's bookkeeping.)
    strip_grid = SampleGrid(
        grid.pixel_format,
        grid.cell_px,
        height,
        width,
        grid.red,
        grid.blue,
        grid.green_a,
        grid.green_b,
        grid.channels,
        image.shape,
    )
    return Strip(image, strip_grid, rows, cols, zones, np.array(shelf_tops), shelf_jobs, scales, shapes)
