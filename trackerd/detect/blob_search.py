"""The blob search: both ends among the ball-shaped blobs of a whole frame or of windows around them.

What :class:`~trackerd.detect.detector.ColourEndDetector` falls back to when
the quick tracked measurement does not stand (report section 3.2, eq. 10-12):

* *near* a tracked pair, the blobs in small windows around each end's
  prediction, then in the tracking window with the subsampled pass;
* in *full*, a subsampled pass over the whole frame (every ``search_step_px``)
  finds seeds of each colour, each refined at full plane resolution in a small
  window (:mod:`trackerd.detect.candidates`).

Then blobs that cannot be a ball are dropped and the red-blue pair most
consistent with one pointer wins (:mod:`trackerd.detect.select`), and the
chosen blobs' centres are measured (:mod:`trackerd.detect.centroid`).
:class:`BlobSearch` holds the per-camera settings; it keeps no state between
frames (the tracking state is the detector's :class:`EndTrack`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.config.models import DetectorConfig
from trackerd.detect.candidates import Candidate, Limits, Rejects, grow, refine, seed_windows
from trackerd.detect.centroid import Measurement, candidate_region, measure_candidate, measure_rims
from trackerd.detect.colour import Region, SampleGrid, Threshold, coarse_masks
from trackerd.detect.flat import WorkspaceCache
from trackerd.detect.result import COLOURS, EndDetection, ImageDetections
from trackerd.detect.select import choose, missing_reason, rod_evidence
from trackerd.detect.window_measure import ANY_SHAPE, measure_windows

MAX_WINDOWS = 12
"""Seed windows refined per colour in one search, largest seed first; more is clutter."""


@dataclass(slots=True)
class EndTrack:
    """What the previous frame said about one end (plain floats: read a few times a frame)."""

    x_px: float
    y_px: float
    vx_px: float
    """Motion since the frame before, pixels per frame."""
    vy_px: float
    area_px: float
    crowded: bool = False
    """Whether the quick measurement had to pick the end out of other blobs of its colour
    (then it does so straight away next time)."""

    @property
    def centre_px(self) -> NDArray[np.float64]:
        return np.array([self.x_px, self.y_px])

    @property
    def velocity_px(self) -> NDArray[np.float64]:
        return np.array([self.vx_px, self.vy_px])


@dataclass(slots=True)
class _Search:
    """Candidates of one colour from one search, with what is needed to explain a miss."""

    candidates: list[Candidate]
    seeds: int
    too_large_seeds: int
    rejects: Rejects
    examined_all: bool


@dataclass(frozen=True, slots=True)
class BlobSearch:
    """One camera's blob search: its sample layout, thresholds, shape limits and pointer proportions."""

    cfg: DetectorConfig
    grid: SampleGrid
    thresholds: dict[str, Threshold]
    limits: Limits
    step_cells: int
    """The subsampled pass's step, in cells."""
    length_over_diameter: float
    rod_over_diameter: float
    weighted: bool
    """Coverage-weighted centres (else the report's eq. 12 bounding-box midpoint)."""
    flat: bool
    """Whether the chosen ends may be measured together (weighted centres on a mosaic)."""
    rim_pixels: bool
    """Whether centres use every pixel of the rim (trackerd.detect.coverage)."""
    work: WorkspaceCache

    def full(self, frame: NDArray[np.uint8]) -> ImageDetections:
        """Both ends searched for over the whole frame, from the subsampled pass's seeds."""
        step = self.step_cells
        r0, r1, c0, c1 = self.grid.interior()
        # Centre the coarse samples in their step x step blocks.
        coarse = (r0 + step // 2, r1, c0 + step // 2, c1)
        red, blue = coarse_masks(frame, self.grid, self.thresholds["red"], self.thresholds["blue"], coarse, step)
        assert red is not None and blue is not None
        seeds = seed_windows({"red": red, "blue": blue}, coarse, step, self.grid, self.limits)
        jobs = [(colour, w) for colour in COLOURS for w in seeds[colour].windows[:MAX_WINDOWS]]
        found = self.refine(frame, jobs)
        searches = {}
        for colour in COLOURS:
            candidates, rejects = found[colour]
            s = seeds[colour]
            searches[colour] = _Search(candidates, s.count, s.too_large, rejects, len(s.windows) <= MAX_WINDOWS)
        result = self.result(frame, searches, "full", None)
        assert result is not None
        return result

    def near(self, frame: NDArray[np.uint8], track: dict[str, EndTrack]) -> ImageDetections | None:
        """Both ends among the blobs near their previous positions, or None (search in full)."""
        jobs = []
        for colour in COLOURS:
            t = track[colour]
            radius = math.sqrt(t.area_px / math.pi)
            speed = math.hypot(float(t.velocity_px[0]), float(t.velocity_px[1]))
            # Just around the ball first: it moves little between frames.
            near = self.window_around(t.centre_px + t.velocity_px, near_half_px(radius, speed))
            if near is None:
                return None
            jobs.append((colour, near))
        found = self.refine(frame, jobs)
        searches = {}
        for colour in COLOURS:
            candidates, rejects = found[colour]
            if not candidates:
                # Then the whole tracking window, with the subsampled pass.
                t = track[colour]
                radius = math.sqrt(t.area_px / math.pi)
                speed = math.hypot(float(t.velocity_px[0]), float(t.velocity_px[1]))
                # Never smaller than the near window: after a jump the prediction can lie off
                # the frame by more than track_window_px while the near window still reaches in.
                wide = self.window_around(
                    t.centre_px + t.velocity_px,
                    max(self.cfg.track_window_px, 4.0 * radius, near_half_px(radius, speed)),
                )
                if wide is None:
                    return None
                thr = self.thresholds[colour]
                mask = coarse_masks(
                    frame,
                    self.grid,
                    thr if colour == "red" else None,
                    thr if colour == "blue" else None,
                    wide,
                    self.step_cells,
                )
                own_mask = mask[0] if colour == "red" else mask[1]
                assert own_mask is not None  # coarse_masks gives the mask of each colour given a threshold
                seeds = seed_windows(
                    {colour: own_mask},
                    wide,
                    self.step_cells,
                    self.grid,
                    self.limits,
                )[colour]
                jobs = [(colour, w) for w in seeds.windows[:MAX_WINDOWS]]
                candidates, rejects = self.refine(frame, jobs)[colour]
                if not candidates:
                    return None
            searches[colour] = _Search(candidates, 1, 0, rejects, True)
        return self.result(frame, searches, "window", {c: track[c].area_px for c in COLOURS}, need_pair=True)

    def window_around(self, centre_px: NDArray[np.float64], half_px: float) -> Region | None:
        """The cells within ``half_px`` of ``centre_px`` (clipped to the frame), or None if none."""
        x, y = float(centre_px[0]), float(centre_px[1])
        if not (math.isfinite(x) and math.isfinite(y)):
            return None
        s = self.grid.cell_px
        lo_r, hi_r, lo_c, hi_c = self.grid.interior()
        region = (
            max(lo_r, int((y - half_px) // s)),
            min(hi_r, int((y + half_px) // s) + 1),
            max(lo_c, int((x - half_px) // s)),
            min(hi_c, int((x + half_px) // s) + 1),
        )
        if region[1] - region[0] < 2 or region[3] - region[2] < 2:
            return None
        return region

    def refine(
        self, frame: NDArray[np.uint8], jobs: list[tuple[str, Region]]
    ) -> dict[str, tuple[list[Candidate], Rejects]]:
        """Ball-shaped candidates and rejects per colour, from refining (colour, window) jobs."""
        refined = refine(frame, self.grid, jobs, self.thresholds, self.limits)
        cut = [j for j, c in enumerate(refined.cut) if c]
        if cut:
            # A blob reaches its window's edge: the seed understated it (weak rim, fast motion).
            again = refine(
                frame,
                self.grid,
                [(jobs[j][0], grow(jobs[j][1], 2 * self.step_cells, self.grid)) for j in cut],
                self.thresholds,
                self.limits,
            )
            for i, j in enumerate(cut):
                refined.candidates[j] = again.candidates[i]
                refined.rejects[j] = again.rejects[i]
        out: dict[str, tuple[list[Candidate], Rejects]] = {c: ([], Rejects({})) for c in COLOURS}
        seen: set[tuple[int, int, int, int]] = set()
        for (colour, _), candidates, rejects in zip(jobs, refined.candidates, refined.rejects, strict=True):
            found, total = out[colour]
            total.merge(rejects)
            for c in candidates:
                # Grown windows can overlap their neighbours: keep each blob once.
                key = c.bbox_px(self.grid)
                if key not in seen:
                    seen.add(key)
                    found.append(c)
        return out

    def result(
        self,
        frame: NDArray[np.uint8],
        found: dict[str, _Search],
        search: str,
        previous_area_px: dict[str, float] | None,
        need_pair: bool = False,
    ) -> ImageDetections | None:
        choice = choose(
            found["red"].candidates,
            found["blue"].candidates,
            self.length_over_diameter,
            previous_area_px,
            lambda r, b: rod_evidence(frame, self.grid, r, b, self.rod_over_diameter),
        )
        if need_pair and not choice.paired:
            return None
        ends = {}
        chosen = {}
        for colour, cand in (("red", choice.red), ("blue", choice.blue)):
            if cand is None:
                s = found[colour]
                ends[colour] = EndDetection.missing(
                    missing_reason(colour, s.seeds, s.too_large_seeds, s.rejects, s.examined_all)
                )
            else:
                chosen[colour] = cand
        measured = self.measure_chosen(frame, list(chosen.values()))
        scores = {"red": choice.red_score, "blue": choice.blue_score}
        for colour, m in zip(chosen, measured, strict=True):
            score = scores[colour]
            ends[colour] = EndDetection(True, m.centre_px, m.area_px, m.bbox_px, score, None)
        return ImageDetections(ends["red"], ends["blue"], search)  # type: ignore[arg-type]

    def measure_chosen(self, frame: NDArray[np.uint8], chosen: list[Candidate]) -> list[Measurement]:
        """The chosen candidates' centres, areas and boxes, all at once when that is the same.

        Measured together (trackerd.detect.window_measure) in square windows around each
        blob's region when each blob was alone in its search window and each
        window's thresholded samples all lie in the region :func:`measure_candidate`
        would measure (then both see the same samples); otherwise one by one, other
        blobs in the region left out.
        """
        if self.flat and chosen and all(c.alone and c.scale == 1 for c in chosen):
            regions = [candidate_region(self.grid, c) for c in chosen]
            ends, half_cells = [], 0
            for c, (r0, r1, c0, c1) in zip(chosen, regions, strict=True):
                row, col = (r0 + r1 - 1) // 2, (c0 + c1 - 1) // 2
                half_cells = max(half_cells, row - r0, r1 - 1 - row, col - c0, c1 - 1 - col)
                dr, dc = self.grid.offset(c.colour)
                ends.append((c.colour, float(2 * col + dc), float(2 * row + dr)))
            found = measure_windows(
                frame,
                self.grid,
                ends,
                half_cells,
                self.thresholds,
                ANY_SHAPE,
                self.work,
                within=regions,
                every_pixel=self.rim_pixels,
            )
            if found is not None:
                return found
        measured = [measure_candidate(frame, self.grid, c, self.thresholds[c.colour], self.weighted) for c in chosen]
        return self.centres(frame, measured)

    def centres(self, frame: NDArray[np.uint8], found: list[Measurement]) -> list[Measurement]:
        """The ends' centres and areas from every pixel of their rims (or as measured)."""
        return measure_rims(frame, self.grid, found, self.work) if self.rim_pixels else found


def near_half_px(radius_px: float, speed_px: float) -> float:
    """Half-size of the first window a tracked end is looked for in (the blob search's near window)."""
    return 2.0 * radius_px + speed_px + 8.0
