"""Per-pixel colour scores of the pointer's ends, on the camera's own planes (report eq. 9-11).

The report keeps only the red channel to find the red end (eq. 10) and only the
blue channel for the blue end (eq. 11). A bright white wall is as red as a red
ball by that measure, so here a sample counts as an end's colour when its
channel *exceeds the larger of the other two* by ``min_excess`` and is itself
at least ``min_value`` (trackerd.config.models.ColourThreshold).

A Bayer frame is never demosaiced. Its 2x2 cells give four planes (R, two G, B)
at half resolution, and each colour sample sits at a known offset inside the
cell (trackerd.pixelformat.BAYER_LAYOUTS): in BayerRG8 the R sample of cell
(i, j) is full-resolution pixel (x, y) = (2j, 2i) and the B sample is
(2j + 1, 2i + 1). Every position this module reports is that sample's own
full-resolution pixel position, so centroids carry no half-pixel bias. RGB8 and
BGR8 frames are treated as a grid of 1x1 cells holding all three channels.

Two scores are computed:

* :func:`coarse_masks`: a yes/no test on a subsampled grid of cells, comparing
  each cell's samples as they are (the cheapest test that finds seeds); it uses
  only uint8 arithmetic, with no whole-frame widening to int16;
* :func:`excess_window`: at full plane resolution in a small window, the
  colour's sample against the other channels *interpolated at that sample's
  position* (mean of its four green neighbours and of its four diagonal
  neighbours), which is symmetric about the sample and so gives an unbiased
  sub-pixel centroid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from trackerd.errors import ImageError
from trackerd.pixelformat import BAYER_LAYOUTS

EXCESS_SCALE = 4
"""Excess values from :func:`excess_window` are grey levels times this (sums of four samples)."""

Region = tuple[int, int, int, int]
"""A rectangle of cells: (row0, row1, col0, col1), half-open."""


@dataclass(frozen=True, slots=True)
class Threshold:
    """One colour's test as plain ints (from ColourThreshold), hoisted out of the per-frame path."""

    min_excess: int
    min_value: int


@dataclass(frozen=True, slots=True)
class SampleGrid:
    """Where each colour's samples are in a frame of one pixel format.

    The frame is a grid of ``cell_px`` x ``cell_px`` cells; cell (i, j) holds
    the sample of a colour at full-resolution pixel
    ``(y, x) = (cell_px * i + offset[0], cell_px * j + offset[1])``.
    """

    pixel_format: str
    cell_px: int
    """2 for Bayer mosaics, 1 for RGB8/BGR8."""
    rows: int
    """Cells down the frame."""
    cols: int
    """Cells across the frame."""
    red: tuple[int, int]
    """Offset (row, col) of the red sample in its cell (Bayer), or (0, 0)."""
    blue: tuple[int, int]
    green_a: tuple[int, int]
    green_b: tuple[int, int]
    channels: tuple[int, int, int]
    """For RGB8/BGR8: the index of red, green and blue in the last axis."""
    frame_shape: tuple[int, ...]

    @property
    def is_bayer(self) -> bool:
        return self.cell_px == 2

    def offset(self, colour: str) -> tuple[int, int]:
        """Offset (row, col) of ``colour``'s sample inside a cell."""
        return self.red if colour == "red" else self.blue

    def interior(self) -> Region:
        """The cells whose samples all have neighbours inside the frame (searches stay inside)."""
        if self.is_bayer:
            return (1, self.rows - 1, 1, self.cols - 1)
        return (0, self.rows, 0, self.cols)


def sample_grid(pixel_format: str, width_px: int, height_px: int) -> SampleGrid:
    """The sample layout of a ``width_px`` x ``height_px`` frame in ``pixel_format``."""
    layout = BAYER_LAYOUTS.get(pixel_format)
    if layout is not None:
        if width_px < 8 or height_px < 8:
            raise ImageError(f"a {width_px}x{height_px} {pixel_format} frame is too small to search")
        return SampleGrid(
            pixel_format,
            2,
            height_px // 2,
            width_px // 2,
            layout.red,
            layout.blue,
            layout.green_a,
            layout.green_b,
            (0, 1, 2),
            (height_px, width_px),
        )
    if pixel_format in ("RGB8", "BGR8"):
        channels = (0, 1, 2) if pixel_format == "RGB8" else (2, 1, 0)
        return SampleGrid(
            pixel_format,
            1,
            height_px,
            width_px,
            (0, 0),
            (0, 0),
            (0, 0),
            (0, 0),
            channels,
            (height_px, width_px, 3),
        )
    raise ImageError(
        f"pixel format {pixel_format!r} cannot show the pointer's colours;"
        " use BayerRG8, BayerGB8, BayerGR8, BayerBG8, RGB8 or BGR8"
    )


def _plane(frame: NDArray[np.uint8], grid: SampleGrid, which: str, region: Region, step: int) -> NDArray[np.uint8]:
    """A strided view of one colour's samples over ``region`` (cells), every ``step``-th cell."""
    r0, r1, c0, c1 = region
    if grid.is_bayer:
        dr, dc = getattr(grid, which)
        s = 2 * step
        return frame[2 * r0 + dr : 2 * r1 : s, 2 * c0 + dc : 2 * c1 : s]
    channel = grid.channels[{"red": 0, "green_a": 1, "green_b": 1, "blue": 2}[which]]
    return frame[r0:r1:step, c0:c1:step, channel]


def _exceeds(value: NDArray[np.uint8], others_max: NDArray[np.uint8], threshold: Threshold) -> NDArray[np.bool_]:
    """``value >= others_max + min_excess and value >= min_value``, in uint8 without overflow."""
    return _exceeds_by(value, others_max, *_limits(threshold))


def _exceeds_by(
    value: NDArray[np.uint8],
    others_max: NDArray[np.uint8],
    min_excess: np.uint8 | NDArray[np.uint8],
    at_least: np.uint8 | NDArray[np.uint8],
) -> NDArray[np.bool_]:
    """:func:`_exceeds` with the threshold as :func:`_limits` gives it: uint8 scalars, or arrays of
    shape (n, 1, 1) for a stack of n planes, one threshold each (:func:`_stacked_limits`).

    ``value - min_excess`` wraps round below zero, but only where ``value`` is
    below ``min_excess``, which the second test (against ``at_least``, the larger
    of ``min_excess`` and ``min_value``) rules out. (No maximum with a constant:
    with a scalar operand NumPy's maximum runs about ten times slower than
    subtracting or comparing one.)
    """
    lowered = value - min_excess
    np.greater_equal(lowered, others_max, out=lowered.view(np.bool_))
    high = value >= at_least
    return np.logical_and(lowered.view(np.bool_), high, out=high)


def _limits(threshold: Threshold) -> tuple[np.uint8, np.uint8]:
    """A threshold's ``min_excess`` and the larger of it and ``min_value``, as :func:`_exceeds_by` takes them."""
    return np.uint8(threshold.min_excess), np.uint8(max(threshold.min_excess, threshold.min_value))


def _stacked_limits(red: Threshold, blue: Threshold) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """Both colours' :func:`_limits` as uint8 arrays of shape (2, 1, 1), red's first, for a stack of
    their planes."""
    # Cached by the thresholds' plain ints (a tuple of ints hashes in C; a dataclass calls Python).
    return _limit_arrays(red.min_excess, red.min_value, blue.min_excess, blue.min_value)


@lru_cache(maxsize=8)
def _limit_arrays(
    red_excess: int, red_value: int, blue_excess: int, blue_value: int
) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """:func:`_stacked_limits`, made once per pair of thresholds: building an array costs more than
    the test's call."""
    limits = np.array(
        [[red_excess, blue_excess], [max(red_excess, red_value), max(blue_excess, blue_value)]], dtype=np.uint8
    ).reshape(2, 2, 1, 1)
    limits.flags.writeable = False
    return limits[0], limits[1]


def coarse_masks(
    frame: NDArray[np.uint8],
    grid: SampleGrid,
    red: Threshold | None,
    blue: Threshold | None,
    region: Region,
    step: int,
) -> tuple[NDArray[np.bool_] | None, NDArray[np.bool_] | None]:
    """Seed masks of both colours on every ``step``-th cell of ``region``.

    Element (a, b) of a mask is cell ``(region[0] + step * a, region[2] + step * b)``.
    Each cell is tested with its samples as they are: the brighter of its two
    greens (so a sharp grey edge running through the cell is not taken for
    colour) and the other colour's sample. Pass None for a colour not wanted.
    Returns (red mask or None, blue mask or None), shape about (rows / step, cols / step).
    """
    g = _plane(frame, grid, "green_a", region, step)
    g = np.maximum(g, _plane(frame, grid, "green_b", region, step)) if grid.is_bayer else g
    if red is not None and blue is not None:
        # Both colours' planes stacked, red over blue, so that each step of the test is one
        # NumPy call for both (the test is per sample: the same masks as testing each alone).
        own = np.empty((2, *g.shape), dtype=np.uint8)
        own[0] = _plane(frame, grid, "red", region, step)
        own[1] = _plane(frame, grid, "blue", region, step)
        both = _exceeds_by(own, np.maximum(g, own[::-1]), *_stacked_limits(red, blue))
        return both[0], both[1]
    # Each plane is read from the frame once, into a small contiguous array: the
    # tests below read each of them twice, and strided reads cost more than copies.
    r = np.ascontiguousarray(_plane(frame, grid, "red", region, step))
    b = np.ascontiguousarray(_plane(frame, grid, "blue", region, step))
    red_mask = _exceeds(r, np.maximum(g, b), red) if red is not None else None
    blue_mask = _exceeds(b, np.maximum(g, r), blue) if blue is not None else None
    return red_mask, blue_mask


def excess_window(
    frame: NDArray[np.uint8], grid: SampleGrid, colour: str, region: Region
) -> tuple[NDArray[np.int16], NDArray[np.uint8]]:
    """The colour's excess over the other channels at full plane resolution in ``region``.

    Returns ``(excess, value)``, both shape (rows, cols) of the region:
    ``excess`` is ``EXCESS_SCALE`` times (the colour's sample minus the larger of
    the green and the other colour interpolated at that sample's position) as
    int16, and ``value`` the colour's own samples. For a Bayer frame the region
    must lie inside :meth:`SampleGrid.interior` (every sample needs its eight
    neighbours).
    """
    r0, r1, c0, c1 = region
    if not grid.is_bayer:
        ch = grid.channels
        own, other = (ch[0], ch[2]) if colour == "red" else (ch[2], ch[0])
        window = frame[r0:r1, c0:c1]
        value = window[..., own]
        others = np.maximum(window[..., ch[1]], window[..., other])
        excess = value.astype(np.int16)
        excess -= others
        excess <<= 2
        return excess, value
    value, greens, others = _bayer_neighbours(frame, grid, colour, region)
    np.maximum(greens, others, out=greens)
    excess = value.astype(np.int16)
    excess <<= 2
    excess -= greens
    return excess, value


def cells_around(grid: SampleGrid, colour: str, x_px: float, y_px: float, reach_px: float) -> Region:
    """The region (cells, inside :meth:`SampleGrid.interior`) holding every sample of ``colour`` within
    ``reach_px`` of (x_px, y_px), with a sample to spare on each side for bilinear interpolation."""
    s = grid.cell_px
    dr, dc = grid.offset(colour)
    lo_r, hi_r, lo_c, hi_c = grid.interior()
    return (
        max(lo_r, math.floor((y_px - reach_px - dr) / s) - 1),
        min(hi_r, math.ceil((y_px + reach_px - dr) / s) + 2),
        max(lo_c, math.floor((x_px - reach_px - dc) / s) - 1),
        min(hi_c, math.ceil((x_px + reach_px - dc) / s) + 2),
    )


def channel_windows(frame: NDArray[np.uint8], grid: SampleGrid, colour: str, region: Region) -> NDArray[np.float32]:
    """All three channels at the colour's samples in ``region``: shape (3, rows, cols), the colour's own
    channel, green and the other colour, in grey levels (on a Bayer frame the green and the other colour
    are the means of the sample's four neighbours of each). The same region rules as :func:`excess_window`."""
    r0, r1, c0, c1 = region
    if not grid.is_bayer:
        ch = grid.channels
        own, other = (ch[0], ch[2]) if colour == "red" else (ch[2], ch[0])
        window = frame[r0:r1, c0:c1]
        return np.stack([window[..., own], window[..., ch[1]], window[..., other]]).astype(np.float32)
    value, greens, others = _bayer_neighbours(frame, grid, colour, region)
    return np.stack([value.astype(np.float32), greens / np.float32(4), others / np.float32(4)])


def _bayer_neighbours(
    frame: NDArray[np.uint8], grid: SampleGrid, colour: str, region: Region
) -> tuple[NDArray[np.uint8], NDArray[np.int16], NDArray[np.int16]]:
    """The colour's samples in ``region`` of a Bayer frame, and the sums of their four green and their four
    other-colour neighbours (int16)."""
    r0, r1, c0, c1 = region
    dr, dc = grid.red if colour == "red" else grid.blue
    h, w = r1 - r0, c1 - c0
    # A patch with one pixel of border: local cell (i, j) has its sample at
    # patch[1 + dr + 2i, 1 + dc + 2j]. Its left and right neighbours sum to
    # pair[Y, X - 1], and its four diagonal neighbours to quad[Y - 1, X - 1]
    # (sums over the whole patch: fewer NumPy calls than gathering each neighbour).
    patch = frame[2 * r0 - 1 : 2 * r1 + 1, 2 * c0 - 1 : 2 * c1 + 1]
    pair = np.add(patch[:, :-2], patch[:, 2:], dtype=np.int16)
    quad = pair[:-2] + pair[2:]
    rows = slice(1 + dr, 1 + dr + 2 * h, 2)
    cols = slice(1 + dc, 1 + dc + 2 * w, 2)
    greens = np.add(pair[rows, dc : dc + 2 * w : 2], patch[dr : dr + 2 * h : 2, cols], dtype=np.int16)
    greens += patch[2 + dr : 2 + dr + 2 * h : 2, cols]
    return patch[rows, cols], greens, quad[dr : dr + 2 * h : 2, dc : dc + 2 * w : 2]


def green_at(frame: NDArray[np.uint8], grid: SampleGrid, points_px: NDArray[np.float64]) -> NDArray[np.float64]:
    """Green, a stand-in for brightness, near points (N, 2) given as (x, y) pixels -> (N,).

    On a Bayer mosaic, the green sample at or right of the nearest pixel (half of
    all pixels are green, in a checkerboard); on RGB8/BGR8 the nearest pixel's
    green. Points are clamped into the frame. One gather per point, because a dark
    rod on a lighter room is as dark in green as in any channel.
    """
    height, width = grid.frame_shape[:2]
    x = np.rint(points_px[:, 0]).astype(np.intp).clip(0, width - 2)
    y = np.rint(points_px[:, 1]).astype(np.intp).clip(0, height - 1)
    if grid.is_bayer:
        # Greens sit where (x + y) has the parity of green_a's row + column.
        parity = (grid.green_a[0] + grid.green_a[1]) & 1
        x += (x + y + parity) & 1
        greens: NDArray[np.float64] = frame.reshape(-1)[y * width + x].astype(np.float64)
        return greens
    rgb_greens: NDArray[np.float64] = frame[y, x, grid.channels[1]].astype(np.float64)
    return rgb_greens


def brightest_at(frame: NDArray[np.uint8], grid: SampleGrid, points_px: NDArray[np.float64]) -> NDArray[np.float64]:
    """The brightest of a pixel's three colours near points (N, 2) given as (x, y) pixels -> (N,).

    On a Bayer mosaic, the largest of the red, blue and two green samples of the cell holding the nearest
    pixel; on RGB8/BGR8 the nearest pixel's largest channel. Points are clamped into the frame. Unlike
    :func:`green_at`, a dark line shows against a saturated surface of any colour: against a red picture
    the green is as dark as the rod, the red is not.
    """
    height, width = grid.frame_shape[:2]
    # On a mosaic, the clamp keeps the whole 2 x 2 cell inside the frame.
    edge = 2 if grid.is_bayer else 1
    x = np.rint(points_px[:, 0]).astype(np.intp).clip(0, width - edge)
    y = np.rint(points_px[:, 1]).astype(np.intp).clip(0, height - edge)
    if grid.is_bayer:
        flat = frame.reshape(-1)
        corner = (y // 2) * 2 * width + (x // 2) * 2
        brightest: NDArray[np.float64] = np.maximum(
            np.maximum(flat[corner], flat[corner + 1]), np.maximum(flat[corner + width], flat[corner + width + 1])
        ).astype(np.float64)
        return brightest
    rgb: NDArray[np.float64] = frame[y, x].max(axis=-1).astype(np.float64)
    return rgb
