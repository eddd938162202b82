"""The sub-pixel centre of an end from the coverage of every pixel around it (Bayer mosaics).

The centroid of an end's visible area is the coverage-weighted mean of pixel
centres. Estimating coverage only at the end's own colour samples (one pixel in
four for red or blue), as :func:`trackerd.detect.centroid.measure` does, samples
the anti-aliased rim on a 2-pixel lattice, and that alone puts about 0.07 px (1
sigma) of error across the pointer's image line into the centroid however good
the estimate at those samples: the renderer's *exact* coverage summed over the
own samples only is that far off, over all pixels 0.001 px (docs/detection.md).
So here each Bayer cell's other three pixels (two greens and the other colour)
get a coverage estimate of their own, each from its own channel.

A pixel is a mix of the ball and what lies behind it: in its own channel
``v = a * ball + (1 - a) * back``. In the other channels the ball is dark
(red 0.86/0.10/0.08, blue 0.10/0.20/0.86), so against a lit background they
resolve the rim at full resolution, which is most of a rim in a lit room. The
two samples of the pixel's channel one Bayer period (2 px) to either side of
it, along its row or its column, whichever pair differs more (that pair
straddles the rim), are the ball (the darker) and the background (the
brighter) right there, whatever the ball's shading and whatever the
background. A pixel is solved that way unless

* the pair differs by less than MIN_CONTRAST (no lit background: a dark
  display, the rod, or the pixel is inside the ball);
* the pixel lies outside the pair's range by more than MIX_SLACK (a third
  colour is in it);
* an own-colour sample next to it is darker than DARK_FRACTION of the end's own
  level: the rod (dark in every channel) may be in the pixel, and the other
  channels cannot tell rod from ball. Only the own channel can, which is why the
  rod's edges and dark backgrounds stay on the own samples' 2-pixel lattice.

An unsolved pixel takes the mean of the own samples beside it (their coverage
from the colour test), steepened to a rim one pixel wide (BESIDE_SLOPE). Cells
surrounded by thresholded samples count as full and cells more than one cell
from any as empty.

On rendered frames of the simulated rig (truth: the renderer's visible-area
centroid) the error across the pointer's image line is 0.041-0.045 px (1 sigma)
against 0.071-0.082 px from the own samples alone; the cost is about 45 NumPy
calls per end when done end by end (0.12-0.16 ms each); here both ends are done
together on flat arrays (:mod:`trackerd.detect.flat`), about 50 calls for both.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.detect.colour import SampleGrid
from trackerd.detect.flat import Ops, Workspace, WorkspaceCache, round_up, run

MIN_CONTRAST = 40.0
"""Grey levels by which the background must be brighter than the ball in a pixel's channel for
that pixel to be solved on its own (2-3 grey levels of sensor noise then cost 0.05 of
coverage; lowering it lets background texture in)."""

MIX_SLACK = 0.25
"""How far outside [ball, background], as a fraction of their difference, a pixel may lie and
still be taken as their mix."""

DARK_FRACTION = 0.45
"""An own-colour sample at most this fraction of the end's mean own level is dark: the rod or a
dark background (the rod is about 0.1 of the ball's level, a grey wall 0.6-0.9)."""

BESIDE_SLOPE = 2.0
"""An unsolved pixel's coverage is ``0.5 + BESIDE_SLOPE * (m - 0.5)``, clipped to [0, 1], where
``m`` is the mean coverage of the own samples beside it. The own samples are two pixels
apart and their mean ramps from 0 to 1 over those two pixels; the coverage across a
sharp rim does so within one pixel (the pixel's own width), hence 2. Measured on
rendered ends (across the pointer, 1 sigma): 0.047 px with 1 (the plain mean), 0.044
with 2, 0.042 with 3-4; with the images blurred (Gaussian, sigma 0.5 and 0.8 px) 2 gives
0.036 against 0.040 and 0.039 with 1, while 3 and more lose again as blur widens the rim."""


@dataclass(frozen=True, slots=True)
class Rim:
    """One end as the colour test of its own samples left it (cells)."""

    colour: str
    origin: tuple[int, int]
    """Frame cell (row, col) of element (0, 0) of the arrays."""
    strong: NDArray[np.bool_]
    """The end's own samples passing the threshold (other blobs' cleared), (rows, cols)."""
    cover: NDArray[np.float32]
    """Coverage of the end's own samples, same shape (0 where no end)."""
    own_level: float
    """Mean own-colour value of the thresholded samples, grey levels."""


def rim_centres(
    frame: NDArray[np.uint8], grid: SampleGrid, rims: list[Rim], cache: WorkspaceCache
) -> list[tuple[float, float, float] | None]:
    """Centre (x, y) and area of each end from the coverage of every pixel, full-resolution pixels.

    All ends are measured at once (their boxes padded to a common size). Each
    ``rim.strong`` should hold every thresholded sample of the end with a cell
    of margin (measure's box does, unless the end reaches its window's border).
    An end gets None when it does not, when its cells and a ring around them do
    not fit in the frame, or when nothing is covered: keep the own samples'
    estimate then.
    """
    out: list[tuple[float, float, float] | None] = [None] * len(rims)
    usable = [k for k, rim in enumerate(rims) if _clear_of_edges(rim.strong)]
    if not usable:
        return out
    # The measured region of every end (its box, padded) and a ring of cells around it.
    rows = round_up(max(rims[k].strong.shape[0] for k in usable)) + 2
    cols = round_up(max(rims[k].strong.shape[1] for k in usable)) + 2
    height_px, width_px = frame.shape[:2]
    placed = []
    for k in usable:
        rim = rims[k]
        h, w = rim.strong.shape
        dr, dc = grid.offset(rim.colour)
        # The region starts at the box unless that would run off the frame's bottom or right.
        r0 = min(rim.origin[0], (height_px - dr) // 2 - rows + 1)
        c0 = min(rim.origin[1], (width_px - dc) // 2 - cols + 1)
        pr, pc = rim.origin[0] - r0, rim.origin[1] - c0
        if r0 >= 1 and c0 >= 1 and pr + h <= rows - 2 and pc + w <= cols - 2:
            placed.append((k, r0, c0, pr, pc, dr, dc))
    if not placed:
        return out
    ws = cache.get(len(placed), rows, cols)
    ws.strong.fill(0.0)
    ws.cover.fill(0.0)
    for e, (k, r0, c0, pr, pc, dr, dc) in enumerate(placed):
        rim = rims[k]
        h, w = rim.strong.shape
        y, x = 2 * r0 - 2 + dr, 2 * c0 - 2 + dc
        ws.pixels[e] = frame[y : y + 2 * rows, x : x + 2 * cols]
        ws.strong_3d[e, 1 + pr : 1 + pr + h, 1 + pc : 1 + pc + w] = rim.strong
        ws.cover_3d[e, 1 + pr : 1 + pr + h, 1 + pc : 1 + pc + w] = rim.cover
    np.copyto(ws.planes_5d, ws.pixels_as_planes)
    sums = solve(ws, [rims[k].own_level for k, *_ in placed])
    for (k, r0, c0, _, _, dr, dc), (total, x_sum, y_sum) in zip(placed, sums, strict=True):
        if total > 0.0:
            out[k] = (x_sum / total + 2 * c0 + dc, y_sum / total + 2 * r0 + dr, total)
    return out


def _clear_of_edges(strong: NDArray[np.bool_]) -> bool:
    """Whether no sample on the array's edges passed (else part of the rim lies outside it)."""
    if strong[0].any() or strong[-1].any():
        return False
    return not (strong[:, 0].any() or strong[:, -1].any())


def solve(ws: Workspace, own_levels: list[float]) -> list[tuple[float, float, float]]:
    """Every pixel's coverage, and the centroid sums of each window in a filled workspace.

    ``ws.planes`` holds the pixels, ``ws.strong`` the end's thresholded samples
    (none on the ring or on the measured region's border) and ``ws.cover`` its
    own samples' coverage (0 away from the end and outside ``lo:hi``), window by
    window; ``own_levels`` the end's mean own-colour value in each. Returns per
    window (summed coverage in pixels, sum of coverage x (2 x column + 1 for a
    pixel right of the own sample), the same for rows), columns and rows counted
    from the measured region's first cell: a centre is sum / coverage from there.
    """
    # One assignment for all windows (each cast to float32 as a window's own assignment would be).
    ws.level_2d[...] = np.array([[DARK_FRACTION * level] for level in own_levels])
    run(ws.ops("solve", _solve_ops))
    # Per window and pixel of the cell (the other pixels, then the own sample): summed
    # coverage, and its moments about the region's first cell in columns and rows.
    m = ws.coverage_2d.dot(ws.moments).tolist()
    n = ws.n
    out = []
    for e in range(n):
        right, below, diagonal, own = m[e], m[n + e], m[2 * n + e], m[3 * n + e]
        total = right[0] + below[0] + diagonal[0] + own[0]
        # The pixels right of the own sample (the right green, the other colour) sit one pixel
        # further right; those below it, one pixel further down.
        x = right[1] + below[1] + diagonal[1] + own[1] + right[0] + diagonal[0]
        y = right[2] + below[2] + diagonal[2] + own[2] + below[0] + diagonal[0]
        out.append((total, x, y))
    return out


def _solve_ops(ws: Workspace) -> Ops:
    """The computation of :func:`solve` for one layout (see trackerd.detect.flat)."""
    lo, hi, s, size = ws.lo, ws.hi, ws.cols, ws.size
    own, level, strong, cover = ws.own, ws.level, ws.strong, ws.cover
    bright, pairs, rows3, near, keep, inside = ws.cell[6:12]
    # Per pixel: the three other planes end to end, and the range with all four neighbours.
    end = 3 * size - lo
    other = ws.planes[1:4].reshape(-1)
    left, right = other[lo - 1 : end - 1], other[lo + 1 : end + 1]
    up, down = other[lo - s : end - s], other[lo + s : end + s]
    a, b, c, d, first, near_bright = (p[lo:end] for p in ws.pixel)
    near_bright_3 = ws.pixel[5].reshape(3, size)
    ones, zeros = ws.ones[lo:end], ws.zeros[lo:end]
    every = ws.coverage.reshape(-1)
    beside = every[lo:end]
    # The own samples beside: two for each green, four for the other colour (their mean),
    # then steepened by BESIDE_SLOPE about one half.
    mean = np.array([0.5, 0.5, 0.25], dtype=np.float32)
    weights = np.repeat(BESIDE_SLOPE * mean, size)[lo:end]
    n_cells = hi - lo
    return [
        # Own samples darker than DARK_FRACTION of the end's level may be the rod (dark in
        # every channel): a cell's other pixels are not solved on their own next to one.
        (np.greater, own, level, bright),
        (np.multiply, bright[:-1], bright[1:], pairs[:-1]),
        (np.multiply, pairs[lo:hi], pairs[lo + s : hi + s], near_bright_3[0, lo:hi]),
        (np.positive, near_bright_3[0], near_bright_3[1:]),  # the same for all three
        # Each other pixel against its channel's two samples two pixels to either side, along
        # the row and along the column, the pair that differs more: the darker is the ball,
        # the brighter what is behind it.
        (np.minimum, left, right, a),
        (np.maximum, left, right, b),
        (np.minimum, up, down, c),
        (np.maximum, up, down, d),
        (np.subtract, b, a, a),  # contrast along the row
        (np.subtract, d, c, c),  # along the column
        (np.greater_equal, a, c, first),  # 1 where the row's pair straddles the rim
        (np.maximum, a, c, a),  # contrast
        (np.subtract, b, d, b),
        (np.multiply, b, first, b),
        (np.add, b, d, b),  # background
        (np.subtract, b, other[lo:end], b),
        (np.maximum, a, ones, c),
        (np.divide, b, c, b),  # the ball's share of the pixel: (background - value) / contrast
        # Solved: contrast enough, the pixel within [ball, background] give or take MIX_SLACK
        # (share in [-MIX_SLACK, 1 + MIX_SLACK]), no dark own sample next to it.
        (np.greater_equal, a, MIN_CONTRAST, first),
        (np.subtract, b, 0.5, c),
        (np.absolute, c, c),
        (np.less_equal, c, 0.5 + MIX_SLACK, d),
        (np.multiply, first, d, first),
        (np.multiply, first, near_bright, first),  # solved
        (np.minimum, b, ones, b),
        (np.maximum, b, zeros, b),
        # Unsolved: from the own samples beside (the green right of the own sample has one
        # left and one right of it, the green below one above and one below, the other colour
        # four at the diagonals).
        (np.add, cover[lo : hi + s], cover[lo + 1 : hi + s + 1], every[lo : hi + s]),
        (np.add, cover[lo:hi], cover[lo + s : hi + s], every[size + lo : size + hi]),
        (np.add, every[lo:hi], every[lo + s : hi + s], every[2 * size + lo : 2 * size + hi]),
        (np.multiply, beside, weights, beside),
        (np.add, beside, 0.5 * (1.0 - BESIDE_SLOPE), beside),
        (np.minimum, beside, ones, beside),
        (np.maximum, beside, zeros, beside),
        (np.subtract, b, beside, b),
        (np.multiply, b, first, b),
        (np.add, beside, b, beside),  # every other pixel's coverage
        # Cells surrounded by thresholded samples count fully, cells further than one cell
        # from any count for nothing (this also clears the ring, where neighbours wrapped).
        (np.add, strong[:-2], strong[1:-1], rows3[1:-1]),
        (np.add, rows3[1:-1], strong[2:], rows3[1:-1]),
        (np.add, rows3[lo - s : hi - s], rows3[lo:hi], near[lo:hi]),
        (np.add, near[lo:hi], rows3[lo + s : hi + s], near[lo:hi]),
        (np.minimum, near[lo:hi], ones[:n_cells], keep[lo:hi]),
        (np.subtract, near[lo:hi], 8.0, inside[lo:hi]),
        (np.maximum, inside[lo:hi], zeros[:n_cells], inside[lo:hi]),
        (np.subtract, keep[lo:hi], inside[lo:hi], keep[lo:hi]),
        (np.multiply, ws.coverage, keep, ws.coverage),
        (np.add, ws.coverage, inside, ws.coverage),
    ]
