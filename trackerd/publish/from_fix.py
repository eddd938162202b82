"""From the daemon's results for one camera pair to the messages that describe it: the one conversion to the wire.

The locator's fix becomes a ``pointer`` and a ``hit`` (:func:`messages_from_fix`);
the extensions' domain events (trackerd.pipeline.events) become their topics'
messages (:func:`event_message`), and :func:`pair_messages` puts a pair's
together in the order they are published. The publishing thread calls it for
every pair, so no other part of the daemon builds a wire message.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any, Literal, cast

from trackerd.geometry.wall import as_vec3
from trackerd.locator import Locator, PointerFix, WallHit
from trackerd.pipeline import events as ev
from trackerd.publish.messages import (
    CommandMessage,
    DwellMessage,
    EnterMessage,
    FixStatus,
    GestureMessage,
    HandMessage,
    HitMessage,
    LeaveMessage,
    Message,
    PointerMessage,
)


def published_hit(fix: PointerFix) -> WallHit | None:
    """The fix's wall hit when it is published as a ``hit`` (see :func:`messages_from_fix`), else None."""
    if not fix.found or fix.line is None:
        return None
    return fix.hit


def messages_from_fix(fix: PointerFix, locator: Locator, *, sequence: int, capture_ns: int) -> list[Message]:
    """The messages for one pair: none, a pointer, or a pointer and a hit (in that order).

    A pointer is sent whenever both ends were seen and the geometry is plausible
    (``fix.found``: not ``not_found`` nor ``rejected``); a hit whenever the line
    meets the wall's plane in front of the pointer (status ``hit`` or ``off_wall``).
    ``sequence`` is the pair's sequence number and ``capture_ns`` its capture
    time on the publisher's clock (see ``Publisher.clock_ns_from_monotonic``).
    """
    return fix_messages(fix, locator.front_colour, sequence=sequence, capture_ns=capture_ns)


def fix_messages(
    fix: PointerFix, front_colour: str, *, sequence: int, capture_ns: int, cursor: ev.CursorHit | None = None
) -> list[Message]:
    """:func:`messages_from_fix` with the front end's colour given (the locator's at the time of the
    fix), and the hit published as ``cursor`` says (smoothed, in a pointing session) when given."""
    line = fix.line
    if not fix.found or line is None:
        return []
    front, back = as_vec3(line.front_m), as_vec3(line.back_m)
    out: list[Message] = [
        PointerMessage(
            sequence=sequence,
            capture_ns=capture_ns,
            # The fix's status, the front colour and the line's method are plain strings where they are
            # made (the locator, the rig, the geometry); the model validates them against its literals.
            status=cast(FixStatus, fix.status),
            front_colour=cast(Literal["red", "blue"], front_colour),
            front_m=front,
            back_m=back,
            direction=as_vec3(line.direction),
            length_m=line.length_m,
            front_gap_mm=line.front_gap_m * 1000.0,
            back_gap_mm=line.back_gap_m * 1000.0,
            method=cast(Literal["planes", "points", "fit"], line.method),
        )
    ]
    hit = fix.hit
    if hit is not None:
        x_m, y_m = (float(v) for v in hit.wall_xy_m[:2])
        display = None if hit.display_px is None else [float(v) for v in hit.display_px[:2]]
        position: dict[str, Any] = {
            "wall_x_m": x_m,
            "wall_y_m": y_m,
            "display_x_px": None if display is None else display[0],
            "display_y_px": None if display is None else display[1],
            "on_wall": hit.on_wall,
        }
        if cursor is not None:
            position = _as_cursor(position, cursor)
        out.append(
            HitMessage(
                sequence=sequence,
                capture_ns=capture_ns,
                **position,
                distance_m=hit.distance_m,
                front_m=front,
                back_m=back,
                ray_gap_mm=line.gap_m * 1000.0,
                uncertainty_mm=None if fix.uncertainty_m is None else fix.uncertainty_m * 1000.0,
            )
        )
    return out


def _as_cursor(located: dict[str, Any], cursor: ev.CursorHit) -> dict[str, Any]:
    """The hit's position fields as ``cursor`` publishes them: smoothed, the located ones as ``raw_*``."""
    smoothed = cursor.smoothed
    if smoothed is None:
        return {**located, "cursor_id": cursor.cursor_id}
    return {
        "wall_x_m": smoothed.x_m,
        "wall_y_m": smoothed.y_m,
        "display_x_px": smoothed.display_x_px,
        "display_y_px": smoothed.display_y_px,
        "on_wall": cursor.smoothed_on_wall,
        "raw_wall_x_m": located["wall_x_m"],
        "raw_wall_y_m": located["wall_y_m"],
        "raw_display_x_px": located["display_x_px"],
        "raw_display_y_px": located["display_y_px"],
        "cursor_id": cursor.cursor_id,
    }


def pair_messages(
    fix: PointerFix, front_colour: str, *, sequence: int, capture_ns: int, events: ev.PairEvents
) -> list[Message]:
    """Every message of one pair, in the order published: the events that end what came before,
    the fix's pointer and hit, the events the pair completed (trackerd.pipeline.events.PairEvents)."""
    return [
        *event_messages(events.earlier),
        *fix_messages(fix, front_colour, sequence=sequence, capture_ns=capture_ns, cursor=events.hit),
        *event_messages(events.events),
    ]


def event_messages(events: Iterable[ev.Event]) -> list[Message]:
    return [event_message(event) for event in events]


def event_message(event: ev.Event) -> Message:
    """The wire message of one extension event."""
    if isinstance(event, ev.PointingEvent):
        return _pointing_message(event)
    if isinstance(event, ev.HandSeen):
        return HandMessage(
            sequence=event.sequence,
            capture_ns=event.capture_ns,
            camera=event.camera,
            present=event.present,
            fingers=event.fingers,
            fingers_now=event.fingers_now,
            image_x_px=event.centre_px[0],
            image_y_px=event.centre_px[1],
            area_px=event.area_px,
        )
    if isinstance(event, ev.CommandIssued):
        cause = event.cause
        position = _pointing_fields(cause) if isinstance(cause, ev.PointingEvent) else {}
        return CommandMessage(
            sequence=event.sequence,
            capture_ns=event.capture_ns,
            command=event.command,
            trigger=event.trigger,
            trigger_topic=cause.kind,
            **position,
        )
    raise TypeError(f"no message for a {type(event).__name__}")


def _pointing_fields(event: ev.PointingEvent) -> dict[str, Any]:
    at = event.at
    return {
        "cursor_id": event.cursor_id,
        "wall_x_m": at.x_m,
        "wall_y_m": at.y_m,
        "display_x_px": at.display_x_px,
        "display_y_px": at.display_y_px,
    }


def _pointing_message(event: ev.PointingEvent) -> Message:
    fields = {"sequence": event.sequence, "capture_ns": event.capture_ns, **_pointing_fields(event)}
    if isinstance(event, ev.Entered):
        return EnterMessage(**fields)
    if isinstance(event, ev.Left):
        return LeaveMessage(**fields, reason=event.reason, duration_ms=event.duration_ms)
    if isinstance(event, ev.Dwelt):
        return DwellMessage(**fields, dwell_ms=event.dwell_ms)
    if isinstance(event, ev.Gestured):
        return GestureMessage(
            **fields,
            name=event.name,
            score=round(event.score, 4),
            start_ns=event.start_ns,
            end_ns=event.end_ns,
            duration_ms=(event.end_ns - event.start_ns) / 1e6,
            path_m=event.path_m,
            start_wall_x_m=event.start_x_m,
            start_wall_y_m=event.start_y_m,
            runner_up=event.runner_up,
            runner_up_score=None if event.runner_up is None else round(event.runner_up_score, 4),
        )
    raise TypeError(f"no message for a {type(event).__name__}")
