"""The software trigger of one camera connection, fired on its own thread at the shared schedule's ticks.

A dedicated thread does nothing but sleep until the next tick and fire, so a
trigger is late only by the operating system's and the interpreter's wake-up
latency, never by frame handling. There is one per camera connection: a
trigger command to a camera that has just died can hang for about 2.5 s
(Aravis's GVCP retries), and that thread is then left to finish on its own
while a fresh connection gets a fresh thread, so no other camera, and no
reconnection, waits for it.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from trackerd.acquisition.trigger import TickMap, TickSchedule, TriggerGate
from trackerd.errors import CameraError

POLL_S = 0.1
SENT_KEPT = 64
"""How many recent ticks' send times a connection keeps (frames answer within a few ticks)."""


class TriggerThread:
    """Fires ``fire()`` at every tick the gate allows, until stopped or a trigger fails.

    ``fire()`` may return when it sent the trigger (host monotonic ns), if it first waited for the
    camera; otherwise the tick's send time is taken just before it is called."""

    def __init__(
        self,
        index: int,
        name: str,
        schedule: TickSchedule,
        gate: TriggerGate,
        fire: Callable[[], int | None],
        max_outstanding: int,
        settle_ns: int = 0,
    ) -> None:
        self.index = index
        self.schedule = schedule
        self.gate = gate
        self._fire = fire
        self.ticks = TickMap(max_outstanding)
        """Which tick each frame of this connection answers."""
        self.settle_ns = settle_ns
        self.failure: str | None = None
        """Why a trigger failed (the thread then stops firing)."""
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"trigger-{name}", daemon=True)
        self._sent: dict[int, int] = {}
        self._sent_lock = threading.Lock()

    def sent_ns(self, tick: int) -> int | None:
        """When tick ``tick`` was sent to the camera (host monotonic clock), if it was (recently)."""
        with self._sent_lock:
            return self._sent.get(tick)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        """Stop firing (returns at once; a trigger command in progress finishes on its own)."""
        self._stop.set()
        self.gate.leave(self.index)

    def join(self, timeout_s: float) -> bool:
        if self._thread.ident is not None:
            self._thread.join(max(timeout_s, 0.0))
        return not self._thread.is_alive()

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

    def _run(self) -> None:
        # Let the connection settle before the first trigger: a frame the camera sends on
        # its own when acquisition starts (Aravis's simulated camera does) then arrives
        # before any trigger is fired, and cannot be taken for the answer to the first.
        if self._stop.wait(self.settle_ns / 1e9):
            return
        self.gate.join(self.index, self.ticks.ready)
        last: int | None = None
        tick: int | None = None
        while not self._stop.is_set():
            now = time.monotonic_ns()
            if tick is None:
                tick = self.schedule.next_tick(last, now)
            wait_s = (self.schedule.due_ns(tick) - now) / 1e9
            if wait_s > 0:
                self._stop.wait(min(wait_s, POLL_S))
                continue
            last, tick = tick, None
            if not self.gate.decide(last, self.index):
                continue
            # Recorded before firing: the frame may be handled before fire() even returns.
            self.ticks.fired(last)
            with self._sent_lock:
                self._sent[last] = time.monotonic_ns()
                if len(self._sent) > SENT_KEPT:
                    del self._sent[min(self._sent)]
            try:
                sent = self._fire()
                if sent is not None:  # the backend knows when the trigger itself went out
                    with self._sent_lock:
                        self._sent[last] = sent
            except CameraError as err:
                if not self._stop.is_set():
                    self.failure = str(err)
                self.stop()
