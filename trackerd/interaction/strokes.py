"""Cutting the wall hit's trajectory into strokes: movements between two pauses.

A gesture is drawn as one movement: the hit is still, moves (a swipe, a
circle), and is still again. The segmenter watches the (smoothed) hit's speed:

* a stroke **begins** when the speed rises above ``start_speed_m_s``; it takes
  in the samples since the hit was last slower than ``stop_speed_m_s``, so the
  start of the movement is not cut off;
* it **ends** when the speed has stayed below ``stop_speed_m_s`` for
  ``pause_ms`` (the pause itself is not part of the stroke), or when the
  pointer is lost or leaves;
* a stroke longer than ``max_stroke_ms`` is abandoned (the pointer is being
  moved about, not gesturing), and no new stroke begins until the next pause.

Speed is measured over about ``SPEED_WINDOW_MS`` of samples, so a single noisy
sample neither starts nor ends a stroke. Times are capture times in ns.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.config.interaction import GesturesConfig
from trackerd.interaction.recognizer import path_length

Array = NDArray[np.float64]

SPEED_WINDOW_MS = 40.0
PRE_ROLL_MS = 250.0
"""How far back a stroke may reach for its slow start."""


@dataclass(frozen=True)
class Stroke:
    """One movement of the hit: capture times (N,) in ns and wall positions (N, 2) in metres."""

    times_ns: NDArray[np.int64]
    points_m: Array

    @property
    def start_ns(self) -> int:
        return int(self.times_ns[0])

    @property
    def end_ns(self) -> int:
        return int(self.times_ns[-1])

    @property
    def path_m(self) -> float:
        return path_length(self.points_m)


class StrokeSegmenter:
    """Feeds on hit samples one at a time; returns a finished stroke when one ends."""

    def __init__(self, config: GesturesConfig) -> None:
        self.config = config
        self._recent: deque[tuple[int, float, float]] = deque()
        self._stroke: list[tuple[int, float, float]] | None = None
        self._slow_since_ns: int | None = None
        self._abandoned = False

    def reset(self) -> None:
        """Forget everything (the pointer was lost): a stroke in progress is dropped."""
        self._recent.clear()
        self._stroke = None
        self._slow_since_ns = None
        self._abandoned = False

    @property
    def in_stroke(self) -> bool:
        return self._stroke is not None

    def end(self) -> Stroke | None:
        """The pointer is gone: the stroke in progress ends here (None if there is none or it is too short)."""
        stroke = self._finish(self._stroke) if self._stroke is not None else None
        self.reset()
        return stroke

    def add(self, time_ns: int, position_m: Array) -> Stroke | None:
        """One hit sample; returns the stroke that this sample ends, if any."""
        cfg = self.config
        sample = (int(time_ns), float(position_m[0]), float(position_m[1]))
        self._recent.append(sample)
        while self._recent and sample[0] - self._recent[0][0] > PRE_ROLL_MS * 1e6:
            self._recent.popleft()
        speed = self._speed()
        slow = speed < cfg.stop_speed_m_s
        if slow:
            if self._slow_since_ns is None:
                self._slow_since_ns = sample[0]
        else:
            self._slow_since_ns = None
        paused = self._slow_since_ns is not None and sample[0] - self._slow_since_ns >= cfg.pause_ms * 1e6

        if self._abandoned:
            if paused:
                self._abandoned = False
            return None
        if self._stroke is None:
            if speed > cfg.start_speed_m_s:
                self._stroke = self._pre_roll()
            return None
        self._stroke.append(sample)
        if sample[0] - self._stroke[0][0] > cfg.max_stroke_ms * 1e6:
            self._stroke = None
            self._abandoned = True
            return None
        if paused:
            assert self._slow_since_ns is not None
            stroke = [s for s in self._stroke if s[0] <= self._slow_since_ns]
            self._stroke = None
            return self._finish(stroke)
        return None

    def _speed(self) -> float:
        """Speed over the last SPEED_WINDOW_MS (m/s); 0 with fewer than two samples."""
        if len(self._recent) < 2:
            return 0.0
        last = self._recent[-1]
        first = last
        for sample in reversed(self._recent):
            first = sample
            if last[0] - sample[0] >= SPEED_WINDOW_MS * 1e6:
                break
        dt_s = (last[0] - first[0]) / 1e9
        if dt_s <= 0.0:
            return 0.0
        return float(np.hypot(last[1] - first[1], last[2] - first[2])) / dt_s

    def _pre_roll(self) -> list[tuple[int, float, float]]:
        """Recent samples from the last one still slow onwards: the start of the movement."""
        samples = list(self._recent)
        start = 0
        for index in range(len(samples) - 1, 0, -1):
            t0, x0, y0 = samples[index - 1]
            t1, x1, y1 = samples[index]
            dt_s = (t1 - t0) / 1e9
            if dt_s > 0 and float(np.hypot(x1 - x0, y1 - y0)) / dt_s < self.config.stop_speed_m_s:
                start = index - 1
                break
        return samples[start:]

    def _finish(self, samples: list[tuple[int, float, float]]) -> Stroke | None:
        if len(samples) < 3:
            return None
        array = np.array(samples, dtype=np.float64)
        stroke = Stroke(np.array([s[0] for s in samples], dtype=np.int64), array[:, 1:3])
        if stroke.path_m < self.config.min_path_m:
            return None
        return stroke
