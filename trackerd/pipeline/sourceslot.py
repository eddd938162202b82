"""The pair source in use, and what carries over when a reload replaces it.

A reload that changes the cameras' settings stops the source and opens a new
one (a GigE Vision camera has one controller: it cannot be opened twice). The
new source counts its pairs afresh, from 0 or 1 as it pleases; subscribers must
never see a sequence go back (a gap detector would take it for a restart), so
its pairs are numbered on from the last one taken, and what the old source
counted (pairs, drops) stays in the status figures.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable

from trackerd.acquisition.frame import FramePair
from trackerd.acquisition.source import PairSource
from trackerd.acquisition.status import SourceStatus
from trackerd.config.models import RigConfig
from trackerd.sdnotify import SdNotify

log = logging.getLogger(__name__)

RECOVERING = ("lost", "reconnecting")
"""Camera states in which a source delivers nothing for a while without the daemon being stuck."""


class Renumbering:
    """Sequences that go on across sources (pure: sequences in, sequences out)."""

    def __init__(self) -> None:
        self.offset = 0
        """Added to the current source's sequences."""
        self.next_sequence = 0
        """One past the last sequence given out (offset included)."""
        self._swapped = False

    def swapped(self) -> None:
        """A new source is in place: its first pair takes the next sequence."""
        self._swapped = True

    def number(self, source_sequence: int) -> int:
        """The published sequence of the current source's pair ``source_sequence``."""
        if self._swapped:
            self._swapped = False
            self.offset = self.next_sequence - source_sequence
        sequence = source_sequence + self.offset
        self.next_sequence = sequence + 1
        return sequence


class SourceSlot:
    """Holds the source; its pairs come out renumbered (see the module's docstring).

    The processing thread takes pairs and replaces the source; the publishing
    thread reads :meth:`status` and the counts carried over.
    """

    def __init__(self, factory: Callable[[RigConfig], PairSource], notifier: SdNotify) -> None:
        self._factory = factory
        self._notifier = notifier
        self.source: PairSource | None = None
        self._numbering = Renumbering()
        self.retired_pairs = 0
        """Pairs counted by the sources replaced."""
        self.retired_dropped_pairs = 0
        """Pairs dropped by the sources replaced."""

    def start(self, rig: RigConfig) -> None:
        """Open the source for ``rig`` (errors raise here)."""
        self.source = self._factory(rig)
        self.source.start()

    def stop(self) -> None:
        if self.source is not None:
            self.source.stop()

    def status(self) -> SourceStatus | None:
        return self.source.status() if self.source is not None else None

    def next_pair(self, timeout_s: float) -> FramePair | None:
        """The next pair, numbered on across sources; None if none came within ``timeout_s``."""
        assert self.source is not None
        pair = self.source.next_pair(timeout_s)
        if pair is None:
            return None
        sequence = self._numbering.number(pair.sequence)
        # A copy only when the numbers differ: the first source's pairs go through as they are.
        return pair if sequence == pair.sequence else dataclasses.replace(pair, sequence=sequence)

    def every_pair_published(self) -> bool:
        """The source wants every pair's messages published, late or not (PairSource.every_pair_published)."""
        return self.source is not None and self.source.every_pair_published

    def some_camera_recovering(self) -> bool:
        """A camera is lost or reconnecting (a power-cycled camera is not a stalled pipeline)."""
        assert self.source is not None
        return any(camera.state in RECOVERING for camera in self.source.status().cameras)

    def reopen(self, rig: RigConfig, old: RigConfig) -> None:
        """Replace the source by one for ``rig``; if it cannot start, reopen the old one and raise.

        The old source stops first; a setting the camera refuses must not leave the daemon without it.
        """
        assert self.source is not None
        start = time.monotonic()
        self.source.stop()
        stopped = self.source.status()
        # Each step can take seconds (a camera's control is released and taken again): the
        # watchdog hears that a reload is progressing, not stalled.
        self._notifier.progress()
        try:
            source = self._factory(rig)
            source.start()
        except BaseException:
            self._notifier.progress()
            log.info("reload: reopening the cameras with the previous settings")
            self._replace(self._factory(old), stopped)
            assert self.source is not None
            self.source.start()
            log.info("reload: cameras reopened with the previous settings after %.1f s", time.monotonic() - start)
            raise
        self._replace(source, stopped)
        log.info("reload: cameras reopened after %.1f s", time.monotonic() - start)

    def _replace(self, source: PairSource, stopped: SourceStatus) -> None:
        """Put ``source`` in place of the stopped one, whose last status is ``stopped`` (the counts
        and the source change together, so no status counts a source twice)."""
        self.retired_pairs += stopped.pairs
        self.retired_dropped_pairs += stopped.dropped_pairs
        self.source = source
        self._numbering.swapped()
