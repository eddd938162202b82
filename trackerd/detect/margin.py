"""How far the pointer's colours stand from everything else a camera sees.

The detector's thresholds (trackerd.detect.colour) pass a sample whose own
channel exceeds the larger of the other two by ``min_excess``. Whether that
works in a room depends on two numbers per colour, both in grey levels of that
excess:

* the **ball's excess**: what the end's paint reaches under this room's light,
  taken as a low percentile over the ball's core (the shaded side of a ball is
  darker; the rim is left out, where the ball blends into what is behind it);
* the **background's excess**: the highest excess that anything *else* in view
  reaches over a block the size of a small blob (a picture on the display, a
  red jumper, skin), not one noisy sample.

Their difference is the colour's **margin**. A threshold between the two finds
the ball and nothing else; a margin near zero or below means something in view
is as much the pointer's colour as the pointer is, and only the geometry
(trackerd.joint) can tell them apart. ``trackerd calibrate pointer`` learns the
thresholds from these figures (trackerd.calibration.colours), and the daemon
watches the background's excess against its thresholds so that the status
warns when a new picture on the wall comes close (trackerd.pipeline.colourwatch).

Samples are taken per cell, exactly as :func:`trackerd.detect.colour.coarse_masks`
tests them (a Bayer cell's own colour sample against the brighter of its two
greens and the other colour's sample; an RGB pixel against its other
channels), so the figures are in the units the thresholds use.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.detect.colour import SampleGrid, _plane

CORE_SHARE = 0.6
"""Ball samples are taken within this share of the ball's imaged radius of its centre."""
CLEAR_SHARE = 1.6
"""Background samples are taken further than this many imaged radii from either ball (its rim,
its blur and the hand holding it right by it are neither ball nor room)."""
BLOCK_SAMPLES = 2
"""The background's excess is the highest that a block of this many by this many neighbouring samples
all reach: on a Bayer frame at full sampling 4 x 4 pixels, about the detector's smallest blob
(``min_area_px`` 12). Not one noisy sample, and not the one-sample colour fringe a Bayer mosaic puts
along a sharp slanted edge (a dark frame on a bright wall), which no blob test takes for a ball."""
BALL_PERCENTILE = 10.0
"""The ball's excess is this percentile of its core samples' (the shaded side included)."""
OUTLIER_SPREADS = 4.0
"""Core samples this many robust spreads below the median are of something in front of the ball."""
HIDDEN_SHARE = 0.5
"""And so are core samples under this share of the median: the core's shading does not reach it."""


@dataclass(frozen=True, slots=True)
class Disc:
    """Where a ball images: centre (x, y) and radius, full-resolution pixels."""

    x_px: float
    y_px: float
    radius_px: float


@dataclass(frozen=True, slots=True)
class ColourSamples:
    """One colour in one frame: the ball's core samples and the background's top excess."""

    colour: str
    ball_excess: NDArray[np.int16]
    """Excess of every core sample of the ball(s) of this colour (empty when none was given)."""
    ball_value: NDArray[np.uint8]
    """The colour's own channel at those samples."""
    background_excess: int
    """The highest excess a block of samples away from both balls reaches (:data:`BLOCK_SAMPLES`; -255 when none)."""
    background_at_px: tuple[float, float] | None
    """Where that block is (its first sample), full-resolution (x, y)."""
    background_samples: int
    """How many blocks the background figure was taken from."""


def cell_excess(
    frame: NDArray[np.uint8], grid: SampleGrid, colour: str, step: int = 1
) -> tuple[NDArray[np.int16], NDArray[np.uint8], NDArray[np.float64], NDArray[np.float64]]:
    """Per cell on every ``step``-th cell: (excess, own value, sample x px, sample y px).

    ``excess`` is the colour's sample minus the larger of the cell's brighter green and its
    other colour's sample, the quantity :func:`~trackerd.detect.colour.coarse_masks` thresholds;
    x and y (1-D, across and down) are the full-resolution positions of the colour's samples.
    """
    region = grid.interior()
    other = "blue" if colour == "red" else "red"
    own = _plane(frame, grid, colour, region, step)
    others = _plane(frame, grid, other, region, step)
    green = _plane(frame, grid, "green_a", region, step)
    if grid.is_bayer:
        green = np.maximum(green, _plane(frame, grid, "green_b", region, step))
    rows = min(own.shape[0], others.shape[0], green.shape[0])
    cols = min(own.shape[1], others.shape[1], green.shape[1])
    own, others, green = own[:rows, :cols], others[:rows, :cols], green[:rows, :cols]
    excess = own.astype(np.int16)
    excess -= np.maximum(green, others)
    dr, dc = grid.offset(colour)
    cell = grid.cell_px
    xs = (cell * (region[2] + step * np.arange(cols)) + dc).astype(np.float64)
    ys = (cell * (region[0] + step * np.arange(rows)) + dr).astype(np.float64)
    return excess, np.ascontiguousarray(own), xs, ys


def _within(xs: NDArray[np.float64], ys: NDArray[np.float64], disc: Disc, share: float) -> NDArray[np.bool_]:
    reach = share * disc.radius_px
    return ((xs[None, :] - disc.x_px) ** 2 + (ys[:, None] - disc.y_px) ** 2) <= reach * reach


def _near_segment(
    xs: NDArray[np.float64], ys: NDArray[np.float64], a: Disc, b: Disc, half_width_px: float
) -> NDArray[np.bool_]:
    """Samples within ``half_width_px`` of the segment between two discs' centres."""
    dx, dy = b.x_px - a.x_px, b.y_px - a.y_px
    length2 = dx * dx + dy * dy
    px = xs[None, :] - a.x_px
    py = ys[:, None] - a.y_px
    t = np.clip((px * dx + py * dy) / length2, 0.0, 1.0) if length2 > 0 else np.zeros((ys.size, xs.size))
    return (px - t * dx) ** 2 + (py - t * dy) ** 2 <= half_width_px * half_width_px


def colour_samples(
    frame: NDArray[np.uint8],
    grid: SampleGrid,
    colour: str,
    balls: dict[str, Disc | None],
    *,
    rod_half_width_px: float = 0.0,
    step: int = 1,
) -> ColourSamples:
    """The figures of one colour in one frame, with both balls where ``balls`` says they image.

    ``balls`` maps 'red' and 'blue' to their discs (None where that ball is not known in this
    frame: then nothing is taken as that ball, and nothing is cleared around it either, so
    call this only on frames where the pointer was located). With ``rod_half_width_px``, the
    band of the rod between the two centres is left out of the ball's core (seen along the
    pointer, the rod crosses the front ball).
    """
    excess, value, xs, ys = cell_excess(frame, grid, colour, step)
    away = np.ones(excess.shape, dtype=np.bool_)
    core = np.zeros(excess.shape, dtype=np.bool_)
    known = {
        name: disc
        for name, disc in balls.items()
        if disc is not None and np.isfinite([disc.x_px, disc.y_px, disc.radius_px]).all()
    }
    for name, disc in known.items():
        away &= ~_within(xs, ys, disc, CLEAR_SHARE)
        if name == colour:
            core |= _within(xs, ys, disc, CORE_SHARE)
    if rod_half_width_px > 0 and len(known) == 2 and core.any():
        red, blue = known["red"], known["blue"]
        core &= ~_near_segment(xs, ys, red, blue, rod_half_width_px)
    block, block_away = _blocks(excess), _blocks(away)
    top, at = -255, None
    if block_away.any():
        masked = np.where(block_away, block, np.int16(-256))
        row, col = np.unravel_index(int(np.argmax(masked)), masked.shape)
        top = int(masked[row, col])
        at = (float(xs[col]), float(ys[row]))
    return ColourSamples(colour, excess[core], value[core], top, at, int(np.count_nonzero(block_away)))


def _blocks(values: NDArray) -> NDArray:
    """The minimum over each :data:`BLOCK_SAMPLES` square block, at its top-left sample."""
    out = values[: values.shape[0] - BLOCK_SAMPLES + 1, : values.shape[1] - BLOCK_SAMPLES + 1].copy()
    for dr in range(BLOCK_SAMPLES):
        for dc in range(BLOCK_SAMPLES):
            if dr or dc:
                part = values[dr : dr + out.shape[0], dc : dc + out.shape[1]]
                np.minimum(out, part, out=out)
    return out


def unhidden(samples: NDArray[np.int16]) -> NDArray[np.int16]:
    """A ball's core samples without those of something in front of it (a hand, the rod, a sleeve).

    What hides part of a ball is not the ball's colour, so its samples lie far below the rest. A
    sample is left out when it is below the median by more than :data:`OUTLIER_SPREADS` robust spreads,
    or below :data:`HIDDEN_SHARE` of the median (not the ball's colour at all; with a quarter of the core
    hidden the spread alone grew wide enough to keep them). The spread is taken from the samples above
    the median only (1.4826 times their median distance from it, at least 2 grey levels), which whatever
    hides the ball cannot widen. The ball's own shading stays in.
    """
    if samples.size == 0:
        return samples
    median = float(np.median(samples))
    upper = samples[samples >= median]
    spread = max(2.0, 1.4826 * float(np.median(upper - median)))
    floor = median - OUTLIER_SPREADS * spread
    if median > 0:
        # A share of a median that shows no excess of the colour would leave out the median itself.
        floor = max(floor, HIDDEN_SHARE * median)
    return samples[samples >= floor]


def ball_excess(samples: NDArray[np.int16]) -> float | None:
    """The ball's excess (:data:`BALL_PERCENTILE` of its core samples), None without samples."""
    if samples.size == 0:
        return None
    return float(np.percentile(samples, BALL_PERCENTILE))
