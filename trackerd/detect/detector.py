"""The colour-end detector: find the pointer's red and blue ends in one camera's frames.

Per frame (report section 3.2, eq. 10-12, made robust and sub-pixel):

1. *Window search*, when both ends were found in the previous frame. Each end
   is first measured directly in a small window around where it should be now
   (previous position plus previous motion); if both are there, whole, round,
   of the size they had and consistent as a pair, that is the answer. Otherwise
   the blobs in those windows, and then in windows of ``track_window_px`` on
   each side, are found and chosen as in a full search.
2. *Full search* otherwise: a subsampled pass over the whole frame (every
   ``search_step_px``) finds seeds of each colour; each seed is refined at full
   plane resolution in a small window (:mod:`trackerd.detect.candidates`).
   Both blob searches are :mod:`trackerd.detect.blob_search`'s.
3. *Selection* (:mod:`trackerd.detect.select`): blobs that cannot be a ball
   (area, elongation, fill) are dropped, and of the rest the red-blue pair most
   consistent with one pointer wins.
4. *Centre* (:mod:`trackerd.detect.centroid`): sub-pixel, from the coverage of
   the end's own samples and, on a Bayer mosaic, of every pixel around it
   (:mod:`trackerd.detect.coverage`; ``centroid = "weighted"``), or the report's
   bounding-box midpoint (eq. 12, ``centroid = "bbox"``).

``ColourEndDetector`` keeps the tracking state; :func:`detect_ends` is the same
search without state. Either way the search is NumPy only (docs/detection.md).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from trackerd.config.models import DetectorConfig, PointerConfig
from trackerd.detect.blob_search import BlobSearch, EndTrack
from trackerd.detect.candidates import Limits, shape_score
from trackerd.detect.centroid import Measurement, keep_nearest_blob, measure, sample
from trackerd.detect.colour import SampleGrid, Threshold, sample_grid
from trackerd.detect.flat import WorkspaceCache
from trackerd.detect.result import COLOURS, EndDetection, ImageDetections
from trackerd.detect.select import pair_consistency
from trackerd.detect.window_measure import BlobShape, WindowOrigin, interior_of, measure_windows, window_origin
from trackerd.errors import ImageError

DEFAULT_LENGTH_OVER_DIAMETER = 12.0
"""Pointer length over ball diameter used when no PointerConfig is given."""

DEFAULT_ROD_OVER_DIAMETER = 0.3
"""Rod diameter over ball diameter used when no PointerConfig is given."""

QUICK_MAX_ELONGATION = 1.6
QUICK_MIN_FILL = 0.6
QUICK_AREA_RATIO = 1.6
"""The quick tracking measurement is taken only for a blob this round, this full and within
this factor of its previous area; anything else (a second blob in the window, occlusion,
a jump) goes through the blob search."""


class ColourEndDetector:
    """Finds both ends of the pointer in the frames of one camera, tracking them between frames.

    Cheap to build; keep one per camera, since it remembers the previous frame's
    result. Call :meth:`reset` when the frames stop being consecutive (pointer
    lost, new recording). ``search_step_px`` overrides ``cfg.search_step_px``;
    ``rim_pixels=False`` keeps the centre from the ends' own colour samples only
    (faster by about half a count-pass per frame, about twice the error across
    the pointer; docs/detection.md).
    """

    def __init__(
        self,
        cfg: DetectorConfig,
        pixel_format: str,
        width_px: int,
        height_px: int,
        pointer: PointerConfig | None = None,
        *,
        search_step_px: int | None = None,
        rim_pixels: bool | None = None,
    ) -> None:
        self.cfg = cfg
        self.pixel_format = pixel_format
        self.grid: SampleGrid = sample_grid(pixel_format, width_px, height_px)
        self.thresholds = {
            "red": Threshold(cfg.red.min_excess, cfg.red.min_value),
            "blue": Threshold(cfg.blue.min_excess, cfg.blue.min_value),
        }
        self.limits = Limits(cfg.min_area_px, cfg.max_area_px, cfg.max_elongation, cfg.min_fill)
        self.weighted = cfg.centroid != "bbox"
        if pointer is not None:
            self.length_over_diameter = pointer.length_m / pointer.end_diameter_m
            self.rod_over_diameter = pointer.rod_diameter_m / pointer.end_diameter_m
        else:
            self.length_over_diameter = DEFAULT_LENGTH_OVER_DIAMETER
            self.rod_over_diameter = DEFAULT_ROD_OVER_DIAMETER
        step_px = search_step_px or cfg.search_step_px
        self.step_cells = max(1, round(step_px / self.grid.cell_px))
        self._track: dict[str, EndTrack] | None = None
        self._crowded: set[str] = set()
        # None: as the configuration says (centroid = "coverage" uses every pixel of the rim).
        every_pixel = cfg.centroid == "coverage" if rim_pixels is None else rim_pixels
        self.rim_pixels = every_pixel and self.weighted and self.grid.is_bayer
        # Weighted centres on a mosaic are measured for both ends at once (trackerd.detect.window_measure)
        # wherever that gives what measuring them one by one gives.
        self.flat = self.weighted and self.grid.is_bayer
        self._work = WorkspaceCache()
        self._blobs = BlobSearch(
            cfg,
            self.grid,
            self.thresholds,
            self.limits,
            self.step_cells,
            self.length_over_diameter,
            self.rod_over_diameter,
            self.weighted,
            self.flat,
            self.rim_pixels,
            self._work,
        )
        self._round_blob = BlobShape(QUICK_MAX_ELONGATION, QUICK_MIN_FILL)

    def reset(self) -> None:
        """Forget the previous frame: the next frame is searched in full."""
        self._track = None

    def detect(self, frame: NDArray[np.uint8]) -> ImageDetections:
        """Both ends in ``frame`` (shape (H, W) for Bayer, (H, W, 3) for RGB8/BGR8, uint8)."""
        self._check(frame)
        result = None
        self._crowded = set()
        if self._track is not None:
            result = self._quick_track(frame, self._track) or self._blobs.near(frame, self._track)
        if result is None:
            result = self._blobs.full(frame)
        self._remember(result)
        return result

    def _check(self, frame: NDArray[np.uint8]) -> None:
        if frame.shape != self.grid.frame_shape or frame.dtype != np.uint8:
            raise ImageError(
                f"frame of shape {frame.shape} and type {frame.dtype} does not match the camera's"
                f" {self.pixel_format} {self.grid.frame_shape[1]}x{self.grid.frame_shape[0]}"
                " (uint8)"
            )

    # ------------------------------------------------------------------ searches

    def _quick_track(self, frame: NDArray[np.uint8], track: dict[str, EndTrack]) -> ImageDetections | None:
        """Each end measured straight in a small window where it should be, if it is plainly there.

        This is the common case while tracking, and costs a few dozen NumPy calls
        per end; None sends the frame to the blob search.
        """
        crowded = {c for c in COLOURS if track[c].crowded}
        if self.flat and not crowded:
            both = self._quick_both(frame, track)
            if both is not None:
                return self._quick_result(both[0], both[1], crowded)
        found: dict[str, Measurement] = {}
        for colour in COLOURS:
            t = track[colour]
            thr = self.thresholds[colour]
            radius = math.sqrt(t.area_px / math.pi)
            speed = math.hypot(float(t.velocity_px[0]), float(t.velocity_px[1]))
            predicted = t.centre_px + t.velocity_px
            window = self._blobs.window_around(predicted, 1.25 * radius + 0.5 * speed + 4.0)
            if window is None:
                return None
            samples = sample(frame, self.grid, colour, thr, window)
            near = (float(predicted[0]), float(predicted[1]))
            if t.crowded:
                keep_nearest_blob(samples, near)
            m = measure(samples, self.weighted)
            if not t.crowded and not self._is_tracked_end(m, t.area_px):
                # Something else of the colour in the window: keep the blob nearest the prediction.
                keep_nearest_blob(samples, near)
                m = measure(samples, self.weighted)
                crowded.add(colour)
            if not self._is_tracked_end(m, t.area_px):
                return None
            assert m is not None
            found[colour] = m
        red, blue = self._blobs.centres(frame, [found["red"], found["blue"]])
        return self._quick_result(red, blue, crowded)

    def _quick_both(
        self, frame: NDArray[np.uint8], track: dict[str, EndTrack]
    ) -> tuple[Measurement, Measurement] | None:
        """Both ends measured together in windows of one size (trackerd.detect.window_measure), if plain."""
        plan = self._quick_plan(track)
        if plan is None:
            return None
        ends, half_cells = plan
        found = measure_windows(
            frame,
            self.grid,
            ends,
            half_cells,
            self.thresholds,
            self._round_blob,
            self._work,
            every_pixel=self.rim_pixels,
        )
        return None if found is None else self._both_tracked(found, track)

    def _quick_plan(self, track: dict[str, EndTrack]) -> tuple[list[tuple[str, float, float]], int] | None:
        """Where to measure each end quickly, (colour, x_px, y_px), and the windows' half size in
        cells: big enough for the larger end and its motion. None if a prediction is not finite."""
        ends = []
        half_px = 0.0
        for colour in COLOURS:
            t = track[colour]
            x, y = t.x_px + t.vx_px, t.y_px + t.vy_px
            if not (math.isfinite(x) and math.isfinite(y)):
                return None
            radius = math.sqrt(t.area_px / math.pi)
            half_px = max(half_px, 1.25 * radius + 0.5 * math.hypot(t.vx_px, t.vy_px) + 4.0)
            ends.append((colour, x, y))
        return ends, math.ceil(half_px / self.grid.cell_px)

    def _both_tracked(
        self, found: list[Measurement], track: dict[str, EndTrack]
    ) -> tuple[Measurement, Measurement] | None:
        for colour, m in zip(COLOURS, found, strict=True):
            if not self._is_tracked_end(m, track[colour].area_px):
                return None
        return found[0], found[1]

    def _quick_result(self, red: Measurement, blue: Measurement, crowded: set[str]) -> ImageDetections | None:
        """The quick path's answer if the two ends are consistent as a pair, else None."""
        pair = pair_consistency(
            red.area_px,
            blue.area_px,
            red.x_px - blue.x_px,
            red.y_px - blue.y_px,
            self.length_over_diameter,
        )
        if pair <= 0.0:
            return None
        ends = [
            EndDetection(
                True,
                m.centre_px,
                m.area_px,
                m.bbox_px,
                shape_score(m.elongation, m.fill) * pair,
                None,
            )
            for m in (red, blue)
        ]
        self._crowded = crowded
        return ImageDetections(ends[0], ends[1], "window")

    def _is_tracked_end(self, m: Measurement | None, previous_area_px: float) -> bool:
        """Whether a quick measurement is plainly the end: whole, round, full, the same size."""
        return (
            m is not None
            and not m.on_border
            and m.elongation <= QUICK_MAX_ELONGATION
            and m.fill >= QUICK_MIN_FILL
            and previous_area_px / QUICK_AREA_RATIO <= m.area_px <= previous_area_px * QUICK_AREA_RATIO
            and self.limits.min_area_px <= m.area_px <= self.limits.max_area_px
        )

    def follow(
        self, red_px: NDArray[np.float64], blue_px: NDArray[np.float64], red_radius_px: float, blue_radius_px: float
    ) -> None:
        """Track the ends from these positions next frame: where a search beyond this detector (the
        locator's, across cameras) found the balls this frame, whatever this detector took for them."""
        self._track = {
            "red": EndTrack(float(red_px[0]), float(red_px[1]), 0.0, 0.0, math.pi * red_radius_px**2),
            "blue": EndTrack(float(blue_px[0]), float(blue_px[1]), 0.0, 0.0, math.pi * blue_radius_px**2),
        }

    def _remember(self, result: ImageDetections) -> None:
        if not result.both_found:
            self._track = None
            return
        previous = self._track
        track = {}
        for colour in COLOURS:
            end = result.end(colour)
            assert end.centroid_px is not None
            x, y = end.centroid_px.tolist()
            vx = vy = 0.0
            if previous is not None:
                vx, vy = x - previous[colour].x_px, y - previous[colour].y_px
            crowded = result.search == "window" and colour in self._crowded
            track[colour] = EndTrack(x, y, vx, vy, end.area_px, crowded)
        self._track = track


def detect_all_cameras(
    detectors: Sequence[ColourEndDetector], frames: Sequence[NDArray[np.uint8]]
) -> list[ImageDetections]:
    """Each camera's frame through its detector (what ``[d.detect(f) for ...]`` gives), with the
    cameras' quick measurements taken in one go where they can be.

    While every camera tracks the pointer plainly, which is the common case,
    the ends of all cameras are measured in one set of flat arrays
    (trackerd.detect.window_measure) instead of one per camera: about half the NumPy
    calls, which is most of the cost of a pair. The windows then have one size,
    the largest any camera needs, and each end's thresholded samples must lie
    inside the window that camera would have used alone, off its border (then
    it sees exactly those samples, and measures what it would alone, to float32
    rounding). Where the joint measurement fails for any end, every camera's
    frame goes through :meth:`ColourEndDetector.detect`; where a camera's ends
    are measured but not accepted (not plainly the ends it tracks, or not a
    consistent pair), that camera's frame does.
    """
    results: list[ImageDetections | None] = [None] * len(detectors)
    # Per camera that can join: (index, its ends, its windows' half size, its own windows' origins).
    planned: list[tuple[int, list[tuple[str, float, float]], int, list[WindowOrigin]]] = []
    reference = detectors[0]
    for index, (detector, frame) in enumerate(zip(detectors, frames, strict=True)):
        detector._check(frame)
        track = detector._track
        if (
            track is None
            or not detector.flat
            or any(t.crowded for t in track.values())
            or detector.thresholds != reference.thresholds
            or (detector.grid.red, detector.grid.blue) != (reference.grid.red, reference.grid.blue)
            or detector.rim_pixels != reference.rim_pixels
        ):
            continue
        plan = detector._quick_plan(track)
        if plan is None:
            continue
        own_ends, own_half = plan
        own = [window_origin(frame.shape, detector.grid, *end, own_half) for end in own_ends]
        origins = [origin for origin in own if origin is not None]
        if len(origins) == len(own):  # else its own windows would not fit in the frame
            planned.append((index, own_ends, own_half, origins))
    if len(planned) >= 2:
        joined = [index for index, _, _, _ in planned]
        half_cells = max(half for _, _, half, _ in planned)
        ends = [end for _, plan_ends, _, _ in planned for end in plan_ends]
        # Where each end may lie (its own window's interior), and the joint windows' origins where a
        # camera's own windows are of the joint size (the same windows: not placed again).
        within = [interior_of(origin, half) for _, _, half, origins in planned for origin in origins]
        known = [origin if half == half_cells else None for _, _, half, origins in planned for origin in origins]
        first = detectors[joined[0]]
        found = measure_windows(
            [frames[i] for i in joined for _ in COLOURS],
            first.grid,
            ends,
            half_cells,
            first.thresholds,
            first._round_blob,
            first._work,
            within=within,
            every_pixel=first.rim_pixels,
            origins=known,
        )
        if found is not None:
            for k, i in enumerate(joined):
                detector = detectors[i]
                assert detector._track is not None
                both = detector._both_tracked(found[2 * k : 2 * k + 2], detector._track)
                if both is not None:
                    result = detector._quick_result(both[0], both[1], set())
                    if result is not None:
                        detector._remember(result)
                        results[i] = result
    return [
        result if result is not None else detector.detect(frame)
        for detector, frame, result in zip(detectors, frames, results, strict=True)
    ]


def detect_ends(
    frame: NDArray[np.uint8],
    pixel_format: str,
    cfg: DetectorConfig,
    pointer: PointerConfig | None = None,
) -> ImageDetections:
    """Both ends in one frame, searched in full, with no memory of other frames."""
    height, width = frame.shape[:2]
    return ColourEndDetector(cfg, pixel_format, width, height, pointer).detect(frame)
