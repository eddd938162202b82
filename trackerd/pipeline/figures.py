"""The counts and latencies the pipeline's two threads keep for the status and the benchmarks.

The processing thread counts pairs and fixes and its CPU time per pair; the
publishing thread adds each published pair's latencies. Each status drains the
latency windows (figures per status period); the counts run from the start.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from trackerd.pipeline.stats import Window

STAGES = ("detect", "triangulate", "publish")
"""The stages timed per pair, in the order the status lists them."""


class PipelineFigures:
    """Counters and latency windows; each counter has one writer thread (see the module's docstring)."""

    def __init__(self) -> None:
        self.latency = Window()
        """Capture to publish (ns), drained into each status."""
        self.processing = Window()
        """Last frame of the pair received to messages published (ns)."""
        self.stages = {name: Window() for name in STAGES}
        self.processing_cpu = Window()
        """CPU time the processing thread spent on each pair (ns): set beside its wall time, what
        was work and what was time off the CPU (benchmarks; not in the status)."""
        self.fixes: dict[str, int] = {}
        """Pairs processed by the fix's status (processing thread)."""
        self.pairs_processed = 0
        """Pairs the processing thread has handed over (processing thread)."""
        self.pairs_published = 0
        """Pairs whose messages the publishing thread has handed to the publisher (publishing thread)."""

    def count_fix(self, status: str) -> None:
        self.fixes[status] = self.fixes.get(status, 0) + 1

    def add_published(self, stage_ns: dict[str, int], publish_ns: int, processing_ns: int, latency_ns: int) -> None:
        """One pair's messages are published: its stages' times, the time taken to publish, last frame
        received to published, and capture to published."""
        self.pairs_published += 1
        self.stages["publish"].add(publish_ns)
        for name in ("detect", "triangulate"):
            self.stages[name].add(stage_ns[name])
        self.processing.add(processing_ns)
        self.latency.add(latency_ns)

    def drain(self) -> dict[str, NDArray[np.int64]]:
        """The latencies (ns) since the last drain, by figure: ``latency``, ``processing``, then each stage."""
        latency = self.latency.drain()
        processing = self.processing.drain()
        stages = {name: window.drain() for name, window in self.stages.items()}
        return {"latency": latency, "processing": processing, **stages}
