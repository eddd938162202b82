"""The software trigger of one camera, fired on its own thread at the shared schedule's ticks.

A dedicated thread does nothing but sleep until the next tick and fire, so a
trigger is late only by the operating system's and the interpreter's wake-up
latency, never by frame handling. Each camera has its own, so a camera whose
trigger command hangs (Aravis waits about 2.5 s for a dead camera's
acknowledgement) holds up no other camera.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from trackerd.acquisition.trigger import TickMap, TickSchedule, TriggerGate
from trackerd.errors import CameraError

POLL_S = 0.1


class TriggerThread:
    """Fires ``fire()`` at every tick the gate allows while armed; reports a failed trigger."""

    def __init__(
        self,
        index: int,
        name: str,
        schedule: TickSchedule,
        gate: TriggerGate,
        stop: threading.Event,
    ) -> None:
        self.index = index
        self.schedule = schedule
        self.gate = gate
        self._stop = stop
        self._lock = threading.Lock()
        self._fire: Callable[[], None] | None = None
        self._ticks: TickMap | None = None
        self.failure: str | None = None
        """Why the last armed connection's trigger failed (the camera is then disarmed)."""
        self._thread = threading.Thread(target=self._run, name=f"trigger-{name}", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def join(self, timeout_s: float) -> bool:
        self._thread.join(max(timeout_s, 0.0))
        return not self._thread.is_alive()

    def arm(self, fire: Callable[[], None], max_outstanding: int) -> TickMap:
        """Start firing for a new connection; returns the tick map its frames are to be read with."""
        ticks = TickMap(max_outstanding)
        with self._lock:
            self._fire, self._ticks, self.failure = fire, ticks, None
        self.gate.join(self.index, ticks.ready)
        return ticks

    def disarm(self) -> None:
        self.gate.leave(self.index)
        with self._lock:
            self._fire, self._ticks = None, None

    def _run(self) -> None:
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
            with self._lock:
                fire, ticks = self._fire, self._ticks
            if fire is None or ticks is None:
                continue
            if not self.gate.decide(last, self.index):
                continue
            # Recorded before firing: the frame may be handled before fire() even returns.
            ticks.fired(last)
            try:
                fire()
            except CameraError as err:
                with self._lock:
                    if self._ticks is ticks:
                        self.failure = str(err)
                self.disarm()
