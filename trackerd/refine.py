"""The locator's refined path: each end's outline fitted, candidates chosen jointly across cameras when
the detector's ends do not make a pointer, and both ends fitted to every camera with the pointer's
length (docs/detection.md, "When the room is not the one the thresholds were set for"; docs/geometry.md,
"The pointer fit").

:class:`~trackerd.locator.Locator` decides which pairs take this path (``[locator] refine``); this
module owns what the path does, and its own state: when the slow search over every camera's candidates
last ran.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from trackerd.errors import GeometryError
from trackerd.geometry.pointer_fit import DROPPED_VARIANCE, EndViews, fit_pointer_robust, hit_covariance
from trackerd.geometry.pointer_line import PointerLine
from trackerd.geometry.sphere import view_map
from trackerd.joint.looks import look_slack_px
from trackerd.locator import COLOURS, PointerFix

if TYPE_CHECKING:
    from trackerd.detect.ballfit import BallFit
    from trackerd.detect.colour import SampleGrid
    from trackerd.detect.result import EndDetection
    from trackerd.detect.search import Candidate
    from trackerd.ends import EndMeasurement
    from trackerd.geometry.camera import CameraModel
    from trackerd.locator import Locator

Array = NDArray[np.float64]

MAX_RADIUS_RATIO = 1.3
"""A ball's fitted outline more than this much larger or smaller than a ball at its distance is left out
of the pointer fit (when its end is measured by two other cameras)."""

MAX_GUIDED_RESIDUAL_PX = 1.0
"""A ball looked for where the geometry puts it must be a circle this closely (rim scatter, pixels)..."""

MAX_GUIDED_RESIDUAL_SHARE = 0.1
"""...or within this share of its expected radius, where that is more: a large ball's rim in motion blur or
under a hand scatters by more than a pixel about its circle and is still plainly a ball (`bench robustness`
seed 7, installation 2, frame 1: a dark blue ball of 18 px radius, in strong blur, 1.45 px). The search's own
limit is looser (:data:`trackerd.detect.ballfit.MAX_SCATTER_SHARE`, 0.12): there nothing says where a ball is."""

GUIDED_SIZE = 1.15
"""And its radius within this factor of a ball's at the distance the geometry puts it."""

TINT_PAINT_DN = 10.0
"""Where the geometry puts a ball, its colour's own channel must exceed both others by this (grey levels) for
the ball to be looked for by its tint (:func:`ball_tint`): it is the pointer's paint, however dull."""

TINT_CONTRAST_DN = 15.0
"""And it must differ from its surroundings by this (grey levels, the length of the colour difference): less
is no outline to fit."""

TOUCHING_LARGEST = 1.05
"""Where that fails, the ball may touch something of its colour; it is fitted again with its radius at most
this factor of the geometry's (an outline's rim lies on or just inside the ball's silhouette; a circle through
the ball's arc and the far edge of a letter it touches is larger; :func:`guided_fits`)..."""

TOUCHING_SLACK_PX = 3.0
"""...and the rim points that no such circle centred within this of where the geometry puts the ball can
pass through left out (the far edges of what it touches)."""

VIVID_SEEDS = 8
"""Seeds fitted per colour by the search's last resort (trackerd.detect.search.vivid_mask): what the plain test
left of a room's vivid colours, best first. Fewer than the plain search's 20, since the last resort runs on
every search that finds nothing (a room without the pointer: every `search_every_pairs`-th pair)."""

PAINT_SPREAD = 0.15
"""The last resort's choice (:meth:`RefinedPath._one_paint`) stands only where each end's candidates in every
camera have their green and their other colour within this share of their own channel of each other (a
ball's own, across four cameras: within 0.11; junk that paired with a navy ball: 0.20 off it)."""

ROD_OFF_DEG = 8.0
"""An end's measurement is left out of the pointer fit when, in its camera, the rod clearly leaves the other
end's sound ball at least this far from the direction to it (:meth:`RefinedPath._off_the_rod`)..."""

ROD_CLEAR = 0.75
"""...along a direction where at least this share of the rod's points are darker than both its sides..."""

ROD_ABSENT = 0.25
"""...and at most this share along any direction within :data:`trackerd.detect.rod.NEAR_DEG` of the one to the
measurement."""

VIEW_TOLERANCE = 0.05
"""Where a camera's view map (:func:`trackerd.geometry.sphere.view_map`) scales some direction by more than
this share away from 1, a ball's outline is not a circle of the expected radius in pixels: a guided look
that fails in pixels there is tried again in the view's units."""

PATIENT_SEARCHES = 8
"""While nothing is found, this many searches in a row run every search_every_pairs-th pair (about 0.8 s at
60 pairs a second with the default 6) before the wait between them doubles (:meth:`RefinedPath._search_wait`):
a presenter who lowers the pointer for a moment is found again as soon as before."""

UNSTEPPED_SLACK_FACTOR = 2.0
"""Where the followed look's prediction has no step (the pair before the last was not found), its slack is
this times the usual half radius: the ends are where they were a frame ago, and a presenter's hand moves
up to half a ball's diameter in a frame (12 mm in `bench robustness --follow`'s motion)."""

SEARCH_VIEW_TOLERANCE = 0.15
"""The same for the search's seeds, which are many and mostly not balls: only where the outline departs
from a circle by more than this (30 degrees off the axis) is a failed seed fitted again in the view's
units. At VIEW_TOLERANCE a wide 4K lens refitted a third of its seeds, and the search took 1.5x as long
on the default robustness run for no ball found that this tolerance misses."""


def blob_radius_px(end: EndDetection) -> float:
    """A ball's image radius as its blob suggests: the larger of the blob's area's and its box's, since
    a ball whose shaded side failed the colour test leaves a blob smaller than the ball."""
    radius = math.sqrt(max(end.area_px, 1.0) / math.pi)
    if end.bbox_px is not None:
        x0, y0, x1, y1 = end.bbox_px
        radius = max(radius, 0.5 * max(x1 - x0 + 1, y1 - y0 + 1))
    return radius


def guided_scatter_limit_px(radius_px: float) -> float:
    """How far a guided fit's rim may scatter about its circle (in the units of ``radius_px``)."""
    return max(MAX_GUIDED_RESIDUAL_PX, MAX_GUIDED_RESIDUAL_SHARE * radius_px)


def guided_fits(
    image: NDArray[np.uint8],
    grid: SampleGrid,
    colour: str,
    x_px: float,
    y_px: float,
    radius_px: float,
    axis: tuple[float, float] | None,
    view: Array | None = None,
    vivid: bool = False,
) -> Iterator[BallFit]:
    """The ball looked for where the geometry puts it (centre, image radius, and the direction where the rod
    meets it), for the joint choice's ``look``: its outlines that are round within
    :func:`guided_scatter_limit_px`, in order of preference, each made only when the one before was not
    taken; none after one not of the pointer's colour (:func:`_of_its_colour`: then something else is
    there). Fitted in its colour's excess, then as touching something of its colour (below), then in its
    tint (:func:`ball_tint`). With ``view`` (:func:`trackerd.geometry.sphere.view_map`), the radius, the
    circle and its scatter are in the view's units (``fit_ball``'s ``view``); the slack below then is too.

    The geometry knows the ball's size to a few percent, so the fit keeps its radius within GUIDED_SIZE and
    takes rising rims (a shaded ball before a brighter surface of its hue). Where that fails (or the caller
    refuses the outline) the ball may
    touch something of its colour (a letter, a picture): on those rays the colour falls only at that
    thing's far edge, and a larger circle through the ball's arc and that edge fits best. So it is fitted
    again with the radius at most TOUCHING_LARGEST of the geometry's and the rims no such circle centred
    within TOUCHING_SLACK_PX of the start can pass through left out. ``vivid``: its colour may pass the
    search's looser test instead (:func:`trackerd.detect.search.vivid_mask`; the search's last resort).
    ``next(guided_fits(...), None)`` is the preferred outline, or None.

    The caller judges each outline against where the geometry allows the ball and asks for the next when it
    is not there: a dark ball before a brighter picture of its hue can give, in the excess, a round outline
    a radius away from it, while its tint gives the ball (`bench robustness --seed 11`, installation 29,
    frame 16: 8 px from where the look started, on a ball of 8 px)."""
    from trackerd.detect.ballfit import fit_ball

    # Plain first; then as a ball touching something of its colour; last in its tint.
    for largest, slack_px, in_excess in (
        (GUIDED_SIZE, None, True),
        (TOUCHING_LARGEST, TOUCHING_SLACK_PX, True),
        (GUIDED_SIZE, None, False),
    ):
        tint = None
        if not in_excess:
            # A ball before a picture with as much of its colour's excess has no rim in the excess, but has one
            # in the direction (in colour) from the picture to the ball.
            tint = ball_tint(image, grid, colour, x_px, y_px, radius_px)
            if tint is None:
                return
        fit = fit_ball(
            image,
            grid,
            colour,
            x_px,
            y_px,
            radius_px,
            axis=axis,
            radius_range_px=(radius_px / GUIDED_SIZE, radius_px * largest),
            rising_rims=in_excess,
            centre_slack_px=slack_px,
            view=view,
            tint=tint,
        )
        if fit.found and fit.residual_px <= guided_scatter_limit_px(radius_px):
            if not _of_its_colour(image, grid, colour, fit, view, vivid):
                return
            yield fit


def _of_its_colour(
    image: NDArray[np.uint8], grid: SampleGrid, colour: str, fit: BallFit, view: Array | None, vivid: bool = False
) -> bool:
    """Whether what a guided fit found is of the pointer's colour by the search's relative hue thresholds
    (:data:`~trackerd.detect.search.RELATIVE_EXCESS`, :data:`~trackerd.detect.search.MIN_EXCESS`), applied to its
    inner half's median colour: the look fits any round edge of the right size where the geometry points, and a
    corner of a tan sleeve in warm light, only 22 % redder than it is green, once made a red end out of
    junk in two cameras for a ball hidden in one (`bench robustness` seed 7, installation 23, frame 38: a
    hit 736 mm off at 17 sigma). The balls the looks rightly found on the frames looked into were 43-91 % (dim,
    dark, blurred, merged). With ``vivid``, the search's looser test (:func:`~trackerd.detect.search.vivid_mask`)
    passes it too."""
    from trackerd.detect.search import vivid_mask

    radius_px = fit.radius_px if view is None else fit.radius_px / math.sqrt(abs(float(np.linalg.det(view))))
    colours = _colour_medians(image, grid, colour, float(fit.centre_px[0]), float(fit.centre_px[1]), radius_px)
    if colours is None:
        return False
    own, green, other = colours[0]
    if _plain_colour(own, green, other):
        return True
    return vivid and bool(vivid_mask(np.array(own), np.array(own - max(green, other)), np.array(min(green, other))))


def _ball_sized(radius_px: float, expected_px: float) -> bool:
    """Whether an outline's radius is within MAX_RADIUS_RATIO of a ball's expected one, either way."""
    return 1.0 / MAX_RADIUS_RATIO <= radius_px / expected_px <= MAX_RADIUS_RATIO


def _support(sound: dict[str, int]) -> tuple[int, int]:
    """What a fix rests on, for comparing two: its weaker end's sound outlines, then both ends' together."""
    return min(sound.values()), sum(sound.values())


def _plain_colour(own: float, green: float, other: float) -> bool:
    """Whether a colour (its own channel, green, the other colour) passes the search's plain hue test."""
    from trackerd.detect.search import hue_mask

    return bool(hue_mask(np.array(own), np.array(own - max(green, other))))


def _ball_radius_px(camera: CameraModel, point_m: Array, ball_radius_m: float) -> float:
    """The image radius of a ball of ``ball_radius_m`` centred at ``point_m`` (its silhouette's half-angle,
    times the focal length)."""
    distance = float(np.linalg.norm(point_m - camera.centre_m))
    return float(camera.focal_px * ball_radius_m / math.sqrt(max(distance**2 - ball_radius_m**2, 1e-6)))


def wrong_size_error(
    measurement: EndMeasurement, camera: CameraModel, point_m: Array, ball_radius_m: float
) -> Array | None:
    """What an outline's error gains for its size, were the ball at ``point_m`` (normalised units squared), as
    the refined fit adds it to an outline it could not fit again: nothing within GUIDED_SIZE of a ball's radius
    there, :func:`trackerd.ends.partial_arc_error` within MAX_RADIUS_RATIO; None beyond (not a ball's outline)."""
    from trackerd.ends import partial_arc_error

    expected = _ball_radius_px(camera, point_m, ball_radius_m)
    ratio = measurement.radius_px / expected
    if 1.0 / GUIDED_SIZE <= ratio <= GUIDED_SIZE:
        return np.zeros((2, 2))
    if not _ball_sized(measurement.radius_px, expected):
        return None
    if measurement.fit is None:
        wrong = abs(measurement.radius_px - expected) / camera.focal_px
        return np.eye(2) * wrong * wrong
    return partial_arc_error(measurement.fit, expected, camera.focal_px)


def _colour_medians(
    image: NDArray[np.uint8], grid: SampleGrid, colour: str, x_px: float, y_px: float, radius_px: float
) -> tuple[Array, Array | None] | None:
    """The median colour (the colour's own channel, green, the other colour, at the colour's samples) over the
    inner half of a ball's radius, and over the ring from 1.5 to 2.2 radii around it (None where the frame's
    edge leaves fewer than 8 samples of it); None at the frame's edge. Medians: a rod or a hand across part of
    either does not move them."""
    from trackerd.detect.colour import cells_around, channel_windows

    s = grid.cell_px
    dr, dc = grid.offset(colour)
    region = cells_around(grid, colour, x_px, y_px, 2.2 * radius_px)
    if region[1] - region[0] < 3 or region[3] - region[2] < 3:
        return None
    channels = channel_windows(image, grid, colour, region)
    rows = (np.arange(region[0], region[1]) * s + dr - y_px)[:, None]
    cols = (np.arange(region[2], region[3]) * s + dc - x_px)[None, :]
    distance = np.hypot(rows, cols)
    inner = distance <= max(0.5 * radius_px, 0.75 * s)
    ring = (distance >= 1.5 * radius_px) & (distance <= 2.2 * radius_px)
    if not inner.any():
        return None
    ball: Array = np.median(channels[:, inner], axis=1).astype(np.float64)
    around: Array | None = None
    if np.count_nonzero(ring) >= 8:
        around = np.median(channels[:, ring], axis=1).astype(np.float64)
    return ball, around


def ball_tint(
    image: NDArray[np.uint8], grid: SampleGrid, colour: str, x_px: float, y_px: float, radius_px: float
) -> Array | None:
    """The direction in colour (weights of the colour's own channel, green and the other colour) from what
    surrounds the place where the geometry puts a ball to what is there, for ``fit_ball``'s ``tint``; None
    where that place is not of the ball's colour (its own channel not above both others by TINT_PAINT_DN) or
    does not differ from its surroundings by TINT_CONTRAST_DN.

    The colours of the ball and of its surroundings are :func:`_colour_medians`."""
    colours = _colour_medians(image, grid, colour, x_px, y_px, radius_px)
    if colours is None:
        return None
    ball, around = colours
    if around is None or ball[0] < max(ball[1], ball[2]) + TINT_PAINT_DN:
        return None
    direction = (ball - around).astype(np.float64)
    size = float(np.linalg.norm(direction))
    if size < TINT_CONTRAST_DN:
        return None
    tint: Array = direction / size
    return tint


def _new_candidates(found: list[Candidate], known: list[Candidate]) -> list[Candidate]:
    """The candidates of ``found`` that are not within half a radius of one of ``known`` (the same ball)."""
    return [
        cand
        for cand in found
        if all(np.hypot(*(cand.fit.centre_px - k.fit.centre_px)) > 0.5 * k.fit.radius_px for k in known)
    ]


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
        from trackerd.ends import across_pointer, measure_end

        start = time.perf_counter_ns()
        sigma_px = self.loc.rig.locator.centroid_sigma_px
        per_camera: list[dict[str, Any]] = []
        for index, (cam, detection, image) in enumerate(zip(self.loc.cameras, detections, images, strict=True)):
            ends: dict[str, Any] = {c: None for c in COLOURS}
            per_camera.append(ends)
            red, blue = detection.red, detection.blue
            across = across_pointer(red.centroid_px, blue.centroid_px) if detection.both_found else None
            # A camera that sees one end only (the other hidden) still measures that one, by its outline.
            for colour, end in (("red", red), ("blue", blue)):
                if end.found:
                    ends[colour] = measure_end(
                        image,
                        self.loc.grids[index],
                        cam,
                        index,
                        colour,
                        end.centroid_px,
                        blob_radius_px(end),
                        end.centroid_px,
                        across,
                        sigma_px,
                    )
        fix = self._fix_from_measurements(per_camera, None, detections, start, images)
        if not fix.found:
            fix = self._followed_from_one_camera(per_camera, detections, start, images) or fix
        support = _support(self._sound_ends(fix)) if fix.found else None
        if support is None or support[0] < 2:
            # The detectors took something else, or lost a ball: the last pair's pointer looked for where it
            # has moved to, before the search over every camera's candidates (a hundred times slower).
            looked = self._looked_where_it_was(per_camera, detections, start, images)
            if looked is not None:
                looked_support = _support(self._sound_ends(looked))
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
            if searched.found and support is not None and _support(self._sound_ends(searched)) > support:
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
            self._weak_fixes = int(_support(self._sound_ends(searched))[0] < 2)
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
        fix = self._fix_from_measurements(
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
                expected = _ball_radius_px(camera, predicted[e], ball_radius_m)
                slack = widen * look_slack_px(expected)
                own = ends[colour]
                if (
                    own is not None
                    and own.source != "centroid"
                    and float(np.hypot(*(own.centre_px - at))) <= slack
                    and _ball_sized(own.radius_px, expected)
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
        fix = self._fix_from_measurements(
            [dict(ends) for ends in looked], (predicted[0], predicted[1]), detections, start, images
        )
        if fix.found:
            return fix
        # An end that one camera alone measured at the last pair, and again now.
        return self._followed_from_one_camera(looked, detections, start, images)

    def _sound_ends(self, fix: PointerFix) -> dict[str, int]:
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
        return _ball_sized(
            measurement.radius_px, _ball_radius_px(camera, point_m, self.loc.pointer.end_diameter_m / 2.0)
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
        """Every camera's candidates of both colours, chosen jointly, then the pointer fit."""
        from trackerd.detect.rod import rod_leaving
        from trackerd.detect.search import Candidate, search_candidates, split_candidates
        from trackerd.joint import choose_jointly

        def searched(**options: Any) -> list[dict[str, list[Candidate]]]:
            return [
                search_candidates(
                    image,
                    self.loc.grids[index],
                    self._radius_range_px(index),
                    view=self._view_at(index, SEARCH_VIEW_TOLERANCE),
                    **options,
                )
                for index, image in enumerate(images)
            ]

        candidates = searched()
        pointer = self.loc.pointer
        room = self._room_side()
        vivid = False  # the last resort below looks for vivid colours too

        def look(
            camera: int, colour: str, x_px: float, y_px: float, radius_px: float, axis: tuple[float, float] | None
        ) -> Iterator[Candidate]:
            # The geometry knows the ball's size to a few percent and where the rod meets it: its angular
            # size, which is its size in pixels only near the lens's axis (VIEW_TOLERANCE).
            grid = self.loc.grids[camera]
            fits = guided_fits(images[camera], grid, colour, x_px, y_px, radius_px, axis, vivid=vivid)
            first = next(fits, None)
            if first is not None:
                fits = itertools.chain([first], fits)
            else:
                # In the view's units only when pixels offered no outline at all.
                local = self._view_at(camera, VIEW_TOLERANCE)(x_px, y_px)
                if local is None:
                    return
                fits = guided_fits(images[camera], grid, colour, x_px, y_px, radius_px, axis, view=local, vivid=vivid)
            for fit in fits:
                yield Candidate(colour, fit, (x_px, y_px), radius_px)

        rod_share = pointer.rod_diameter_m / pointer.end_diameter_m
        rods: dict[tuple[int, float, float, float], tuple[float, float] | None] = {}

        def rod(camera: int, x_px: float, y_px: float, radius_px: float) -> tuple[float, float] | None:
            # A clear dark line leaving the ball, and no other as clear (an edge of a picture, the presenter's
            # arm): the rod, followed to a ball no camera offered. Once per ball: each stage's choice asks again.
            key = (camera, x_px, y_px, radius_px)
            if key not in rods:
                leaving = rod_leaving(
                    images[camera], self.loc.grids[camera], np.array([x_px, y_px]), radius_px, rod_share * radius_px
                )
                clear = leaving.evidence >= ROD_CLEAR and leaving.rival < leaving.evidence
                rods[key] = (float(leaving.direction[0]), float(leaving.direction[1])) if clear else None
            return rods[key]

        def choose(offered: list[dict[str, list[Candidate]]]) -> Any:
            return choose_jointly(
                self.loc.cameras,
                offered,
                pointer.end_diameter_m / 2.0,
                pointer.length_m,
                pointer.length_tolerance_m,
                self.loc.rig.locator.max_ray_gap_m,
                room,
                look,
                rod,
            )

        # The plain candidates first; then, while their choice makes no pointer or one whose weaker end rests on
        # fewer than two sound outlines (something of its colour taken where a camera's ball merged with a
        # picture), the merged groups split, and last the vivid colours. The best-supported fix is kept.
        best: PointerFix | None = None
        best_support = (-1, -1)  # of best, while it is found
        reason = ""
        for stage in ("plain", "split", "vivid"):
            if stage == "plain":
                choice = choose(candidates)
            elif stage == "split":
                # A ball of nearly its picture's hue stays merged with the picture in every camera that sees
                # it there, and then no camera offers it. Split the merged groups (slower, and only now: the
                # plain candidates make a pointer on nearly every first sighting) and choose again from all.
                extra = [
                    split_candidates(image, self.loc.grids[index], self._radius_range_px(index))
                    for index, image in enumerate(images)
                ]
                if not any(extra_per_camera[c] for extra_per_camera in extra for c in COLOURS):
                    continue
                choice = choose(
                    [{c: plain[c] + more[c] for c in COLOURS} for plain, more in zip(candidates, extra, strict=True)]
                )
            else:
                # Last, a paint the plain test does not take for its colour (cyan in warm light: bluer than it
                # is green by a fifth only): the vivid colours whose strongest channel is the end's join, and
                # the looks may find them too (vivid_mask).
                vivid = True
                loose = searched(vivid=True, max_seeds=VIVID_SEEDS)
                added = [
                    {c: _new_candidates(more[c], plain[c]) for c in COLOURS}
                    for plain, more in zip(candidates, loose, strict=True)
                ]
                if not any(per_camera[c] for per_camera in added for c in COLOURS):
                    continue
                choice = choose(
                    [{c: plain[c] + more[c] for c in COLOURS} for plain, more in zip(candidates, added, strict=True)]
                )
                painted = None if isinstance(choice, str) else self._one_paint(images, choice)
                if painted is None:
                    continue
                choice = replace(choice, chosen=painted)
            if isinstance(choice, str):
                reason = reason or choice
                continue
            fix = self._fix_from_choice(choice, detections, start, images)
            if not fix.found:
                reason = reason or (fix.reason or "")
                best = best or fix
                continue
            support = _support(self._sound_ends(fix))
            if support > best_support:
                best, best_support = fix, support
            if best_support[0] >= 2:
                break
        if best is not None:
            return best
        missing = self.loc._missing(detections)
        reason = "; ".join([reason, *missing]) if missing else reason
        empty: tuple[dict[str, Array | None], ...] = tuple({c: None for c in COLOURS} for _ in self.loc.cameras)
        return PointerFix(
            "not_found",
            reason,
            empty,
            timings_ns={"triangulate_ns": time.perf_counter_ns() - start},
            detections=detections,
        )

    def _fix_from_choice(
        self, choice: Any, detections: tuple, start: int, images: Sequence[NDArray[np.uint8]]
    ) -> PointerFix:
        """The pointer fit on a joint choice's outlines, started from its triangulated points."""
        from trackerd.ends import from_fit

        per_camera = []
        for index, (cam, picks) in enumerate(zip(self.loc.cameras, choice.chosen, strict=True)):
            ends = {}
            for colour in COLOURS:
                cand = picks[colour]
                ends[colour] = None if cand is None else from_fit(cam, index, colour, cand.fit)
            per_camera.append(ends)
        points = {"red": choice.red_m, "blue": choice.blue_m}
        init = (points[self.loc.front_colour], points[self.loc.back_colour])
        return self._fix_from_measurements(
            per_camera, init, detections, start, images, one_camera_end=choice.one_camera is not None
        )

    def _one_paint(self, images: Sequence[NDArray[np.uint8]], choice: Any) -> list[dict[str, Any]] | None:
        """Each end's chosen candidates, kept where they are of one paint in every camera: all of them pass the
        plain hue test or none does (:func:`~trackerd.detect.search.hue_mask` on their inner halves' median
        colour), and their median green and other colour, as shares of their own channel, lie within
        PAINT_SPREAD of each other. Where they do not, the camera farthest from the others (the lone one of
        its kind, else the farthest from the median shares) is left out of that end while two remain; None
        when they still do not. The last resort's looser test admits vivid things of nearly any hue, and
        one of them in a camera that does not see an end pairs with the ball in one that does (`bench
        robustness --seed 7`, installation 21, frame 17: a hit 1.86 m off at 109 mm sigma; installation 9,
        frame 1: 784 mm off at 71 mm sigma, its junk 0.64 of a ball's size). And a candidate whose outline is
        not within MAX_RADIUS_RATIO of a ball's size where the choice puts it is left out first."""
        kept = [dict(picks) for picks in choice.chosen]
        ball_radius = self.loc.pointer.end_diameter_m / 2.0
        vivid_end = False
        for colour in COLOURS:
            point = choice.red_m if colour == "red" else choice.blue_m
            shares: dict[int, Array] = {}
            plain: dict[int, bool] = {}
            for index, picks in enumerate(kept):
                cand = picks.get(colour)
                if cand is None:
                    continue
                expected = _ball_radius_px(self.loc.cameras[index], point, ball_radius)
                if not _ball_sized(cand.fit.radius_px, expected):
                    picks[colour] = None
                    continue
                x_px, y_px = (float(v) for v in cand.fit.centre_px)
                medians = _colour_medians(images[index], self.loc.grids[index], colour, x_px, y_px, cand.fit.radius_px)
                if medians is None:
                    return None
                own, green, other = medians[0]
                shares[index] = np.array([green, other]) / max(float(own), 1.0)
                plain[index] = _plain_colour(own, green, other)
            if sum(1 for picks in kept if picks.get(colour) is not None) < 2:
                return None
            while shares:
                kinds = set(plain[i] for i in shares)
                spread = float(np.max(np.ptp(np.array(list(shares.values())), axis=0)))
                if len(kinds) == 1 and spread <= PAINT_SPREAD:
                    break
                if len(shares) <= 2:
                    return None
                if len(kinds) > 1:
                    count = sum(plain[i] for i in shares)
                    minority = count * 2 < len(shares)
                    suspects = [i for i in shares if plain[i] == minority] if count * 2 != len(shares) else list(shares)
                else:
                    suspects = list(shares)
                middle = np.median(np.array(list(shares.values())), axis=0)
                farthest = max(suspects, key=lambda i: float(np.max(np.abs(shares[i] - middle))))
                del shares[farthest]
                kept[farthest][colour] = None
            vivid_end = vivid_end or not any(plain[i] for i in shares)
        # A choice of plain colours only is one the plain candidates could have made: the last resort is for
        # a paint the plain test does not take (seed 11, installation 5, frame 13: red hidden from two
        # cameras of three, a red block of the display's in one paired with the ball in the other, 1.0 m off
        # at 8 mm sigma, found only through the looser looks).
        return kept if vivid_end else None

    def _look_again(
        self,
        images: Sequence[NDArray[np.uint8]],
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
            self.loc.grids[camera_index],
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

    def _view_at(self, index: int, tolerance: float) -> Callable[[float, float], Array | None]:
        """Camera ``index``'s view map at a pixel, or None where it is within ``tolerance`` of the identity
        (a ball's outline there is a circle of its expected radius in pixels)."""
        camera = self.loc.cameras[index]

        def at(x_px: float, y_px: float) -> Array | None:
            local = view_map(camera, np.array([x_px, y_px]))
            scales = np.linalg.svd(local, compute_uv=False)
            if float(np.max(np.abs(scales - 1.0))) <= tolerance:
                return None
            return local

        return at

    def _radius_range_px(self, index: int) -> tuple[float, float]:
        """The image radius a ball can have in camera ``index``: from half a metre away to as far as the
        wall's farthest corner (it is held in front of the wall)."""
        cam = self.loc.cameras[index]
        radius = self.loc.pointer.end_diameter_m / 2.0
        farthest = float(np.max(np.linalg.norm(self.loc.wall.corners_m - cam.centre_m, axis=1))) + 0.5
        return cam.focal_px * radius / farthest, cam.focal_px * radius / 0.5

    def _room_side(self) -> tuple[Array, float]:
        """The wall's plane, oriented so that the cameras (the room) are on its positive side."""
        plane = self.loc.wall.plane
        sign = 1.0 if float(np.mean(plane.signed_distance_m(self.loc._centres))) >= 0 else -1.0
        return sign * plane.normal, sign * plane.offset_m

    def _checked_by_rod(
        self, fix: PointerFix, detections: tuple, start: int, images: Sequence[NDArray[np.uint8]]
    ) -> PointerFix:
        """A found fix fitted again without the measurements that the rod says are not their ball
        (:meth:`_off_the_rod`): not found when an end is left with fewer than two cameras, rejected when what
        is left makes no pointer."""
        off = self._off_the_rod(images, fix)
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
        refit = self._fix_from_measurements(kept, init, detections, start, images, check_rod=False)
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

    def _off_the_rod(self, images: Sequence[NDArray[np.uint8]], fix: PointerFix) -> list[tuple[int, str, float]]:
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
                    self.loc.grids[index],
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

    def _fix_from_measurements(
        self,
        per_camera: list[dict[str, Any]],
        init: tuple[Array, Array] | None,
        detections: tuple,
        start: int,
        images: Sequence[NDArray[np.uint8]],
        *,
        check_rod: bool = True,
        one_camera_end: bool = False,
    ) -> PointerFix:
        """The pointer fit on each camera's end measurements (None where a camera does not see an end); a found
        fix then checked against the rod (:meth:`_checked_by_rod`) unless ``check_rod`` is false.
        ``one_camera_end``: one end may be measured by one camera only (a joint choice placed it by its ray and
        the pointer's length, :mod:`trackerd.joint.lone`), the other by two or more; the fit starts from
        ``init``."""
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
        # What each measurement's error truly is, where its weight says less (trackerd/ends.py): the hit's
        # uncertainty is the weighted fit's under these errors.
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
                    covariances[k, e] = m.covariance
                    errors[k, e] = m.actual_covariance
        # A ball's outline of the wrong size for its distance is likely a fit to something else (the part of a
        # ball a hand leaves, a disc on the display beside it). Off by more than GUIDED_SIZE, the ball is looked
        # for again where the start puts it, told its size; off by more than MAX_RADIUS_RATIO and not found
        # again, it is left out while each end keeps two cameras, and otherwise kept with an error as large as
        # its radius is wrong, so that the hit's uncertainty says what it rests on. Within MAX_RADIUS_RATIO
        # and not found again, it keeps its weight, and a partial outline has an error along its arc's axis,
        # where its centre moves with its radius, and one smaller than the ball its shortfall in every
        # direction besides (:func:`trackerd.ends.partial_arc_error`).
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
                expected = _ball_radius_px(camera, start_points[e], ball_radius)
                ratio = m.radius_px / expected
                if 1.0 / GUIDED_SIZE <= ratio <= GUIDED_SIZE:
                    continue
                again = self._look_again(images, i, colour, start_points[e], start_points[1 - e], expected)
                if again is not None:
                    per_camera[i][colour] = again
                    measured[k, e] = again.normalised
                    covariances[k, e] = again.covariance
                    errors[k, e] = again.actual_covariance
                    continue
                if _ball_sized(m.radius_px, expected):
                    if m.fit is not None:
                        added = partial_arc_error(m.fit, expected, camera.focal_px)
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
        return self._checked_by_rod(fix, detections, start, images) if check_rod and fix.found else fix
