"""What extensions make of a located pair: domain events, turned into wire messages once, at the hand-over.

An extension (trackerd.pipeline.extensions) is handed the pair, its fix and its
capture time, and answers with :class:`PairEvents`: the pair's hit as it is to be
published (smoothed, with its pointing session) and the events the pair
completed. None of these is a wire message: trackerd.publish.from_fix turns them
into messages on the publishing thread, the one place where the daemon's
results become the wire protocol (docs/protocol.md).

Every event carries the pair it was decided on (``sequence``) and that pair's
capture time on the publishing clock (``capture_ns``): an event that ends a
session at a reset or a reload carries the session's last pair, not the next.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar, Literal


@dataclass(frozen=True, slots=True)
class WallPoint:
    """A position on the wall (metres from the display's bottom-left corner) and on the display
    (pixels from its top-left corner; None when the rig gives no display size)."""

    x_m: float
    y_m: float
    display_x_px: float | None
    display_y_px: float | None


@dataclass(frozen=True, slots=True)
class CursorHit:
    """How the pair's hit is published: its pointing session and, with smoothing, the smoothed position."""

    cursor_id: int | None
    """The pointing session the hit belongs to; None while the pointer is not entered."""
    smoothed: WallPoint | None
    """The smoothed position (the located one is then published as ``raw_*``); None: as located."""
    smoothed_on_wall: bool = False
    """Whether the smoothed position lies on the display (meaningful with ``smoothed`` only)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class Event:
    """Something an extension decided on pair ``sequence``, captured at ``capture_ns`` (publishing clock)."""

    kind: ClassVar[str] = "event"
    """What happened, in one word: the topic of the message it becomes."""
    sequence: int
    capture_ns: int


@dataclass(frozen=True, slots=True, kw_only=True)
class PointingEvent(Event):
    """An event of a pointing session, at a position on the wall."""

    cursor_id: int
    at: WallPoint


@dataclass(frozen=True, slots=True, kw_only=True)
class Entered(PointingEvent):
    """The pointer started pointing at the display."""

    kind: ClassVar[str] = "enter"


@dataclass(frozen=True, slots=True, kw_only=True)
class Left(PointingEvent):
    """The pointer stopped pointing at the display (``at``: its last position on it)."""

    kind: ClassVar[str] = "leave"
    reason: Literal["off_display", "lost"]
    """off_display: it points beside the display (or away); lost: no hit at all."""
    duration_ms: float
    """Time from the session's enter to this leave."""


@dataclass(frozen=True, slots=True, kw_only=True)
class Dwelt(PointingEvent):
    """The hit rested for ``dwell_ms`` (a click)."""

    kind: ClassVar[str] = "dwell"
    dwell_ms: float
    """How long the hit had rested when the dwell was decided (at least the configured time)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class Gestured(PointingEvent):
    """A stroke recognised as the gesture ``name`` (``at``: where it ended); times on the publishing clock."""

    kind: ClassVar[str] = "gesture"
    name: str
    """The template's name (``swipe_left``, ``circle_cw``, one an operator recorded)."""
    score: float
    """How well the stroke matched the template, 0 to 1."""
    start_ns: int
    end_ns: int
    """The stroke's first and last hit, capture times on the publishing clock."""
    path_m: float
    """The stroke's path length on the wall."""
    start_x_m: float
    start_y_m: float
    """Where on the wall the stroke began."""
    runner_up: str | None
    runner_up_score: float
    """The next best gesture and its score (None and 0.0 with a single template)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class HandSeen(Event):
    """A hand in one camera's image with its debounced finger count (``present`` False: gone again;
    the other fields then repeat the last look's)."""

    kind: ClassVar[str] = "hand"
    camera: str
    """The id of the camera the hand was looked for in."""
    present: bool
    fingers: int
    """Extended fingers, debounced (seen on ``debounce_pairs`` looks in a row)."""
    fingers_now: int
    """Extended fingers in this look alone."""
    centre_px: tuple[float, float]
    """The palm's centre in the camera's full-resolution image (x right, y down)."""
    area_px: float
    """The hand's area in full-resolution pixels."""


@dataclass(frozen=True, slots=True, kw_only=True)
class CommandIssued(Event):
    """A command of the rig's grammar, set off by ``cause`` (published right after it)."""

    kind: ClassVar[str] = "command"
    command: str
    trigger: str
    """What set it off: a gesture's name, ``enter``, ``leave``, ``dwell`` or ``hand_N``."""
    cause: PointingEvent | HandSeen
    """The event that set it off (published right before it)."""


@dataclass(frozen=True, slots=True)
class PairEvents:
    """An extension's answer for one pair, published in this order: ``earlier``, the pair's pointer
    and hit (the hit as ``hit`` says), ``events``."""

    earlier: Sequence[Event] = ()
    """Events that end what came before this pair (a reset or a reload ended a session)."""
    hit: CursorHit | None = None
    """How the pair's hit is published; None: as the locator found it."""
    events: Sequence[Event] = ()
    """What the pair completed."""

    def then(self, other: PairEvents) -> PairEvents:
        """This extension's answer followed by the next one's (a later extension's ``hit`` wins)."""
        if not other.earlier and other.hit is None and not other.events:
            return self
        return PairEvents(
            [*other.earlier, *self.earlier],
            other.hit if other.hit is not None else self.hit,
            [*self.events, *other.events],
        )


NOTHING = PairEvents()
"""The answer of an extension that adds nothing."""
