"""A pair source that serves image sets held in memory, paced like cameras or as fast as possible.

It stands in for cameras where the frames already exist: the pipeline
benchmark feeds pre-rendered 1920x1080 scenes through it at 60 pairs per second
(the virtual GigE rig cannot sustain that on two cores alongside the daemon),
and tests use it to run the real pipeline on rendered frames. Paced like a
camera, it never waits for the consumer: a pair not taken by the time the next
one is due is dropped and counted, as live cameras would drop it.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from trackerd.acquisition.frame import Frame, FramePair
from trackerd.acquisition.pacing import wait_until_due
from trackerd.acquisition.source import PairSource
from trackerd.acquisition.status import CameraState, CameraStatus, SourceStatus
from trackerd.config.models import RigConfig


class MemoryPairSource(PairSource):
    """Serves ``image_sets`` (one image per camera, rig order) in order, looping if asked.

    ``rate_hz`` paces delivery like free-running cameras (None: as fast as the
    consumer takes them). ``count`` stops after that many pairs (None: once
    through, or forever when looping). ``drop_late=False`` serves every pair
    however late the consumer is, stamped with the time it was due (as a
    recording replayed at pace would be), for tests whose subject is what the
    pairs show rather than how a stall is survived.
    """

    def __init__(
        self,
        rig: RigConfig,
        image_sets: Sequence[Sequence[NDArray[np.uint8]]],
        *,
        rate_hz: float | None = 60.0,
        loop: bool = True,
        count: int | None = None,
        pixel_formats: Sequence[str] | None = None,
        drop_late: bool = True,
    ) -> None:
        if not image_sets:
            raise ValueError("no image sets to serve")
        self.rig = rig
        self._sets = [tuple(images) for images in image_sets]
        self._period_ns = None if rate_hz is None else int(1e9 / rate_hz)
        self._loop = loop
        self._drop_late = drop_late
        self._count = count
        self._formats = list(pixel_formats or [c.pixel_format for c in rig.cameras])
        self._ids = [c.id for c in rig.cameras]
        self._lock = threading.Lock()
        self._running = False
        self._start_ns = 0
        self._served = 0
        self._dropped = 0
        self._next_index = 0

    def start(self) -> None:
        with self._lock:
            self._running = True
            self._start_ns = time.monotonic_ns()
            self._served = self._dropped = self._next_index = 0

    def stop(self) -> None:
        with self._lock:
            self._running = False

    def _end_index(self) -> int:
        """One past the last pair to serve (a very large number when serving forever)."""
        if self._count is not None:
            return self._count
        return len(self._sets) if not self._loop else 1 << 62

    def _finished(self, index: int) -> bool:
        return index >= self._end_index()

    def next_pair(self, timeout_s: float) -> FramePair | None:
        deadline = time.monotonic_ns() + int(timeout_s * 1e9)
        with self._lock:
            if not self._running:
                return None
            index = self._next_index
            if self._period_ns is not None and self._drop_late:
                now = time.monotonic_ns()
                # The pair due most recently: any earlier ones were missed, as cameras would miss them.
                current = (now - self._start_ns) // self._period_ns
                # Pairs past the end were never going to be served: they are not drops.
                current = min(current, self._end_index())
                if current > index:
                    self._dropped += current - index
                    index = current
            if self._finished(index):
                self._running = False
                return None
            due = self._start_ns + index * (self._period_ns or 0)
            self._next_index = index + 1
        if not wait_until_due(due, deadline, clock_ns=time.monotonic_ns, sleep=time.sleep):
            with self._lock:
                self._next_index = index  # not delivered: serve it on the next call
            return None
        images = self._sets[index % len(self._sets)]
        # Paced, a pair arrives when it is due, as a camera's frame does, however late the consumer
        # takes it: the time it waited (the consumer's wake-up included) is part of its latency.
        capture = due if self._period_ns is not None else time.monotonic_ns()
        frames = tuple(
            Frame(camera_id, index, capture, capture, fmt, image)
            for camera_id, fmt, image in zip(self._ids, self._formats, images, strict=True)
        )
        with self._lock:
            self._served += 1
        return FramePair(frames, capture, 0, index)

    def status(self) -> SourceStatus:
        with self._lock:
            elapsed_s = max((time.monotonic_ns() - self._start_ns) / 1e9, 1e-9)
            rate = self._served / elapsed_s if self._running else 0.0
            state: CameraState = "streaming" if self._running else "stopped"
            return SourceStatus(
                running=self._running,
                trigger="memory",
                pairing="memory",
                pairs=self._served + self._dropped,
                pair_rate_hz=rate,
                delivered=self._served,
                dropped_pairs=self._dropped,
                skew_p50_us=0.0,
                skew_p99_us=0.0,
                skew_max_us=0.0,
                cameras=tuple(
                    CameraStatus(camera_id, state, "memory", frames=self._served, frame_rate_hz=rate)
                    for camera_id in self._ids
                ),
            )
