"""The interaction stage's results as the daemon's domain events (trackerd.pipeline.events).

The engine (trackerd/interaction/engine.py) decides events on the pairs' monotonic
capture times, with positions in wall metres; :class:`EventMaker` turns them
into typed events on the publishing clock, with display pixels from the rig's
wall and each followed by the command the grammar maps its trigger to. The
publisher turns those into wire messages (trackerd.publish.from_fix).
"""

from __future__ import annotations

from typing import Any, Literal, cast

import numpy as np
from numpy.typing import NDArray

from trackerd.geometry.wall import WallFrame
from trackerd.interaction.engine import Event as EngineEvent
from trackerd.interaction.grammar import Grammar
from trackerd.pipeline.events import (
    CommandIssued,
    CursorHit,
    Dwelt,
    Entered,
    Event,
    Gestured,
    HandSeen,
    Left,
    PointingEvent,
    WallPoint,
)


class EventMaker:
    """Domain events from the engine's, for one wall, grammar and smoothing setting."""

    def __init__(self, wall: WallFrame, grammar: Grammar, *, smoothing: bool) -> None:
        self.wall = wall
        self.grammar = grammar
        self.smoothing = smoothing

    def point(self, position_m: NDArray[np.float64]) -> WallPoint:
        """A wall position (2,) in metres with its display pixels (None without a display size)."""
        x_px: float | None = None
        y_px: float | None = None
        if self.wall.has_display:
            px = self.wall.to_display_px(position_m)
            x_px, y_px = float(px[0]), float(px[1])
        return WallPoint(float(position_m[0]), float(position_m[1]), x_px, y_px)

    def cursor_hit(self, smoothed_m: NDArray[np.float64], cursor_id: int | None) -> CursorHit:
        """How a pair's hit is published: in session ``cursor_id``, at ``smoothed_m`` when smoothing is on."""
        if not self.smoothing:
            return CursorHit(cursor_id, None)
        return CursorHit(cursor_id, self.point(smoothed_m), bool(self.wall.on_wall(smoothed_m)))

    def events(
        self, engine_events: list[EngineEvent], *, sequence: int, capture_ns: int, clock_offset_ns: int
    ) -> list[Event]:
        """The engine's events of pair ``sequence``, each followed by its command; ``clock_offset_ns``
        takes the engine's capture times (a gesture's start and end) to the publishing clock."""
        out: list[Event] = []
        for engine_event in engine_events:
            event = self._event(engine_event, sequence, capture_ns, clock_offset_ns)
            out.append(event)
            trigger = event.name if isinstance(event, Gestured) else event.kind
            self.add_command(out, trigger, event)
        return out

    def add_command(self, out: list[Event], trigger: str, cause: PointingEvent | HandSeen) -> None:
        """Append the command ``trigger`` sets off, if the grammar maps it."""
        command = self.grammar.command_for(trigger)
        if command is not None:
            out.append(
                CommandIssued(
                    sequence=cause.sequence, capture_ns=cause.capture_ns, command=command, trigger=trigger, cause=cause
                )
            )

    def _event(self, event: EngineEvent, sequence: int, capture_ns: int, clock_offset_ns: int) -> PointingEvent:
        common: dict[str, Any] = {
            "sequence": sequence,
            "capture_ns": capture_ns,
            "cursor_id": event.cursor_id,
            "at": self.point(event.position_m),
        }
        d = event.detail
        if event.kind == "enter":
            return Entered(**common)
        if event.kind == "leave":
            return Left(
                **common, reason=cast(Literal["off_display", "lost"], d["reason"]), duration_ms=d["duration_ms"]
            )
        if event.kind == "dwell":
            return Dwelt(**common, dwell_ms=d["dwell_ms"])
        return Gestured(
            **common,
            name=d["name"],
            score=float(d["score"]),
            start_ns=d["start_ns"] + clock_offset_ns,
            end_ns=d["end_ns"] + clock_offset_ns,
            path_m=d["path_m"],
            start_x_m=float(d["start_m"][0]),
            start_y_m=float(d["start_m"][1]),
            runner_up=d["runner_up"],
            runner_up_score=float(d["runner_up_score"]),
        )
