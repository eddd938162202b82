"""Rolling figures the pipeline keeps so latency is visible, not guessed."""

from __future__ import annotations

import threading
from collections import deque

import numpy as np


class Window:
    """The last ``size`` samples of a quantity (nanoseconds), with percentiles on demand; thread-safe."""

    def __init__(self, size: int = 4096) -> None:
        self._values: deque[int] = deque(maxlen=size)
        self._lock = threading.Lock()
        self.total = 0
        """Samples added since creation."""
        self._recording: list[int] | None = None

    def add(self, value_ns: int) -> None:
        with self._lock:
            self._values.append(value_ns)
            self.total += 1
            if self._recording is not None:
                self._recording.append(value_ns)

    def record(self) -> None:
        """Also keep every sample from now on, whatever drains the window (for benchmarks)."""
        with self._lock:
            self._recording = []

    def recorded(self) -> np.ndarray:
        """Every sample since :meth:`record`, in ns."""
        with self._lock:
            return np.asarray(self._recording or [], dtype=np.int64)

    def drain(self) -> np.ndarray:
        """The samples so far, in ns, and forget them (for figures per status period)."""
        with self._lock:
            values = np.fromiter(self._values, dtype=np.int64, count=len(self._values))
            self._values.clear()
        return values

    def snapshot(self) -> np.ndarray:
        with self._lock:
            return np.fromiter(self._values, dtype=np.int64, count=len(self._values))


def percentiles_ms(values_ns: np.ndarray, quantiles: tuple[float, ...] = (50, 90, 99)) -> dict[str, float | None]:
    """{'p50_ms': ..., 'p90_ms': ..., 'p99_ms': ..., 'max_ms': ...}; None for an empty sample."""
    keys = [f"p{q:g}_ms" for q in quantiles] + ["max_ms"]
    if values_ns.size == 0:
        return dict.fromkeys(keys)
    qs = np.percentile(values_ns, quantiles) / 1e6
    out: dict[str, float | None] = {k: round(float(v), 4) for k, v in zip(keys, qs, strict=False)}
    out["max_ms"] = round(float(values_ns.max()) / 1e6, 4)
    return out
