"""A hook into each pair's way through the pipeline's two threads, for benchmarks.

The pipeline benchmark takes every pair's latency apart (trackerd.bench.pairtrace):
how long the pair waited to be taken, how long each thread was off the CPU while
on it, how long the hand-over took. The pipeline knows nothing of how: it calls
an installed :class:`PairObserver` at fixed points and carries what the observer
returns from one thread to the other. Without one (the daemon), it calls nothing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol


@dataclass(frozen=True)
class PairTimes:
    """One pair's moments on the monotonic clock (ns)."""

    received_ns: int
    """The last frame of the pair arrived."""
    taken_ns: int
    """The processing thread took the pair."""
    queued_ns: int
    """The processing thread handed the pair's messages to the publishing thread."""
    sending_ns: int
    """The publishing thread started sending them."""
    sent_ns: int
    """The last of them was handed to ZeroMQ."""


class PairObserver(Protocol):
    """Called on the pipeline's own threads, inside the pairs' latency: each call must take microseconds.

    ``mark`` samples the calling thread's clocks, opaque to the pipeline: the
    processing thread marks as it takes a pair and as it hands it over, the
    publishing thread as it starts sending; ``published`` then gets all three.
    """

    def thread_started(self) -> None:
        """In each of the processing and publishing threads, before their first pair."""
        ...

    def thread_stopped(self) -> None:
        """In each of them, after their last pair."""
        ...

    def mark(self) -> object:
        """The calling thread's clocks now."""
        ...

    def published(self, times: PairTimes, processing: tuple[object, object], sending: object) -> None:
        """On the publishing thread, once a pair's messages are handed to ZeroMQ: its moments, the
        processing thread's marks (taken, handed over) and the publishing thread's (started sending)."""
        ...
