"""The sub-pixel centre of an end: intensity-weighted centroid, or the report's eq. 12.

Both are measured on the colour test of :func:`~trackerd.detect.colour.excess_window`,
which compares each of the colour's samples with its neighbours *interpolated
at that sample's own position* (symmetric about it), so that neither the test
nor the weights lean towards where the other colours sit in the Bayer cell.
Every sample is placed at its own full-resolution pixel position (for the R
sample of cell (i, j) in BayerRG8, (x, y) = (2j, 2i); for the B sample
(2j + 1, 2i + 1)), which removes the half-pixel bias a cell-centred position
would have.

Weighted centroid: over the blob's samples and a one-cell ring around them,
each sample weighs an estimate of how much of it the ball covers: its excess
over the largest excess in its 3x3 neighbourhood (see :func:`_coverage`).
Inside the ball every sample therefore weighs about the same, however the ball
is shaded (the lit side does not pull the centre towards the light), and a
partly covered sample of the rim weighs in proportion to its coverage, which
is what gives sub-pixel resolution. The area is the summed coverage. On a Bayer
mosaic these samples are one pixel in four, which costs about 0.07 px across
the pointer (a 2-pixel sampling lattice); :func:`measure_rims` then measures
the centre from every pixel instead (:mod:`trackerd.detect.coverage`), starting
from the coverage of the own samples computed here (``Measurement.rim``).

Eq. 12: the midpoint of the extent (min and max x and y) of the samples passing
the threshold, and the area is their count.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.detect.blobs import find_runs, label_runs
from trackerd.detect.candidates import Candidate
from trackerd.detect.colour import EXCESS_SCALE, Region, SampleGrid, Threshold, excess_window
from trackerd.detect.coverage import Rim, rim_centres
from trackerd.detect.flat import WorkspaceCache

COVERAGE_FLOOR = 0.1
"""A sample whose excess is below this fraction of its neighbourhood's largest weighs nothing
(noise, and the faint colour of surfaces around the ball)."""

COVERAGE_FULL = 0.9
"""A sample whose excess reaches this fraction of its neighbourhood's largest counts as fully
covered (noise keeps fully covered samples a little below their brightest neighbour)."""


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
    """Of the samples passing the threshold: from their second moments with ``shape=True``,
    else their bounding box's longer side over its shorter (cheaper, and enough for a check)."""
    fill: float
    """Samples passing the threshold over their bounding box, in samples."""
    rim: Rim | None = None
    """What :func:`measure_rims` needs to measure the centre from every pixel (Bayer, weighted)."""

    @property
    def centre_px(self) -> NDArray[np.float64]:
        return np.array([self.x_px, self.y_px])


@dataclass(slots=True)
class Samples:
    """The colour test over one region: what :func:`measure` works on."""

    excess: NDArray[np.int16]
    """EXCESS_SCALE x (sample - larger interpolated other channel), (rows, cols) of the region."""
    weight: NDArray[np.float32]
    """The excess as float, with the samples of blobs that do not count set to 0."""
    strong: NDArray[np.bool_]
    """Samples passing the threshold (of the blob measured)."""
    x0_px: float
    """Full-resolution position of the region's first sample."""
    y0_px: float
    cell_px: int
    colour: str = ""
    region: Region = (0, 0, 0, 0)
    value: NDArray[np.uint8] | None = None
    """The colour's own samples over the region (Bayer only)."""


def sample(frame: NDArray[np.uint8], grid: SampleGrid, colour: str, threshold: Threshold, region: Region) -> Samples:
    """The colour test over ``region`` (cells, inside ``grid.interior()``)."""
    excess, value = excess_window(frame, grid, colour, region)
    strong = excess >= EXCESS_SCALE * threshold.min_excess
    if threshold.min_value > 0:
        strong &= value >= threshold.min_value
    s = grid.cell_px
    dr, dc = grid.offset(colour)
    return Samples(
        excess,
        excess.astype(np.float32),
        strong,
        s * region[2] + dc,
        s * region[0] + dr,
        s,
        colour,
        region,
        value if grid.is_bayer else None,
    )


def measure(samples: Samples, weighted: bool, *, shape: bool = False) -> Measurement | None:
    """Centre, area, bounding box and shape of the strong samples; None if there are none."""
    strong = samples.strong
    n_strong = int(np.count_nonzero(strong))
    if n_strong == 0:
        return None
    h, w = strong.shape
    cols = np.flatnonzero(strong.any(axis=0))
    rows = np.flatnonzero(strong.any(axis=1))
    c0, c1, r0, r1 = int(cols[0]), int(cols[-1]), int(rows[0]), int(rows[-1])
    s, x0, y0 = samples.cell_px, samples.x0_px, samples.y0_px
    bbox = (int(x0) + s * c0, int(y0) + s * r0, int(x0) + s * c1, int(y0) + s * r1)
    on_border = c0 == 0 or r0 == 0 or c1 == w - 1 or r1 == h - 1
    fill = n_strong / ((c1 - c0 + 1) * (r1 - r0 + 1))
    if shape:
        elongation = _elongation(strong, n_strong)
    else:
        sides = (c1 - c0 + 1, r1 - r0 + 1)
        elongation = max(sides) / min(sides)
    if not weighted:
        centre = ((bbox[0] + bbox[2]) / 2.0, (bbox[1] + bbox[3]) / 2.0)
        return Measurement(*centre, float(n_strong * s * s), bbox, on_border, elongation, fill)
    # Only the blob and a one-cell ring around it: the rest of the region is background,
    # whose faint colour (a reddish floor, noise) must not pull on the centre.
    level = float(samples.excess[strong].sum()) / n_strong
    top, left = max(r0 - 1, 0), max(c0 - 1, 0)
    weight = _coverage(samples.weight[top : r1 + 2, left : c1 + 2], level)
    total = float(weight.sum())
    mx = float(weight.sum(axis=0) @ _ramp(weight.shape[1])) / total + left
    my = float(weight.sum(axis=1) @ _ramp(weight.shape[0])) / total + top
    rim = None
    if samples.value is not None:
        box = samples.strong[top : r1 + 2, left : c1 + 2]
        own_level = float(samples.value[top : r1 + 2, left : c1 + 2][box].mean())
        origin = (samples.region[0] + top, samples.region[2] + left)
        rim = Rim(samples.colour, origin, box, weight, own_level)
    return Measurement(x0 + s * mx, y0 + s * my, total * s * s, bbox, on_border, elongation, fill, rim)


def measure_rims(
    frame: NDArray[np.uint8],
    grid: SampleGrid,
    measurements: list[Measurement],
    cache: WorkspaceCache,
) -> list[Measurement]:
    """The measurements with centre and area from every pixel around the end (Bayer frames).

    See :mod:`trackerd.detect.coverage` (all ends at once); a measurement without
    a rim (RGB8, BGR8, the bounding-box centre) or too near the frame's edge is
    kept as it is.
    """
    rims = [m.rim for m in measurements if m.rim is not None]
    if not rims:
        return measurements
    centres = iter(rim_centres(frame, grid, rims, cache))
    out = []
    for m in measurements:
        centre = next(centres) if m.rim is not None else None
        if centre is None:
            out.append(m)
        else:
            out.append(dataclasses.replace(m, x_px=centre[0], y_px=centre[1], area_px=centre[2]))
    return out


def _coverage(excess: NDArray[np.float32], level: float) -> NDArray[np.float32]:
    """How much of each sample the ball covers, in [0, 1], from its excess.

    A sample's excess is compared with the largest in its 3x3 neighbourhood,
    which inside a ball, and on its rim next to the inside, is about what a fully
    covered sample shows there: the comparison follows the ball's shading, so
    the lit side does not weigh more than the dark side. Where the neighbourhood
    holds no ball (a corner of the box), half the blob's mean excess stands in.
    The ratio maps linearly to coverage between COVERAGE_FLOOR and COVERAGE_FULL.
    """
    h, w = excess.shape
    padded = np.zeros((h + 2, w + 2), dtype=np.float32)
    padded[1:-1, 1:-1] = excess
    across = np.maximum(padded[:, :-2], padded[:, 1:-1])
    np.maximum(across, padded[:, 2:], out=across)
    local = np.maximum(across[:-2], across[1:-1])
    np.maximum(local, across[2:], out=local)
    np.maximum(local, 0.5 * level, out=local)
    ratio = excess / local
    ratio -= COVERAGE_FLOOR
    ratio *= 1.0 / (COVERAGE_FULL - COVERAGE_FLOOR)
    np.clip(ratio, 0.0, 1.0, out=ratio)
    return ratio.astype(np.float32, copy=False)  # float32 already (float32 / float32): typed, not copied


def keep_nearest_blob(samples: Samples, near_px: tuple[float, float]) -> None:
    """Keep only the 8-connected blob of strong samples nearest to ``near_px`` (x, y).

    The blob kept is the one holding the strong sample nearest that point; the
    other blobs' samples leave ``strong`` and weigh nothing.
    """
    runs = find_runs(samples.strong)
    labels, n = label_runs(runs)
    if n <= 1:
        return
    s = samples.cell_px
    nx, ny = (near_px[0] - samples.x0_px) / s, (near_px[1] - samples.y0_px) / s
    # Distance from the point to each run (a horizontal segment of samples).
    dx = np.maximum(np.maximum(runs.first - nx, nx - runs.last), 0.0)
    k = int(labels[int(np.argmin(dx * dx + (runs.rows - ny) ** 2))])
    keep = np.zeros_like(samples.strong)
    for row, first, last, label in zip(
        runs.rows.tolist(), runs.first.tolist(), runs.last.tolist(), labels.tolist(), strict=True
    ):
        if label == k:
            keep[row, first : last + 1] = True
        else:
            samples.weight[row, first : last + 1] = 0.0
    samples.strong = keep


def candidate_region(grid: SampleGrid, c: Candidate) -> Region:
    """The cells :func:`measure_candidate` measures: the blob's box grown, inside the interior.

    One cell around the blob (one strip cell, in a window measured at a coarser
    scale), and one more on a mosaic: the colour test here can reach a cell
    beyond the blob found in the strip, and the centre from every pixel needs a
    ring of cells around all of it.
    """
    x0, y0, x1, y1 = c.frame_cells()
    lo_r, hi_r, lo_c, hi_c = grid.interior()
    grow = c.scale + (1 if grid.is_bayer else 0)
    return (
        max(lo_r, y0 - grow),
        min(hi_r, y1 + 1 + grow),
        max(lo_c, x0 - grow),
        min(hi_c, x1 + 1 + grow),
    )


def measure_candidate(
    frame: NDArray[np.uint8], grid: SampleGrid, c: Candidate, threshold: Threshold, weighted: bool
) -> Measurement:
    """Measure a chosen candidate around its blob (box grown by a cell), other blobs left out."""
    region = candidate_region(grid, c)
    samples = sample(frame, grid, c.colour, threshold, region)
    if c.scale > 1:
        keep_nearest_blob(samples, (c.x_px, c.y_px))
    elif not c.alone:
        r, q = c.origin
        _clear_other_blobs(samples, c, region[0] - r, region[2] - q)
    m = measure(samples, weighted)
    if m is None:  # only if the cell test and the symmetric test disagree on every sample
        bbox = c.bbox_px(grid)
        return Measurement(c.x_px, c.y_px, c.area_px, bbox, False, c.elongation, c.fill)
    return m


def _elongation(strong: NDArray[np.bool_], n: int) -> float:
    """Elongation of the set samples of a mask (as trackerd.detect.blobs.BlobStats.elongation)."""
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
    return math.sqrt((half_sum + root) / max(half_sum - root, 1e-12))


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


def _clear_other_blobs(samples: Samples, c: Candidate, sy0: int, sx0: int) -> None:
    """Take the samples of the candidate's window's other blobs out of ``samples``.

    ``samples`` covers strip cells from (sy0, sx0) (see trackerd.detect.strip);
    strip cells outside the candidate's window are black gap or other windows,
    whose runs lie outside ``samples`` or are skipped.
    """
    h, w = samples.weight.shape
    runs = c.runs
    near = (runs.rows >= sy0) & (runs.rows < sy0 + h) & (runs.last >= sx0) & (runs.first < sx0 + w)
    near &= c.labels != c.label
    for i in near.nonzero()[0].tolist():
        row = int(runs.rows[i]) - sy0
        span = slice(max(int(runs.first[i]) - sx0, 0), int(runs.last[i]) - sx0 + 1)
        samples.weight[row, span] = 0.0
        samples.strong[row, span] = False
