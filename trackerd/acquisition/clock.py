"""Clocks and counters of camera frames: frame-id unwrapping and device-to-host time mapping.

Pure bookkeeping on integers (nanoseconds, counters); no threads of its own.
:class:`DeviceClock` is the only class that may be shared between camera
threads (in PTP mode), so it carries its own lock.
"""

from __future__ import annotations

import threading
import time
from collections import deque

GEV_BLOCK_ID_MAX = 0xFFFF
"""GigE Vision 1.x block (frame) ids are 16 bits and wrap from 65535 to 1, skipping 0."""


class FrameIdUnwrapper:
    """Turns a camera's wrapping frame counter into one that keeps increasing.

    GigE Vision 1.x ids are 16-bit and skip 0 when they wrap (65535 is followed
    by 1); a camera that sends 0 is taken to count through it. Extended (64-bit)
    ids, recognised by any value above 65535, never wrap.
    """

    def __init__(self) -> None:
        self._last: int | None = None
        self._value = 0
        self._wide = False
        self._uses_zero = False

    def __call__(self, raw_id: int) -> int:
        """The unwrapped id of the next frame's raw id."""
        if self._last is None:
            self._last, self._value = raw_id, raw_id
            self._wide = raw_id > GEV_BLOCK_ID_MAX
            return raw_id
        if raw_id > GEV_BLOCK_ID_MAX:
            self._wide = True
        if self._wide:
            delta = raw_id - self._last
        else:
            if raw_id == 0:
                self._uses_zero = True
            delta = (raw_id - self._last) & GEV_BLOCK_ID_MAX
            if raw_id < self._last and not self._uses_zero:
                delta -= 1
            if delta > GEV_BLOCK_ID_MAX // 2:  # an older frame than the last one
                delta -= GEV_BLOCK_ID_MAX
        self._last = raw_id
        self._value += delta
        return self._value


class DeviceClock:
    """Maps device timestamps to the host's monotonic clock: ``host ~ device + offset``.

    Each frame gives one observation ``host_received - device_exposed``: the true
    offset plus the frame's transfer delay, which is never negative. The smallest
    observation over the last ``window_ns`` therefore tracks the offset plus the
    minimum transfer delay, free of jitter, and follows slow drift between the
    clocks. A device clock that steps backwards (a camera reset, a PTP step) is
    noticed after ``step_frames`` consecutive observations far above the estimate,
    and the estimate restarts.
    """

    def __init__(self, window_ns: int, step_ns: int = 100_000_000, step_frames: int = 3) -> None:
        self.window_ns = int(window_ns)
        self.step_ns = int(step_ns)
        self.step_frames = step_frames
        self._minima: deque[tuple[int, int]] = deque()  # (host_ns, delay_ns), delays increasing
        self._above = 0
        self._lock = threading.Lock()
        self.observations = 0
        """Frames observed since the last reset (the estimate settles over the first few)."""

    def observe(self, device_ns: int, host_ns: int) -> None:
        """Record one frame's device timestamp and host arrival time."""
        delay = host_ns - device_ns
        with self._lock:
            self.observations += 1
            minima = self._minima
            if minima and delay > minima[0][1] + self.step_ns:
                self._above += 1
                if self._above < self.step_frames:
                    return
                minima.clear()
            self._above = 0
            while minima and minima[-1][1] >= delay:
                minima.pop()
            minima.append((host_ns, delay))
            while minima[0][0] < host_ns - self.window_ns:
                minima.popleft()

    @property
    def offset_ns(self) -> int | None:
        """Current estimate of host minus device time, None before the first observation."""
        with self._lock:
            return self._minima[0][1] if self._minima else None

    def to_host_ns(self, device_ns: int, host_ns: int) -> int:
        """Estimated capture time on the host clock; the arrival time when nothing is known yet."""
        offset = self.offset_ns
        if offset is None or device_ns == 0:
            return host_ns
        return device_ns + offset

    def reset(self) -> None:
        with self._lock:
            self._minima.clear()
            self._above = 0
            self.observations = 0


def realtime_to_monotonic_ns(realtime_ns: int) -> int:
    """A CLOCK_REALTIME instant (Aravis's buffer system timestamps) on the monotonic clock.

    The offset between the two clocks is sampled now, so this is exact for recent
    instants even across an NTP step.
    """
    offset = time.time_ns() - time.monotonic_ns()
    return realtime_ns - offset


class NonDecreasing:
    """Publishes timestamps that never go backwards: each is at least the previous one."""

    def __init__(self) -> None:
        self._last: int | None = None

    def __call__(self, value_ns: int) -> int:
        if self._last is not None and value_ns < self._last:
            value_ns = self._last
        self._last = value_ns
        return value_ns
