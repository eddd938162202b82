"""The real-time pipeline: pairs in, pointer fixes out, published over ZeroMQ.

Threads (besides each camera's acquisition thread inside the pair source):

* processing: takes the newest pairs from the source, detects both ends in
  every image, triangulates, intersects the wall (trackerd/locator.py) and
  hands the resulting messages to the publisher through a bounded queue that
  drops its oldest item when full;
* publishing: owns the ZeroMQ publisher, sends the messages, and sends a status
  about once a second and on every change of state; once a pair's messages are
  sent, it measures calibration health from the pair's fix (every fourth pair),
  and it alone reads and writes the health record;
* colour watch: every few seconds, the room's colours against the pointer's, on
  the newest located pair the processing thread hands it
  (trackerd.pipeline.colourwatch).

Latency is measured, not guessed: per stage (detect, triangulate, publish) and
end to end, from the moment the last frame of a pair arrived to the moment its
messages were handed to ZeroMQ. Signals are not handled here: the CLI calls
:meth:`Pipeline.stop` and :meth:`Pipeline.request_reload`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import trackerd
from trackerd.acquisition.source import PairSource
from trackerd.acquisition.status import SourceStatus
from trackerd.calibration.health import CalibrationHealth
from trackerd.config.models import RigConfig
from trackerd.locator import Locator, PointerFix
from trackerd.pipeline.colourwatch import ColourWatch, WatchThread
from trackerd.pipeline.extensions import PipelineExtension
from trackerd.pipeline.queues import DropOldestQueue
from trackerd.pipeline.stats import Window, percentiles_ms
from trackerd.pipeline.tap import ConsoleTap
from trackerd.pipeline.threadtime import OffCpu, ThreadClock, off_cpu
from trackerd.publish import Publisher, StatusMessage, messages_from_fix
from trackerd.publish.messages import (
    CalibrationHealthPart,
    CameraStatusPart,
    ColourWatchPart,
    LatencyPart,
    Message,
    PairingPart,
)
from trackerd.sdnotify import SdNotify

log = logging.getLogger(__name__)

STATE_POLL_S = 0.2
"""How often the publisher looks for a change of camera state (a change sends a status at once)."""
PAIR_WAIT_S = 0.05
"""How long the processing thread waits for a pair before checking for stop or reload."""
STOP_DRAIN_S = 0.5
"""How long, at stop, the publisher waits for the processing thread's last messages."""
HEALTH_EVERY = 4
"""Calibration health is measured on every fourth pair: drift is slow, and each
measurement reprojects every end into every camera (0.35-0.5 ms on the
development VM). The publishing thread does it once the pair's messages are
sent, so it adds nothing to that pair's latency (done by the processing thread
after the hand-over, it still held the GIL while they were being sent); it can
delay a pair that arrives meanwhile, as any work of the daemon's can."""


@dataclass
class _Processed:
    """What the processing thread hands the publisher for one pair."""

    messages: list[Message]
    received_ns: int
    """Monotonic time the last frame of the pair arrived."""
    capture_ns: int
    """Capture time on the publishing clock."""
    stage_ns: dict[str, int] = field(default_factory=dict)
    final: bool = False
    """The extensions' last messages at stop, not a pair's: not counted in the figures."""
    started_ns: int = 0
    """Monotonic time the processing thread took the pair."""
    queued_ns: int = 0
    """Monotonic time the messages were handed to the publishing thread."""
    processing_off: OffCpu | None = None
    """The processing thread's time off the CPU while on this pair (with ``account_threads``)."""
    health: tuple[CalibrationHealth, PointerFix] | None = None
    """A fix to add to the calibration health record it was located under, once the messages are sent."""


@dataclass(frozen=True)
class PairTrace:
    """One pair's latency taken apart (``Pipeline(account_threads=True)``, for benchmarks)."""

    received_ns: int
    """Monotonic time the last frame of the pair arrived."""
    latency_ns: int
    """Last frame received to messages handed to ZeroMQ, as in the ``processing`` figures."""
    waiting_ns: int
    """Last frame received to the processing thread taking the pair."""
    processing: OffCpu
    """The processing thread, from taking the pair to handing over its messages."""
    handoff_ns: int
    """Messages handed over to the publishing thread starting on them."""
    publishing: OffCpu
    """The publishing thread, sending the pair's messages."""


class Pipeline:
    """Runs a pair source through the locator into a publisher until stopped.

    ``source_factory`` and ``publisher_factory`` build the parts from a rig, so a
    reloaded configuration can replace them; ``clock_offset_ns`` turns the
    monotonic clock into the epoch timestamps published (fixed at start, so
    published times never go backwards even if the wall clock is stepped).
    """

    def __init__(
        self,
        rig: RigConfig,
        source_factory: Callable[[RigConfig], PairSource],
        publisher_factory: Callable[[RigConfig], Publisher],
        notifier: SdNotify | None = None,
        *,
        queue_length: int = 16,
        clock_offset_ns: int | None = None,
        extensions: Sequence[PipelineExtension] | None = None,
        account_threads: bool = False,
        tap: ConsoleTap | None = None,
    ) -> None:
        self.rig = rig
        self.tap = tap
        """The operator's console's view of the pipeline (trackerd.pipeline.tap), or None."""
        self._account_threads = account_threads
        self._trace: list[PairTrace] | None = None
        self._source_factory = source_factory
        self._publisher_factory = publisher_factory
        self._notifier = notifier or SdNotify({})
        self.clock_offset_ns = (
            time.time_ns() - time.monotonic_ns() if clock_offset_ns is None else clock_offset_ns
        )
        self._queue: DropOldestQueue[_Processed] = DropOldestQueue(queue_length)
        self._stop = threading.Event()
        self._processing_done = threading.Event()
        self._done = threading.Event()
        self._failure: BaseException | None = None
        self._failure_text: str | None = None
        self._pending_rig: RigConfig | None = None
        self._pending_outputs: RigConfig | None = None
        self._pending_lock = threading.Lock()
        self._threads: list[threading.Thread] = []
        self._started_ns = time.monotonic_ns()
        self._ready_sent = False
        self._reloading = False
        self._state = "starting"
        self._detail: str | None = None
        self._status_sequence = 0
        self._drained: dict = {}
        """The latencies (ns) the last status summarised, by figure (for the console's histograms)."""
        self._fixes: dict[str, int] = {}
        self.latency = Window()
        """Capture to publish (ns), drained into each status."""
        self.processing = Window()
        """Last frame of the pair received to messages published (ns)."""
        self.stages = {name: Window() for name in ("detect", "triangulate", "publish")}
        self.processing_cpu = Window()
        """CPU time the processing thread spent on each pair (ns): set beside its wall time, what
        was work and what was time off the CPU (benchmarks; not in the status)."""
        self.pairs_processed = 0
        self.pairs_published = 0
        """Pairs whose messages the publishing thread has handed to the publisher."""
        self.source: PairSource | None = None
        self.publisher: Publisher | None = None
        # A reload that reopens the cameras replaces the source, which counts its pairs afresh:
        # published sequences go on from the last one, and its counts carry into the status.
        self._sequence_offset = 0
        self._next_sequence = 0
        """One past the last sequence published (offset included)."""
        self._renumber = False
        """The source was replaced: its first pair takes the next sequence."""
        self._retired_pairs = 0
        self._retired_dropped_pairs = 0
        self.locator = Locator(rig)
        self.extensions: list[PipelineExtension] = list(extensions or [])
        self.health = CalibrationHealth.for_rig(rig, self.locator.cameras)
        self.colour_watch = ColourWatch(rig, self.locator.cameras)
        self._watch_thread = WatchThread()

    # ------------------------------------------------------------------ control

    def start(self) -> None:
        """Bind the publisher, open the cameras and start the threads (errors raise here)."""
        self.publisher = self._publisher_factory(self.rig)
        self._publisher_rig = self.rig
        try:
            self.source = self._source_factory(self.rig)
            self.source.start()
        except BaseException:
            self.publisher.close()
            raise
        self._threads = [
            threading.Thread(target=self._guard, args=(self._process_loop,), name="trackerd-process", daemon=True),
            threading.Thread(target=self._guard, args=(self._publish_loop,), name="trackerd-publish", daemon=True),
        ]
        for thread in self._threads:
            thread.start()
        self._watch_thread.start()

    def stop(self, timeout_s: float = 1.0) -> None:
        """Stop every thread, release the cameras and close the publisher; idempotent."""
        self._notifier.stopping("stopping")
        self._stop.set()
        deadline = time.monotonic() + timeout_s
        for thread in self._threads:
            thread.join(max(0.0, deadline - time.monotonic()))
        self._watch_thread.stop(max(0.0, deadline - time.monotonic()))
        if self.source is not None:
            self.source.stop()
        if self.publisher is not None:
            self.publisher.close()
        for extension in self.extensions:
            extension.close()
        self._done.set()

    def request_reload(self, rig: RigConfig) -> None:
        """Apply a new, already validated configuration between two pairs."""
        with self._pending_lock:
            self._pending_rig = rig
        self._notifier.reloading()

    def wait(self, timeout_s: float | None = None) -> bool:
        """Block until a thread fails or stop() is called; True if stopping."""
        return self._stop.wait(timeout_s)

    def start_trace(self) -> None:
        """Keep a :class:`PairTrace` of every pair published from now on (needs ``account_threads``).

        For benchmarks: the trace grows by one small record a pair until the pipeline stops."""
        if not self._account_threads:
            raise ValueError("a pair trace needs Pipeline(account_threads=True)")
        self._trace = []

    def trace(self) -> list[PairTrace]:
        """The pairs traced since :meth:`start_trace`."""
        return list(self._trace or [])

    @property
    def failure(self) -> str | None:
        """The traceback of a thread that crashed (the daemon then exits non-zero), else None."""
        return self._failure_text

    @property
    def state(self) -> str:
        return self._state

    @property
    def backlog(self) -> int:
        """Pairs processed whose messages are neither published nor dropped yet (0: nothing in flight).

        A finite source (a replay) is done once it has delivered its last pair and this is 0."""
        return self.pairs_processed - self.pairs_published - self._queue.dropped

    def _guard(self, loop: Callable[[], None]) -> None:
        try:
            loop()
        except BaseException as err:  # noqa: BLE001 - any crash must stop the daemon, loudly
            self._failure = err
            self._failure_text = traceback.format_exc()
            log.error("pipeline thread %s crashed:\n%s", threading.current_thread().name, self._failure_text)
            self._stop.set()

    # ------------------------------------------------------------------ processing

    def _process_loop(self) -> None:
        try:
            self._process_until_stopped()
            # The extensions' last words (a session still entered ends with a leave), queued
            # ahead of the final status so subscribers hear them before the socket closes.
            last = [message for extension in self.extensions for message in extension.finish()]
            if last:
                now = time.monotonic_ns()
                self._queue.put(_Processed(last, now, now + self.clock_offset_ns, final=True))
        finally:
            self._processing_done.set()

    def _thread_clock(self) -> contextlib.AbstractContextManager[ThreadClock | None]:
        """The calling thread's clock with ``account_threads``, else nothing (closed on exit)."""
        return ThreadClock() if self._account_threads else contextlib.nullcontext()

    def _process_until_stopped(self) -> None:
        with self._thread_clock() as clock:
            self._process_pairs(clock)

    def _process_pairs(self, clock: ThreadClock | None) -> None:
        while not self._stop.is_set():
            self._apply_pending_reload()
            assert self.source is not None
            pair = self.source.next_pair(PAIR_WAIT_S)
            if pair is None:
                if self._some_camera_recovering():
                    # A power-cycled camera is not a stalled pipeline: keep systemd's watchdog fed.
                    self._notifier.progress()
                continue
            if self._renumber:
                # Whether a source counts from 0 or 1 is its own affair: numbering goes on.
                self._renumber = False
                self._sequence_offset = self._next_sequence - pair.sequence
            if self._sequence_offset:
                pair = dataclasses.replace(pair, sequence=pair.sequence + self._sequence_offset)
            self._next_sequence = pair.sequence + 1
            before = clock.now() if clock is not None else None
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
            fix = self.locator.locate(pair.images)
            capture = pair.timestamp_ns + self.clock_offset_ns
            messages = messages_from_fix(fix, self.locator, sequence=pair.sequence, capture_ns=capture)
            for extension in self.extensions:
                messages = extension.on_fix(fix, pair, messages)
            self._fixes[fix.status] = self._fixes.get(fix.status, 0) + 1
            if fix.status == "not_found":
                # Tracking windows are stale once the pointer is gone.
                self.locator.reset()
            stage = {"detect": fix.timings_ns.get("detect_ns", 0),
                     "triangulate": fix.timings_ns.get("triangulate_ns", 0)}
            processing_off = off_cpu(before, clock.now()) if clock is not None and before is not None else None
            # Every fix with a line, rejected ones included: a bumped camera shows as fixes rejected
            # for their ray gap, which is what the health record is for (trackerd.calibration.health).
            measure = fix.line is not None and self.pairs_processed % HEALTH_EVERY == 0
            health = (self.health, fix) if measure else None
            watch = self.colour_watch
            if watch.due(fix):
                self._watch_thread.offer(watch, pair.images, tuple(frame.pixel_format for frame in pair.frames), fix)
            tap = self.tap
            if tap is not None and tap.frame_wanted:
                tap.offer(pair, fix, self.locator)
            self._queue.put(_Processed(messages, received, capture, stage, started_ns=start,
                                       queued_ns=time.monotonic_ns() if clock is not None else 0,
                                       processing_off=processing_off,
                                       health=health))
            self.processing_cpu.add(time.thread_time_ns() - start_cpu)
            self.pairs_processed += 1
            self._notifier.progress()

    def _apply_pending_reload(self) -> None:
        with self._pending_lock:
            rig, self._pending_rig = self._pending_rig, None
        if rig is None:
            return
        old = self.rig
        self._reloading = True
        try:
            locator = Locator(rig)
            if _source_settings(rig) != _source_settings(old):
                log.info("reload: camera settings changed, reopening the cameras")
                self._reopen_source(rig, old)
        except Exception as err:  # noqa: BLE001 - a bad reload keeps the old configuration
            log.error("reload failed, keeping the previous configuration: %s", err)
            self._notifier.ready("running (reload failed: previous configuration kept)")
            return
        finally:
            self._reloading = False
        self.locator = locator
        for extension in self.extensions:
            extension.reload(rig)
        if rig.cameras != old.cameras or rig.wall != old.wall:
            # A new calibration starts a new health record.
            self.health = CalibrationHealth.for_rig(rig, locator.cameras)
        if (rig.cameras, rig.pointer, rig.detector, rig.pointer_colours) != (
                old.cameras, old.pointer, old.detector, old.pointer_colours):
            self.colour_watch = ColourWatch(rig, locator.cameras)
        self.rig = rig
        with self._pending_lock:
            # The publishing thread rebinds for changed outputs; unchanged ones still re-read the
            # CURVE client keys, so adding or revoking a subscriber is a reload, not a restart.
            self._pending_outputs = rig
        log.info("reload: configuration applied")
        self._notifier.ready("running (configuration reloaded)")

    def _reopen_source(self, rig: RigConfig, old: RigConfig) -> None:
        """Replace the source by one for ``rig``; if it cannot start, reopen the old one and raise.

        The cameras cannot be opened twice (a GigE Vision camera has one controller), so the old
        source stops first; a setting the camera refuses must not leave the daemon without it.
        """
        assert self.source is not None
        start = time.monotonic()
        self.source.stop()
        stopped = self.source.status()
        # Each step can take seconds (a camera's control is released and taken again): the
        # watchdog hears that a reload is progressing, not stalled.
        self._notifier.progress()
        try:
            source = self._source_factory(rig)
            source.start()
        except BaseException:
            self._notifier.progress()
            log.info("reload: reopening the cameras with the previous settings")
            self._replace_source(self._source_factory(old), stopped)
            self.source.start()
            log.info("reload: cameras reopened with the previous settings after %.1f s", time.monotonic() - start)
            raise
        self._replace_source(source, stopped)
        log.info("reload: cameras reopened after %.1f s", time.monotonic() - start)

    def _replace_source(self, source: PairSource, stopped: SourceStatus) -> None:
        """Put ``source`` in place of the stopped one, whose last status is ``stopped``: the
        new one's pairs are numbered on from the last pair published, and what the old one counted
        stays in the status figures (both changed together, so no status counts a source twice)."""
        self._retired_pairs += stopped.pairs
        self._retired_dropped_pairs += stopped.dropped_pairs
        self.source = source
        self._renumber = True

    def _some_camera_recovering(self) -> bool:
        assert self.source is not None
        return any(cam.state in ("lost", "reconnecting") for cam in self.source.status().cameras)

    # ------------------------------------------------------------------ publishing

    def _publish_loop(self) -> None:
        with self._thread_clock() as clock:
            self._publish_until_stopped(clock)

    def _publish_until_stopped(self, clock: ThreadClock | None) -> None:
        next_status = 0.0
        next_poll = 0.0
        last_states: tuple[str, ...] = ()
        while True:
            now = time.monotonic()
            if now >= next_poll:
                next_poll = now + STATE_POLL_S
                status = self.source.status() if self.source is not None else None
                states = tuple(c.state for c in status.cameras) if status is not None else ()
                states += ("reloading",) if self._reloading else ()
                if states != last_states or now >= next_status:
                    last_states = states
                    # Read each time: a reload may change it.
                    next_status = now + self._publisher_rig.outputs.zmq.status_interval_ms / 1000.0
                    self._send_status(status)
            if self._stop.is_set():
                # What the processing thread handed over before it stopped, its last words
                # included, goes out before the final status (which the publisher flushes).
                self._processing_done.wait(STOP_DRAIN_S)
                while (item := self._queue.get(0.0)) is not None:
                    self._publish_item(item, clock)
                break
            self._apply_pending_outputs()
            item = self._queue.get(min(PAIR_WAIT_S, max(0.0, next_poll - time.monotonic())))
            if item is not None:
                self._publish_item(item, clock)
        self._state = "stopping"
        self._detail = "stopping"
        self._send_status(self.source.status() if self.source is not None else None)

    def _publish_item(self, item: _Processed, clock: ThreadClock | None = None) -> None:
        assert self.publisher is not None
        before = clock.now() if clock is not None and self._trace is not None and not item.final else None
        start = time.monotonic_ns()
        for message in item.messages:
            self.publisher.publish(message)
        if item.final:
            return
        done = time.monotonic_ns()
        self.pairs_published += 1
        self.stages["publish"].add(done - start)
        for name in ("detect", "triangulate"):
            self.stages[name].add(item.stage_ns[name])
        self.processing.add(done - item.received_ns)
        self.latency.add(done + self.clock_offset_ns - item.capture_ns)
        trace = self._trace
        if before is not None and trace is not None and item.processing_off is not None:
            trace.append(PairTrace(
                received_ns=item.received_ns, latency_ns=done - item.received_ns,
                waiting_ns=item.started_ns - item.received_ns, processing=item.processing_off,
                handoff_ns=start - item.queued_ns, publishing=off_cpu(before, clock.now()),
            ))
        tap = self.tap
        if tap is not None and tap.messages_wanted:
            tap.on_messages(item.messages)
        if item.health is not None:
            # The messages are sent: the time to the next pair is idle anyway.
            record, fix = item.health
            record.add_fix(fix)
            if tap is not None:
                tap.on_fix_measured(fix)

    def _apply_pending_outputs(self) -> None:
        """Rebind the publisher for changed outputs; on failure go back to the old endpoints."""
        with self._pending_lock:
            rig, self._pending_outputs = self._pending_outputs, None
        if rig is None:
            return
        assert self.publisher is not None
        if rig.outputs == self._publisher_rig.outputs:
            try:
                self.publisher.reload_authorized_keys(allow_empty=True)
            except Exception as err:  # noqa: BLE001 - keep the keys already loaded
                log.error("reload: cannot read the CURVE client keys again (%s); keeping the previous ones", err)
            else:
                if rig.outputs.zmq.curve_authorized_keys_dir is not None:
                    log.info("reload: CURVE client keys read again from %s", rig.outputs.zmq.curve_authorized_keys_dir)
            return
        self.publisher.close()
        try:
            self.publisher = self._publisher_factory(rig)
            self._publisher_rig = rig
            log.info("reload: publisher rebound to %s", ", ".join(rig.outputs.zmq.endpoints))
        except Exception as err:  # noqa: BLE001 - keep publishing on the old endpoints
            log.error("reload: cannot apply the new outputs (%s); keeping the previous ones", err)
            self.publisher = self._publisher_factory(self._publisher_rig)

    def _send_status(self, source_status: SourceStatus | None) -> None:
        assert self.publisher is not None
        message = self.build_status(source_status)
        self.publisher.publish_status(message)
        if self.tap is not None:
            self.tap.on_status(message, self._drained)
        line = f"{message.state}: " + ", ".join(f"{c.id} {c.state} {c.frame_rate_hz:.0f} fps" for c in message.cameras)
        self._notifier.status(line if message.detail is None else f"{line} ({message.detail})")
        if message.state == "running" and not self._ready_sent:
            self._ready_sent = True
            self._notifier.ready(line)

    def build_status(self, source_status: SourceStatus | None) -> StatusMessage:
        """The status message for now: camera states, pairing, latency since the last status, fixes."""
        cameras = source_status.cameras if source_status is not None else ()
        states = [c.state for c in cameras]
        if self._state != "stopping":
            if self._reloading:
                self._state, self._detail = "reloading", "applying a new configuration"
            elif states and all(s == "streaming" for s in states):
                self._state, self._detail = "running", None
            elif self._ready_sent:
                bad = [c.camera_id for c in cameras if c.state != "streaming"]
                self._state, self._detail = "degraded", f"camera {', '.join(bad)} not streaming"
            else:
                waiting = [c.camera_id for c in cameras if c.state != "streaming"]
                self._state, self._detail = "starting", f"waiting for {', '.join(waiting) or 'cameras'}"
        health = self.health  # once: a reload may replace it meanwhile
        colours = self.colour_watch.to_json()
        latency = self.latency.drain()
        processing = self.processing.drain()
        stages = {name: window.drain() for name, window in self.stages.items()}
        self._drained = {"latency": latency, "processing": processing, **stages}
        self._status_sequence += 1
        now = time.monotonic_ns()
        pairing = PairingPart(pair_rate_hz=0.0)
        if source_status is not None:
            pairing = PairingPart(
                pair_rate_hz=source_status.pair_rate_hz,
                pairs=source_status.pairs + self._retired_pairs,
                dropped_frames=dict(source_status.dropped_frames),
                dropped_pairs=source_status.dropped_pairs + self._retired_dropped_pairs + self._queue.dropped,
                skew_p50_us=source_status.skew_p50_us,
                skew_p99_us=source_status.skew_p99_us, mode=source_status.pairing,
            )
        return StatusMessage(
            sequence=self._status_sequence,
            capture_ns=now + self.clock_offset_ns,
            state=self._state,
            version=trackerd.__version__,
            uptime_s=(now - self._started_ns) / 1e9,
            rig=self.rig.name,
            cameras=tuple(
                CameraStatusPart(
                    id=c.camera_id, state=c.state, frame_rate_hz=c.frame_rate_hz, frames=c.frames,
                    dropped=dict(c.failed_buffers), losses=c.losses, reconnects=c.reconnects,
                    last_error=c.last_error, stream=dict(c.stream), ptp_state=c.ptp_state,
                )
                for c in cameras
            ),
            pairing=pairing,
            latency=LatencyPart(samples=int(latency.size), **percentiles_ms(latency)),
            processing=LatencyPart(samples=int(processing.size), **percentiles_ms(processing)),
            stages={
                name: LatencyPart(samples=int(values.size), **percentiles_ms(values))
                for name, values in stages.items()
            },
            calibration=CalibrationHealthPart.model_validate(health.to_json()) if health.total else None,
            fixes=dict(self._fixes),
            detail=self._detail,
            colours=ColourWatchPart.model_validate(colours) if colours is not None else None,
            **{name: figures for name, figures in ((e.name, e.status()) for e in self.extensions) if figures},
        )


def _source_settings(rig: RigConfig) -> object:
    """What a change of which requires reopening the cameras (not their calibration)."""
    cameras = tuple(c.model_copy(update={"intrinsics": None, "extrinsics": None}) for c in rig.cameras)
    return (cameras, rig.acquisition)
