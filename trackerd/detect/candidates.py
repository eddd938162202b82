"""Candidate ends: seeds from a subsampled pass, refined into measured blobs at full resolution.

The search is two-level. A subsampled pass (every ``step``-th cell,
:func:`~trackerd.detect.colour.coarse_masks`) finds *seeds*: connected groups of
coarse cells of an end's colour. Each seed's bounding box, grown by one coarse
step, is a small window (:func:`seed_windows`) in which every cell is tested,
the mask is split into blobs and each blob's area, elongation and fill are
measured (:func:`refine`).

A frame has a handful of such windows, each a few hundred cells, so the cost of
measuring them is NumPy's per-call overhead, not arithmetic. :func:`refine`
therefore copies all windows, of both colours, side by side into one small
*strip* image and measures the strip with a single set of NumPy calls. Only the
windows are touched at full resolution; the sub-pixel centroid is computed only
for the blobs finally chosen (:mod:`trackerd.detect.centroid`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.detect.blobs import Runs, blob_boxes, blob_stats, find_runs, label_runs
from trackerd.detect.colour import Region, SampleGrid, Threshold, coarse_masks
from trackerd.detect.strip import pack

DISC_FILL = math.pi / 4.0
"""Fill (area over bounding-box area) of an ideal disc."""

MAX_CANDIDATES_PER_WINDOW = 6
"""Ball-shaped blobs kept per refinement window, largest first."""

OPENING_MIN_CELLS = 5
"""The strip's mask is opened (3x3 cross) when the smallest end is at least this many cells:
a cross-shaped blob of 5 cells is the smallest that survives the opening."""


def shape_score(elongation: float, fill: float) -> float:
    """How ball-like a blob is, in (0, 1]: 1 for a round blob that fills its box as a disc does."""
    return min(1.0, fill / DISC_FILL) / elongation


@dataclass(frozen=True, slots=True)
class Limits:
    """Shape limits of a ball's image (from DetectorConfig), hoisted out of the per-frame path."""

    min_area_px: float
    max_area_px: float
    max_elongation: float
    min_fill: float


@dataclass(slots=True, eq=False)
class Candidate:
    """One ball-shaped blob of an end's colour, measured from its thresholded mask.

    ``runs`` and the bounding box are in *strip* cells (:mod:`trackerd.detect.strip`):
    strip cell c is frame cell ``origin + scale * c``.
    """

    colour: str
    window: Region
    """The frame window (cells) it was measured in."""
    origin: tuple[int, int]
    """(row, col) of the frame cell of strip cell (0, 0)."""
    scale: int
    """Frame cells per strip cell along each axis (1, or 2 or 4 in a large window)."""
    runs: Runs
    labels: NDArray[np.int64]
    label: int
    alone: bool
    """Whether it is the only blob in its window (then no other blob needs masking out)."""
    area_px: float
    """Thresholded area in full-resolution pixels (cells times cell area)."""
    x_px: float
    """Unweighted centroid of the thresholded samples, full resolution."""
    y_px: float
    bbox_cells: tuple[int, int, int, int]
    """(x0, y0, x1, y1) inclusive, strip cells."""
    elongation: float
    fill: float
    diameter_px: float = 0.0
    """Diameter of a disc of the same area."""
    shape_score: float = 0.0
    """How ball-like, in (0, 1]: 1 for a round blob that fills its box as a disc does."""

    def __post_init__(self) -> None:
        self.diameter_px = 2.0 * math.sqrt(self.area_px / math.pi)
        self.shape_score = shape_score(self.elongation, self.fill)

    @property
    def centre_px(self) -> NDArray[np.float64]:
        """Unweighted centroid (x, y), full resolution."""
        return np.array([self.x_px, self.y_px])

    def bbox_px(self, grid: SampleGrid) -> tuple[int, int, int, int]:
        """The blob's outermost samples (x0, y0, x1, y1), inclusive, full resolution."""
        dr, dc = grid.offset(self.colour)
        s = grid.cell_px
        x0, y0, x1, y1 = self.frame_cells()
        return (s * x0 + dc, s * y0 + dr, s * x1 + dc, s * y1 + dr)

    def frame_cells(self) -> tuple[int, int, int, int]:
        """The blob's bounding box (x0, y0, x1, y1), inclusive, in frame cells."""
        x0, y0, x1, y1 = self.bbox_cells
        r, c = self.origin
        k = self.scale
        return (c + k * x0, r + k * y0, c + k * x1 + k - 1, r + k * y1 + k - 1)


@dataclass(slots=True)
class Rejects:
    """Blobs of one colour that cannot be a ball: counts per problem and the largest one."""

    counts: dict[str, int]
    largest: tuple[float, float, float] | None = None
    """(area px, elongation, fill) of the largest rejected blob."""

    def add(self, problem: str, area_px: float, elongation: float, fill: float) -> None:
        self.counts[problem] = self.counts.get(problem, 0) + 1
        if self.largest is None or area_px > self.largest[0]:
            self.largest = (area_px, elongation, fill)

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def merge(self, other: Rejects) -> None:
        """Add another set of rejects to this one."""
        for problem, n in other.counts.items():
            self.counts[problem] = self.counts.get(problem, 0) + n
        if other.largest is not None and (self.largest is None or other.largest[0] > self.largest[0]):
            self.largest = other.largest


def classify(area_px: float, elongation: float, fill: float, limits: Limits) -> str | None:
    """The first shape limit a blob breaks, or None if it could be a ball."""
    if area_px < limits.min_area_px:
        return "too small"
    if area_px > limits.max_area_px:
        return "too large"
    if elongation > limits.max_elongation:
        return "elongated"
    if fill < limits.min_fill:
        return "sparse"
    return None


@dataclass(slots=True)
class Seeds:
    """Refinement windows of one colour from the subsampled pass."""

    windows: list[Region]
    """Largest seed first."""
    count: int
    """Seeds found (before merging windows)."""
    too_large: int
    """Seeds dropped because even their subsampled area is far above max_area_px."""


def seed_windows(
    masks: dict[str, NDArray[np.bool_]], region: Region, step: int, grid: SampleGrid, limits: Limits
) -> dict[str, Seeds]:
    """Refinement windows around the seeds of each colour's subsampled mask.

    ``mask[a, b]`` is cell ``(region[0] + step * a, region[2] + step * b)``. Each
    seed's box is grown by one step and a cell (the blob's edge lies between a
    seed sample and the next, unseen one); overlapping windows of a colour are
    merged, so a speckled object costs one window. The masks (all the same
    shape) are stacked and split into blobs in one go.
    """
    colours = list(masks)
    height, width = next(iter(masks.values())).shape
    # Stacked with a False column before them and a False row after each: framed for
    # find_runs, which then need not pad (and copy) a frame's worth of samples again.
    # Columns of the stack are the masks' plus one.
    stacked = np.zeros(((height + 1) * len(colours), width + 1), dtype=bool)
    for i, colour in enumerate(colours):
        stacked[i * (height + 1) : i * (height + 1) + height, 1:] = masks[colour]
    out = {colour: Seeds([], 0, 0) for colour in colours}
    runs = find_runs(stacked, framed=True)
    if len(runs) == 0:
        return out
    labels, n = label_runs(runs)
    count, x0, y0, x1, y1 = blob_boxes(runs, labels, n)
    sample_area = float(step * grid.cell_px) ** 2
    lo_r, hi_r, lo_c, hi_c = grid.interior()
    margin = step + 1
    left = region[2] - step  # the cell of the stack's column 0
    boxes: dict[str, list[list[int]]] = {colour: [] for colour in colours}
    # Largest first (reverse keeps the order of equal counts, as a key of -count did).
    for k in sorted(range(n), key=count.__getitem__, reverse=True):
        layer = y0[k] // (height + 1)
        seeds = out[colours[layer]]
        seeds.count += 1
        # A seed is a sample of its blob: the true area may be a few times more or less than
        # samples x sample area, so only a gross excess is decided at this level.
        if count[k] * sample_area > 4.0 * limits.max_area_px:
            seeds.too_large += 1
            continue
        top = region[0] - layer * (height + 1) * step
        merged = [
            max(lo_r, top + step * y0[k] - margin),
            min(hi_r, top + step * y1[k] + margin + 1),
            max(lo_c, left + step * x0[k] - margin),
            min(hi_c, left + step * x1[k] + margin + 1),
        ]
        if merged[1] <= merged[0] or merged[3] <= merged[2]:
            continue
        windows = boxes[colours[layer]]
        # Fold in every window it overlaps (repeat: a merge can reach further windows).
        changed = True
        while changed:
            changed = False
            for w in windows:
                if w[0] < merged[1] and merged[0] < w[1] and w[2] < merged[3] and merged[2] < w[3]:
                    merged = [
                        min(w[0], merged[0]),
                        max(w[1], merged[1]),
                        min(w[2], merged[2]),
                        max(w[3], merged[3]),
                    ]
                    windows.remove(w)
                    changed = True
                    break
        windows.append(merged)
    for colour in colours:
        out[colour].windows = [(w[0], w[1], w[2], w[3]) for w in boxes[colour]]
    return out


@dataclass(slots=True)
class Refined:
    """What :func:`refine` found in each window (lists parallel to its ``jobs``)."""

    candidates: list[list[Candidate]]
    rejects: list[Rejects]
    cut: list[bool]
    """Whether a blob reaches the window's border where the window could be larger."""


def refine(
    frame: NDArray[np.uint8],
    grid: SampleGrid,
    jobs: list[tuple[str, Region]],
    thresholds: dict[str, Threshold],
    limits: Limits,
) -> Refined:
    """Measure every blob in each (colour, window) job; windows must lie in ``grid.interior()``.

    All windows are packed into one strip (:mod:`trackerd.detect.strip`), each
    colour's zone gets its colour's cell test (as the subsampled pass, but on
    every cell), and the strip is split into blobs at once. Blobs that cannot be
    a ball are counted in their job's ``rejects``; the others become candidates.
    """
    n_jobs = len(jobs)
    out = Refined([[] for _ in range(n_jobs)], [Rejects({}) for _ in range(n_jobs)], [False] * n_jobs)
    if n_jobs == 0:
        return out
    strip = pack(frame, grid, jobs)
    height, width = strip.grid.rows, strip.grid.cols
    # Both colours' tests over all the zones (red's, then blue's, one after the other) in one
    # call, fewer NumPy calls than one call per zone (the cells are few); each zone then takes
    # its own colour's rows.
    colours = [colour for colour, _, _ in strip.zones]
    first, last = strip.zones[0][1], strip.zones[-1][2]
    red, blue = coarse_masks(
        strip.image,
        strip.grid,
        thresholds["red"] if "red" in colours else None,
        thresholds["blue"] if "blue" in colours else None,
        (first, last, 0, width),
        1,
    )
    mask = np.zeros((height, width), dtype=bool)
    for colour, top, end in strip.zones:
        tested = red if colour == "red" else blue
        assert tested is not None  # coarse_masks tests each colour given a threshold
        mask[top:end] = tested[top - first : end - first]
    if limits.min_area_px >= OPENING_MIN_CELLS * grid.cell_px * grid.cell_px:
        mask = _open(mask)
    runs = find_runs(mask, framed=True)
    if len(runs) == 0:
        return out
    labels, n = label_runs(runs)
    stats = blob_stats(runs, labels, n)
    s = grid.cell_px
    owner = strip.jobs_at(runs.rows[stats.first_run], runs.first[stats.first_run])
    # Each blob's area from its window's scale, the cells' sizes as plain ints (a handful of blobs:
    # fewer NumPy calls than an array of the scales indexed by the owners).
    scales = strip.scales
    area = stats.count * np.array([scales[j] * scales[j] * s * s for j in owner])
    # Specks (noise, the rim of a reddish surface) are common: classify all blobs at once
    # and build candidates only from the ball-shaped ones.
    elongation = stats.elongation()
    fill = stats.fill()
    # The first limit each blob breaks (0: none), in the order of classify().
    problem = np.zeros(len(area), dtype=np.int64)
    problem[fill < limits.min_fill] = 4
    problem[elongation > limits.max_elongation] = 3
    problem[area > limits.max_area_px] = 2
    problem[area < limits.min_area_px] = 1
    _count_rejects(out.rejects, owner, problem, area, elongation, fill)
    blobs_in = [0] * n_jobs
    for j in owner:
        blobs_in[j] += 1
    ok = (problem == 0).nonzero()[0]
    if ok.size == 0:
        return out
    # Keep the largest few per window: a speckled surface can make dozens of small round
    # clumps, none of which is an end when the window holds a bigger one.
    ok = ok[(-area[ok]).argsort(kind="stable")]
    per_job = [0] * n_jobs
    lo_r, hi_r, lo_c, hi_c = grid.interior()
    mean_x, mean_y = stats.means()
    for k in ok.tolist():
        j = owner[k]
        per_job[j] += 1
        if per_job[j] > MAX_CANDIDATES_PER_WINDOW:
            out.rejects[j].counts["smaller than others"] = out.rejects[j].counts.get("smaller than others", 0) + 1
            continue
        colour, window = jobs[j]
        r0, r1, c0, c1 = window
        x0, y0, x1, y1 = int(stats.x0[k]), int(stats.y0[k]), int(stats.x1[k]), int(stats.y1[k])
        y, x = strip.rows[j], strip.cols[j]
        h, w = strip.shapes[j]
        # A ball-shaped blob reaching the window's edge may be cut short: measure again wider.
        if (
            (x0 == x and c0 > lo_c)
            or (y0 == y and r0 > lo_r)
            or (x1 == x + w - 1 and c1 < hi_c)
            or (y1 == y + h - 1 and r1 < hi_r)
        ):
            out.cut[j] = True
        dr, dc = grid.offset(colour)
        origin = strip.origin(j, window)
        k_scale = strip.scales[j]
        out.candidates[j].append(
            Candidate(
                colour,
                window,
                origin,
                k_scale,
                runs,
                labels,
                k,
                blobs_in[j] == 1,
                float(area[k]),
                s * (origin[1] + k_scale * float(mean_x[k])) + dc,
                s * (origin[0] + k_scale * float(mean_y[k])) + dr,
                (x0, y0, x1, y1),
                float(elongation[k]),
                float(fill[k]),
            )
        )
    return out


_PROBLEMS = ("too small", "too large", "elongated", "sparse")


def _count_rejects(
    rejects: list[Rejects],
    owner: list[int],
    problem: NDArray[np.int64],
    area: NDArray[np.float64],
    elongation: NDArray[np.float64],
    fill: NDArray[np.float64],
) -> None:
    """Add each rejected blob to its window's rejects (counts per problem, and the largest one)."""
    bad = problem.nonzero()[0]
    if bad.size == 0:
        return
    n_jobs = len(rejects)
    owners = np.asarray(owner)
    jobs = owners[bad]
    counts = np.bincount(jobs * len(_PROBLEMS) + problem[bad] - 1, minlength=n_jobs * len(_PROBLEMS))
    for key in counts.nonzero()[0].tolist():
        j, p = divmod(key, len(_PROBLEMS))
        rejects[j].counts[_PROBLEMS[p]] = int(counts[key])
    # The largest rejected blob of each window: the highest area rank among its blobs.
    order = bad[area[bad].argsort(kind="stable")]
    rank = np.full(n_jobs, -1)
    np.maximum.at(rank, owners[order], np.arange(order.size))
    for j, r in enumerate(rank.tolist()):
        if r >= 0:
            k = int(order[r])
            rejects[j].largest = (float(area[k]), float(elongation[k]), float(fill[k]))


def _open(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Morphological opening of a mask by a 3x3 cross (the mask's border must be clear).

    Keeps the cells of every blob at least three cells across, less a little of its
    corners, and removes the rest: specks of noise, one-cell lines along sharp
    edges (where a Bayer cell straddles a bright and a dark surface), and the
    salt-and-pepper of a surface whose colour is near the threshold, which would
    otherwise make hundreds of tiny blobs to label and measure.
    """
    eroded = np.zeros_like(mask)
    core = eroded[1:-1, 1:-1]
    np.logical_and(mask[1:-1, 1:-1], mask[:-2, 1:-1], out=core)
    core &= mask[2:, 1:-1]
    core &= mask[1:-1, :-2]
    core &= mask[1:-1, 2:]
    opened = eroded.copy()
    grown = opened[1:-1, 1:-1]
    grown |= eroded[:-2, 1:-1]
    grown |= eroded[2:, 1:-1]
    grown |= eroded[1:-1, :-2]
    grown |= eroded[1:-1, 2:]
    return opened


def grow(window: Region, by: int, grid: SampleGrid) -> Region:
    """``window`` grown by ``by`` cells on every side, kept inside the frame's interior."""
    lo_r, hi_r, lo_c, hi_c = grid.interior()
    return (
        max(lo_r, window[0] - by),
        min(hi_r, window[1] + by),
        max(lo_c, window[2] - by),
        min(hi_c, window[3] + by),
    )
