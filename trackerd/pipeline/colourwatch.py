"""The colour watch: does anything the cameras see come close to the pointer's colours?

A DataWall's display shows pictures, and a new slide can hold the pointer's
red. The detector still finds the ball (the geometry tells the picture from
it), but first sightings slow down and a ball in front of that picture is
harder to measure. The operator should hear of it before the presenter does.

Every :data:`WATCH_EVERY_S` seconds, on a pair where the pointer was located,
each camera's frame is measured as ``trackerd calibrate pointer`` measures it
(trackerd.detect.margin, on every :data:`WATCH_STEP`-th cell): the room's
highest excess of each end's colour, away from both balls. The status carries
the figures (``colours``); it warns when the room's excess has risen by
:data:`WARN_RISE` grey levels or more above its baseline and

* with learned colours (the baseline is the room when they were learned), the
  margin to the ball's learned excess has lost half of what it was, or there
  was none;
* without (the baseline is the room when the daemon first measured it), it now
  passes the detector's threshold.

A room already above the ball when the colours were learned (the simulated
room's red and blue distractor balls) is no news, and is not warned of again:
``calibrate pointer`` said so then.

It is logged when the set of ends warned of changes (not every time the
figures in it do), and when it clears.

The measurement runs on a thread of its own (:class:`WatchThread`), handed the
newest due pair through a one-slot mailbox: a few milliseconds every few
seconds (the first, tens), which on the publishing thread delayed the messages
queued behind it, and a replay as fast as possible lost some to its drop-oldest
queue.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.config.models import RigConfig
from trackerd.detect.colour import SampleGrid, sample_grid
from trackerd.detect.margin import Disc, colour_samples
from trackerd.geometry.camera import CameraModel
from trackerd.locator import PointerFix

log = logging.getLogger(__name__)

COLOURS = ("red", "blue")
WATCH_EVERY_S = 2.0
"""How often the room's colours are measured."""
WATCH_STEP = 3
"""Every this many-th cell is measured (a picture is large; a block of samples this far apart is still small)."""
WARN_RISE = 10
"""The room's excess must rise by this many grey levels above its baseline to warn (noise and
the pointer's own reflections move it by a few)."""
GOOD_GAP_M = 0.005
"""Measured only on pairs whose rays meet this well (the balls are where the fix says)."""


@dataclass(frozen=True)
class Reading:
    """One colour's figures from one measurement."""

    room_excess: int
    camera: str | None
    at_px: tuple[float, float] | None


class ColourWatch:
    """Measures the room's colours now and then, and says when they come close to the pointer's."""

    def __init__(self, rig: RigConfig, cameras: Sequence[CameraModel]) -> None:
        self.rig = rig
        self.cameras = list(cameras)
        self.learned = rig.pointer_colours
        self._grids: dict[tuple[int, str], SampleGrid] = {}
        self._next_ns = 0
        self._latest: dict[str, Reading] | None = None
        self._measured_ns = 0
        self._baseline: dict[str, int] = {}
        self._warned: tuple[str, ...] = ()
        """The colours warned of at the last measurement (logged when it changes, not every time the figures do)."""

    def due(self, fix: PointerFix, now_ns: int | None = None) -> bool:
        """Whether this pair's frames should be measured (called on the processing thread)."""
        now_ns = time.monotonic_ns() if now_ns is None else now_ns
        line = fix.line
        if now_ns < self._next_ns or not fix.found or line is None:
            return False
        if max(line.front_gap_m, line.back_gap_m) > GOOD_GAP_M:
            return False
        self._next_ns = now_ns + int(WATCH_EVERY_S * 1e9)
        return True

    def measure(
        self,
        images: Sequence[NDArray[np.uint8]],
        pixel_formats: Sequence[str],
        fix: PointerFix,
        now_ns: int | None = None,
    ) -> None:
        """Measure one located pair's frames (on the watch's own thread)."""
        from trackerd.calibration.colours import ball_discs

        pointer, line = self.rig.pointer, fix.line
        if pointer is None or line is None:
            return  # nothing to measure around (due() passes only located pairs of a rig that tracks)
        radius_m = pointer.end_diameter_m / 2.0
        best: dict[str, Reading] = {}
        for index, (camera, image, pixel_format) in enumerate(zip(self.cameras, images, pixel_formats, strict=True)):
            discs: dict[str, Disc | None] = ball_discs(
                camera, line.front_m, line.back_m, radius_m, pointer.front_colour
            )
            if any(d is None for d in discs.values()):
                continue
            grid = self._grid(index, camera, pixel_format)
            for colour in COLOURS:
                samples = colour_samples(image, grid, colour, discs, step=WATCH_STEP)
                seen = best.get(colour)
                if samples.background_samples and (seen is None or samples.background_excess > seen.room_excess):
                    best[colour] = Reading(samples.background_excess, camera.camera_id, samples.background_at_px)
        if len(best) < len(COLOURS):
            return
        self._latest = best
        self._measured_ns = time.monotonic_ns() if now_ns is None else now_ns
        for colour, reading in best.items():
            self._baseline.setdefault(colour, reading.room_excess)
        warned = self.warned_colours()
        if warned != self._warned:
            if warned:
                log.warning("colour watch: %s", self.warning())
            else:
                log.info("colour watch: the room's colours are back clear of the pointer's")
            self._warned = warned

    def _grid(self, index: int, camera: CameraModel, pixel_format: str) -> SampleGrid:
        key = (index, pixel_format)
        if key not in self._grids:
            self._grids[key] = sample_grid(pixel_format, camera.width_px, camera.height_px)
        return self._grids[key]

    # ------------------------------------------------------------------ judging

    def _reference(self, colour: str) -> tuple[int | None, int | None]:
        """(the room's baseline excess, the ball's excess) this colour is judged against."""
        if self.learned is not None:
            learned = self.learned.of(colour)
            return learned.background_excess, learned.ball_excess
        return self._baseline.get(colour), None

    def warned_colours(self) -> tuple[str, ...]:
        """The ends whose colour the room has come close to at the last measurement."""
        if self._latest is None:
            return ()
        return tuple(colour for colour in COLOURS if self._close(colour))

    def _threshold(self, colour: str) -> int:
        """The detector's ``min_excess`` for the end of this colour."""
        detector = self.rig.detector
        return (detector.red if colour == "red" else detector.blue).min_excess

    def _close(self, colour: str) -> bool:
        if self._latest is None:
            return False
        reading = self._latest[colour]
        baseline, ball = self._reference(colour)
        if baseline is None or reading.room_excess < baseline + WARN_RISE:
            return False
        if ball is None:
            return reading.room_excess >= self._threshold(colour)
        then, now = ball - baseline, ball - reading.room_excess
        return not (then > 0 and now >= then / 2.0)

    def warning(self) -> str | None:
        """One line when the room has come close to an end's colour, else None."""
        lines = []
        latest = self._latest or {}
        for colour in self.warned_colours():
            reading = latest[colour]
            baseline, ball = self._reference(colour)
            threshold = self._threshold(colour)
            where = "" if reading.at_px is None else f" near ({reading.at_px[0]:.0f}, {reading.at_px[1]:.0f})"
            against = f"the pointer's {ball:.0f}" if ball is not None else f"the threshold {threshold}"
            since = "when learned" if self.learned is not None else "at start"
            lines.append(
                f"{colour}: something in camera {reading.camera}{where} reaches {reading.room_excess} grey levels of"
                f" {colour} excess ({baseline} {since}), against {against}: a new picture on the wall?"
            )
        if not lines:
            return None
        return "; ".join(lines) + " First sightings slow down; `trackerd calibrate pointer` again if it stays."

    def to_json(self, now_ns: int | None = None) -> dict[str, object] | None:
        """The status's ``colours`` part; None before the first measurement."""
        if self._latest is None:
            return None
        now_ns = time.monotonic_ns() if now_ns is None else now_ns
        part: dict[str, object] = {
            "learned": self.learned is not None,
            "age_s": round(max(0.0, (now_ns - self._measured_ns) / 1e9), 1),
            "warning": self.warning(),
        }
        for colour in COLOURS:
            reading = self._latest[colour]
            baseline, ball = self._reference(colour)
            part[colour] = {
                "threshold": self._threshold(colour),
                "room_excess": reading.room_excess,
                "camera": reading.camera,
                "at_px": reading.at_px,
                "ball_excess": ball,
                "baseline_excess": baseline,
            }
        return part


class WatchThread:
    """Measures the pairs the processing thread hands it, one at a time, off every path a pair's
    messages take; a pair handed over while one is measured replaces the one waiting (only the
    newest matters)."""

    def __init__(self) -> None:
        self._slot: tuple[ColourWatch, Sequence[NDArray[np.uint8]], Sequence[str], PointerFix] | None = None
        self._wake = threading.Condition()
        self._stopping = False
        self._thread = threading.Thread(target=self._run, name="trackerd-colour-watch", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def offer(
        self, watch: ColourWatch, images: Sequence[NDArray[np.uint8]], pixel_formats: Sequence[str], fix: PointerFix
    ) -> None:
        """A due pair for ``watch`` (called on the processing thread; never waits)."""
        with self._wake:
            self._slot = (watch, images, pixel_formats, fix)
            self._wake.notify()

    def stop(self, timeout_s: float = 1.0) -> None:
        with self._wake:
            self._stopping = True
            self._wake.notify()
        if self._thread.ident is not None:
            self._thread.join(timeout_s)

    def _run(self) -> None:
        while True:
            with self._wake:
                self._wake.wait_for(lambda: self._slot is not None or self._stopping)
                if self._stopping:
                    return
                if self._slot is None:
                    continue
                watch, images, pixel_formats, fix = self._slot
                self._slot = None
            try:
                watch.measure(images, pixel_formats, fix)
            except Exception:
                log.exception("colour watch: measuring a pair failed")
