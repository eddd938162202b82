"""The real-time pipeline: pairs in, pointer fixes out, published over ZeroMQ.

:class:`Pipeline` wires the stages together and runs their threads; each stage
owns one thing (docs/architecture.md, "The pipeline's stages"):

* processing (trackerd.pipeline.processing): takes the newest pairs from the
  source (trackerd.pipeline.sourceslot numbers them on across a reload that
  reopens the cameras), locates the pointer and hands the messages to the
  publisher through a bounded queue that drops its oldest item when full;
* publishing (trackerd.pipeline.publishing): owns the ZeroMQ publisher, sends
  the messages, a status about once a second and on every change of state, and
  measures calibration health from the fixes the processing thread marked;
* colour watch: every few seconds, the room's colours against the pointer's, on
  the newest located pair the processing thread hands it
  (trackerd.pipeline.colourwatch).

The status is built by a pure function from figures gathered at one moment
(trackerd.pipeline.status), with the daemon's state advanced by a small state
machine (trackerd.pipeline.state). A reload is applied in two phases, one per
thread (trackerd.pipeline.reload). Latency is measured, not guessed: per stage
(detect, triangulate, publish) and end to end, from the moment the last frame of
a pair arrived to the moment its messages were handed to ZeroMQ; a benchmark
that wants more installs an observer (trackerd.pipeline.observer). Signals are
not handled here: the CLI calls :meth:`Pipeline.stop` and :meth:`Pipeline.request_reload`.
"""

from __future__ import annotations

import logging
import threading
import time
import traceback
from collections.abc import Callable, Mapping, Sequence
from typing import Generic, TypeVar, cast

import numpy as np
from numpy.typing import NDArray

from trackerd.acquisition.source import PairSource
from trackerd.acquisition.status import SourceStatus
from trackerd.config.models import RigConfig
from trackerd.locator import Locator
from trackerd.pipeline.colourwatch import ColourWatch
from trackerd.pipeline.extensions import ExtensionContext, ExtensionKind, PipelineExtension
from trackerd.pipeline.figures import PipelineFigures
from trackerd.pipeline.handover import Processed, StageLinks
from trackerd.pipeline.observer import PairObserver
from trackerd.pipeline.processing import HEALTH_EVERY, ProcessingStage
from trackerd.pipeline.publishing import PublishingStage
from trackerd.pipeline.queues import DropOldestQueue
from trackerd.pipeline.reload import ReloadRequests
from trackerd.pipeline.sourceslot import SourceSlot
from trackerd.pipeline.state import DaemonStateMachine
from trackerd.pipeline.status import StatusFigures, status_message
from trackerd.pipeline.tap import ConsoleTap
from trackerd.publish import Publisher, StatusMessage
from trackerd.publish.messages import DaemonState
from trackerd.sdnotify import SdNotify

__all__ = ["HEALTH_EVERY", "Pipeline"]

log = logging.getLogger(__name__)
T = TypeVar("T")


class _ReadThrough(Generic[T]):
    """A read-only attribute of the pipeline that is one of its parts' (``part.name``), read at each access."""

    def __init__(self, part: str, name: str) -> None:
        self.part = part
        self.name = name

    def __get__(self, pipeline: object, owner: type | None = None) -> T:
        return cast(T, getattr(getattr(pipeline, self.part), self.name))  # typed by the declaration


class Pipeline:
    """Runs a pair source through the locator into a publisher until stopped.

    ``source_factory`` and ``publisher_factory`` build the parts from a rig, so a
    reloaded configuration can replace them; ``clock_offset_ns`` turns the
    monotonic clock into the epoch timestamps published (fixed at start, so
    published times never go backwards even if the wall clock is stepped);
    ``observer`` sees every pair through both threads (benchmarks only).
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
        extension_kinds: Sequence[ExtensionKind] = (),
        extension_context: ExtensionContext | None = None,
        tap: ConsoleTap | None = None,
        observer: PairObserver | None = None,
    ) -> None:
        self.tap = tap
        """The operator's console's view of the pipeline (trackerd.pipeline.tap), or None."""
        self._notifier = notifier or SdNotify({})
        self.clock_offset_ns = time.time_ns() - time.monotonic_ns() if clock_offset_ns is None else clock_offset_ns
        self.figures = PipelineFigures()
        """Counts and latency windows (trackerd.pipeline.figures): the status drains the latencies."""
        self._queue: DropOldestQueue[Processed] = DropOldestQueue(queue_length)
        self._reload = ReloadRequests()
        self._state = DaemonStateMachine()
        self._stop = threading.Event()
        self._failure_text: str | None = None
        self._threads: list[threading.Thread] = []
        self._started_ns = time.monotonic_ns()
        self._status_sequence = 0
        self._slot = SourceSlot(source_factory, self._notifier)
        links = StageLinks(self._queue, self.figures, self._reload, self._notifier, self.clock_offset_ns, tap, observer)
        self._processing = ProcessingStage(
            rig, self._slot, links, list(extensions or []), extension_kinds, extension_context
        )
        self._publishing = PublishingStage(
            rig, publisher_factory, links, self._state, source_status=self._slot.status, status_for=self._status_for
        )

    # ------------------------------------------------------------------ control

    def start(self) -> None:
        """Bind the publisher, open the cameras and start the threads (errors raise here)."""
        self._publishing.open()
        try:
            self._slot.start(self.rig)
        except BaseException:
            self._publishing.close()
            raise
        self._threads = [
            threading.Thread(
                target=self._guard, args=(self._processing.run, self._stop), name="trackerd-process", daemon=True
            ),
            threading.Thread(
                target=self._guard,
                args=(self._publishing.run, self._stop, self._processing.done),
                name="trackerd-publish",
                daemon=True,
            ),
        ]
        for thread in self._threads:
            thread.start()
        self._processing.watch_thread.start()

    def stop(self, timeout_s: float = 1.0) -> None:
        """Stop every thread, release the cameras and close the publisher; idempotent."""
        self._notifier.stopping("stopping")
        self._stop.set()
        deadline = time.monotonic() + timeout_s
        for thread in self._threads:
            thread.join(max(0.0, deadline - time.monotonic()))
        self._processing.watch_thread.stop(max(0.0, deadline - time.monotonic()))
        self._slot.stop()
        self._publishing.close()
        for extension in self.extensions:
            extension.close()

    def request_reload(self, rig: RigConfig) -> None:
        """Apply a new, already validated configuration between two pairs."""
        self._reload.request(rig)
        self._notifier.reloading()

    def wait(self, timeout_s: float | None = None) -> bool:
        """Block until a thread fails or stop() is called; True if stopping."""
        return self._stop.wait(timeout_s)

    def _guard(self, loop: Callable[..., None], *args: object) -> None:
        try:
            loop(*args)
        except BaseException:  # noqa: BLE001 - any crash must stop the daemon, loudly
            self._failure_text = traceback.format_exc()
            log.error("pipeline thread %s crashed:\n%s", threading.current_thread().name, self._failure_text)
            self._stop.set()

    # ------------------------------------------------------------------ what callers read

    @property
    def failure(self) -> str | None:
        """The traceback of a thread that crashed (the daemon then exits non-zero), else None."""
        return self._failure_text

    # What callers read of what a part owns, read through at each access (a reload replaces some).
    state = _ReadThrough[DaemonState]("_state", "state")
    reload_pending = _ReadThrough[bool]("_reload", "pending")
    """A requested configuration that the processing or the publishing thread has yet to take."""
    rig = _ReadThrough[RigConfig]("_processing", "rig")
    """The configuration in force (a reload replaces it)."""
    colour_watch = _ReadThrough[ColourWatch]("_processing", "colour_watch")
    extensions = _ReadThrough["list[PipelineExtension]"]("_processing", "extensions")
    """The extensions, in order; a reload that builds one replaces the list (never changes it in place), so a
    thread going through it sees the old list or the new one whole."""
    source = _ReadThrough["PairSource | None"]("_slot", "source")
    publisher = _ReadThrough["Publisher | None"]("_publishing", "publisher")
    pairs_processed = _ReadThrough[int]("figures", "pairs_processed")
    pairs_published = _ReadThrough[int]("figures", "pairs_published")
    """Pairs whose messages the publishing thread has handed to the publisher."""

    @property
    def locator(self) -> Locator:
        return self._processing.locator

    @locator.setter
    def locator(self, locator: Locator) -> None:
        """Before :meth:`start` only (a benchmark's own locator): the processing thread owns it."""
        self._processing.locator = locator

    @property
    def pairs_dropped_before_publishing(self) -> int:
        """Pairs whose messages the hand-over to the publishing thread dropped (it was full)."""
        return self._queue.dropped

    @property
    def backlog(self) -> int:
        """Pairs processed whose messages are neither published nor dropped yet (0: nothing in flight).

        A finite source (a replay) is done once it has delivered its last pair and this is 0."""
        return self.pairs_processed - self.pairs_published - self._queue.dropped

    # ------------------------------------------------------------------ status

    def build_status(self, source_status: SourceStatus | None) -> StatusMessage:
        """The status message for now: camera states, pairing, latency since the last status, fixes.

        Advances the daemon's state from the cameras' (the publishing thread calls it for every status)."""
        return self._status_for(source_status)[0]

    def _status_for(self, source_status: SourceStatus | None) -> tuple[StatusMessage, Mapping[str, NDArray[np.int64]]]:
        cameras = source_status.cameras if source_status is not None else ()
        state, detail = self._state.observe(
            [(c.camera_id, c.state) for c in cameras], reloading=self._reload.in_progress
        )
        health = self._processing.health  # once: a reload may replace it meanwhile
        colours = self.colour_watch.to_json()
        drained = self.figures.drain()
        self._status_sequence += 1
        now = time.monotonic_ns()
        figures = StatusFigures(
            sequence=self._status_sequence,
            capture_ns=now + self.clock_offset_ns,
            uptime_s=(now - self._started_ns) / 1e9,
            state=state,
            detail=detail,
            rig_name=self.rig.name,
            source=source_status,
            latency_ns=drained,
            retired_pairs=self._slot.retired_pairs,
            retired_dropped_pairs=self._slot.retired_dropped_pairs,
            queue_dropped_pairs=self._queue.dropped,
            calibration=health.to_json() if health.total else None,
            colours=colours,
            fixes=dict(self.figures.fixes),
            extensions={e.name: e.status() for e in self.extensions},
        )
        return status_message(figures), drained
