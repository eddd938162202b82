"""The sub-pixel centre of an end: intensity-weighted centroid, or the report's eq. 12.

Both are measured on the colour test of :func:`~trackerd.detect.colour.excess_window`,
which compares each of the colour's samples with its neighbours *interpolated
at that sample's own position* (symmetric about it), so that neither the test
nor the weights lean towards where the other colours sit in the Bayer cell.
Every sample is placed at its own full-resolution pixel position (for the R
sample of cell (i, j) in BayerRG8, (x, y) = (2j, 2i); for the B sample
(2j + 1, 2i + 1)), which removes the half-pixel bias a cell-centred position
would have.

Weighted centroid: each sample weighs its colour excess less WEIGHT_FLOOR,
capped at WEIGHT_SATURATION times the blob's mean excess. Inside the ball every
sample therefore weighs the same (the lit side does not pull the centre towards
the light), and a partly covered sample of the rim weighs in proportion to how
much of it the ball covers, which is what gives sub-pixel resolution. The area
is the summed coverage.

Eq. 12: the midpoint of the extent (min and max x and y) of the samples passing
the threshold, and the area is their count.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.detect.candidates import Candidate
from trackerd.detect.colour import EXCESS_SCALE, Region, SampleGrid, Threshold, excess_window

WEIGHT_FLOOR = 8
"""Excess (grey levels) below which a sample gets no weight: sensor noise and neutral
surfaces sit below it, the anti-aliased rim of a ball mostly above."""

WEIGHT_SATURATION = 0.6
"""A sample whose excess reaches this fraction of the blob's mean excess counts as fully covered."""


@dataclass(frozen=True, slots=True)
class Measurement:
    """An end measured in one region of a frame (full-resolution pixel units)."""

    x_px: float
    y_px: float
    area_px: float
    bbox_px: tuple[int, int, int, int]
    """(x0, y0, x1, y1), inclusive: the outermost samples passing the threshold."""
    on_border: bool
    """Whether samples passing the threshold touch the region's border (the end may be cut)."""
    elongation: float
    """Of the samples passing the threshold (NaN unless measured with ``shape=True``)."""
    fill: float
    """Samples passing the threshold over their bounding box (NaN unless ``shape=True``)."""

    @property
    def centre_px(self) -> NDArray[np.float64]:
        return np.array([self.x_px, self.y_px])


def measure_region(
    frame: NDArray[np.uint8],
    grid: SampleGrid,
    colour: str,
    threshold: Threshold,
    region: Region,
    weighted: bool,
    *,
    shape: bool = False,
    candidate: Candidate | None = None,
) -> Measurement | None:
    """Measure the samples of ``colour`` in ``region`` (cells, inside ``grid.interior()``).

    Everything in the region counts, except, when ``candidate`` is given, the
    samples of the other blobs found with it. Returns None if no sample passes
    the threshold.
    """
    excess, value = excess_window(frame, grid, colour, region)
    weight = excess.astype(np.float32)
    if candidate is not None and not candidate.alone:
        _clear_other_blobs(
            weight, candidate, region[0] - candidate.origin[0], region[2] - candidate.origin[1]
        )
    strong = weight >= EXCESS_SCALE * threshold.min_excess
    if threshold.min_value > 0:
        strong &= value >= threshold.min_value
    n_strong = int(np.count_nonzero(strong))
    if n_strong == 0:
        return None
    h, w = strong.shape
    cols = strong.any(axis=0).nonzero()[0]
    rows = strong.any(axis=1).nonzero()[0]
    c0, c1, r0, r1 = int(cols[0]), int(cols[-1]), int(rows[0]), int(rows[-1])
    s = grid.cell_px
    dr, dc = grid.offset(colour)
    x0, y0 = s * region[2] + dc, s * region[0] + dr  # full-resolution position of cell (0, 0)
    bbox = (x0 + s * c0, y0 + s * r0, x0 + s * c1, y0 + s * r1)
    on_border = c0 == 0 or r0 == 0 or c1 == w - 1 or r1 == h - 1
    elongation = fill = math.nan
    if shape:
        elongation, fill = _shape(strong, n_strong, c0, c1, r0, r1)
    if not weighted:
        return Measurement(
            (bbox[0] + bbox[2]) / 2.0,
            (bbox[1] + bbox[3]) / 2.0,
            float(n_strong * s * s),
            bbox,
            on_border,
            elongation,
            fill,
        )
    floor = float(EXCESS_SCALE * WEIGHT_FLOOR)
    cap = max(WEIGHT_SATURATION * float(weight[strong].sum()) / n_strong, floor + 1.0)
    weight -= floor
    np.clip(weight, 0.0, cap - floor, out=weight)
    total = float(weight.sum())
    mx = float(weight.sum(axis=0) @ _ramp(w)) / total
    my = float(weight.sum(axis=1) @ _ramp(h)) / total
    return Measurement(
        x0 + s * mx, y0 + s * my, total / (cap - floor) * s * s, bbox, on_border, elongation, fill
    )


def measure_candidate(
    frame: NDArray[np.uint8], grid: SampleGrid, c: Candidate, threshold: Threshold, weighted: bool
) -> Measurement:
    """Measure a chosen candidate around its blob (box grown by a cell), other blobs left out."""
    x0, y0, x1, y1 = c.bbox_cells
    r, q = c.origin
    lo_r, hi_r, lo_c, hi_c = grid.interior()
    region = (
        max(lo_r, r + y0 - 1),
        min(hi_r, r + y1 + 2),
        max(lo_c, q + x0 - 1),
        min(hi_c, q + x1 + 2),
    )
    m = measure_region(frame, grid, c.colour, threshold, region, weighted, candidate=c)
    if m is None:  # only if the cell test and the symmetric test disagree on every sample
        bbox = c.bbox_px(grid)
        return Measurement(c.x_px, c.y_px, c.area_px, bbox, False, c.elongation, c.fill)
    return m


def _shape(
    strong: NDArray[np.bool_], n: int, c0: int, c1: int, r0: int, r1: int
) -> tuple[float, float]:
    """Elongation and fill of the set samples of a mask (see trackerd.detect.blobs.BlobStats)."""
    h, w = strong.shape
    mass = strong.astype(np.float32)
    xs, ys = _ramp(w), _ramp(h)
    col, row = mass.sum(axis=0), mass.sum(axis=1)
    mx, my = float(col @ xs) / n, float(row @ ys) / n
    xx = float(col @ (xs * xs)) / n - mx * mx + 1.0 / 12.0
    yy = float(row @ (ys * ys)) / n - my * my + 1.0 / 12.0
    xy = float(ys @ mass @ xs) / n - mx * my
    half_sum = 0.5 * (xx + yy)
    root = math.sqrt(0.25 * (xx - yy) ** 2 + xy * xy)
    elongation = math.sqrt((half_sum + root) / max(half_sum - root, 1e-12))
    return elongation, n / ((c1 - c0 + 1) * (r1 - r0 + 1))


_RAMPS: dict[int, NDArray[np.float32]] = {}


def _ramp(n: int) -> NDArray[np.float32]:
    """0, 1, ..., n - 1 as float32 (cached: windows come in few sizes)."""
    ramp = _RAMPS.get(n)
    if ramp is None:
        ramp = np.arange(n, dtype=np.float32)
        ramp.setflags(write=False)
        if len(_RAMPS) < 4096:
            _RAMPS[n] = ramp
    return ramp


def _clear_other_blobs(weight: NDArray[np.float32], c: Candidate, sy0: int, sx0: int) -> None:
    """Zero the weight of every sample of the candidate's window's other blobs.

    ``weight`` covers strip cells from (sy0, sx0) (see trackerd.detect.strip);
    strip cells outside the candidate's window are black gap or other windows,
    whose runs lie outside ``weight`` or are skipped.
    """
    h, w = weight.shape
    runs = c.runs
    near = (runs.rows >= sy0) & (runs.rows < sy0 + h) & (runs.last >= sx0) & (runs.first < sx0 + w)
    near &= c.labels != c.label
    for i in near.nonzero()[0].tolist():
        weight[
            int(runs.rows[i]) - sy0, max(int(runs.first[i]) - sx0, 0) : int(runs.last[i]) - sx0 + 1
        ] = 0.0
