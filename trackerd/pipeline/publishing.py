"""The publishing stage: each pair's messages out over ZeroMQ, and the status about once a second.

It owns the publisher (ZeroMQ sockets are never shared between threads): it
binds it, sends the messages of each pair's result the processing thread hands over
(converted once, by trackerd.publish.from_fix, as it was handed over), sends a status
on a schedule and at once on any change of the cameras' states, and rebinds it
when a reload changes the outputs (the second phase, trackerd.pipeline.reload).
Once a pair's messages are sent it measures calibration health from the pair's
fix when the processing thread asked for it, so the measurement is in no pair's
latency; it alone writes the health records. It never touches the source, the
locator or the extensions beyond reading their status.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping

import numpy as np
from numpy.typing import NDArray

from trackerd.acquisition.status import SourceStatus
from trackerd.config.models import RigConfig
from trackerd.pipeline.handover import Processed, StageLinks
from trackerd.pipeline.observer import PairTimes
from trackerd.pipeline.processing import PAIR_WAIT_S
from trackerd.pipeline.state import DaemonStateMachine
from trackerd.publish import Publisher, StatusMessage

log = logging.getLogger(__name__)

STATE_POLL_S = 0.2
"""How often the publisher looks for a change of camera state (a change sends a status at once)."""
STOP_DRAIN_S = 0.5
"""How long, at stop, the publisher waits for the processing thread's last messages."""

StatusFor = Callable[[SourceStatus | None], tuple[StatusMessage, Mapping[str, NDArray[np.int64]]]]
"""Builds the status for a source status: the message, and the latencies (ns) it summarised."""


class PublishingStage:
    """The publishing thread's loop and the publisher it owns (see the module's docstring)."""

    def __init__(
        self,
        rig: RigConfig,
        publisher_factory: Callable[[RigConfig], Publisher],
        links: StageLinks,
        state: DaemonStateMachine,
        *,
        source_status: Callable[[], SourceStatus | None],
        status_for: StatusFor,
    ) -> None:
        self._rig = rig
        """The rig whose outputs the publisher is bound to."""
        self._factory = publisher_factory
        self._links = links
        self._state = state
        self._source_status = source_status
        self._status_for = status_for
        self.publisher: Publisher | None = None

    def open(self) -> None:
        """Bind the publisher (errors raise here)."""
        self.publisher = self._factory(self._rig)

    def close(self) -> None:
        if self.publisher is not None:
            self.publisher.close()

    def run(self, stop: threading.Event, processing_done: threading.Event) -> None:
        """The thread's body: messages and statuses until ``stop``, then what is left and the last status."""
        observer = self._links.observer
        if observer is not None:
            observer.thread_started()
        try:
            self._publish_until(stop, processing_done)
        finally:
            if observer is not None:
                observer.thread_stopped()

    def _publish_until(self, stop: threading.Event, processing_done: threading.Event) -> None:
        next_status = 0.0
        next_poll = 0.0
        last_states: tuple[str, ...] = ()
        while True:
            now = time.monotonic()
            if now >= next_poll:
                next_poll = now + STATE_POLL_S
                status = self._source_status()
                states: tuple[str, ...] = tuple(c.state for c in status.cameras) if status is not None else ()
                states += ("reloading",) if self._links.reload.in_progress else ()
                if states != last_states or now >= next_status:
                    last_states = states
                    # Read each time: a reload may change it.
                    next_status = now + self._rig.outputs.zmq.status_interval_ms / 1000.0
                    self._send_status(status)
            if stop.is_set():
                # What the processing thread handed over before it stopped, its last words
                # included, goes out before the final status (which the publisher flushes).
                processing_done.wait(STOP_DRAIN_S)
                while (item := self._links.queue.get(0.0)) is not None:
                    self._publish_item(item)
                break
            self._apply_outputs()
            item = self._links.queue.get(min(PAIR_WAIT_S, max(0.0, next_poll - time.monotonic())))
            if item is not None:
                self._publish_item(item)
        self._state.stop()
        self._send_status(self._source_status())

    def _publish_item(self, item: Processed) -> None:
        assert self.publisher is not None
        links = self._links
        observer = links.observer
        sending_mark = observer.mark() if observer is not None and not item.pairless else None
        start = time.monotonic_ns()
        messages = item.messages()
        for message in messages:
            self.publisher.publish(message)
        item.sent.set()
        if item.pairless:
            return
        done = time.monotonic_ns()
        links.figures.add_published(
            item.stage_ns,
            publish_ns=done - start,
            processing_ns=done - item.received_ns,
            latency_ns=done + links.clock_offset_ns - item.capture_ns,
        )
        if observer is not None and item.marks is not None:
            times = PairTimes(
                received_ns=item.received_ns,
                taken_ns=item.taken_ns,
                queued_ns=item.queued_ns,
                sending_ns=start,
                sent_ns=done,
            )
            observer.published(times, item.marks, sending_mark)
        tap = links.tap
        if tap is not None and tap.messages_wanted:
            tap.on_messages(messages)
        if item.health is not None:
            # The messages are sent: the time to the next pair is idle anyway.
            record, fix = item.health
            record.add_fix(fix)
            if tap is not None:
                tap.on_fix_measured(fix)

    def _apply_outputs(self) -> None:
        """The second phase of a reload: rebind the publisher for changed outputs (on failure go back
        to the old endpoints), else read the CURVE client keys again."""
        rig = self._links.reload.take_outputs()
        if rig is None:
            return
        assert self.publisher is not None
        if rig.outputs == self._rig.outputs:
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
            self.publisher = self._factory(rig)
            self._rig = rig
            log.info("reload: publisher rebound to %s", ", ".join(rig.outputs.zmq.endpoints))
        except Exception as err:  # noqa: BLE001 - keep publishing on the old endpoints
            log.error("reload: cannot apply the new outputs (%s); keeping the previous ones", err)
            self.publisher = self._factory(self._rig)

    def _send_status(self, source_status: SourceStatus | None) -> None:
        assert self.publisher is not None
        message, drained = self._status_for(source_status)
        self.publisher.publish_status(message)
        if self._links.tap is not None:
            self._links.tap.on_status(message, drained)
        line = f"{message.state}: " + ", ".join(f"{c.id} {c.state} {c.frame_rate_hz:.0f} fps" for c in message.cameras)
        self._links.notifier.status(line if message.detail is None else f"{line} ({message.detail})")
        if self._state.announce_ready():
            self._links.notifier.ready(line)
