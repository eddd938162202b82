"""Choosing which blob is which end: ball shape, then consistency with the other end.

Both ends are balls of the same physical size, held ``length_m`` apart, and in
the presenter's area they are at similar distances from a camera. So the pair
(red blob, blue blob) that is the pointer has

* similar image areas: the ratio stays near 1 (perspective between a near and a
  far end and a hand over part of a ball make it 2 or so, rarely more);
* centres no further apart than the pointer's length in ball diameters
  (``length_m / end_diameter_m``) times the larger blob's diameter, plus slack;
* a dark rod between them, wherever the background is light enough to show it.

A lone blob of the right colour and shape (a sticker, a ball on the floor) may
look exactly like an end; what usually gives it away is that no blob of the
other colour sits where the other end would have to be, or that no rod joins
them. The rod is only looked for when more than one pair is possible.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.detect.candidates import Candidate, Rejects
from trackerd.detect.colour import SampleGrid, green_at
from trackerd.detect.rod import darker_share

AREA_RATIO_SIGMA = 0.7
"""Spread of log(area ratio) of a true pair: a ratio of 2 scores 0.61, of 4 scores 0.14."""

DISTANCE_SLACK = 1.3
"""Allowed distance over the length-to-diameter bound (blob diameters are measured, not exact)."""

DISTANCE_SLACK_PX = 6.0

UNPAIRED_FACTOR = 0.5
"""Score factor of an end chosen without a consistent partner."""

PREVIOUS_AREA_SIGMA = 0.7
"""Spread of log(area / previous area) between consecutive frames while tracking."""

MAX_ROD_CHECKS = 4
"""Pairs whose rod is looked for, at most, per image."""

ROD_UNSEEN = 0.5
"""Rod evidence when the balls are too close together for any rod to show."""


@dataclass(frozen=True, slots=True)
class Choice:
    """The chosen blob per colour (or None) and its score."""

    red: Candidate | None
    blue: Candidate | None
    red_score: float
    blue_score: float
    paired: bool
    """Whether the two were chosen as a consistent pair."""


def pair_consistency(
    area_a_px: float, area_b_px: float, dx_px: float, dy_px: float, length_over_diameter: float
) -> float:
    """How consistent two blobs (areas, offset between centres) are with one pointer, in [0, 1]."""
    ratio = math.log(area_a_px / area_b_px)
    diameter = 2.0 * math.sqrt(max(area_a_px, area_b_px) / math.pi)
    if math.hypot(dx_px, dy_px) > length_over_diameter * diameter * DISTANCE_SLACK + DISTANCE_SLACK_PX:
        return 0.0
    return math.exp(-0.5 * (ratio / AREA_RATIO_SIGMA) ** 2)


def pair_score(red: Candidate, blue: Candidate, length_over_diameter: float) -> float:
    """:func:`pair_consistency` of two candidates."""
    return pair_consistency(red.area_px, blue.area_px, red.x_px - blue.x_px, red.y_px - blue.y_px, length_over_diameter)


def rod_evidence(
    frame: NDArray[np.uint8],
    grid: SampleGrid,
    red: Candidate,
    blue: Candidate,
    rod_over_diameter: float,
) -> float:
    """Fraction of points between the two blobs' rims darker than both sides of the line, in [0, 1].

    A pointer's rod shows as a dark line between its balls on any surface lighter
    than it; two unrelated blobs have, almost always, plain room between them.
    Returns ROD_UNSEEN when the balls are too close for a rod to be measured.
    """
    dx, dy = blue.x_px - red.x_px, blue.y_px - red.y_px
    distance = math.hypot(dx, dy)
    start = red.diameter_px / 2.0 + 2.0
    stop = distance - blue.diameter_px / 2.0 - 2.0
    if stop - start < 6.0:
        return ROD_UNSEEN
    side = 0.5 * rod_over_diameter * 0.5 * (red.diameter_px + blue.diameter_px) + 3.0
    # In green, as this choice was built and measured; the rod's check on a fix (trackerd.refine) reads the
    # brightest colour, since it must see the rod over a saturated picture as well.
    direction = np.array([[dx / distance, dy / distance]])
    origin_px = np.array([red.x_px, red.y_px])
    return float(darker_share(frame, grid, origin_px, direction, start, stop - start, side, green_at)[0])


def _own_score(c: Candidate, previous_area_px: float | None) -> float:
    score = c.shape_score
    if previous_area_px:
        ratio = math.log(c.area_px / previous_area_px)
        score *= math.exp(-0.5 * (ratio / PREVIOUS_AREA_SIGMA) ** 2)
    return score


def choose(
    red: list[Candidate],
    blue: list[Candidate],
    length_over_diameter: float,
    previous_area_px: dict[str, float] | None = None,
    rod: Callable[[Candidate, Candidate], float] | None = None,
) -> Choice:
    """The best (red, blue) pair; failing any consistent pair, the best ball of each colour alone.

    A pair scores shape(red) x shape(blue) x size-and-distance consistency; when
    more than one pair is possible and ``rod`` is given, also x (1 + rod evidence) / 2.
    """
    prev = previous_area_px or {}
    reds = [(c, _own_score(c, prev.get("red"))) for c in red]
    blues = [(c, _own_score(c, prev.get("blue"))) for c in blue]
    pairs = []
    for r, rs in reds:
        for b, bs in blues:
            p = pair_score(r, b, length_over_diameter)
            if p > 0.0:
                pairs.append((r, rs, b, bs, p))
    if pairs:
        pairs.sort(key=lambda q: -q[1] * q[3] * q[4])
        best = pairs[0]
        # The rod factor is in [1/2, 1], so only pairs within a factor 2 of the best can
        # change places: look for the rod only then, and only in those, best first.
        if rod is not None and len(pairs) > 1 and _total(pairs[1]) > 0.5 * _total(best):
            best_total = 0.0
            for r, rs, b, bs, p in pairs[:MAX_ROD_CHECKS]:
                if rs * bs * p <= best_total:
                    break
                p_rod = p * 0.5 * (1.0 + rod(r, b))
                if rs * bs * p_rod > best_total:
                    best, best_total = (r, rs, b, bs, p_rod), rs * bs * p_rod
        r, rs, b, bs, p = best
        return Choice(r, b, rs * p, bs * p, True)
    r_best = max(reds, key=lambda cs: cs[1], default=None)
    b_best = max(blues, key=lambda cs: cs[1], default=None)
    return Choice(
        r_best[0] if r_best else None,
        b_best[0] if b_best else None,
        r_best[1] * UNPAIRED_FACTOR if r_best else 0.0,
        b_best[1] * UNPAIRED_FACTOR if b_best else 0.0,
        False,
    )


def _total(pair: tuple[Candidate, float, Candidate, float, float]) -> float:
    return pair[1] * pair[3] * pair[4]


def missing_reason(colour: str, seeds: int, too_large_seeds: int, rejects: Rejects, examined_all: bool) -> str:
    """One line on why no blob of ``colour`` was taken for an end."""
    if seeds == 0:
        return f"no {colour} pixels above threshold"
    if rejects.total == 0 and too_large_seeds == seeds:
        return f"{seeds} {colour} region{'s' if seeds != 1 else ''}, all far larger than max_area_px"
    if rejects.total == 0:
        return f"{colour} pixels above threshold, but no {colour} blob at full resolution"
    n = rejects.total + too_large_seeds
    counts = dict(rejects.counts)
    if too_large_seeds:
        counts["too large"] = counts.get("too large", 0) + too_large_seeds
    what = ", ".join(f"{v} {k}" for k, v in sorted(counts.items(), key=lambda kv: -kv[1]))
    text = f"{n} {colour} blob{'s' if n != 1 else ''}, none ball-shaped ({what}"
    if rejects.largest is not None:
        area, elongation, fill = rejects.largest
        text += f"; largest {area:.0f} px, elongation {elongation:.1f}, fill {fill:.2f}"
    text += ")"
    if not examined_all:
        text += " (only the largest were examined)"
    return text
