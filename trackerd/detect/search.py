"""Every place in a frame that could be one of the pointer's balls, by a colour test relative to brightness.

The detector's thresholds (``[detector.red]``, ``[detector.blue]``) are absolute:
a ball in dim light, or painted darker, fails them, and a display showing reds
and blues passes them. This search asks less of each pixel and more of the
geometry that follows (:mod:`trackerd.joint`):

* a sample is of an end's colour when its channel exceeds the larger of the
  other two by at least :data:`RELATIVE_EXCESS` of its own value and by
  :data:`MIN_EXCESS` grey levels (above the sensor's noise): a hue test, the
  same at any exposure;
* connected groups of such samples on a subsampled grid are *seeds*; those of a
  size a ball can have in this camera (``radius_range_px``) are kept, the most
  ball-like first: round, vivid (well past the hue test's edge) and alone (not
  one speck among many of its colour);
* each seed's outline is fitted, all of a colour's seeds together
  (:func:`trackerd.detect.ballfit.fit_balls`); the fits are the candidates.

It runs on a first sighting and when the quick detector's answer does not hold
together; it is not on the tracking path.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.detect.ballfit import BallFit, BallLook, fit_balls, fit_looks
from trackerd.detect.blobs import Runs, blob_stats, find_runs, label_runs
from trackerd.detect.colour import SampleGrid, _plane

RELATIVE_EXCESS = 0.3
"""A sample's own channel must exceed the others by this share of itself."""

MIN_EXCESS = 12
"""And by this many grey levels."""

VIVID_EXCESS = 0.1
"""The looser test of :func:`vivid_mask`: a sample's own channel exceeds the larger of the other two by this
share of itself (and by MIN_EXCESS)..."""

VIVID_SHARE = 0.6
"""...and the smaller of the other two by this share of itself: a vivid colour whose strongest channel is the
end's. A cyan paint in warm light is 0.8 as green as it is blue and fails the plain test's RELATIVE_EXCESS
(`bench robustness` seed 11, installation 18: every frame of a four-camera room lost, the blue ball (15, 111,
139) in RGB); a tan sleeve or skin in warm light, only 22 % redder than it is green, is not vivid (its weakest
channel, blue, is 0.6 of its red or more where the test asks at most 0.4) and still fails."""

STRICTER = (0.5, 0.65)
"""Shares of its own value a sample's excess must reach, in turn, inside a group too large to be a ball."""

MAX_SEEDS = 20
"""Seeds fitted per colour, best first."""

VIVID_MARGIN = 0.2
"""A seed whose mean hue strength (:func:`_strength`) is this far above RELATIVE_EXCESS keeps its whole
score; one at the test's edge a tenth of it."""

CROWDING_WEIGHT = 4.0
"""A seed's score is divided by 1 + this times its crowding (:func:`_crowding`: the share of samples of
its colour in a frame of half its size around it): a quarter crowded halves it."""

DARKER_SHARE = 0.7
"""Inside a group larger than the smallest ball, samples whose own channel is below this share of the
group's median are looked at apart (a ball darker than a picture of its own hue behind it: navy before a
bright blue, a shaded red before a lit red block), and so are those above the median over it (a bright
ball touching a dark picture of its hue, a navy slide)."""

SPLIT_FROM = 2.0
"""Groups whose box reaches this many times the smallest ball's radius are split."""

MAX_SPLIT_SEEDS = 12
"""Seeds from the split of groups too large to be a ball, fitted per colour (:func:`split_candidates`)."""


ViewAt = Callable[[float, float], "NDArray[np.float64] | None"]
"""``view(x_px, y_px)``: the camera's map from image offsets there to units in which a ball's outline is a
circle (:func:`trackerd.geometry.sphere.view_map`), or None where it is a circle in pixels already."""


@dataclass(frozen=True, slots=True)
class Candidate:
    """One possible ball of one colour in one frame: its fitted outline."""

    colour: str
    fit: BallFit
    seed_px: tuple[float, float]
    """Where the seed was (its samples' centroid)."""
    seed_radius_px: float


@dataclass(frozen=True, slots=True)
class _Sampled:
    """The frame's channels on the search's subsampled grid (int16, one value per sample)."""

    red: NDArray[np.int16]
    green: NDArray[np.int16]
    """The brighter of a Bayer cell's two greens."""
    blue: NDArray[np.int16]
    region: tuple[int, int, int, int]
    step: int
    spacing_px: float

    def planes(self, colour: str) -> tuple[NDArray[np.int16], NDArray[np.int16]]:
        """(own channel, the other colour's channel) for ``colour``."""
        return (self.red, self.blue) if colour == "red" else (self.blue, self.red)

    def excess(self, colour: str, where: NDArray[np.bool_] | None = None) -> NDArray[np.int16]:
        """Each sample's own channel less the larger of the other two (only the samples ``where`` is set,
        in row order, when given)."""
        own, other = self.planes(colour)
        if where is None:
            return own - np.maximum(self.green, other)
        return own[where] - np.maximum(self.green[where], other[where])


def hue_mask(own: NDArray[Any], excess: NDArray[Any]) -> NDArray[np.bool_]:
    """The relative colour test (see the module) on every sample (or on any colour given as its own channel
    and its excess over the larger other: `trackerd.refine` holds a guided look's find to it)."""
    return (excess >= MIN_EXCESS) & (10 * excess >= int(10 * RELATIVE_EXCESS) * own)


def vivid_mask(own: NDArray[Any], excess: NDArray[Any], weakest: NDArray[Any]) -> NDArray[np.bool_]:
    """The looser colour test of the search's last resort (:data:`VIVID_EXCESS`, :data:`VIVID_SHARE`):
    ``weakest`` is the smaller of the two other channels. Not a superset of :func:`hue_mask`: a dull colour
    that passes the plain test may fail this one; the last resort takes either."""
    vivid: NDArray[np.bool_] = (
        (excess >= MIN_EXCESS)
        & (10 * excess >= int(10 * VIVID_EXCESS) * own)
        & (10 * (own - weakest) >= int(10 * VIVID_SHARE) * own)
    )
    return vivid


def _sample(frame: NDArray[np.uint8], grid: SampleGrid, smallest_px: float) -> _Sampled:
    """The frame subsampled finely enough that a ball of the smallest radius still covers a few samples."""
    step = max(1, int(smallest_px // (1.5 * grid.cell_px)))
    region = grid.interior()
    r = _plane(frame, grid, "red", region, step).astype(np.int16)
    b = _plane(frame, grid, "blue", region, step).astype(np.int16)
    g = _plane(frame, grid, "green_a", region, step).astype(np.int16)
    if grid.is_bayer:
        np.maximum(g, _plane(frame, grid, "green_b", region, step), out=g)
    rows = min(r.shape[0], b.shape[0], g.shape[0])
    cols = min(r.shape[1], b.shape[1], g.shape[1])
    return _Sampled(r[:rows, :cols], g[:rows, :cols], b[:rows, :cols], region, step, step * grid.cell_px)


def search_candidates(
    frame: NDArray[np.uint8],
    grid: SampleGrid,
    radius_range_px: tuple[float, float],
    *,
    colours: tuple[str, ...] = ("red", "blue"),
    max_seeds: int = MAX_SEEDS,
    view: ViewAt | None = None,
    vivid: bool = False,
) -> dict[str, list[Candidate]]:
    """The fitted candidates of each colour (see the module), best seeds first.

    ``vivid``: the samples that pass :func:`vivid_mask` and not the plain test, instead (the locator's last
    resort, when the plain test's candidates make no pointer: trackerd/refine.py).

    ``view``: where a seed's outline is not a circle in pixels (far off a wide lens's axis) and its fit in
    pixels fails, it is fitted again in the units ``view`` gives there; its radius is then in those units
    (the focal length times the ball's angular radius, what the joint choice expects)."""
    smallest, largest = radius_range_px
    sampled = _sample(frame, grid, smallest)
    out: dict[str, list[Candidate]] = {}
    for colour in colours:
        own, other = sampled.planes(colour)
        excess = sampled.excess(colour)
        mask = hue_mask(own, excess)
        if vivid:
            # Only what the plain test left: its seeds were fitted already.
            mask = vivid_mask(own, excess, np.minimum(sampled.green, other)) & ~mask
        plain, merged = _seeds(mask, sampled, grid, colour, smallest, largest)
        passes = [plain]
        # A ball in front of a picture of a nearby hue merges with it; a stricter hue test, inside the merged
        # group only, separates what is only nearly the paint's colour (a magenta beside a red).
        for share in STRICTER:
            if not merged:
                break
            stricter = (excess >= MIN_EXCESS) & (100 * excess >= int(100 * share) * own)
            keep = np.zeros_like(mask)
            for y0, y1, x0, x1 in merged:
                keep[y0:y1, x0:x1] = stricter[y0:y1, x0:x1]
            more, merged = _seeds(keep, sampled, grid, colour, smallest, largest)
            passes.append(more)
        found: list[Candidate] = []
        seeds = _in_turn(passes)[:max_seeds]
        # Every seed's outline fitted in one go; those it does not find are looked at again, together too.
        starts = np.array([(x, y, max(radius, smallest)) for _, x, y, radius in seeds]).reshape(-1, 3)
        fits = fit_balls(frame, grid, colour, starts)
        again: list[int] = []
        looks: list[BallLook] = []
        for i, (_, x, y, radius) in enumerate(seeds):
            local = None if fits[i].found or view is None else view(x, y)
            if local is not None:
                # The seed's size is in pixels: in the view's units, by its mean scale there.
                scale = math.sqrt(abs(float(np.linalg.det(local))))
                again.append(i)
                looks.append(BallLook(frame, grid, colour, x, y, scale * max(radius, smallest), view=local))
        for i, fit in zip(again, fit_looks(looks), strict=True):
            fits[i] = fit
        # A ball touching something that only just passes the hue test (a hand's skin beside a red ball) is
        # one seed with it, and the outline fitted from there is not round: fitted again from the vivid part
        # of the seed alone, each stricter share only for the seeds the one before did not find.
        trying = [i for i, fit in enumerate(fits) if not fit.found]
        for share in STRICTER:
            again, looks = [], []
            for i in trying:
                _, x, y, radius = seeds[i]
                part = _vivid_part(own, excess, sampled, grid, colour, x, y, radius, share, smallest)
                if part is not None:
                    vx, vy, vradius = part
                    again.append(i)
                    looks.append(BallLook(frame, grid, colour, vx, vy, max(vradius, smallest)))
            for i, fit in zip(again, fit_looks(looks), strict=True):
                fits[i] = fit
            trying = [i for i in again if not fits[i].found]
        for (_, x, y, radius), fit in zip(seeds, fits, strict=True):
            if fit.found and 0.6 * smallest <= fit.radius_px <= 1.4 * largest:
                found.append(Candidate(colour, fit, (x, y), radius))
        out[colour] = _distinct(found)
    return out


def split_candidates(
    frame: NDArray[np.uint8],
    grid: SampleGrid,
    radius_range_px: tuple[float, float],
    *,
    colours: tuple[str, ...] = ("red", "blue"),
) -> dict[str, list[Candidate]]:
    """Candidates that :func:`search_candidates` cannot offer: balls of nearly the same hue as a picture
    behind them, which stay merged with it under every hue test.

    Such a ball still differs from the picture in brightness (a navy ball before a bright blue, a shaded
    red one before a lit red block) or in which of the other two channels is the larger (an orange ball
    before a magenta, a cyan-blue one before a violet). So inside every group of the colour larger than
    SPLIT_FROM times the smallest ball's radius (one too large to be a ball, or one whose centre the
    picture pulls off the ball), the samples darker than DARKER_SHARE of the group's median, those brighter
    than the median over it, and each side of that channel split, are seeds of their own. Their outlines
    are fitted taking rising rims too (the excess of a dark ball is *below* that of the bright picture
    behind it; :func:`~trackerd.detect.ballfit.fit_ball`), with
    the radius kept near the seed's. Slower than the plain search and more easily fooled, so the locator
    asks for these only when the plain candidates do not make a pointer (trackerd/refine.py)."""
    smallest, largest = radius_range_px
    sampled = _sample(frame, grid, smallest)
    out: dict[str, list[Candidate]] = {}
    for colour in colours:
        own, other = sampled.planes(colour)
        mask = hue_mask(own, sampled.excess(colour))
        greener = sampled.green >= other
        boxes = _large_groups(mask, sampled.spacing_px, SPLIT_FROM * smallest)
        split = _split_seeds(mask, own, greener, boxes, sampled, grid, colour, smallest, largest)
        seeds = split[:MAX_SPLIT_SEEDS]
        sizes = np.array([max(radius, smallest) for _, _, _, radius in seeds])
        starts = np.array([(x, y, size) for (_, x, y, _), size in zip(seeds, sizes, strict=True)]).reshape(-1, 3)
        fits = fit_balls(
            frame, grid, colour, starts, radius_range_px=np.column_stack([0.6 * sizes, 1.6 * sizes]), rising_rims=True
        )
        found = [
            Candidate(colour, fit, (x, y), radius)
            for (_, x, y, radius), fit in zip(seeds, fits, strict=True)
            if fit.found and 0.6 * smallest <= fit.radius_px <= 1.4 * largest
        ]
        out[colour] = _distinct(found)
    return out


def _seeds(
    mask: NDArray[np.bool_],
    sampled: _Sampled,
    grid: SampleGrid,
    colour: str,
    smallest: float,
    largest: float,
) -> tuple[list[tuple[float, float, float, float]], list[tuple[int, int, int, int]]]:
    """(score, x, y, radius), in pixels, of the mask's blobs of a ball's size, best (roundest, most vivid,
    least crowded) first; and the boxes (row0, row1, col0, col1 in mask samples) of the blobs too large to
    be one ball."""
    if not mask.any():
        return [], []
    runs = find_runs(mask)
    labels, count = label_runs(runs)
    stats = blob_stats(runs, labels, count)
    dr, dc = grid.offset(colour)
    r0, _, c0, _ = sampled.region
    step, spacing, s = sampled.step, sampled.spacing_px, grid.cell_px
    crowding = _crowding(mask, stats.y0, stats.y1, stats.x0, stats.x1)
    strength = _strength(mask, sampled, colour, runs, labels, count)
    scored = []
    merged = []
    for k in range(count):
        n = float(stats.count[k])
        width = (stats.x1[k] - stats.x0[k] + 1) * spacing
        height = (stats.y1[k] - stats.y0[k] + 1) * spacing
        radius = 0.5 * max(width, height)
        area_radius = math.sqrt(n / math.pi) * spacing
        if radius > 1.6 * largest:
            merged.append((int(stats.y0[k]), int(stats.y1[k]) + 1, int(stats.x0[k]), int(stats.x1[k]) + 1))
        if radius < 0.5 * smallest or area_radius > 1.6 * largest:
            continue
        fill = n * spacing * spacing / max(width * height, 1e-9)
        x = (c0 + step * float(stats.mean_x[k])) * s + dc
        y = (r0 + step * float(stats.mean_y[k])) * s + dr
        roundness = min(width, height) / max(width, height)
        # Ball-like first, whatever the size: a small ball must not wait behind the large letters of a slide;
        # and alone before crowded: the specks of a textured picture are as round as a ball, and hundreds
        # of them kept a clear ball on a plain wall beyond MAX_SEEDS.
        shape = roundness * min(1.0, fill / 0.6) * min(1.0, radius / smallest)
        vivid = min(1.0, max(0.0, float(strength[k]) - RELATIVE_EXCESS) / VIVID_MARGIN)
        scored.append(
            (shape * (0.1 + 0.9 * vivid) / (1.0 + CROWDING_WEIGHT * float(crowding[k])), x, y, max(radius, area_radius))
        )
    scored.sort(reverse=True)
    return scored, merged


def _vivid_part(
    own: NDArray[np.int16],
    excess: NDArray[np.int16],
    sampled: _Sampled,
    grid: SampleGrid,
    colour: str,
    x_px: float,
    y_px: float,
    radius_px: float,
    share: float,
    smallest: float,
) -> tuple[float, float, float] | None:
    """(x, y, radius) in pixels of the largest group of samples within 1.5 radii of a seed at (x, y) whose
    ``excess`` reaches ``share`` of their ``own`` channel (the search's sampled planes); None when it is
    smaller than half the smallest ball, or is the seed again (within a fifth of its radius, in place and
    size: its fit would fail alike)."""
    r0, _, c0, _ = sampled.region
    step, spacing, cell = sampled.step, sampled.spacing_px, grid.cell_px
    dr, dc = grid.offset(colour)
    row = ((y_px - dr) / cell - r0) / step
    col = ((x_px - dc) / cell - c0) / step
    reach = 1.5 * radius_px / spacing + 1.0
    top, left = max(0, int(row - reach)), max(0, int(col - reach))
    bottom, right = min(own.shape[0], int(row + reach) + 1), min(own.shape[1], int(col + reach) + 1)
    if bottom <= top or right <= left:
        return None
    window_excess = excess[top:bottom, left:right]
    strict = (window_excess >= MIN_EXCESS) & (100 * window_excess >= int(100 * share) * own[top:bottom, left:right])
    count, _, stats, centroids = cv2.connectedComponentsWithStats(strict.view(np.uint8), connectivity=8)
    if count < 2:
        return None
    biggest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    samples = float(stats[biggest, cv2.CC_STAT_AREA])
    radius = math.sqrt(samples / math.pi) * spacing
    if radius < 0.5 * smallest:
        return None
    x = (c0 + step * (left + float(centroids[biggest, 0]))) * cell + dc
    y = (r0 + step * (top + float(centroids[biggest, 1]))) * cell + dr
    if math.hypot(x - x_px, y - y_px) < 0.2 * radius_px and radius > 0.8 * radius_px:
        return None
    return x, y, radius


def _strength(
    mask: NDArray[np.bool_], sampled: _Sampled, colour: str, runs: Runs, labels: NDArray[np.int64], count: int
) -> NDArray[np.float64]:
    """Each blob's mean hue strength: its samples' excess over their own channel (RELATIVE_EXCESS at the
    hue test's edge; a painted ball's is well above it, where the noise of a wall of a nearby hue only
    just passes)."""
    # Only the blobs' samples: in mask order (row by row), which is the runs' order.
    own, _ = sampled.planes(colour)
    ratio = sampled.excess(colour, mask) / np.maximum(own[mask], 1).astype(np.float64)
    sizes = runs.last - runs.first + 1
    totals = np.bincount(np.repeat(labels, sizes), ratio, count)
    sizes = np.bincount(labels, sizes, count)
    mean: NDArray[np.float64] = totals / np.maximum(sizes, 1)
    return mean


def _crowding(
    mask: NDArray[np.bool_],
    y0: NDArray[np.int64],
    y1: NDArray[np.int64],
    x0: NDArray[np.int64],
    x1: NDArray[np.int64],
) -> NDArray[np.float64]:
    """For each blob (its box, inclusive, in mask samples): the share of the mask's samples in the frame of
    half the box's size around the box (other blobs of the colour nearby; 0 for a blob alone)."""
    if len(y0) < 2:
        return np.zeros(len(y0))
    table: NDArray[np.int32] = np.asarray(cv2.integral(mask.view(np.uint8), sdepth=cv2.CV_32S))
    rows, cols = mask.shape
    half_h = (y1 - y0 + 2) // 2
    half_w = (x1 - x0 + 2) // 2
    oy0, oy1 = np.maximum(y0 - half_h, 0), np.minimum(y1 + 1 + half_h, rows)
    ox0, ox1 = np.maximum(x0 - half_w, 0), np.minimum(x1 + 1 + half_w, cols)

    def total(
        a0: NDArray[np.int64], a1: NDArray[np.int64], b0: NDArray[np.int64], b1: NDArray[np.int64]
    ) -> NDArray[np.int32]:
        counts: NDArray[np.int32] = table[a1, b1] - table[a0, b1] - table[a1, b0] + table[a0, b0]
        return counts

    around = total(oy0, oy1, ox0, ox1) - total(y0, y1 + 1, x0, x1 + 1)
    area = (oy1 - oy0) * (ox1 - ox0) - (y1 - y0 + 1) * (x1 - x0 + 1)
    crowding: NDArray[np.float64] = around / np.maximum(area, 1)
    return crowding


def _split_seeds(
    mask: NDArray[np.bool_],
    own: NDArray[np.int16],
    greener: NDArray[np.bool_],
    boxes: list[tuple[int, int, int, int]],
    sampled: _Sampled,
    grid: SampleGrid,
    colour: str,
    smallest: float,
    largest: float,
) -> list[tuple[float, float, float, float]]:
    """Seeds (score, x, y, radius) of a ball's size inside the groups in ``boxes`` (mask samples): the group's
    samples darker than DARKER_SHARE of its median, those brighter than the median over it, and those whose
    second channel is green against those whose second is the other colour (``greener``), each looked at
    alone; the parts' seeds taken in turn (:func:`_in_turn`: appended part after part, seed 7 installation 1
    frame 16's blue ball, touching a navy square, in the brighter part, never came)."""
    if not boxes:
        return []
    darker = np.zeros_like(mask)
    brighter = np.zeros_like(mask)
    side_a = np.zeros_like(mask)
    side_b = np.zeros_like(mask)
    for y0, y1, x0, x1 in boxes:
        inside = mask[y0:y1, x0:x1]
        values = own[y0:y1, x0:x1]
        median = float(np.median(values[inside]))
        darker[y0:y1, x0:x1] = inside & (values < DARKER_SHARE * median)
        brighter[y0:y1, x0:x1] = inside & (DARKER_SHARE * values > median)
        side_a[y0:y1, x0:x1] = inside & greener[y0:y1, x0:x1]
        side_b[y0:y1, x0:x1] = inside & ~greener[y0:y1, x0:x1]
    return _in_turn(
        [_seeds(part, sampled, grid, colour, smallest, largest)[0] for part in (darker, brighter, side_a, side_b)]
    )


def _in_turn(lists: list[list[tuple[float, float, float, float]]]) -> list[tuple[float, float, float, float]]:
    """Seeds of several tests, each list best first, taken in turn: every list's best, then every list's
    second, and so on. Not appended list after list: the later tests' seeds (a ball split from a picture by the
    stricter hue test) came after every speck of the first and were cut off by the cap (`bench robustness`
    seed 7, installation 24, frame 28: a clear orange ball was seed 21 of 28, first of its test). Not ranked
    together by score either: a seed that passed a stricter test scores as vivid by that alone, and a picture's
    fragments then outranked a dull ball of the plain test; and `split_candidates`' parts each guess
    differently how the ball differs from the picture (seed 2026, installation 2, frame 13: a red ball before
    red text, the darker part's first seed, outranked by round fragments of the text)."""
    return [seeds[rank] for rank in range(max(map(len, lists), default=0)) for seeds in lists if rank < len(seeds)]


def _large_groups(mask: NDArray[np.bool_], spacing: float, min_radius_px: float) -> list[tuple[int, int, int, int]]:
    """Boxes (row0, row1, col0, col1 in mask samples) of the mask's groups whose box is at least
    ``min_radius_px`` in half-extent."""
    if not mask.any():
        return []
    runs = find_runs(mask)
    labels, count = label_runs(runs)
    stats = blob_stats(runs, labels, count)
    half = 0.5 * spacing * np.maximum(stats.x1 - stats.x0 + 1, stats.y1 - stats.y0 + 1)
    return [
        (int(stats.y0[k]), int(stats.y1[k]) + 1, int(stats.x0[k]), int(stats.x1[k]) + 1)
        for k in np.nonzero(half >= min_radius_px)[0]
    ]


def _distinct(candidates: list[Candidate]) -> list[Candidate]:
    """One candidate per ball: fits of two seeds that found the same circle are one."""
    kept: list[Candidate] = []
    for cand in sorted(candidates, key=lambda c: -c.fit.rim_fraction):
        if all(np.hypot(*(cand.fit.centre_px - k.fit.centre_px)) > 0.5 * k.fit.radius_px for k in kept):
            kept.append(cand)
    return kept
