"""The processing stage: pairs in, each pair's result out to the publishing thread.

For each pair the source delivers (renumbered across sources,
trackerd.pipeline.sourceslot): the extensions see it, the locator locates the
pointer, the extensions add their events, and the result goes to the publishing
thread through a bounded queue that drops its oldest item when full
(trackerd.pipeline.handover), with its wire messages built as it is handed over.
Once they are sent, the locator measures again the ball outlines the next pair
would need (:meth:`trackerd.locator.Locator.measure_ahead`), in the time
between pairs rather than in the next pair's latency.
Between pairs it applies a requested configuration (the first phase of a
reload, trackerd.pipeline.reload).

It owns the locator (detectors keep tracking state from pair to pair), the
source's slot and the extensions' per-pair calls. It decides which fixes the
calibration health measures, but never measures: the publishing thread does,
once the pair's messages are sent (:data:`HEALTH_EVERY`). It never touches the
publisher.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Sequence

from trackerd.calibration.health import CalibrationHealth
from trackerd.config.models import RigConfig
from trackerd.errors import ConfigError
from trackerd.locator import Locator, PointerFix
from trackerd.pipeline.colourwatch import ColourWatch, WatchThread
from trackerd.pipeline.events import NOTHING, Event, PairEvents
from trackerd.pipeline.extensions import ExtensionContext, ExtensionKind, Located, PipelineExtension
from trackerd.pipeline.handover import Processed, StageLinks
from trackerd.pipeline.reload import changes_calibration, changes_colours, source_settings
from trackerd.pipeline.sourceslot import SourceSlot

log = logging.getLogger(__name__)

PAIR_WAIT_S = 0.05
"""How long the processing thread waits for a pair before checking for stop or reload."""
HEALTH_EVERY = 4
"""Calibration health is measured on every fourth pair: drift is slow, and each
measurement reprojects every end into every camera (0.35-0.5 ms on the
development VM). The publishing thread does it once the pair's messages are
sent, so it adds nothing to that pair's latency (done by the processing thread
after the hand-over, it still held the GIL while they were being sent); it can
delay a pair that arrives meanwhile, as any work of the daemon's can."""
SENT_WAIT_S = 0.005
"""How long the processing thread waits for a pair's messages to be sent before the locator's work between
pairs (:meth:`trackerd.locator.Locator.measure_ahead`) starts regardless: the publishing thread sends within a
fraction of a millisecond, and never sends a result the queue dropped."""


def measures_health(pair_index: int, fix: PointerFix) -> bool:
    """Whether the ``pair_index``-th pair processed (from 0) goes to the calibration health record.

    Every fix with a line, rejected ones included: a bumped camera shows as fixes rejected for
    their ray gap, which is what the health record is for (trackerd.calibration.health)."""
    return fix.line is not None and pair_index % HEALTH_EVERY == 0


class ProcessingStage:
    """The processing thread's loop and what it owns (see the module's docstring)."""

    def __init__(
        self,
        rig: RigConfig,
        slot: SourceSlot,
        links: StageLinks,
        extensions: list[PipelineExtension],
        kinds: Sequence[ExtensionKind] = (),
        context: ExtensionContext | None = None,
    ) -> None:
        """``extensions`` is read by the daemon's other threads too (its status, the console): an extension a
        reload first asks for (one of ``kinds``, built with ``context``) goes into a new list, in the kinds'
        order, which replaces it whole."""
        self.rig = rig
        self.slot = slot
        self._links = links
        self.extensions = extensions
        self._kinds = tuple(kinds)
        self._context = context or ExtensionContext()
        self.locator = Locator(rig)
        self.health = CalibrationHealth.for_rig(rig, self.locator.cameras)
        """The record fixes are measured into; a reload with a new calibration replaces it."""
        self.colour_watch = ColourWatch(rig, self.locator.cameras)
        self.watch_thread = WatchThread()
        self.done = threading.Event()
        """Set once the loop has ended and the extensions' last messages are queued."""

    def run(self, stop: threading.Event) -> None:
        """The thread's body: pairs until ``stop``, then the extensions' last words."""
        try:
            observer = self._links.observer
            if observer is not None:
                observer.thread_started()
            try:
                self._process_pairs(stop)
            finally:
                if observer is not None:
                    observer.thread_stopped()
            # The extensions' last words (a session still entered ends with a leave), queued
            # ahead of the final status so subscribers hear them before the socket closes.
            self._hand_over_pairless([event for extension in self.extensions for event in extension.finish()])
        finally:
            self.done.set()

    def _process_pairs(self, stop: threading.Event) -> None:
        links = self._links
        observer, figures = links.observer, links.figures
        while not stop.is_set():
            self._apply_requested_rig()
            pair = self.slot.next_pair(PAIR_WAIT_S)
            if pair is None:
                if self.slot.some_camera_recovering():
                    # A power-cycled camera is not a stalled pipeline: keep systemd's watchdog fed.
                    self._links.notifier.progress()
                now = time.monotonic_ns()
                self._hand_over_pairless([event for extension in self.extensions for event in extension.on_quiet(now)])
                continue
            taken_mark = observer.mark() if observer is not None else None
            start, start_cpu = time.monotonic_ns(), time.thread_time_ns()
            received = max(frame.host_timestamp_ns for frame in pair.frames)
            fresh = pair.fresh_start
            for extension in self.extensions:
                fresh = bool(extension.on_pair(pair)) or fresh
            if fresh:
                # A recording starts with this pair, or a replay looped round: what is published
                # from here on depends on these pairs only (trackerd.pipeline.extensions).
                self.locator.reset()
                for extension in self.extensions:
                    extension.reset()
            # A replay locating ahead (trackerd.recording.ahead) went through every pair before with a
            # locator of this rig, started afresh and reset where this one would have been.
            fix = pair.located if pair.located is not None else self.locator.locate(pair.images)
            capture = pair.timestamp_ns + links.clock_offset_ns
            located = Located(pair, fix, capture)
            events = NOTHING
            for extension in self.extensions:
                events = events.then(extension.on_located(located))
            figures.count_fix(fix.status)
            stage = {
                "detect": fix.timings_ns.get("detect_ns", 0),
                "triangulate": fix.timings_ns.get("triangulate_ns", 0),
            }
            marks = (taken_mark, observer.mark()) if observer is not None else None
            health = (self.health, fix) if measures_health(figures.pairs_processed, fix) else None
            watch = self.colour_watch
            if watch.due(fix):
                self.watch_thread.offer(watch, pair.images, tuple(frame.pixel_format for frame in pair.frames), fix)
            tap = links.tap
            if tap is not None and tap.frame_wanted:
                tap.offer(pair, fix, self.locator)
            processed = Processed(
                fix,
                self.locator.front_colour,
                pair.sequence,
                received,
                capture,
                events,
                stage,
                taken_ns=start,
                marks=marks,
                health=health,
            )
            # The one conversion to wire messages happens here, not on the publishing thread: there it
            # lengthened the publish stage from 0.16 to 0.38 ms and the latency median by 0.3-0.6 ms
            # (`trackerd bench pipeline`), the two threads contending for the interpreter.
            processed.messages()
            if observer is not None:
                processed.queued_ns = time.monotonic_ns()
            if self.slot.every_pair_published():
                links.queue.put_waiting(processed, stop)
            else:
                links.queue.put(processed)
            # The pair's own work, set beside its latency by the benchmarks (what follows is in neither; the
            # process's CPU time counts it).
            figures.processing_cpu.add(time.thread_time_ns() - start_cpu)
            if self.locator.ahead_pending:
                # The outlines the next pair would find stale are measured now, on this pair, so that the next
                # one does not wait for them; once this pair's messages are out, since the measurement holds
                # the interpreter and would keep the publishing thread from sending them.
                processed.sent.wait(SENT_WAIT_S)
                self.locator.measure_ahead()
            figures.pairs_processed += 1
            self._links.notifier.progress()

    def _hand_over_pairless(self, events: list[Event]) -> None:
        """Events of no pair (the extensions' last words at stop, a session a stalled source ended), to the
        publishing thread now: stamped with the time they were decided."""
        if not events:
            return
        now = time.monotonic_ns()
        self._links.queue.put(
            Processed(
                None,
                self.locator.front_colour,
                0,
                now,
                now + self._links.clock_offset_ns,
                PairEvents(events=events),
                pairless=True,
            )
        )

    def _build_asked_for(self, rig: RigConfig) -> None:
        """The extensions the reloaded rig asks for that were not built (none was asked for before: a
        ``[recording] directory`` added, ``[interaction]`` turned on), put in their kinds' order. One
        whose ``create`` refuses the rig is left out, and the log says why."""
        order = {kind.name: n for n, kind in enumerate(self._kinds)}
        for kind in self._kinds:
            if any(extension.name == kind.name for extension in self.extensions):
                continue
            try:
                extension = kind.create(rig, self._context)
            except ConfigError as err:
                log.error("reload: %s not started: %s", kind.name, err)
                continue
            if extension is None:
                continue
            position = sum(1 for e in self.extensions if order.get(e.name, -1) < order[kind.name])
            self.extensions = [*self.extensions[:position], extension, *self.extensions[position:]]
            log.info("reload: %s started", kind.name)

    def _apply_requested_rig(self) -> None:
        """The first phase of a reload (trackerd.pipeline.reload); a failure keeps the old rig."""
        rig = self._links.reload.take_rig()
        if rig is None:
            return
        old = self.rig
        self._links.reload.in_progress = True
        try:
            locator = Locator(rig)
            if source_settings(rig) != source_settings(old):
                log.info("reload: camera settings changed, reopening the cameras")
                self.slot.reopen(rig, old)
        except Exception as err:  # noqa: BLE001 - a bad reload keeps the old configuration
            log.error("reload failed, keeping the previous configuration: %s", err)
            self._links.notifier.ready("running (reload failed: previous configuration kept)")
            return
        finally:
            self._links.reload.in_progress = False
        self.locator = locator
        for extension in self.extensions:
            extension.reload(rig)
        self._build_asked_for(rig)
        if changes_calibration(rig, old):
            self.health = CalibrationHealth.for_rig(rig, locator.cameras)
        if changes_colours(rig, old):
            self.colour_watch = ColourWatch(rig, locator.cameras)
        self.rig = rig
        # The publishing thread rebinds for changed outputs; unchanged ones still re-read the
        # CURVE client keys, so adding or revoking a subscriber is a reload, not a restart.
        self._links.reload.applied(rig)
        log.info("reload: configuration applied")
        self._links.notifier.ready("running (configuration reloaded)")
