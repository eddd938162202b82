"""The locator's refined path: each end's outline fitted, candidates chosen jointly across cameras when
the detector's ends do not make a pointer, and both ends fitted to every camera with the pointer's
length (docs/detection.md, "When the room is not the one the thresholds were set for"; docs/geometry.md,
"The pointer fit").

:class:`~trackerd.locator.Locator` decides which pairs take this path (``[locator] refine``); this
module owns what the path does, and its own state: when the slow search over every camera's candidates
last ran. The search itself is :class:`trackerd.joint.search.JointSearch`; a ball looked for where the
geometry puts it, :mod:`trackerd.detect.guided`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from trackerd.detect.guided import (
    GUIDED_SIZE,
    MAX_GUIDED_RESIDUAL_PX,
    guided_fits,
)
from trackerd.detect.rod import ROD_ABSENT, ROD_CLEAR, ROD_OFF_DEG
from trackerd.ends import ball_sized, expected_radius_px
from trackerd.errors import GeometryError
from trackerd.geometry.pointer_fit import DROPPED_VARIANCE, EndViews, fit_pointer_robust, hit_covariance
from trackerd.geometry.pointer_line import PointerLine
from trackerd.joint.looks import look_slack_px
from trackerd.joint.search import JointSearch, fix_support
from trackerd.locator import COLOURS, PointerFix

if TYPE_CHECKING:
    from trackerd.detect.colour import SampleGrid
    from trackerd.detect.result import EndDetection
    from trackerd.ends import EndMeasurement
    from trackerd.geometry.camera import CameraModel
    from trackerd.locator import Locator

Array = NDArray[np.float64]

PATIENT_SEARCHES = 8
"""While nothing is found, this many searches in a row run every search_every_pairs-th pair (about 0.8 s at
60 pairs a second with the default 6) before the wait between them doubles (:meth:`RefinedPath._search_wait`):
a presenter who lowers the pointer for a moment is found again as soon as before."""

UNSTEPPED_SLACK_FACTOR = 2.0
"""Where the followed look's prediction has no step (the pair before the last was not found), its slack is
this times the usual half radius: the ends are where they were a frame ago, and a presenter's hand moves
up to half a ball's diameter in a frame (12 mm in `bench robustness --follow`'s motion)."""


def blob_radius_px(end: EndDetection) -> float:
    """A ball's image radius as its blob suggests: the larger of the blob's area's and its box's, since
    a ball whose shaded side failed the colour test leaves a blob smaller than the ball."""
    radius = math.sqrt(max(end.area_px, 1.0) / math.pi)
    if end.bbox_px is not None:
        x0, y0, x1, y1 = end.bbox_px
        radius = max(radius, 0.5 * max(x1 - x0 + 1, y1 - y0 + 1))
    return radius


def wrong_size_error(
    measurement: EndMeasurement, camera: CameraModel, point_m: Array, ball_radius_m: float
) -> Array | None:
    """What an outline's error gains for its size, were the ball at ``point_m`` (normalised units squared), as
    the refined fit adds it to an outline it could not fit again: nothing within GUIDED_SIZE of a ball's radius
    there, :func:`trackerd.ends.partial_arc_error` within MAX_RADIUS_RATIO; None beyond (not a ball's outline)."""
    from trackerd.ends import partial_arc_error

    expected = expected_radius_px(camera, point_m, ball_radius_m)
    ratio = measurement.radius_px / expected
    if 1.0 / GUIDED_SIZE <= ratio <= GUIDED_SIZE:
        return np.zeros((2, 2))
    if not ball_sized(measurement.radius_px, expected):
        return None
    if measurement.fit is None:
        wrong = abs(measurement.radius_px - expected) / camera.focal_px
        return np.eye(2) * wrong * wrong
    return partial_arc_error(measurement.fit, expected, camera.focal_px)


def _tracks(detection: Any, red: Any, blue: Any) -> bool:
    """Whether a detector's ends are the balls these measurements are of (within half a radius)."""
    from trackerd.ends import same_ball

    for end, m in ((detection.red, red), (detection.blue, blue)):
        if not end.found or not same_ball(end.centroid_px, m):
            return False
    return True


class RefinedPath:
    """The refined path of one :class:`~trackerd.locator.Locator` (not thread-safe, like it)."""

    def __init__(self, locator: Locator) -> None:
        self.loc = locator
        self._since_search = 0
        self._searched_once = False
        self._weak_fixes = 0
        """Refined fixes in a row with an end on one sound outline (the search runs on every
        search_every_pairs-th of them, the first included)."""
        self._fruitless = 0
        """Searches in a row that found nothing (the wait before the next doubles: :meth:`_search_wait`)."""
        self._lone_line: PointerLine | None = None
        """The line of the last refined fix when one of its ends was measured by one camera alone (the pairs
        after it follow that end without searching: :meth:`_followed_from_one_camera`), else None."""

    def reset(self) -> None:
        """The next pair is a first sighting: searched at once if the detector's ends do not do."""
        self._searched_once = False
        self._since_search = 0
        self._weak_fixes = 0
        self._fruitless = 0
        self._lone_line = None

    def locate(self, images: Sequence[NDArray[np.uint8]], detections: tuple) -> PointerFix:
        """Each end's outline fitted, then the pointer fitted to every camera's ends at once with the
        pointer's length (trackerd/ends.py, trackerd/geometry/pointer_fit.py). When the detector's ends do
        not make a pointer, every camera's candidates are searched and chosen jointly (trackerd/joint/)."""
        from trackerd.ends import EndRequest, across_pointer, measure_ends

        start = time.perf_counter_ns()
        per_camera: list[dict[str, Any]] = [{c: None for c in COLOURS} for _ in self.loc.cameras]
        requests: list[EndRequest] = []
        for index, (cam, detection, image) in enumerate(zip(self.loc.cameras, detections, images, strict=True)):
            red, blue = detection.red, detection.blue
            across = across_pointer(red.centroid_px, blue.centroid_px) if detection.both_found else None
            # A camera that sees one end only (the other hidden) still measures that one, by its outline.
            for colour, end in (("red", red), ("blue", blue)):
                if end.found:
                    requests.append(
                        EndRequest(
                            image,
                            self.loc.grids[index],
                            cam,
                            index,
                            colour,
                            end.centroid_px,
                            blob_radius_px(end),
                            end.centroid_px,
                            across,
                        )
                    )
        # Every camera's ends measured together: one batched outline fit over all their windows.
        for request, measured in zip(
            requests, measure_ends(requests, self.loc.rig.locator.centroid_sigma_px), strict=True
        ):
            per_camera[request.camera_index][request.colour] = measured
        fix = self.fix_from_measurements(per_camera, None, detections, start, images)
        if not fix.found:
            fix = self._followed_from_one_camera(per_camera, detections, start, images) or fix
        support = fix_support(self.sound_ends(fix)) if fix.found else None
        if support is None or support[0] < 2:
            # The detectors took something else, or lost a ball: the last pair's pointer looked for where it
            # has moved to, before the search over every camera's candidates (a hundred times slower).
            looked = self._looked_where_it_was(per_camera, detections, start, images)
            if looked is not None:
                looked_support = fix_support(self.sound_ends(looked))
                if support is None or looked_support > support:
                    fix, support = looked, looked_support
        weak = support is not None and support[0] < 2
        self._weak_fixes = self._weak_fixes + 1 if weak else 0
        if weak and (self._weak_fixes - 1) % self.loc.rig.locator.search_every_pairs == 0:
            # An end rests on one sound outline and a doubtful one (a centroid, an outline of the wrong size:
            # part of the ball, or something else of its colour where a camera does not see it). The search
            # over every camera's candidates may find what the detectors missed (`bench robustness --seed
            # 11`, installation 20: a dim ball no detector took in two cameras of four, and one cut by the
            # frame's edge taken by its centroid, 66-104 mm off at 5 sigma; the search's three outlines put
            # it within 4 mm). Its answer is kept when its weaker end rests on more sound outlines (on as many:
            # when both ends together do). At the search's cadence while such fixes follow each other (the
            # search takes tens of milliseconds, a refined pair a few).
            searched = self._locate_searched(images, detections, start)
            if searched.found and support is not None and fix_support(self.sound_ends(searched)) > support:
                fix = searched
        if fix.found:
            self._after_refined(fix)
            return fix
        # The search over every camera's candidates is slow: at once on a first sighting, then on every
        # search_every_pairs-th pair while nothing is found, less often when nothing is found for long.
        self._since_search += 1
        if self._searched_once and self._since_search < self._search_wait():
            return fix
        self._since_search = 0
        self._searched_once = True
        searched = self._locate_searched(images, detections, start)
        self._fruitless += 1
        if searched.found:
            self._after_refined(searched)
            # On one sound outline, this pair's search counts as the first of the cadence's above.
            self._weak_fixes = int(fix_support(self.sound_ends(searched))[0] < 2)
            return searched
        if fix.status == "not_found":
            return searched
        # The detector's ends made an impossible pointer, and the search found none: both say why (the
        # search's first clause; the rest repeats the detector's reasons).
        searched_why = (searched.reason or "").split(";")[0]
        return replace(fix, reason=f"{fix.reason}; searched: {searched_why}" if searched_why else fix.reason)

    def _search_wait(self) -> int:
        """Pairs between searches while nothing is found: search_every_pairs after each of the first
        PATIENT_SEARCHES that found nothing, then twice as many after each, up to search_longest_pairs (at least
        search_every_pairs). A fixed cadence kept a core searching in a room without the pointer before a
        busy display (0.2-0.9 s a search, every sixth pair)."""
        config = self.loc.rig.locator
        every = config.search_every_pairs
        doubled = every << min(max(self._fruitless - PATIENT_SEARCHES + 1, 0), 16)
        return max(every, min(doubled, config.search_longest_pairs))

    def _followed_from_one_camera(
        self, per_camera: list[dict[str, Any]], detections: tuple, start: int, images: Sequence[NDArray[np.uint8]]
    ) -> PointerFix | None:
        """The last pair's pointer followed while one end is measured by one camera alone (the presenter has
        stepped in front of it in the others), the other by two or more, when the last pair's was too: the
        pointer fit from the last pair's ends (:mod:`trackerd.joint.lone`, the same end a first sighting's
        search would place). Kept where the length still fixes that end's depth along its camera's ray
        (:func:`trackerd.joint.length_fixes_depth`) and the end stayed within LONE_MIN_COS lengths of where
        it was (the ray's other point at the length is twice that away at least); None otherwise, or when the
        fit or the rod's check refuses it. Without this, each such pair found by the search would make the
        next one search again."""
        from trackerd.joint import LONE_MIN_COS, length_fixes_depth

        last = self.loc._last_line
        seeing = {c: [i for i, ends in enumerate(per_camera) if ends[c] is not None] for c in COLOURS}
        lone = [c for c in COLOURS if len(seeing[c]) == 1]
        # Only after a pair whose end one camera alone measured: where the last pair's end had two cameras,
        # a detector that lost it in one may have lost a ball that is there, and the search finds it (a
        # tracked pair of `bench robustness --seed 2026` followed this way had 16-24 mm sigmas where the
        # search's two cameras gave 5-7, and one hit 77 mm off).
        if last is None or last is not self._lone_line or len(lone) != 1 or max(len(v) for v in seeing.values()) < 2:
            return None
        fix = self.fix_from_measurements(
            [dict(ends) for ends in per_camera],
            (last.front_m, last.back_m),
            detections,
            start,
            images,
            one_camera_end=True,
        )
        if not fix.found:
            return None
        assert fix.line is not None
        front = lone[0] == self.loc.front_colour
        end_m, other_m = (fix.line.front_m, fix.line.back_m) if front else (fix.line.back_m, fix.line.front_m)
        was_m = last.front_m if front else last.back_m
        camera = self.loc.cameras[seeing[lone[0]][0]]
        if not length_fixes_depth(camera.centre_m, end_m, other_m):
            return None
        if float(np.linalg.norm(end_m - was_m)) > LONE_MIN_COS * self.loc.pointer.length_m:
            return None
        return fix

    def _looked_where_it_was(
        self, per_camera: list[dict[str, Any]], detections: tuple, start: int, images: Sequence[NDArray[np.uint8]]
    ) -> PointerFix | None:
        """The last pair's pointer, moved on by its last step (:meth:`Locator.predicted_ends_m`), looked for in
        every camera: each end's outline where the pointer now projects, within half a ball's radius
        (:func:`trackerd.joint.looks.look_slack_px`: a presenter's hand changes speed by less than that in a
        frame; twice that without a step to predict by, UNSTEPPED_SLACK_FACTOR) and of a ball's size there
        (the detector's own measurement where it is that, else fitted there by :func:`guided_fits`), and the
        pointer fitted to them from the predicted ends. None without a last
        pair or when the fit makes no pointer (nor :meth:`_followed_from_one_camera` on the same outlines,
        where the last pair's end rested on one camera).

        While the detectors follow the balls this is never asked for. Where one takes something else of the
        ball's colour or loses the ball (a dark ball on a picture of its hue, a hand over it), the search over
        every camera's candidates would run on every pair (`bench robustness --follow 20`: a quarter to a third
        of the followed pairs on three seeds, 0.2-1 s each)."""
        from trackerd.ends import from_fit

        predicted = self.loc.predicted_ends_m()
        if predicted is None:
            return None
        ball_radius_m = self.loc.pointer.end_diameter_m / 2.0
        # Without a step the ends are where they were a frame ago: the slack takes a frame's motion too.
        widen = 1.0 if self.loc.step_known else UNSTEPPED_SLACK_FACTOR
        looked: list[dict[str, Any]] = []
        for index, (camera, ends) in enumerate(zip(self.loc.cameras, per_camera, strict=True)):
            found: dict[str, Any] = {c: None for c in COLOURS}
            looked.append(found)
            projected = camera.project(predicted)
            if not np.all(np.isfinite(projected)):
                continue
            size = self.loc.rig.cameras[index]
            for e, colour in enumerate((self.loc.front_colour, self.loc.back_colour)):
                at, toward = projected[e], projected[1 - e]
                if not (0.0 <= at[0] < size.width_px and 0.0 <= at[1] < size.height_px):
                    continue
                expected = expected_radius_px(camera, predicted[e], ball_radius_m)
                slack = widen * look_slack_px(expected)
                own = ends[colour]
                if (
                    own is not None
                    and own.source != "centroid"
                    and float(np.hypot(*(own.centre_px - at))) <= slack
                    and ball_sized(own.radius_px, expected)
                ):
                    found[colour] = own
                    continue
                axis = (float(toward[0] - at[0]), float(toward[1] - at[1]))
                grid = self.loc.grids[index]
                # The search's looser colour test too (vivid): a paint the plain test does not take (cyan in
                # warm light) is found by the search's last resort on every pair otherwise (`bench robustness
                # --seed 11 --follow 20`, installation 18: 1.1-1.8 s a pair). Here it is of the ball's size where
                # the pointer was, and the fit and the rod's check follow.
                for fit in guided_fits(
                    images[index], grid, colour, float(at[0]), float(at[1]), expected, axis, vivid=True
                ):
                    if float(np.hypot(*(fit.centre_px - at))) <= slack:
                        found[colour] = from_fit(camera, index, colour, fit)
                        break
        fix = self.fix_from_measurements(
            [dict(ends) for ends in looked], (predicted[0], predicted[1]), detections, start, images
        )
        if fix.found:
            return fix
        # An end that one camera alone measured at the last pair, and again now.
        return self._followed_from_one_camera(looked, detections, start, images)

    def sound_ends(self, fix: PointerFix) -> dict[str, int]:
        """How many cameras measured each end of a found fix by an outline of a ball's size where the fit puts
        it (within MAX_RADIUS_RATIO)."""
        assert fix.line is not None
        points = {self.loc.front_colour: fix.line.front_m, self.loc.back_colour: fix.line.back_m}
        sound = {colour: 0 for colour in COLOURS}
        for camera, ends in zip(self.loc.cameras, fix.measurements, strict=True):
            for colour in COLOURS:
                m = ends.get(colour)
                sound[colour] += int(m is not None and self._sound(camera, m, points[colour]))
        return sound

    def _sound(self, camera: CameraModel, measurement: Any, point_m: Array) -> bool:
        """Whether an end's measurement is an outline of a ball's size at ``point_m`` (not a centroid)."""
        if measurement.source == "centroid":
            return False
        return ball_sized(
            measurement.radius_px, expected_radius_px(camera, point_m, self.loc.pointer.end_diameter_m / 2.0)
        )

    def _after_refined(self, fix: PointerFix) -> None:
        """Remember each end's outline beside its detector's centroid, and let the detectors track the balls
        the fit used (a search may have found them where a detector took something else)."""
        self.loc.learn_offsets(fix)
        self._searched_once = False
        self._since_search = 0
        self._fruitless = 0
        seen_by = [sum(1 for ends in fix.measurements if ends.get(c) is not None) for c in COLOURS]
        self._lone_line = fix.line if min(seen_by) == 1 else None
        if self.loc._detectors is None:
            return
        for detector, detection, per_camera in zip(self.loc._detectors, fix.detections, fix.measurements, strict=True):
            red, blue = per_camera.get("red"), per_camera.get("blue")
            if red is None or blue is None or _tracks(detection, red, blue):
                continue  # the detector already follows these balls (with its own motion estimate)
            detector.follow(red.centre_px, blue.centre_px, red.radius_px, blue.radius_px)

    def _locate_searched(self, images: Sequence[NDArray[np.uint8]], detections: tuple, start: int) -> PointerFix:
        """Every camera's candidates of both colours, chosen jointly, then the pointer fit
        (:class:`trackerd.joint.search.JointSearch`, which keeps no state of its own: what the search
        leaves for the next pair, when it last ran, is this path's, and all of it is in ``vars(self)``, which
        the windowed recording's check compares, trackerd/recording/windowed.py).

        Where it finds no pointer and a camera delivers a Bayer mosaic, it is searched again with those frames
        demosaiced (the module's second pass): what the mosaic's search finds stands as it is."""
        searched = JointSearch(self).locate(images, detections, start)
        if searched.found or not any(grid.is_bayer for grid in self.loc.grids):
            return searched
        again = JointSearch(self, demosaiced=True).locate(images, detections, start)
        return again if again.found else searched

    def _look_again(
        self,
        images: Sequence[NDArray[np.uint8]],
        grids: Sequence[SampleGrid],
        camera_index: int,
        colour: str,
        point_m: Array,
        partner_m: Array,
        expected_px: float,
    ) -> Any:
        """The ball looked for where ``point_m`` projects, told its image radius and where the rod meets it
        (towards ``partner_m``); its measurement, or None."""
        from trackerd.detect.ballfit import fit_ball
        from trackerd.ends import from_fit

        camera = self.loc.cameras[camera_index]
        at, partner = camera.project(np.stack([point_m, partner_m]))
        if not (np.all(np.isfinite(at)) and np.all(np.isfinite(partner))):
            return None
        fit = fit_ball(
            images[camera_index],
            grids[camera_index],
            colour,
            float(at[0]),
            float(at[1]),
            expected_px,
            axis=(float(partner[0] - at[0]), float(partner[1] - at[1])),
            radius_range_px=(expected_px / GUIDED_SIZE, expected_px * GUIDED_SIZE),
        )
        if not fit.found or fit.residual_px > MAX_GUIDED_RESIDUAL_PX:
            return None
        if float(np.hypot(*(fit.centre_px - at))) > look_slack_px(expected_px):
            return None
        return from_fit(camera, camera_index, colour, fit)

    def _checked_by_rod(
        self,
        fix: PointerFix,
        detections: tuple,
        start: int,
        images: Sequence[NDArray[np.uint8]],
        grids: Sequence[SampleGrid],
    ) -> PointerFix:
        """A found fix fitted again without the measurements that the rod says are not their ball
        (:meth:`_off_the_rod`): not found when an end is left with fewer than two cameras, rejected when what
        is left makes no pointer."""
        off = self._off_the_rod(images, grids, fix)
        if not off:
            return fix
        assert fix.line is not None
        kept = [dict(ends) for ends in fix.measurements]
        for index, colour, _ in off:
            kept[index][colour] = None
        # Started afresh where two cameras still see both ends (the first estimate's length and ray-gap checks
        # judge what is left), otherwise from the fix: its line is wrong only where the left-out ends put it.
        both = sum(1 for ends in kept if all(ends.get(c) is not None for c in COLOURS))
        init = None if both >= 2 else (fix.line.front_m, fix.line.back_m)
        refit = self.fix_from_measurements(kept, init, detections, start, images, check_rod=False, grids=grids)
        if refit.found:
            return refit
        timings = {"triangulate_ns": time.perf_counter_ns() - start}
        seeing = {c: sum(1 for ends in kept if ends.get(c) is not None) for c in COLOURS}
        # Name a left-out measurement of an end now seen by fewer than two cameras, when there is one.
        index, colour, degrees = min(off, key=lambda o: seeing[o[1]])
        other = "blue" if colour == "red" else "red"
        camera_id = self.loc.cameras[index].camera_id
        why = f"the rod leaves {camera_id}'s {other} ball {degrees:.0f} degrees away from its {colour} candidate"
        if seeing[colour] >= 2:
            reason = f"{refit.reason} (without {camera_id}'s {colour} candidate: {why})"
        else:
            reason = f"{why}, and fewer than two cameras measured the {colour} end otherwise"
        return replace(refit, reason=reason, timings_ns=timings)

    def _off_the_rod(
        self, images: Sequence[NDArray[np.uint8]], grids: Sequence[SampleGrid], fix: PointerFix
    ) -> list[tuple[int, str, float]]:
        """End measurements that the rod contradicts: in their camera, the rod clearly leaves the other end's
        ball (a sound outline: :meth:`_sound`) ROD_OFF_DEG or more away from them, and no rod leads to them
        (trackerd/detect/rod.py). Something of the end's colour where a camera does not see the ball, of the
        ball's size or not (`bench robustness --seed 11`: a navy sleeve's edge, a red block's corner, a red
        thing of another shade, each paired with the ball in another camera, 0.17-1.66 m off at up to 19 sigma).
        Returns (camera, colour, degrees off) for each."""
        from trackerd.detect.rod import rod_bearing

        assert fix.line is not None
        pointer = self.loc.pointer
        rod_share = pointer.rod_diameter_m / pointer.end_diameter_m
        points = {self.loc.front_colour: fix.line.front_m, self.loc.back_colour: fix.line.back_m}
        off: list[tuple[int, str, float]] = []
        for index, (camera, ends) in enumerate(zip(self.loc.cameras, fix.measurements, strict=True)):
            for colour, other in (("red", "blue"), ("blue", "red")):
                measured, anchor = ends.get(colour), ends.get(other)
                if measured is None or anchor is None or not self._sound(camera, anchor, points[other]):
                    continue
                bearing = rod_bearing(
                    images[index],
                    grids[index],
                    anchor.centre_px,
                    anchor.radius_px,
                    measured.centre_px,
                    measured.radius_px,
                    rod_share * anchor.radius_px,
                )
                if (
                    bearing is not None
                    and bearing.evidence >= ROD_CLEAR
                    and bearing.evidence_toward <= ROD_ABSENT
                    and abs(bearing.offset_deg) >= ROD_OFF_DEG
                ):
                    off.append((index, colour, abs(bearing.offset_deg)))
        return off

    def fix_from_measurements(
        self,
        per_camera: list[dict[str, Any]],
        init: tuple[Array, Array] | None,
        detections: tuple,
        start: int,
        images: Sequence[NDArray[np.uint8]],
        *,
        check_rod: bool = True,
        one_camera_end: bool = False,
        grids: Sequence[SampleGrid] | None = None,
    ) -> PointerFix:
        """The pointer fit on each camera's end measurements (None where a camera does not see an end); a found
        fix then checked against the rod (:meth:`_checked_by_rod`) unless ``check_rod`` is false.
        ``one_camera_end``: one end may be measured by one camera only (a joint choice placed it by its ray and
        the pointer's length, :mod:`trackerd.joint.lone`), the other by two or more; the fit starts from
        ``init``. ``grids``: the sample grids of ``images`` where they are not the cameras' own (the joint
        search's demosaiced frames)."""
        grids = self.loc.grids if grids is None else grids
        front, back = self.loc.front_colour, self.loc.back_colour
        centroids = tuple({c: (None if ends[c] is None else ends[c].centre_px) for c in COLOURS} for ends in per_camera)
        used = [i for i, ends in enumerate(per_camera) if ends[front] is not None or ends[back] is not None]
        seeing = {end: sum(1 for ends in per_camera if ends[end] is not None) for end in (front, back)}
        timings = {"triangulate_ns": 0}
        fewest = 1 if one_camera_end and init is not None else 2
        if min(seeing.values()) < fewest or max(seeing.values()) < 2:
            missing = self.loc._missing(detections)
            reason = "; ".join(missing) if missing else "fewer than two cameras measured each end"
            return PointerFix("not_found", reason, centroids, timings_ns=timings, detections=detections)
        view = self.loc.camera_set.subset(used)
        both = [k for k, i in enumerate(used) if per_camera[i][front] is not None and per_camera[i][back] is not None]
        pointer = self.loc.pointer
        if init is None:
            if len(both) < 2:
                return PointerFix(
                    "not_found",
                    "fewer than two cameras measured both ends",
                    centroids,
                    timings_ns=timings,
                    detections=detections,
                )
            sub = self.loc.camera_set.subset([used[k] for k in both])
            normalised_both = np.stack(
                [np.stack([per_camera[used[k]][front].normalised, per_camera[used[k]][back].normalised]) for k in both]
            )
            try:
                estimate = self.loc._estimate(normalised_both, False, sub)
                first = estimate.line
            except GeometryError as err:
                return PointerFix("rejected", str(err), centroids, timings_ns=timings, detections=detections)
            if abs(first.length_m - pointer.length_m) > pointer.length_tolerance_m or (
                first.gap_m > self.loc.rig.locator.max_ray_gap_m
            ):
                fix = self.loc._judge(first, centroids, estimate)
                return replace(
                    fix, timings_ns={"triangulate_ns": time.perf_counter_ns() - start}, detections=detections
                )
            init = (first.front_m, first.back_m)
            gaps = (first.front_gap_m, first.back_gap_m, first.plane_angle_sin)
        else:
            gaps = (0.0, 0.0, 0.0)
        # Every used camera's two ends; an end a camera does not see is given a covariance so wide it weighs
        # nothing, at the position the start puts it.
        rotations = view.rotations
        translations = view.translations_m
        start_points = np.stack([np.asarray(init[0], dtype=np.float64), np.asarray(init[1], dtype=np.float64)])
        measured = np.zeros((len(used), 2, 2))
        covariances = np.zeros((len(used), 2, 2, 2))
        # What each measurement's error truly is (trackerd/ends.py: EndMeasurement.actual_covariance), and each is
        # weighed by it: weighed by its narrower statistical covariance instead, a partial or disturbed outline
        # pulled the fit as a clean one does (`bench robustness`, seeds 2026 and 7: 2.94 / 2.58 mm median
        # before, 2.83 / 2.45 after; docs/geometry.md, "Weights and errors"). The hit's uncertainty is the
        # weighted fit's under these errors.
        errors = np.zeros((len(used), 2, 2, 2))
        for k, i in enumerate(used):
            for e, colour in enumerate((front, back)):
                m = per_camera[i][colour]
                if m is None:
                    xc = rotations[k] @ start_points[e] + translations[k]
                    measured[k, e] = xc[:2] / xc[2]
                    covariances[k, e] = np.eye(2) * DROPPED_VARIANCE
                    errors[k, e] = covariances[k, e]
                else:
                    measured[k, e] = m.normalised
                    covariances[k, e] = m.actual_covariance
                    errors[k, e] = m.actual_covariance
        # A ball's outline of the wrong size for its distance is likely a fit to something else (the part of a
        # ball a hand leaves, a disc on the display beside it). Off by more than GUIDED_SIZE, the ball is looked
        # for again where the start puts it, told its size; off by more than MAX_RADIUS_RATIO and not found
        # again, it is left out while each end keeps two cameras, and otherwise kept with an error as large as
        # its radius is wrong, so that the hit's uncertainty says what it rests on. Within MAX_RADIUS_RATIO
        # and not found again, a partial outline has an error along its arc's axis, where its centre moves
        # with its radius, and one smaller than the ball its shortfall in every direction besides
        # (:func:`trackerd.ends.partial_arc_error`), in its weight as in its error.
        from trackerd.ends import partial_arc_error

        ball_radius = pointer.end_diameter_m / 2.0
        # What this fit adds to each measurement's error, kept with the measurement (EndMeasurement.fit_error)
        # for the tracked pairs that follow: they take the outline's offset from its centroid, and with it
        # what is known of its error. A measurement fitted again starts from its own errors.
        for i, ends in enumerate(per_camera):
            for colour, m in ends.items():
                if m is not None and m.fit_error is not None:
                    per_camera[i][colour] = replace(m, fit_error=None)
        for k, i in enumerate(used):
            for e, colour in enumerate((front, back)):
                m = per_camera[i][colour]
                if m is None or m.source == "centroid":
                    continue
                camera = self.loc.cameras[i]
                expected = expected_radius_px(camera, start_points[e], ball_radius)
                ratio = m.radius_px / expected
                if 1.0 / GUIDED_SIZE <= ratio <= GUIDED_SIZE:
                    continue
                again = self._look_again(images, grids, i, colour, start_points[e], start_points[1 - e], expected)
                if again is not None:
                    per_camera[i][colour] = again
                    measured[k, e] = again.normalised
                    covariances[k, e] = again.covariance
                    errors[k, e] = again.actual_covariance
                    continue
                if ball_sized(m.radius_px, expected):
                    if m.fit is not None:
                        added = partial_arc_error(m.fit, expected, camera.focal_px)
                        covariances[k, e] = covariances[k, e] + added
                        errors[k, e] = errors[k, e] + added
                        per_camera[i][colour] = replace(m, fit_error=added)
                    continue
                seen_by = int(np.count_nonzero(np.trace(covariances[:, e], axis1=1, axis2=2) < DROPPED_VARIANCE))
                if seen_by > 2:
                    covariances[k, e] = np.eye(2) * DROPPED_VARIANCE
                    errors[k, e] = covariances[k, e]
                    per_camera[i][colour] = replace(m, fit_error=errors[k, e] - m.actual_covariance)
                else:
                    wrong = abs(m.radius_px - expected) / camera.focal_px
                    covariances[k, e] = covariances[k, e] + np.eye(2) * wrong * wrong
                    errors[k, e] = errors[k, e] + np.eye(2) * wrong * wrong
                    per_camera[i][colour] = replace(m, fit_error=np.eye(2) * wrong * wrong)
        try:
            views = EndViews.of(
                rotations,
                translations,
                measured,
                covariances,
                pointer.length_m,
                self.loc.rig.locator.length_sigma_m,
                error_covariances=errors,
            )
            fitted = fit_pointer_robust(views, start_points[0], start_points[1])
        except GeometryError as err:
            return PointerFix("rejected", str(err), centroids, timings_ns=timings, detections=detections)
        line = PointerLine(fitted.front_m, fitted.back_m, gaps[0], gaps[1], "fit", gaps[2])
        uncertainty = None
        try:
            wall = self.loc.wall
            covariance = hit_covariance(
                fitted.front_m, fitted.back_m, fitted.covariance, wall.plane.normal, wall.plane.offset_m, wall.axes
            )
            uncertainty = float(np.sqrt(max(np.trace(covariance), 0.0)))
        except GeometryError:
            pass
        judged = self.loc._judge(line, centroids, uncertainty_m=uncertainty)
        fix = PointerFix(
            judged.status,
            judged.reason,
            judged.centroids_px,
            judged.line,
            judged.hit,
            judged.uncertainty_m,
            {"triangulate_ns": time.perf_counter_ns() - start},
            detections,
            tuple(dict(ends) for ends in per_camera),
        )
        return self._checked_by_rod(fix, detections, start, images, grids) if check_rod and fix.found else fix
