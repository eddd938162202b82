"""The refined path's search over every camera's candidates: each camera's candidates of both colours
(:mod:`trackerd.detect.search`), chosen jointly (:mod:`trackerd.joint.choice`), looked for where the geometry
puts a ball no camera offered (:mod:`trackerd.detect.guided`), then the pointer fit; in stages, plain
candidates first, then the groups merged with a picture split, last the vivid colours.

A Bayer camera's frame is searched on its mosaic first. Where that finds no pointer, the search runs again with
the frame demosaiced, at full resolution (``demosaiced=True``; :func:`trackerd.pixelformat.search_rgb`). On the
mosaic each colour has one sample per 2x2 cell, and a ball of 2-4 px radius (a 960x600 camera across a room) is
one or two samples across, too few to seed and fit an outline: the independently rendered rooms
(tests/independent) found from their raw mosaics fewer than half of the pointers they found from the RGB of
the same scenes. Demosaiced for every search, `bench robustness` lost a pointer it had found (0.9 -> 150 mm) and
put an answer beyond 5 sigma, so the mosaic's answer, where it finds one, stands (docs/detection.md, "A Bayer
frame searched as RGB"). The tracked path keeps the mosaic.

It runs where the detectors' ends make no pointer (:class:`trackerd.refine.RefinedPath` decides when: a first
sighting at once, then at the search's cadence) and costs tens of milliseconds where a tracked pair costs
one or two (docs/detection.md, "When the room is not the one the thresholds were set for").
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from trackerd.detect.guided import colour_medians, guided_fits, plain_colour
from trackerd.detect.rod import ROD_CLEAR, rod_leaving
from trackerd.ends import ball_sized, expected_radius_px, hidden_share
from trackerd.geometry.sphere import view_map
from trackerd.locator import COLOURS, PointerFix
from trackerd.pixelformat import search_rgb

if TYPE_CHECKING:
    from trackerd.detect.colour import SampleGrid
    from trackerd.detect.search import Candidate
    from trackerd.refine import RefinedPath

Array = NDArray[np.float64]

VIVID_SEEDS = 8
"""Seeds fitted per colour by the search's last resort (trackerd.detect.search.vivid_mask): what the plain test
left of a room's vivid colours, best first. Fewer than the plain search's 20, since the last resort runs on
every search that finds nothing (a room without the pointer: every `search_every_pairs`-th pair)."""

PAINT_SPREAD = 0.15
"""The last resort's choice (:meth:`JointSearch._one_paint`) stands only where each end's candidates in every
camera have their green and their other colour within this share of their own channel of each other (a
ball's own, across four cameras: within 0.11; junk that paired with a navy ball: 0.20 off it)."""

MAX_HIDDEN_SHARE = 0.75
"""A choice's fit stands only if no camera measured an end whose silhouette, where the fit puts the ends,
the other ball covers by more than this share: what that camera measured there is not that ball. An
independently rendered room (tests/independent, seed 2, pose 7 with the operator's exposure) paired a red
and a blue block of the display into a hit 854 mm off at 9 sigma whose red end, in one camera, lay 99 %
behind its blue one; that camera had measured a whole red outline there."""

MIN_DEMOSAICED_RADIUS_PX = 1.5
"""A Bayer camera's search candidates (fitted on its demosaiced frame, see the module) smaller than this in
radius are left out. A ball that small is one or two of its colour's samples across on the mosaic; on the
demosaiced frame, what is that small and of an end's hue is mostly the demosaicing's false colour (a speck of
noise, the corner of a letter). The independent rooms as raw Bayer at 960x600 (tests/independent, ``--exposure
set --format bayer``, seeds 1-16) paired such candidates into two hits 0.5 and 1.9 m off at 23 and 70 sigma;
with them left out, none, and the pointers found are the same (11 right answers, where the mosaic alone gave 5)."""

VIEW_TOLERANCE = 0.05
"""Where a camera's view map (:func:`trackerd.geometry.sphere.view_map`) scales some direction by more than
this share away from 1, a ball's outline is not a circle of the expected radius in pixels: a guided look
that fails in pixels there is tried again in the view's units."""

SEARCH_VIEW_TOLERANCE = 0.15
"""The same for the search's seeds, which are many and mostly not balls: only where the outline departs
from a circle by more than this (30 degrees off the axis) is a failed seed fitted again in the view's
units. At VIEW_TOLERANCE a wide 4K lens refitted a third of its seeds, and the search took 1.5x as long
on the default robustness run for no ball found that this tolerance misses."""


def fix_support(sound: dict[str, int]) -> tuple[int, int]:
    """What a fix rests on, for comparing two: its weaker end's sound outlines, then both ends' together."""
    return min(sound.values()), sum(sound.values())


def new_candidates(found: list[Candidate], known: list[Candidate]) -> list[Candidate]:
    """The candidates of ``found`` that are not within half a radius of one of ``known`` (the same ball)."""
    return [
        cand
        for cand in found
        if all(np.hypot(*(cand.fit.centre_px - k.fit.centre_px)) > 0.5 * k.fit.radius_px for k in known)
    ]


class JointSearch:
    """The search of one :class:`~trackerd.refine.RefinedPath` (not thread-safe, like it)."""

    def __init__(self, path: RefinedPath, *, demosaiced: bool = False) -> None:
        self.path = path
        self.loc = path.loc
        self.demosaiced = demosaiced
        """Whether the Bayer cameras' frames are searched demosaiced (the second pass: see the module)."""

    def locate(self, images: Sequence[NDArray[np.uint8]], detections: tuple, start: int) -> PointerFix:
        """Every camera's candidates of both colours, chosen jointly, then the pointer fit."""
        from trackerd.detect.search import Candidate, search_candidates, split_candidates
        from trackerd.joint import choose_jointly

        images, grids = self._searched_frames(images) if self.demosaiced else (list(images), list(self.loc.grids))

        def sized(index: int, found: dict[str, list[Candidate]]) -> dict[str, list[Candidate]]:
            # A demosaiced frame's smallest candidates are its false colour (MIN_DEMOSAICED_RADIUS_PX).
            if grids[index] is self.loc.grids[index]:
                return found
            return {c: [cand for cand in found[c] if cand.fit.radius_px >= MIN_DEMOSAICED_RADIUS_PX] for c in found}

        def searched(**options: Any) -> list[dict[str, list[Candidate]]]:
            return [
                sized(
                    index,
                    search_candidates(
                        image,
                        grids[index],
                        self.radius_range_px(index),
                        view=self._view_at(index, SEARCH_VIEW_TOLERANCE),
                        **options,
                    ),
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
            grid = grids[camera]
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
                    images[camera], grids[camera], np.array([x_px, y_px]), radius_px, rod_share * radius_px
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
                    sized(index, split_candidates(image, grids[index], self.radius_range_px(index)))
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
                    {c: new_candidates(more[c], plain[c]) for c in COLOURS}
                    for plain, more in zip(candidates, loose, strict=True)
                ]
                if not any(per_camera[c] for per_camera in added for c in COLOURS):
                    continue
                choice = choose(
                    [{c: plain[c] + more[c] for c in COLOURS} for plain, more in zip(candidates, added, strict=True)]
                )
                painted = None if isinstance(choice, str) else self._one_paint(images, grids, choice)
                if painted is None:
                    continue
                choice = replace(choice, chosen=painted)
            if isinstance(choice, str):
                reason = reason or choice
                continue
            fix = self._fix_from_choice(choice, detections, start, images, grids)
            if not fix.found:
                reason = reason or (fix.reason or "")
                best = best or fix
                continue
            support = fix_support(self.path.sound_ends(fix))
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

    def _searched_frames(self, images: Sequence[NDArray[np.uint8]]) -> tuple[list[NDArray[np.uint8]], list[SampleGrid]]:
        """The frames the search looks at, and their sample grids: a Bayer mosaic demosaiced (see the module),
        any other frame as it is."""
        from trackerd.detect.colour import sample_grid

        frames, grids = [], []
        for image, grid in zip(images, self.loc.grids, strict=True):
            if grid.is_bayer:
                image = search_rgb(image, grid.pixel_format)
                grid = sample_grid("RGB8", image.shape[1], image.shape[0])
            frames.append(image)
            grids.append(grid)
        return frames, grids

    def _fix_from_choice(
        self,
        choice: Any,
        detections: tuple,
        start: int,
        images: Sequence[NDArray[np.uint8]],
        grids: Sequence[SampleGrid],
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
        fix = self.path.fix_from_measurements(
            per_camera, init, detections, start, images, one_camera_end=choice.one_camera is not None, grids=grids
        )
        behind = self._measured_behind_the_other(fix)
        if behind is None:
            return fix
        return replace(fix, status="rejected", reason=behind, hit=None, uncertainty_m=None)

    def _measured_behind_the_other(self, fix: PointerFix) -> str | None:
        """Why a found fix cannot stand (see MAX_HIDDEN_SHARE), or None where it can."""
        if not fix.found or fix.line is None:
            return None
        ends = {self.loc.front_colour: fix.line.front_m, self.loc.back_colour: fix.line.back_m}
        radius_m = self.loc.pointer.end_diameter_m / 2.0
        for camera, measured in zip(self.loc.cameras, fix.measurements, strict=False):
            for colour, measurement in measured.items():
                if measurement is None:
                    continue
                other = "blue" if colour == "red" else "red"
                share = hidden_share(camera, ends[colour], ends[other], radius_m)
                if share > MAX_HIDDEN_SHARE:
                    return (
                        f"camera {camera.camera_id} measured a {colour} ball where the fit puts it {share:.0%} behind"
                        f" the {other} one: not the pointer"
                    )
        return None

    def _one_paint(
        self, images: Sequence[NDArray[np.uint8]], grids: Sequence[SampleGrid], choice: Any
    ) -> list[dict[str, Any]] | None:
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
                expected = expected_radius_px(self.loc.cameras[index], point, ball_radius)
                if not ball_sized(cand.fit.radius_px, expected):
                    picks[colour] = None
                    continue
                x_px, y_px = (float(v) for v in cand.fit.centre_px)
                medians = colour_medians(images[index], grids[index], colour, x_px, y_px, cand.fit.radius_px)
                if medians is None:
                    return None
                own, green, other = medians[0]
                shares[index] = np.array([green, other]) / max(float(own), 1.0)
                plain[index] = plain_colour(own, green, other)
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

    def radius_range_px(self, index: int) -> tuple[float, float]:
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
