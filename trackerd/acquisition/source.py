"""The one interface the pipeline consumes: a source of synchronized frame pairs.

Live cameras through Aravis or pylon (:class:`trackerd.acquisition.live.LivePairSource`) are one
implementation; recording replay is another. The pipeline cannot tell which
one it is fed::

    with LivePairSource(rig) as source:
        while running:
            pair = source.next_pair(timeout_s=0.5)
            if pair is not None:
                fix = locator.locate(pair.images)
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from types import TracebackType

from trackerd.acquisition.frame import FramePair
from trackerd.acquisition.status import SourceStatus


class PairSource(ABC):
    """A context manager that starts on entry and stops on exit."""

    every_pair_published: bool = False
    """True: the pipeline waits for its publishing thread rather than drop a pair's messages when
    that thread falls behind (a replay as fast as possible, where nothing can be late); False:
    the oldest waiting pair is dropped and counted, so latency stays bounded (cameras)."""

    @abstractmethod
    def start(self) -> None:
        """Begin acquiring. Raises CameraError (or RecordingError) when the source cannot start."""

    @abstractmethod
    def stop(self) -> None:
        """Stop acquiring, join every thread and release every buffer. Safe to call twice."""

    @abstractmethod
    def next_pair(self, timeout_s: float) -> FramePair | None:
        """The oldest pair not yet delivered, waiting at most ``timeout_s`` seconds (> 0).

        Returns None on timeout or when the source has stopped (check ``status().running``).
        """

    @abstractmethod
    def status(self) -> SourceStatus:
        """A snapshot of counters and per-camera state; cheap enough to call once a second."""

    def __enter__(self) -> PairSource:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.stop()
