"""The hand-over from the processing thread to the publishing thread, and what the two stages share.

The processing thread hands over each pair's domain result (:class:`Processed`:
the fix, the extensions' events, the pair's times) with its wire messages,
converted once as it is handed over (trackerd.publish.from_fix.pair_messages);
the publishing thread sends them.
Both stages are built with the same :class:`StageLinks`: the drop-oldest queue
between them and what both report to.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

from trackerd.calibration.health import CalibrationHealth
from trackerd.locator import PointerFix
from trackerd.pipeline.events import NOTHING, PairEvents
from trackerd.pipeline.figures import PipelineFigures
from trackerd.pipeline.observer import PairObserver
from trackerd.pipeline.queues import DropOldestQueue
from trackerd.pipeline.reload import ReloadRequests
from trackerd.pipeline.tap import ConsoleTap
from trackerd.publish.from_fix import event_messages, pair_messages
from trackerd.publish.messages import Message
from trackerd.sdnotify import SdNotify


@dataclass
class Processed:
    """What the processing thread hands the publisher for one pair (or, ``pairless``, events of none)."""

    fix: PointerFix | None
    """The pair's fix (None: events of no pair, at stop or while no pair comes)."""
    front_colour: str
    """The colour of the pointer's front end when the pair was located (a reload may change it)."""
    sequence: int
    received_ns: int
    """Monotonic time the last frame of the pair arrived."""
    capture_ns: int
    """Capture time on the publishing clock."""
    events: PairEvents = NOTHING
    """What the extensions made of the pair."""
    stage_ns: dict[str, int] = field(default_factory=dict)
    pairless: bool = False
    """The extensions' events of no pair (their last ones at stop, or a session a stalled source ended):
    not counted in the figures."""
    taken_ns: int = 0
    """Monotonic time the processing thread took the pair."""
    queued_ns: int = 0
    """Monotonic time the result was handed to the publishing thread (with an observer only)."""
    marks: tuple[object, object] | None = None
    """The observer's marks of the processing thread, taking the pair and handing it over."""
    health: tuple[CalibrationHealth, PointerFix] | None = None
    """A fix to add to the calibration health record it was located under, once the messages are sent."""

    wire: list[Message] | None = None
    """The wire messages, once :meth:`messages` has built them."""
    sent: threading.Event = field(default_factory=threading.Event)
    """Set by the publishing thread once the messages are handed to ZeroMQ (never, for a result the queue
    dropped): the processing thread's work between pairs waits for it (trackerd.pipeline.processing)."""

    def messages(self) -> list[Message]:
        """The wire messages, in the order published (the one conversion, trackerd.publish.from_fix);
        built once, by whichever thread asks first."""
        if self.wire is None:
            self.wire = self._convert()
        return self.wire

    def _convert(self) -> list[Message]:
        if self.fix is None:
            return event_messages([*self.events.earlier, *self.events.events])
        return pair_messages(
            self.fix, self.front_colour, sequence=self.sequence, capture_ns=self.capture_ns, events=self.events
        )


@dataclass(frozen=True)
class StageLinks:
    """What the processing and publishing stages share."""

    queue: DropOldestQueue[Processed]
    """Processing -> publishing: drops its oldest item when full, and counts the drop."""
    figures: PipelineFigures
    reload: ReloadRequests
    notifier: SdNotify
    clock_offset_ns: int
    """Monotonic time -> publishing clock (fixed at start)."""
    tap: ConsoleTap | None
    observer: PairObserver | None
