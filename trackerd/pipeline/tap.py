"""What the daemon hands the operator's console, at no cost when nobody watches.

The console (trackerd/console) runs on threads of its own. The pipeline's threads
only ever check a flag, and when it is set hand over a reference without waiting:

* the processing thread: when :attr:`ConsoleTap.frame_wanted` is set (the console
  sets it a few times a second while a page is open, or for a snapshot), it puts
  the newest pair, its fix and the locator in a one-slot mailbox and clears the
  flag; the console demosaics, scales and encodes it on its own thread;
* the publishing thread: when :attr:`ConsoleTap.messages_wanted` is set (a page
  is open), it appends the pair's hit and pointer messages to a bounded deque the
  console drains (the oldest fall out: a slow page never holds anything up); every
  status message, about once a second, is kept for the page and ``/metrics``,
  and the latency figures it drained are added to cumulative histograms;
* a live calibration check (``trackerd ctl check``, the console's button) is a
  health record of its own, fed the fixes the publishing thread already measures
  for the daemon's record (every fourth pair) while the check runs.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

LATENCY_BUCKETS_MS: tuple[float, ...] = (
    0.5,
    1.0,
    1.5,
    2.0,
    3.0,
    4.0,
    6.0,
    8.0,
    12.0,
    16.0,
    25.0,
    50.0,
    100.0,
    250.0,
    1000.0,
)
"""Upper bounds of the latency histograms' buckets (Prometheus ``le``; +Inf is implied)."""
MESSAGES_KEPT = 1024
"""Hit and pointer messages kept for the console between two of its reads (about 8 s at 60 pairs/s)."""


class LatencyHistogram:
    """Cumulative counts of latencies in :data:`LATENCY_BUCKETS_MS`, and their sum."""

    def __init__(self) -> None:
        self.counts = np.zeros(len(LATENCY_BUCKETS_MS) + 1, dtype=np.int64)
        """Per bucket, not cumulative; the last is beyond the largest bound."""
        self.sum_ms = 0.0

    def add(self, values_ns: NDArray[np.int64]) -> None:
        if values_ns.size == 0:
            return
        values_ms = np.asarray(values_ns, dtype=np.float64) / 1e6
        index = np.searchsorted(np.asarray(LATENCY_BUCKETS_MS), values_ms, side="left")
        self.counts += np.bincount(index, minlength=self.counts.size)
        self.sum_ms += float(values_ms.sum())


class ConsoleTap:
    """The mailbox and the figures between the pipeline and the console (see the module's docstring)."""

    def __init__(self) -> None:
        self.frame_wanted = False
        """Set by the console; the processing thread then offers its next pair and clears it."""
        self.messages_wanted = False
        """Set by the console while a page is open; the publishing thread then hands over messages."""
        self.messages: deque[Any] = deque(maxlen=MESSAGES_KEPT)
        self.offered = 0
        """Pairs handed over so far (for the figures and tests: 0 while nobody has watched)."""
        self._slot: tuple[Any, Any, Any] | None = None
        self._wake = threading.Condition()
        self._lock = threading.Lock()
        self._status: Any = None
        self.histograms: dict[str, LatencyHistogram] = {}
        self.check: Any = None
        """A live calibration check's health record (trackerd.calibration.health), or None; read
        and fed under :attr:`check_lock` (the record is not thread-safe)."""
        self.check_lock = threading.Lock()

    # ------------------------------------------------------------------ processing thread

    def offer(self, pair: Any, fix: Any, locator: Any) -> None:
        """The newest pair, its fix and the locator that made it (never waits)."""
        self.frame_wanted = False
        self.offered += 1
        with self._wake:
            self._slot = (pair, fix, locator)
            self._wake.notify()

    # ------------------------------------------------------------------ publishing thread

    def on_messages(self, messages: list[Any]) -> None:
        self.messages.extend(m for m in messages if m.topic in ("hit", "pointer"))

    def on_fix_measured(self, fix: Any) -> None:
        """A fix the daemon's health record was given: a running check gets it too."""
        if self.check is not None:
            with self.check_lock:
                if self.check is not None:
                    self.check.add_fix(fix)

    def on_status(self, status: Any, drained_ns: Mapping[str, NDArray[np.int64]]) -> None:
        """Each status message, with the latencies (ns) it summarised, by figure name."""
        with self._lock:
            self._status = status
            for name, values in drained_ns.items():
                self.histograms.setdefault(name, LatencyHistogram()).add(values)

    # ------------------------------------------------------------------ console

    def take(self, timeout_s: float) -> tuple[Any, Any, Any] | None:
        """The pair offered since the last take, waiting up to ``timeout_s``; None if none came."""
        with self._wake:
            self._wake.wait_for(lambda: self._slot is not None, timeout_s)
            slot, self._slot = self._slot, None
            return slot

    def wake(self) -> None:
        """Wake a :meth:`take` (the console is stopping)."""
        with self._wake:
            self._wake.notify_all()

    @property
    def status(self) -> Any:
        """The last status message (None before the first)."""
        with self._lock:
            return self._status

    def histogram_snapshot(self) -> dict[str, tuple[NDArray[np.int64], float]]:
        """Per figure, (counts per bucket, sum in ms), copied."""
        with self._lock:
            return {name: (h.counts.copy(), h.sum_ms) for name, h in self.histograms.items()}
