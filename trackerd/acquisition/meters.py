"""Small meters behind the status snapshot: event rates and recent skew percentiles."""

from __future__ import annotations

from collections import deque

import numpy as np


class RateMeter:
    """Events per second over the last ``window_ns``.

    The rate is 0.0 until the events in the window span at least ``min_span_ns`` up to now:
    two frames a few milliseconds apart right after a camera starts would otherwise read as
    hundreds per second.
    """

    def __init__(self, window_ns: int = 2_000_000_000, min_span_ns: int = 500_000_000) -> None:
        self.window_ns = window_ns
        self.min_span_ns = min_span_ns
        self._times: deque[int] = deque()

    def tick(self, now_ns: int) -> None:
        self._times.append(now_ns)
        self._trim(now_ns)

    def rate_hz(self, now_ns: int) -> float:
        self._trim(now_ns)
        times = self._times
        if len(times) < 2:
            return 0.0
        span = max(times[-1], now_ns) - times[0]
        if span < max(self.min_span_ns, 1):
            return 0.0
        # Count intervals up to "now", so a rate decays once events stop.
        return (len(times) - 1) * 1e9 / span

    def _trim(self, now_ns: int) -> None:
        while self._times and self._times[0] < now_ns - self.window_ns:
            self._times.popleft()


class SkewWindow:
    """The most recent ``size`` pair skews, for percentiles in the status."""

    def __init__(self, size: int = 2048) -> None:
        self._values: deque[int] = deque(maxlen=size)

    def add(self, skew_ns: int) -> None:
        self._values.append(skew_ns)

    def percentiles_us(self) -> tuple[float, float, float] | None:
        """(median, 99th percentile, max) in microseconds, None before the first pair."""
        if not self._values:
            return None
        values = np.fromiter(self._values, dtype=np.float64) / 1000.0
        p50, p99 = np.percentile(values, [50, 99])
        return float(p50), float(p99), float(values.max())
