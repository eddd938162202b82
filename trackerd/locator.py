"""The locator: from one synchronized image per camera to the pointer's 3D line and its wall hit.

This is the report's program (section 4) and the daemon's processing stage:
detect both coloured ends in every image (trackerd/detect), turn the end
centroids into rays (eq. 14 and the lens model), estimate the pointer's line
(trackerd/geometry/pointer_line.py; eq. 15-17 for each end), and intersect it
with the wall plane (eq. 23-28).

Every outcome is a :class:`PointerFix` with a ``status``:

``hit``       the pointer points at the display;
``off_wall``  it points at the wall's plane outside the display;
``away``      it points away from the wall (the hit would be behind the pointer);
``parallel``  it is parallel to the wall;
``rejected``  both ends were seen but the geometry is impossible (length, ray gap);
``not_found`` an end is missing in some camera.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import NDArray

from trackerd.config.models import PointerConfig, RigConfig
from trackerd.config.rig_geometry import camera_model, wall_frame
from trackerd.detect.result import ImageDetections
from trackerd.errors import ConfigError, GeometryError
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.camera_set import (
    CameraSet,
    LineEstimate,
    across_sigma_px,
    estimate_line,
    hit_uncertainty_m,
)
from trackerd.geometry.pointer_fit import EndViews, fit_pointer_step, hit_covariance
from trackerd.geometry.pointer_line import PointerLine, ray_gaps_m, world_rays
from trackerd.geometry.wall import LineHit, WallFrame, intersect_line_plane
from trackerd.tracked_ends import (
    END_CORRELATION,
    GUIDED_RADIUS_RATIO,
    EndOffset,
    area_change_log,
    corrected_end,
    due_next_pair,
    end_depth_m,
    end_offset,
    is_stale,
    moved_px,
    stale_share,
    staleness,
)

if TYPE_CHECKING:
    from trackerd.detect.detector import ColourEndDetector
    from trackerd.ends import EndMeasurement
    from trackerd.refine import RefinedPath

Array = NDArray[np.float64]

COLOURS = ("red", "blue")

LineStatus = Literal["hit", "off_wall", "away", "parallel"]
"""The outcomes of a fix with a plausible line: a pointer message's ``status`` on the wire."""
FixStatus = LineStatus | Literal["rejected", "not_found"]
"""A fix's outcome, as the wire's ``status`` strings (see the module's docstring)."""

TRACKED_REDUCED_CHI2 = 4.0
"""A tracked pair whose pointer fit leaves a chi-square above this times its degrees of freedom is refined:
its corrected ends do not agree within their stated errors (one of them is on something else, or hidden)."""

TIGHT_GAP_M = 0.004
TIGHT_LENGTH_M = 0.012
"""While tracking, a fix from the corrected centroids whose rays miss by more than TIGHT_GAP_M or whose
length is off by more than TIGHT_LENGTH_M is refined: a good one is within a millimetre or two of both."""


PARALLEL_ANGLE_DEG = 0.5
"""A pointer within this angle of the wall's plane is reported as parallel: its line would meet
the plane more than a hundred times further away than the tip is from the wall, and which way
it crosses is decided by noise."""


@dataclass(frozen=True)
class WallHit:
    """Where the pointer's line meets the wall plane."""

    wall_xy_m: Array
    """In the wall's 2D frame: metres from the display's bottom-left corner, x right, y up."""
    world_m: Array
    display_px: Array | None
    """Display pixels (origin top-left, y down) when the wall has a display size."""
    on_wall: bool
    distance_m: float
    """From the pointer's front end to the hit, along the line."""


@dataclass(frozen=True)
class PointerFix:
    """The locator's answer for one set of images."""

    status: FixStatus
    reason: str | None
    centroids_px: tuple[dict[str, Array | None], ...]
    """Per camera, per colour: the centroid used (None where the end was not found)."""
    line: PointerLine | None = None
    hit: WallHit | None = None
    uncertainty_m: float | None = None
    """Estimated standard error of the hit on the wall (RMS radius), from centroid noise."""
    timings_ns: dict[str, int] = field(default_factory=dict)
    detections: tuple[ImageDetections, ...] = ()
    """The detector's full results, per camera (empty when centroids were given directly)."""
    measurements: tuple[dict[str, EndMeasurement | None], ...] = ()
    """Per camera, per colour: the end measurement the pointer fit used (trackerd.ends.EndMeasurement, or
    None where that camera did not measure that end); empty when the fit was not used."""

    @property
    def found(self) -> bool:
        """Both ends were seen and triangulated to a plausible pointer."""
        return self.line is not None and self.status != "rejected"


def _finite_point(point_px: Array | None) -> bool:
    """A centroid that is there and finite (plain floats: this runs for every end of every pair)."""
    return point_px is not None and all(math.isfinite(v) for v in point_px)


def _detected_centroids(detections: tuple) -> tuple[dict[str, Array | None], ...]:
    """Per camera, per colour: the detector's centroid (None where the end was not found)."""
    return tuple(
        {colour: (d.end(colour).centroid_px if d.end(colour).found else None) for colour in COLOURS} for d in detections
    )


@dataclass(frozen=True, slots=True)
class StaleEnd:
    """A tracked end whose correction has been carried too far (trackerd/tracked_ends.py: is_stale): its
    outline is measured again before its centroid is trusted."""

    camera_index: int
    colour: str
    offset: EndOffset
    """Its outline as last measured."""
    depth_m: float
    """Its depth in the camera where the last pair put it (0 when unknown)."""
    point_m: Array | None
    """Where the last pair put it (None when the last pair was not found)."""


@dataclass(frozen=True, slots=True)
class AheadWork:
    """Ends to measure again between pairs (:meth:`Locator.measure_ahead`): the pair just located, and its ends
    whose corrections will be carried too far by the next pair (trackerd/tracked_ends.py: due_next_pair)."""

    images: tuple[NDArray[np.uint8], ...]
    detections: tuple[ImageDetections, ...]
    ends: tuple[StaleEnd, ...]
    """Each with where this pair put it (``point_m``, ``depth_m``)."""


class Locator:
    """Detectors for each camera plus the rig's geometry; one instance per stream of image sets.

    Not thread-safe: it keeps each camera's detector tracking state between calls.
    """

    def __init__(
        self,
        rig: RigConfig,
        cameras: Sequence[CameraModel] | None = None,
        wall: WallFrame | None = None,
        pixel_formats: Sequence[str] | None = None,
    ) -> None:
        """``pixel_formats`` overrides the rig's per-camera format (still images read as RGB, say)."""
        self.rig = rig
        if wall is None and rig.wall is not None:
            wall = wall_frame(rig.wall)
        if rig.pointer is None or wall is None:
            raise ConfigError(f"rig '{rig.name}' has no [pointer] or no [wall]: it cannot locate the pointer")
        self.pointer: PointerConfig = rig.pointer
        self.wall: WallFrame = wall
        self.cameras = list(cameras) if cameras is not None else [camera_model(c) for c in rig.cameras]
        self.front_colour = self.pointer.front_colour
        self.back_colour = "blue" if self.front_colour == "red" else "red"
        self._detectors: list[ColourEndDetector] | None = None
        self.pixel_formats = list(pixel_formats) if pixel_formats else [c.pixel_format for c in rig.cameras]
        self._min_plane_sin = float(np.sin(np.radians(rig.locator.min_plane_angle_deg)))
        self._parallel_sin = float(np.sin(np.radians(PARALLEL_ANGLE_DEG)))
        self.camera_set = CameraSet.build(self.cameras)
        self._centres = self.camera_set.centres_m
        self._grids: list | None = None
        self._refined: RefinedPath | None = None
        """The refined path (trackerd/refine.py), made on first use."""
        self.offsets: list[dict[str, EndOffset]] | None = None
        """Per camera, per colour: the offset of the end's outline from the detector's centroid, as last
        measured (trackerd/tracked_ends.py); None until a refined pair has measured them. A tracked pair
        takes the tracked path only when every end its detectors found has one."""
        self._tracked_by_fit: bool | None = None
        """Whether tracked pairs take the pointer fit (else the planes) until an end's outline is measured
        again; None: decided on the next tracked pair (:meth:`_tracked_line`)."""
        self._tracked_plane_sin = 0.0
        """The interpretation planes' angle (sine) at the pair that last made that choice."""
        self._last_line: PointerLine | None = None
        """The last found pointer's line: each end's depth in each camera, for the tracked ends' area check."""
        self._line_before: PointerLine | None = None
        """The found pointer's line of the pair before the last, when the last one's was found too."""
        self._shares: dict[tuple[int, str], tuple[EndOffset, float]] = {}
        """Per camera and colour: the offset a tracked end was last corrected by and how stale it was then
        (trackerd/tracked_ends.py: stale_share), for predicting which ends the next pair would find stale."""
        self._ahead: AheadWork | None = None
        """What :meth:`measure_ahead` will measure; done at the start of the next :meth:`locate` if the caller
        has not found a moment for it between pairs."""
        self.measured_in_pair = 0
        """How many ends' outlines the last :meth:`locate` measured again before answering, for a tracked pair:
        those it found stale, and those left to measure ahead that nobody did (the work that time between
        pairs did not take off this pair's latency)."""
        self.measured_between_pairs = 0
        """How many ends' outlines :meth:`measure_ahead` has measured, since the locator was made."""
        self.measured_in_pairs = 0
        """How many :attr:`measured_in_pair` has counted, since the locator was made."""

    # ------------------------------------------------------------------ detection

    @property
    def detectors(self) -> list:
        if self._detectors is None:
            from trackerd.detect import ColourEndDetector, detect_all_cameras

            self._detect_all = detect_all_cameras

            self._detectors = [
                ColourEndDetector(self.rig.detector, fmt, cfg.width_px, cfg.height_px, self.pointer)
                for cfg, fmt in zip(self.rig.cameras, self.pixel_formats, strict=True)
            ]
        return self._detectors

    def reset(self) -> None:
        """Forget tracking state (the pointer left, a new recording starts)."""
        for detector in self._detectors or []:
            detector.reset()
        self.offsets = None
        self._tracked_by_fit = None
        self._last_line = None
        self._line_before = None
        self._ahead = None
        if self._refined is not None:
            self._refined.reset()

    def locate(self, images: Sequence[NDArray[np.uint8]]) -> PointerFix:
        """Detect the ends in one image per camera (rig order) and locate the pointer."""
        if len(images) != len(self.cameras):
            raise ValueError(f"expected {len(self.cameras)} images, got {len(images)}")
        ahead_ns = 0
        self.measured_in_pair = 0
        if self._ahead is not None:
            # What nobody measured ahead is measured now, before this pair: the answers never depend on whether
            # the time between pairs allowed it, only this pair's latency does.
            begun = time.perf_counter_ns()
            self.measured_in_pair = self._measure_ahead()
            ahead_ns = time.perf_counter_ns() - begun
        start = time.perf_counter_ns()
        # Every camera's frame, the quick measurements of all taken together (trackerd.detect.detector).
        detectors = self.detectors  # made on first use, with the function below
        detections = tuple(self._detect_all(detectors, images))
        detected = time.perf_counter_ns()
        mode = self.rig.locator.refine
        fix = None
        if mode == "auto" and self.offsets is not None and all(d.search == "window" for d in detections):
            # Tracking, with every end's outline measured at a refined pair: the tracked path, as long as its
            # pointer holds together as tightly as a good one does.
            fix = self._locate_tracked(images, detections)
            if fix is not None and (not fix.found or not self._tight(fix)):
                fix = None
                self._ahead = None  # what the tracked path put aside is the refined pair's to replace
        if fix is None:
            fix = self._locate_detected(detections) if mode == "never" else self._locate_refined(images, detections)
        fix.timings_ns["detect_ns"] = detected - start
        if ahead_ns:
            fix.timings_ns["triangulate_ns"] = fix.timings_ns.get("triangulate_ns", 0) + ahead_ns
        self.measured_in_pairs += self.measured_in_pair
        if not fix.found:
            self._lost()
        line = fix.line if fix.found else None
        self._line_before = self._last_line if line is not None else None
        self._last_line = line
        return fix

    @property
    def ahead_pending(self) -> bool:
        """Whether :meth:`measure_ahead` has ends to measure (the caller may wait for a quiet moment)."""
        return self._ahead is not None

    def measure_ahead(self) -> int:
        """Measure again, on the pair just located, the outlines of the tracked ends the next pair would find
        stale (trackerd/tracked_ends.py: due_next_pair), so that it need not: an outline fit takes about a
        millisecond an end, most of a tracked pair's time. The processing stage calls this once the pair's
        messages are sent; :meth:`locate` calls it first if nobody did. An end measured again must pass what
        one measured in the pair must (:meth:`_measure_again`); if any does not, every offset stays as it was
        and the next pair decides as it would have. Returns how many ends were measured."""
        measured = self._measure_ahead()
        self.measured_between_pairs += measured
        return measured

    def _measure_ahead(self) -> int:
        work, self._ahead = self._ahead, None
        if work is None or self.offsets is None:
            return 0
        again = self._measure_again(work.images, work.detections, work.ends)
        if again is None:
            return 0
        for end, offset in zip(work.ends, again, strict=True):
            self.offsets[end.camera_index][end.colour] = offset
        # As after an outline measured in the pair: the next tracked pair chooses the planes or the fit anew.
        self._tracked_by_fit = None
        return len(work.ends)

    def _lost(self) -> None:
        """The pointer was not found at this pair: the detectors' tracking windows and the tracked path's
        offsets are stale, and the next pair is detected in full. The refined path's search keeps its cadence
        (trackerd.refine.RefinedPath._search_wait): a reset here would make a room without the pointer search
        on every pair (52 ms a pair on a plain 4K-class frame, hundreds before a busy
        display). Every user of a locator (the processing stage, replay ahead, export, windowed recording)
        gets this from locate itself."""
        for detector in self._detectors or []:
            detector.reset()
        self.offsets = None
        self._tracked_by_fit = None
        self._ahead = None

    @property
    def step_known(self) -> bool:
        """Whether :meth:`predicted_ends_m` moves the last pair's ends on by a step (the pair before was found
        too); without one, the prediction lags the pointer by a frame's motion."""
        return self._line_before is not None  # kept only while the last pair's line is

    def predicted_ends_m(self) -> Array | None:
        """Where the pointer's ends (front, back; (2, 3)) should be at this pair: the last pair's, moved on by the
        step they made from the pair before when that was found too; None when the last pair's pointer was
        not found."""
        last = self._last_line
        if last is None:
            return None
        ends = np.stack([last.front_m, last.back_m])
        before = self._line_before
        if before is not None:
            ends = 2.0 * ends - np.stack([before.front_m, before.back_m])
        return ends

    def _tight(self, fix: PointerFix) -> bool:
        """Whether a fix from the detector's centroids holds together as a good one does."""
        line = fix.line
        assert line is not None
        return line.gap_m <= TIGHT_GAP_M and abs(line.length_m - self.pointer.length_m) <= TIGHT_LENGTH_M

    def _locate_tracked(self, images: Sequence[NDArray[np.uint8]], detections: tuple) -> PointerFix | None:
        """The tracked path (trackerd/tracked_ends.py): each tracked centroid corrected by its ball's outline
        as last measured, with the error that leaves, and the planes or the pointer fit on them
        (:meth:`_tracked_line`; eq. 1-2, 15-17). An end that has drifted too far since its outline is
        measured again first. None when the refined path must answer (an end without a measured outline,
        one whose outline is not found again, ends that disagree beyond their errors)."""
        offsets = self.offsets
        assert offsets is not None
        start = time.perf_counter_ns()
        used = [i for i, d in enumerate(detections) if d.both_found]
        if len(used) < 2 or any(
            d.end(colour).found and colour not in offsets[i] for i, d in enumerate(detections) for colour in COLOURS
        ):
            return None
        last = self._last_line
        # Each end's drift since its outline; the stale ends of every camera are measured again together, in
        # one batched measurement (:meth:`_measure_again`), before any end is corrected.
        drifts: list[tuple[float, float]] = []
        stale: list[StaleEnd] = []
        due: list[tuple[int, str]] = []
        for i in used:
            camera, detection = self.cameras[i], detections[i]
            for e, colour in enumerate((self.front_colour, self.back_colour)):
                end = detection.end(colour)
                point = None if last is None else (last.front_m if e == 0 else last.back_m)
                depth = 0.0 if point is None else end_depth_m(camera, point)
                offset = offsets[i][colour]
                area_change = area_change_log(offset, end.area_px, depth)
                moved = moved_px(offset, end.centroid_px)
                if is_stale(staleness(offset, moved, area_change), area_change):
                    stale.append(StaleEnd(i, colour, offset, depth, point))
                    moved = area_change = 0.0  # measured again beside this very centroid
                else:
                    share = stale_share(offset, moved, area_change)
                    before = self._shares.get((i, colour))
                    if due_next_pair(share, before[1] if before is not None and before[0] is offset else 0.0):
                        due.append((i, colour))
                    self._shares[(i, colour)] = (offset, share)
                drifts.append((moved, area_change))
        if stale:
            self.measured_in_pair += len(stale)
            again = self._measure_again(images, detections, stale)
            if again is None:
                return None
            for end_again, offset in zip(stale, again, strict=True):
                offsets[end_again.camera_index][end_again.colour] = offset
        normalised = np.empty((len(used), 2, 2))
        covariances = np.empty((len(used), 2, 2, 2))
        for k, i in enumerate(used):
            camera, detection = self.cameras[i], detections[i]
            ends = (detection.end(self.front_colour), detection.end(self.back_colour))
            centroids_n = camera.normalized_from_pixels(np.array([ends[0].centroid_px, ends[1].centroid_px]))
            for e, colour in enumerate((self.front_colour, self.back_colour)):
                moved, area_change = drifts[2 * k + e]
                normalised[k, e], covariances[k, e] = corrected_end(
                    offsets[i][colour], centroids_n[e], moved, area_change, camera.focal_px
                )
        centroids = _detected_centroids(detections)
        view = self.camera_set.subset(used)
        try:
            # Each corrected end already points at its ball's centre (the outline's sphere direction): no
            # sphere correction.
            line_and_uncertainty = self._tracked_line(normalised, covariances, view, bool(stale))
        except GeometryError:
            return None
        if line_and_uncertainty is None:
            return None  # an end is not where the others put it: the refined path looks again
        line, uncertainty = line_and_uncertainty
        if due:
            # Put aside with where this pair's line puts them, for measure_ahead (dropped by locate if this
            # pair's fix is not kept).
            points = {self.front_colour: line.front_m, self.back_colour: line.back_m}
            self._ahead = AheadWork(
                tuple(images),
                detections,
                tuple(
                    StaleEnd(i, c, offsets[i][c], end_depth_m(self.cameras[i], points[c]), points[c]) for i, c in due
                ),
            )
        fix = self._judge(line, centroids, uncertainty_m=uncertainty)
        return replace(fix, timings_ns={"triangulate_ns": time.perf_counter_ns() - start}, detections=detections)

    def _tracked_line(
        self, normalised: Array, covariances: Array, view: CameraSet, remeasured: bool
    ) -> tuple[PointerLine, float | None] | None:
        """The pointer's line and its hit's uncertainty from corrected ends (C, 2, 2) with their covariances
        (C, 2, 2, 2); None when the pointer fit finds them inconsistent. Raises GeometryError.

        Two estimates, each with the uncertainty its own use of the ends gives: the interpretation planes
        (what each end says across the pointer) and the pointer fit (everything, with the length; started
        from the last pair's ends, millimetres away). The one stating the smaller is taken: the planes where
        the cameras see the pointer side-on (they leave out each end's position along it, which a rod over a
        ball pulls and an outline measures less well), the fit where they look along it (the planes nearly
        coincide). Which one wins changes only as slowly as the views do, so both are made on the first
        tracked pair after any end's outline was measured, and that choice holds until the next."""
        wall = self.wall
        both = remeasured or self._tracked_by_fit is None
        planes = None
        if both or not self._tracked_by_fit:
            estimate = estimate_line(
                normalised, view, self._min_plane_sin, None, across_sigma_px(normalised, covariances, view.focal_px)
            )
            planes = estimate.line
            planes_uncertainty = (
                hit_uncertainty_m(estimate, wall, END_CORRELATION) if planes.method == "planes" else None
            )
            if not both:
                return planes, planes_uncertainty
            gaps = (planes.front_gap_m, planes.back_gap_m)
            self._tracked_plane_sin = planes.plane_angle_sin
        else:
            # The rays' gaps (published, and what the calibration's health reads) without the planes.
            gaps = tuple(ray_gaps_m(view.centres_m, np.swapaxes(world_rays(normalised, view.rotations), 0, 1)))
        start_line = self._last_line or planes or estimate_line(normalised, view, self._min_plane_sin, None).line
        fitted = fit_pointer_step(
            EndViews.of(
                view.rotations,
                view.translations_m,
                normalised,
                covariances,
                self.pointer.length_m,
                self.rig.locator.length_sigma_m,
            ),
            start_line.front_m,
            start_line.back_m,
            END_CORRELATION,
        )
        if fitted.chi2 > TRACKED_REDUCED_CHI2 * fitted.dof:
            return None
        try:
            covariance = hit_covariance(
                fitted.front_m, fitted.back_m, fitted.covariance, wall.plane.normal, wall.plane.offset_m, wall.axes
            )
            uncertainty: float | None = float(np.sqrt(max(np.trace(covariance), 0.0)))
        except GeometryError:
            uncertainty = None
        if planes is not None:
            self._tracked_by_fit = not (
                planes_uncertainty is not None and (uncertainty is None or planes_uncertainty < uncertainty)
            )
            if not self._tracked_by_fit:
                return planes, planes_uncertainty
        # The planes' angle as at the pair that chose the fit (it changes as slowly as the choice does).
        line = PointerLine(
            fitted.front_m, fitted.back_m, float(gaps[0]), float(gaps[1]), "fit", self._tracked_plane_sin
        )
        return line, uncertainty

    def _measure_again(
        self, images: Sequence[NDArray[np.uint8]], detections: tuple, stale: Sequence[StaleEnd]
    ) -> list[EndOffset] | None:
        """The stale ends' outlines measured again beside their tracked centroids, all in one batched
        measurement (:func:`trackerd.ends.measure_ends`); None when any is not found, is not the ball the
        detector follows, or is not the size the ball had (scaled by its distance). Where the last pair put an
        end (``StaleEnd.point_m``), an outline of another size than a ball's there keeps the error the refined
        fit would give it (:func:`trackerd.refine.wrong_size_error`), as the outline it replaces did."""
        from trackerd.ends import EndRequest, across_pointer, measure_ends, same_ball
        from trackerd.refine import blob_radius_px, wrong_size_error

        requests = []
        for end in stale:
            detection = detections[end.camera_index]
            centroid, red, blue = (
                detection.end(end.colour).centroid_px,
                detection.red.centroid_px,
                detection.blue.centroid_px,
            )
            assert centroid is not None and red is not None and blue is not None  # a camera that sees both ends
            requests.append(
                EndRequest(
                    images[end.camera_index],
                    self.grids[end.camera_index],
                    self.cameras[end.camera_index],
                    end.camera_index,
                    end.colour,
                    centroid,
                    blob_radius_px(detection.end(end.colour)),
                    centroid,
                    across_pointer(red, blue),
                )
            )
        offsets: list[EndOffset] = []
        for end, request, measured in zip(
            stale, requests, measure_ends(requests, self.rig.locator.centroid_sigma_px), strict=True
        ):
            centroid = request.centroid_px
            assert centroid is not None
            if measured is None or not same_ball(centroid, measured):
                return None
            expected = end.offset.radius_px
            if end.depth_m > 0.0 and end.offset.depth_m > 0.0:
                expected *= end.offset.depth_m / end.depth_m
            if not 1.0 / GUIDED_RADIUS_RATIO <= measured.radius_px / expected <= GUIDED_RADIUS_RATIO:
                return None
            if end.point_m is not None:
                added = wrong_size_error(measured, request.camera, end.point_m, self.pointer.end_diameter_m / 2.0)
                if added is None:
                    return None
                measured = replace(measured, fit_error=added)
            area_px = detections[end.camera_index].end(end.colour).area_px
            offset = end_offset(request.camera, measured, centroid, area_px, end.depth_m)
            if offset is None:
                return None
            offsets.append(offset)
        return offsets

    def learn_offsets(self, fix: PointerFix) -> None:
        """Each end's offset from a refined fix's outline measurements (the refined path calls this on every
        found fix): an end whose detector follows another blob than the one measured gets none."""
        from trackerd.ends import same_ball

        line = fix.line
        assert line is not None
        offsets: list[dict[str, EndOffset]] = []
        for camera, detection, measured in zip(self.cameras, fix.detections, fix.measurements, strict=True):
            ends: dict[str, EndOffset] = {}
            for colour in COLOURS:
                m, end = measured.get(colour), detection.end(colour)
                centroid = end.centroid_px if end.found else None
                if m is None or centroid is None or not same_ball(centroid, m):
                    continue
                point = line.front_m if colour == self.front_colour else line.back_m
                offset = end_offset(camera, m, centroid, end.area_px, end_depth_m(camera, point))
                if offset is not None:
                    ends[colour] = offset
            offsets.append(ends)
        self.offsets = offsets
        self._tracked_by_fit = None

    def _locate_detected(self, detections: tuple) -> PointerFix:
        """The pointer from the detector's centroids (the interpretation planes), as they are."""
        centroids = _detected_centroids(detections)
        missing = self._missing(detections)
        seeing = sum(1 for d in detections if all(d.end(colour).found for colour in COLOURS))
        if seeing < 2:
            return PointerFix("not_found", "; ".join(missing), centroids, detections=detections)
        fix = self.locate_centroids(centroids)
        return replace(fix, timings_ns=dict(fix.timings_ns), detections=detections)

    def _missing(self, detections: tuple) -> list[str]:
        return [
            f"{cam.camera_id}: {d.end(colour).reason or 'not found'}"
            for cam, d in zip(self.cameras, detections, strict=True)
            for colour in COLOURS
            if not d.end(colour).found
        ]

    # ------------------------------------------------------------------ refined

    @property
    def grids(self) -> list:
        """Each camera's sample layout (for the refined path's outline fits)."""
        if self._grids is None:
            from trackerd.detect.colour import sample_grid

            self._grids = [
                sample_grid(fmt, cfg.width_px, cfg.height_px)
                for cfg, fmt in zip(self.rig.cameras, self.pixel_formats, strict=True)
            ]
        return self._grids

    def _locate_refined(self, images: Sequence[NDArray[np.uint8]], detections: tuple) -> PointerFix:
        if self._refined is None:
            from trackerd.refine import RefinedPath

            self._refined = RefinedPath(self)
        return self._refined.locate(images, detections)

    # ------------------------------------------------------------------ geometry

    def locate_centroids(self, centroids: Sequence[dict[str, Array | None]]) -> PointerFix:
        """Locate the pointer from end centroids (pixels), one dict per camera keyed by colour."""
        start = time.perf_counter_ns()
        centroids = tuple(centroids)
        used: list[int] = []
        missing: list[str] = []
        for index, (cam, per_camera) in enumerate(zip(self.cameras, centroids, strict=True)):
            absent = [c for c in COLOURS if not _finite_point(per_camera.get(c))]
            missing += [f"{cam.camera_id}: no {colour} end" for colour in absent]
            if not absent:
                used.append(index)
        if len(used) < 2:
            return PointerFix("not_found", "; ".join(missing), centroids)
        # Cameras that saw both ends; with three or more cameras one may miss an end.
        view = self.camera_set.subset(used)
        # Undistort once: (C, 2, 2) normalised image coordinates, [camera, front/back, xy].
        normalised = np.stack(
            [
                view.cameras[k].normalized_from_pixels(
                    np.array([centroids[i][self.front_colour], centroids[i][self.back_colour]], dtype=np.float64)
                )
                for k, i in enumerate(used)
            ]
        )
        try:
            estimate = self._estimate(normalised, self.rig.locator.sphere_correction, view)
        except GeometryError as err:
            return PointerFix("rejected", str(err), centroids, timings_ns={"triangulate_ns": 0})
        fix = self._judge(estimate.line, centroids, estimate)
        fix.timings_ns["triangulate_ns"] = time.perf_counter_ns() - start
        return fix

    def _estimate(self, normalised: Array, sphere_correction: bool, view: CameraSet) -> LineEstimate:
        """Pointer line from normalised coordinates (C, 2 ends, 2) of the cameras in ``view``, with the
        planes of each centroid moved by centroid_sigma_px across the pointer for its uncertainty."""
        radius = self.pointer.end_diameter_m / 2.0 if sphere_correction else None
        return estimate_line(normalised, view, self._min_plane_sin, radius, self.rig.locator.centroid_sigma_px)

    def _judge(
        self,
        line: PointerLine,
        centroids: tuple[dict[str, Array | None], ...],
        estimate: LineEstimate | None = None,
        uncertainty_m: float | None = None,
    ) -> PointerFix:
        """The fix for a line: rejected (length, ray gap), parallel, away, or a hit on or off the display
        with its uncertainty (``uncertainty_m``, or the spread of the ``estimate``'s moved planes)."""
        pointer = self.pointer
        length_error = line.length_m - pointer.length_m
        if abs(length_error) > pointer.length_tolerance_m:
            return PointerFix(
                "rejected",
                f"ends are {line.length_m * 1000:.0f} mm apart, the pointer is {pointer.length_m * 1000:.0f}"
                f" +- {pointer.length_tolerance_m * 1000:.0f} mm",
                centroids,
                line,
                timings_ns={},
            )
        if line.gap_m > self.rig.locator.max_ray_gap_m:
            return PointerFix(
                "rejected",
                f"rays miss by {line.gap_m * 1000:.0f} mm (limit {self.rig.locator.max_ray_gap_m * 1000:.0f} mm):"
                " the cameras do not agree on an end",
                centroids,
                line,
                timings_ns={},
            )
        if not abs(float(line.direction @ self.wall.plane.normal)) >= self._parallel_sin:
            return PointerFix(
                "parallel",
                f"the pointer is within {PARALLEL_ANGLE_DEG} degrees of parallel to the wall",
                centroids,
                line,
                timings_ns={},
            )
        try:
            intersection = intersect_line_plane(line.back_m, line.front_m, self.wall.plane)  # eq. 26-28
        except GeometryError as err:
            return PointerFix("parallel", str(err), centroids, line, timings_ns={})
        if not float(intersection.u) > 0.0:
            return PointerFix("away", "the pointer points away from the wall", centroids, line, timings_ns={})
        hit = self._wall_hit(intersection, line)
        uncertainty = uncertainty_m
        if uncertainty is None and estimate is not None:
            uncertainty = hit_uncertainty_m(estimate, self.wall)
        status: FixStatus = "hit" if hit.on_wall else "off_wall"
        reason = None if hit.on_wall else "the pointer points at the wall outside the display"
        return PointerFix(status, reason, centroids, line, hit, uncertainty, timings_ns={})

    def _wall_hit(self, intersection: LineHit, line: PointerLine) -> WallHit:
        """The hit in the wall's frame and the display's pixels."""
        wall_xy = self.wall.to_wall_m(intersection.point_m)
        display = self.wall.to_display_px(wall_xy) if self.wall.has_display else None
        distance = (float(intersection.u) - 1.0) * line.length_m
        return WallHit(wall_xy, intersection.point_m, display, bool(self.wall.on_wall(wall_xy)), distance)
