"""Learning the pointer's colours in this room: ``trackerd calibrate pointer`` (docs/calibration.md).

The detector's default thresholds were set on the simulated DataWall: a paint,
a light and a room. A darker paint, a dim room or a display full of reds moves
both what the ends reach and what everything else reaches. Here the pointer is
waved in view and located by the daemon's own locator (whose outline search
and joint choice find it even where the thresholds do not,
trackerd/detect/search.py); on every pair where it is located well, each
camera's frame gives:

* the **ball's excess** over its core (trackerd.detect.margin), for each end;
* the **background's excess**: the highest anything else reaches.

Pooled over cameras and frames (the darkest camera's ball, the most colourful
camera's background), each end gets a threshold:

* with a margin (ball above background): :data:`ROOM_SIDE` of the way from the
  background's excess to the ball's, and no lower than :data:`BALL_SHARE` of the ball's excess (the default
  thresholds are about that share on the simulated DataWall: room for the ball
  to move into shade);
* without one (something in view is as much that colour as the ball):
  :data:`BALL_SHARE` of the ball's, and a warning naming where that something
  is. Only the geometry tells them apart then (trackerd.joint).

The figures and thresholds go to the calibration file's ``[pointer_colours]``;
the daemon compares what it sees with them (trackerd.pipeline.colourwatch).
"""

from __future__ import annotations

import math
import re
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, TypedDict

import numpy as np
from numpy.typing import NDArray

from trackerd.calibration import CalibrationError
from trackerd.calibration.health import ellipse_centre_px
from trackerd.calibration.live import Event
from trackerd.config.models import (
    MIN_LEARNED_EXCESS,
    ColourThreshold,
    DetectorConfig,
    LearnedColour,
    PointerColours,
    PointerConfig,
    RigConfig,
)
from trackerd.detect.colour import sample_grid
from trackerd.detect.margin import BALL_PERCENTILE, Disc, colour_samples, unhidden
from trackerd.geometry.camera import CameraModel

if TYPE_CHECKING:
    from trackerd.detect.detector import ColourEndDetector
    from trackerd.locator import Locator, PointerFix

COLOURS = ("red", "blue")

BALL_SHARE = 0.55
"""A learned threshold is at least this share of the ball's excess."""
ROOM_SIDE = 0.4
"""With a margin, the threshold sits this share of it above the room's excess: nearer the room than the
ball, because the ball moves into shade across the room more often than the room turns more colourful."""
MIN_EXCESS = MIN_LEARNED_EXCESS
"""No threshold below this many grey levels: sensor noise reaches it on grey."""
VALUE_SHARE = 0.6
"""The brightness threshold is this share of the ball's (10th percentile of its own channel), and no
stricter than the excess threshold (which a sample's own channel passes anyway)."""
GOOD_GAP_M = 0.005
"""Pairs are learned from only where both ends' rays meet within this (the pointer located well)."""
CENTRE_AGREEMENT = 0.25
"""A camera's view of a ball is used only where its measured centre lies within this share of the
ball's imaged radius of where the located pointer puts it (a ball partly hidden is not)."""
MIN_CORE_SAMPLES = 20
"""Fewest core samples of an end, over all frames, to learn its colour from."""
NARROW_MARGIN = 0.25
"""A margin under this share of the ball's excess is reported as narrow."""
HIDDEN_VIEW_SHARE = 0.7
"""A view of a ball whose core's median excess is under this share of that camera's typical view is
of a ball mostly hidden (by more than its core's outliers show), and is left out."""
CHECK_FRAMES = 12
"""Frames kept to try the detector's own search with the old and the learned thresholds."""


@dataclass
class _Camera:
    """What one camera contributed."""

    ball: dict[str, list[NDArray[np.int16]]] = field(default_factory=lambda: {c: [] for c in COLOURS})
    value: dict[str, list[NDArray[np.uint8]]] = field(default_factory=lambda: {c: [] for c in COLOURS})
    background: dict[str, tuple[int, int, tuple[float, float] | None]] = field(default_factory=dict)
    """colour -> (excess, frame number, where): the highest seen."""


@dataclass(frozen=True)
class CameraFigures:
    """One camera's figures for one end."""

    camera_id: str
    colour: str
    ball_excess: float | None
    background_excess: int | None
    background_frame: int | None
    background_at_px: tuple[float, float] | None


class DetectorCheck(TypedDict):
    """How often the detector's own search finds both ends where the located pointer is."""

    before: tuple[int, int]
    """(images found in, images tried) with the rig's thresholds."""
    after: tuple[int, int]
    """The same with the learned thresholds."""
    pairs: int
    """How many pairs those images are from."""


@dataclass(frozen=True)
class LearnedFigures:
    """The result: what each end and the room reached, the thresholds, and what to say about them."""

    colours: PointerColours
    per_camera: tuple[CameraFigures, ...]
    frames: int
    """Pairs offered."""
    used: int
    """Pairs the pointer was located well enough in to learn from."""
    warnings: tuple[str, ...]
    detector_check: DetectorCheck | None = None
    """'before' / 'after' -> (images where the detector's own search found both ends where the pointer
    is, images tried), and 'pairs': how many pairs those images are from (a sample of
    :data:`CHECK_FRAMES`); None when not tried."""


def ball_discs(
    camera: CameraModel, front_m: NDArray[np.float64], back_m: NDArray[np.float64], radius_m: float, front_colour: str
) -> dict[str, Disc | None]:
    """Where each ball of the located pointer images in ``camera`` (None behind it or off the image)."""
    back_colour = "blue" if front_colour == "red" else "red"
    discs: dict[str, Disc | None] = {}
    for colour, centre in ((front_colour, front_m), (back_colour, back_m)):
        distance = float(np.linalg.norm(camera.to_camera_frame(np.asarray(centre)[None])[0]))
        if distance <= 2.0 * radius_m:
            discs[colour] = None
            continue
        x, y = ellipse_centre_px(camera, centre, radius_m)
        radius_px = camera.focal_px * radius_m / math.sqrt(distance**2 - radius_m**2)
        inside = bool(np.isfinite([x, y]).all()) and bool(camera.contains(np.array([[x, y]]), margin_px=radius_px)[0])
        discs[colour] = Disc(float(x), float(y), radius_px) if inside else None
    return discs


def learned_threshold(ball_excess: float, background_excess: float) -> int:
    """The threshold for an end whose paint reaches ``ball_excess`` in a room reaching ``background_excess``."""
    share = BALL_SHARE * ball_excess
    if ball_excess > background_excess:
        share = max(share, background_excess + ROOM_SIDE * (ball_excess - background_excess))
    return int(min(255, max(MIN_EXCESS, round(share))))


class ColourLearner:
    """Accumulates ball and background figures from located pairs (a live session's ``feed``)."""

    def __init__(
        self,
        rig: RigConfig,
        cameras: Sequence[CameraModel],
        wanted: int = 60,
        locator: Locator | None = None,
        seed: int = 0,
    ) -> None:
        if rig.pointer is None:
            raise CalibrationError("learning the pointer's colours needs the rig's [pointer] table")
        self.pointer: PointerConfig = rig.pointer
        from trackerd.locator import Locator as LocatorClass

        self.rig = rig
        self.cameras = list(cameras)
        self.wanted = wanted
        self.locator = locator or LocatorClass(rig, cameras=self.cameras)
        self.frames = 0
        self.used = 0
        # Why pairs were not located, by the reason's wording with its figures left out (the first
        # sentence of each, as it was first given), so that "nothing to learn from" can say which end
        # the locator missed: a blue end too dark to be told by its colour is not fixed by more waving.
        self._missed: Counter[str] = Counter()
        self._missed_first: dict[str, str] = {}
        self._cameras = [_Camera() for _ in self.cameras]
        self._kept: list[tuple[list[tuple[NDArray[np.uint8], str]], list[dict[str, Disc | None]]]] = []
        self._rng = np.random.default_rng(seed)
        self._last_report = 0

    @property
    def done(self) -> bool:
        return self.used >= self.wanted

    def feed(self, frames: Sequence[tuple[str, NDArray[np.uint8], str]]) -> Event | None:
        """One pair as (name, image, pixel format) per camera, in rig order."""
        self.frames += 1
        self.locator.reset()  # each pair judged on its own: a frame tracked wrongly teaches nothing
        fix = self.locator.locate([image for _, image, _ in frames])
        line = fix.line
        if not fix.found or line is None or max(line.front_gap_m, line.back_gap_m) > GOOD_GAP_M:
            self._note_missed(fix, line is not None and fix.found)
            if self.frames % 25 == 0 and self.used == 0:
                return Event(
                    f"[{self.frames} pairs] the pointer is not located yet"
                    f" ({fix.reason or fix.status}): wave it where both cameras see it"
                )
            return None
        self.used += 1
        pointer = self.pointer
        radius_m = pointer.end_diameter_m / 2.0
        discs_all = []
        for index, (camera, (_, image, pixel_format)) in enumerate(zip(self.cameras, frames, strict=True)):
            discs = ball_discs(camera, line.front_m, line.back_m, radius_m, pointer.front_colour)
            discs_all.append(discs)
            if any(d is None for d in discs.values()):
                continue
            grid = sample_grid(pixel_format, camera.width_px, camera.height_px)
            widest_px = max(d.radius_px for d in discs.values() if d is not None)
            rod_px = 0.5 * pointer.rod_diameter_m / pointer.end_diameter_m * widest_px
            for colour in COLOURS:
                samples = colour_samples(image, grid, colour, discs, rod_half_width_px=rod_px + 1.5)
                seen = self._cameras[index]
                # A ball whose core shows no excess of its colour (hidden in this camera, though the fix's
                # centre agrees) teaches nothing about it.
                shows = samples.ball_excess.size > 0 and float(np.median(samples.ball_excess)) > 0
                if self._centre_agrees(fix, index, colour, discs[colour]) and shows:
                    kept = unhidden(samples.ball_excess)
                    seen.ball[colour].append(kept)
                    seen.value[colour].append(samples.ball_value[samples.ball_excess >= kept.min()])
                best = seen.background.get(colour)
                if samples.background_samples and (best is None or samples.background_excess > best[0]):
                    seen.background[colour] = (samples.background_excess, self.frames, samples.background_at_px)
        self._keep([(image, fmt) for _, image, fmt in frames], discs_all)
        if self.used - self._last_report >= 10 or self.done:
            self._last_report = self.used
            red, blue = (self._pooled(c) for c in COLOURS)
            return Event(
                f"[{self.used:>3} pairs] red ball {_level(red[0])} / room {_level(red[1])};"
                f" blue ball {_level(blue[0])} / room {_level(blue[1])} (grey levels of colour excess)",
                accepted=True,
                finished=self.done,
            )
        return None

    def _note_missed(self, fix: PointerFix, located: bool) -> None:
        if located:
            reason = f"rays met more than {GOOD_GAP_M * 1000:.0f} mm apart at an end"
        else:
            reason = (fix.reason or fix.status).split(";")[0].strip()
        kind = re.sub(r"[-+]?\d+(\.\d+)?", "#", reason)
        self._missed[kind] += 1
        self._missed_first.setdefault(kind, reason)

    def _missed_most(self) -> str:
        """The commonest reason pairs were not located, as ``; most often (k of n): reason`` ("" if none)."""
        if not self._missed:
            return ""
        kind, count = self._missed.most_common(1)[0]
        return f"; most often ({count} of {self.frames}): {self._missed_first[kind]}"

    def _centre_agrees(self, fix: PointerFix, index: int, colour: str, disc: Disc | None) -> bool:
        if disc is None or index >= len(fix.centroids_px):
            return False
        measured = fix.centroids_px[index].get(colour)
        if measured is None or not np.isfinite(measured).all():
            return False
        return math.hypot(measured[0] - disc.x_px, measured[1] - disc.y_px) <= CENTRE_AGREEMENT * disc.radius_px

    def _keep(self, images: list[tuple[NDArray[np.uint8], str]], discs: list[dict[str, Disc | None]]) -> None:
        """Reservoir of :data:`CHECK_FRAMES` pairs for the detector check."""
        if len(self._kept) < CHECK_FRAMES:
            self._kept.append((images, discs))
            return
        slot = int(self._rng.integers(0, self.used))
        if slot < CHECK_FRAMES:
            self._kept[slot] = (images, discs)

    def _pooled(self, colour: str) -> tuple[float | None, int | None]:
        """(ball excess of the darkest camera, background excess of the most colourful camera)."""
        balls = [b for b in (_percentile(cam.ball[colour]) for cam in self._cameras) if b is not None]
        rooms = [cam.background[colour][0] for cam in self._cameras if colour in cam.background]
        return (min(balls) if balls else None, max(rooms) if rooms else None)

    # ------------------------------------------------------------------ result

    def result(self, learned_on: str, *, check_detector: bool = True) -> LearnedFigures:
        """The thresholds and figures; CalibrationError when too little was seen to learn from."""
        if self.used == 0:
            raise CalibrationError(
                f"the pointer was not located well in any of {self.frames} pair(s) (both ends seen by two cameras,"
                f" rays meeting within {GOOD_GAP_M * 1000:.0f} mm): nothing to learn from; wave it where every"
                " camera sees both ends (`trackerd calibrate check` says whether the calibration still fits)"
                f"{self._missed_most()}. An end that looks dark or grey in the images cannot be told by its colour:"
                " it needs more light, a longer exposure or a brighter paint, not more waving"
            )
        per_camera = []
        learned = {}
        warnings = []
        for colour in COLOURS:
            for camera, seen in zip(self.cameras, self._cameras, strict=True):
                background = seen.background.get(colour)
                per_camera.append(
                    CameraFigures(
                        camera.camera_id,
                        colour,
                        _percentile(seen.ball[colour]),
                        background[0] if background else None,
                        background[1] if background else None,
                        background[2] if background else None,
                    )
                )
            samples = sum(a.size for cam in self._cameras for a in cam.ball[colour])
            if samples < MIN_CORE_SAMPLES:
                raise CalibrationError(
                    f"the {colour} end was seen whole in too few views ({samples} core samples in {self.used}"
                    f" pair(s), at least {MIN_CORE_SAMPLES} needed): hold it nearer the cameras, or for longer"
                )
            ball, room = self._pooled(colour)
            assert ball is not None
            room = room if room is not None else -255
            threshold = learned_threshold(ball, room)
            if BALL_SHARE * ball < MIN_EXCESS:
                raise CalibrationError(
                    f"the {colour} end barely differs from grey under this light (its paint reaches {ball:.0f}"
                    f" grey levels of {colour} excess): more light, a longer exposure or a stronger paint"
                )
            values = np.concatenate([v for cam in self._cameras for v in cam.value[colour]])
            min_value = min(threshold, round(VALUE_SHARE * float(np.percentile(values, BALL_PERCENTILE))))
            learned[colour] = LearnedColour(
                min_excess=threshold, min_value=min_value, ball_excess=round(ball), background_excess=room
            )
            if room >= threshold:
                worst = _worst_figures(per_camera, colour)
                at = worst.background_at_px
                where = f" near ({at[0]:.0f}, {at[1]:.0f})" if at else ""
                warnings.append(
                    f"{colour}: something in camera {worst.camera_id}{where} (pair {worst.background_frame}) reaches"
                    f" {room} grey levels of {colour} excess, the ball {ball:.0f}: no threshold tells them apart,"
                    " only the geometry does (slower first sightings); take it out of view if you can"
                )
            elif ball - room < NARROW_MARGIN * ball:
                warnings.append(
                    f"{colour}: the margin to the room is only {ball - room:.0f} grey levels (the ball {ball:.0f},"
                    f" the room {room} in camera {_worst(per_camera, colour)}): a little less light on the ball,"
                    " or a little more colour in the room, and the threshold takes the room or loses the ball"
                )
        colours = PointerColours(learned=learned_on, frames=self.used, red=learned["red"], blue=learned["blue"])
        check = self._detector_check(colours) if check_detector and self._kept else None
        return LearnedFigures(colours, tuple(per_camera), self.frames, self.used, tuple(warnings), check)

    def _detector_check(self, colours: PointerColours) -> DetectorCheck:
        """How often the detector's own search (no outline fit, no joint choice) finds both ends where the
        located pointer is, with the rig's thresholds and with the learned ones."""
        from trackerd.detect.detector import ColourEndDetector

        before = self.rig.detector
        after = before.model_copy(
            update={
                c: ColourThreshold(min_excess=colours.of(c).min_excess, min_value=colours.of(c).min_value)
                for c in COLOURS
            }
        )
        found = {name: self._found_with(cfg, ColourEndDetector) for name, cfg in (("before", before), ("after", after))}
        return {"before": found["before"], "after": found["after"], "pairs": len(self._kept)}

    def _found_with(self, cfg: DetectorConfig, detector_class: type[ColourEndDetector]) -> tuple[int, int]:
        found = tried = 0
        for images, discs in self._kept:
            for camera, (image, fmt), disc in zip(self.cameras, images, discs, strict=True):
                ends = {c: d for c, d in disc.items() if d is not None}
                if len(ends) < len(disc):
                    continue
                tried += 1
                result = detector_class(cfg, fmt, camera.width_px, camera.height_px, self.pointer).detect(image)
                found += all(
                    result.end(c).found
                    and (at := result.end(c).centroid_px) is not None
                    and math.hypot(at[0] - ends[c].x_px, at[1] - ends[c].y_px) <= 0.5 * ends[c].radius_px
                    for c in COLOURS
                )
        return found, tried


def _percentile(arrays: list[NDArray[np.int16]]) -> float | None:
    """:data:`BALL_PERCENTILE` of one camera's views of a ball, leaving out the views mostly hidden
    (whose median is under :data:`HIDDEN_VIEW_SHARE` of the typical view's)."""
    arrays = [a for a in arrays if a.size]
    if not arrays:
        return None
    medians = np.array([np.median(a) for a in arrays])
    typical = float(np.median(medians))
    kept = [a for a, m in zip(arrays, medians, strict=True) if m >= HIDDEN_VIEW_SHARE * typical]
    return float(np.percentile(np.concatenate(kept or arrays), BALL_PERCENTILE))


def _worst_figures(per_camera: list[CameraFigures], colour: str) -> CameraFigures:
    """The camera whose room reached the most of ``colour``."""
    return max(
        (f for f in per_camera if f.colour == colour and f.background_excess is not None),
        key=lambda f: -1 if f.background_excess is None else f.background_excess,
    )


def _worst(per_camera: list[CameraFigures], colour: str) -> str:
    worst = _worst_figures(per_camera, colour)
    at = worst.background_at_px
    return worst.camera_id + ("" if at is None else f" near ({at[0]:.0f}, {at[1]:.0f})")


def _level(value: float | None) -> str:
    return "-" if value is None else f"{value:.0f}"
