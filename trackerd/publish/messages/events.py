"""The interaction stage's topics: pointing events, gestures, commands and hand poses (docs/interaction.md)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from trackerd.publish.messages.envelope import Message


class WallPoint(Message):
    """Fields shared by the pointing events: where on the wall, in metres and display pixels."""

    topic: str
    cursor_id: int = Field(ge=1)
    """Counts the pointer's pointing sessions since start: every ``enter`` starts a new one, and
    every event until the matching ``leave`` carries its id (TUIO's session id is the same)."""
    wall_x_m: float
    """Wall x of the event's position (smoothed), metres from the display's bottom-left corner."""
    wall_y_m: float
    """Wall y of the event's position (smoothed), metres up from the display's bottom edge."""
    display_x_px: float | None = None
    """Display pixels from the left edge; null when the rig gives no display size."""
    display_y_px: float | None = None
    """Display pixels from the top edge; null when the rig gives no display size."""


class EnterMessage(WallPoint):
    """The pointer started pointing at the display (its hit stayed on it for ``enter_after_ms``)."""

    topic: Literal["enter"] = "enter"
    """Always ``enter``."""


class LeaveMessage(WallPoint):
    """The pointer stopped pointing at the display: off it (beyond the edge margin) or not seen,
    for ``leave_after_ms``. The position is the last one on the display."""

    topic: Literal["leave"] = "leave"
    """Always ``leave``."""
    reason: Literal["off_display", "lost"]
    """off_display: it points at the wall outside the display (or away); lost: no hit at all (the
    pointer is out of view, hidden, or points away from the wall), or no pair at all for half a second or
    more (a camera lost, the cameras stalled)."""
    duration_ms: float = Field(ge=0.0)
    """Time from the ``enter`` to this ``leave``."""


class DwellMessage(WallPoint):
    """Select (click): the hit stayed within ``radius_mm`` for ``time_ms``; once per rest."""

    topic: Literal["dwell"] = "dwell"
    """Always ``dwell``."""
    dwell_ms: float = Field(ge=0.0)
    """How long the hit had been still when the event was sent (at least the configured time)."""


class GestureMessage(WallPoint):
    """A gesture recognised from the hit's trajectory; the position is where the stroke ended."""

    topic: Literal["gesture"] = "gesture"
    """Always ``gesture``."""
    name: str
    """The gesture's name: its template's (``swipe_left``, ``swipe_right``, ``swipe_up``,
    ``swipe_down``, ``circle_cw``, ``circle_ccw``, or one an operator recorded)."""
    score: float = Field(ge=0.0, le=1.0)
    """How well the stroke matched the template, 0 to 1 (1: the same shape)."""
    start_ns: int = Field(ge=0)
    """Capture time of the stroke's first hit, same clock as capture_ns."""
    end_ns: int = Field(ge=0)
    """Capture time of the stroke's last hit, same clock as capture_ns."""
    duration_ms: float = Field(ge=0.0)
    """end_ns - start_ns in milliseconds."""
    path_m: float = Field(ge=0.0)
    """Length of the stroke's path on the wall."""
    start_wall_x_m: float
    """Wall x where the stroke began."""
    start_wall_y_m: float
    """Wall y where the stroke began."""
    runner_up: str | None = None
    """The next best gesture's name (null with a single template)."""
    runner_up_score: float | None = Field(default=None, ge=0.0, le=1.0)
    """The next best gesture's score."""


class CommandMessage(Message):
    """A command of the rig's grammar (``[interaction.commands]``), sent when its trigger happens,
    right after the trigger's own message."""

    topic: Literal["command"] = "command"
    """Always ``command``."""
    command: str
    """The command's name, as the rig file gives it (``previous_slide``, ...)."""
    trigger: str
    """What set it off: a gesture's name, ``enter``, ``leave``, ``dwell``, or ``hand_N`` (a hand
    showing N fingers)."""
    trigger_topic: str
    """The topic of the triggering message (``gesture``, ``dwell``, ``hand``, ...)."""
    cursor_id: int | None = Field(default=None, ge=1)
    """The pointing session of a pointer trigger; null for hand poses."""
    wall_x_m: float | None = None
    """Wall x of a pointer trigger (as in its message); null for hand poses."""
    wall_y_m: float | None = None
    """Wall y of a pointer trigger; null for hand poses."""
    display_x_px: float | None = None
    """Display x of a pointer trigger; null without a display size or for hand poses."""
    display_y_px: float | None = None
    """Display y of a pointer trigger; null without a display size or for hand poses."""


class HandMessage(Message):
    """A hand seen in one camera's image, with its extended fingers counted (the report's section 3.9)."""

    topic: Literal["hand"] = "hand"
    """Always ``hand``."""
    camera: str
    """The id of the camera the hand was seen in."""
    present: bool
    """False once, when a hand seen before is no longer found (then the other fields repeat the
    last values)."""
    fingers: int = Field(ge=0, le=5)
    """Extended fingers, 0 (a fist) to 5, debounced: the count seen on the last ``debounce_pairs``
    looks in a row."""
    fingers_now: int = Field(ge=0, le=5)
    """The count in this image alone, before debouncing."""
    image_x_px: float
    """The hand's centre (the palm's, where the hand is widest) in the camera's full-resolution
    image, pixels from the left."""
    image_y_px: float
    """The hand's centre, pixels from the top."""
    area_px: float = Field(ge=0.0)
    """The hand's area in full-resolution pixels."""
