"""The wire protocol's messages: one pydantic model per topic over a common envelope.

Every message travels as two ZeroMQ frames, ``[topic, payload]``: the topic in
ASCII (what subscribers filter on) and the payload as one UTF-8 JSON object
holding the envelope's fields and the topic's own fields side by side. The
models here are the single source of truth: docs/schema/*.json and the field
tables of docs/protocol.md are generated from them (scripts/export_schemas.py).

Versioning (docs/protocol.md, "Versions"): ``schema_version`` is
``MAJOR.MINOR``. Adding a field or a topic raises MINOR only, so subscribers
must ignore fields they do not know; renaming, removing or changing the
meaning or unit of a field raises MAJOR.

Adding a topic: subclass :class:`Message`, give it ``topic: Literal["name"]``
and register it in :data:`TOPICS`. A topic's name must not begin with another
topic's name, because ZeroMQ subscriptions match by prefix.
"""

from __future__ import annotations

import typing
from collections.abc import Mapping
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from trackerd.publish.payload import payload_json

SCHEMA_VERSION = "1.4"
"""MAJOR.MINOR of the message set this code writes."""

SCHEMA_MAJOR = int(SCHEMA_VERSION.split(".")[0])

Vec3M = tuple[float, float, float]

FixStatus = Literal["hit", "off_wall", "away", "parallel"]
CameraState = Literal["connecting", "connected", "streaming", "lost", "reconnecting", "stopped"]
DaemonState = Literal["starting", "running", "degraded", "reloading", "stopping"]


class _Part(BaseModel):
    """Base of every message and sub-object: closed for the producer (a misspelt field is a bug
    caught here), while subscribers are told to ignore unknown fields (the exported schemas allow them)."""

    model_config = ConfigDict(
        extra="forbid", use_attribute_docstrings=True, allow_inf_nan=False,
        json_schema_serialization_defaults_required=True,
    )


class Message(_Part):
    """The envelope every payload carries."""

    schema_version: str = SCHEMA_VERSION
    """MAJOR.MINOR of the message set; a subscriber accepts any MINOR of the MAJOR it was written for."""
    topic: str
    """The topic, repeated from the first frame so a payload stands on its own (logs, files)."""
    sequence: int = Field(ge=0)
    """hit and pointer: the camera pair's sequence number (a hit and a pointer from the same pair
    share it); events (enter, leave, dwell, gesture, command, hand): the pair in which the event was
    decided; status: counts status messages. Gaps in hit/pointer are normal (pairs without a pointer).
    Within one run of the daemon a pair's sequence only increases, also across a reload that reopens
    the cameras; it starts again from 0 when the daemon restarts (``uptime_s`` in the status tells)."""
    capture_ns: int = Field(ge=0)
    """When the images were taken (mean of the pair's frames), nanoseconds since the UNIX epoch
    on the daemon host's clock; for status, when the figures were gathered."""
    publish_ns: int = Field(default=0, ge=0)
    """When the message was handed to ZeroMQ, same clock as capture_ns; set by the publisher.
    publish_ns - capture_ns is the daemon's latency for this message."""


class HitMessage(Message):
    """Where the pointer points on the wall: one per camera pair in which it points at the wall's plane."""

    topic: Literal["hit"] = "hit"
    """Always ``hit``."""
    wall_x_m: float
    """Metres from the display's bottom-left corner, to the right along the wall."""
    wall_y_m: float
    """Metres up the wall from the display's bottom edge."""
    display_x_px: float | None = None
    """Display pixels from the left edge (origin top-left); null when the rig gives no display size."""
    display_y_px: float | None = None
    """Display pixels from the top edge (y down); null when the rig gives no display size."""
    on_wall: bool
    """True when the hit lies on the display area; false when it is on the wall's plane outside it."""
    distance_m: float
    """From the pointer's front end to the hit, along the pointer's line."""
    front_m: Vec3M
    """Centre of the pointer's front end (the end nearer the wall), world coordinates in metres."""
    back_m: Vec3M
    """Centre of the pointer's back end, world coordinates in metres."""
    ray_gap_mm: float = Field(ge=0.0)
    """How far the cameras' rays through an end miss each other (the worse end): the quality signal.
    A few mm is normal; large gaps mean a camera saw the wrong blob."""
    uncertainty_mm: float | None = Field(default=None, ge=0.0)
    """Estimated standard error of the hit on the wall (RMS radius) from centroid noise; null when
    it could not be estimated."""
    raw_wall_x_m: float | None = None
    """(1.1) With smoothing on, wall_x_m, wall_y_m, the display pixels and on_wall are smoothed
    (docs/interaction.md) and this is the unsmoothed wall x; null when smoothing is off."""
    raw_wall_y_m: float | None = None
    """(1.1) Unsmoothed wall y; null when smoothing is off."""
    raw_display_x_px: float | None = None
    """(1.1) Unsmoothed display x; null when smoothing is off or the rig gives no display size."""
    raw_display_y_px: float | None = None
    """(1.1) Unsmoothed display y; null when smoothing is off or the rig gives no display size."""
    cursor_id: int | None = Field(default=None, ge=1)
    """(1.1) The pointing session this hit belongs to (see ``enter``); null while the pointer is
    not entered on the display or pointing events are off."""


class PointerMessage(Message):
    """The pointer in 3D whenever both ends are seen and agree, even when it points away from the wall."""

    topic: Literal["pointer"] = "pointer"
    """Always ``pointer``."""
    status: FixStatus
    """hit: points at the display; off_wall: at the wall's plane outside the display; away: away
    from the wall; parallel: along the wall (within half a degree)."""
    front_colour: Literal["red", "blue"]
    """Colour of the front end (the pointing direction runs from the back end to the front end)."""
    front_m: Vec3M
    """Centre of the front end, world coordinates in metres."""
    back_m: Vec3M
    """Centre of the back end, world coordinates in metres."""
    direction: Vec3M
    """Unit vector from the back end to the front end (world frame)."""
    length_m: float = Field(ge=0.0)
    """Distance between the two end centres as triangulated."""
    front_gap_mm: float = Field(ge=0.0)
    """Ray gap at the front end (see hit.ray_gap_mm)."""
    back_gap_mm: float = Field(ge=0.0)
    """Ray gap at the back end."""
    method: Literal["planes", "points", "fit"]
    """How the line was estimated: interpretation planes, the report's two triangulated points (used
    when the planes are ill-conditioned), or (1.3) the pointer fit, both ends fitted to every camera's
    measurements of the balls' outlines with the pointer's known length (docs/geometry.md). Open: treat
    a value you do not know as one more way of estimating the same line."""


class CameraStatusPart(_Part):
    """One camera's state in a status message."""

    id: str
    """The camera's id in the rig (``left``, ``right``, ...)."""
    state: CameraState
    """connecting (first open, or waiting for the camera to appear), connected (open, waiting for
    its first complete frame; 1.2), streaming (its connection has delivered frames), lost (no
    frames, no answer), reconnecting, stopped. Treat a state you do not know as not streaming."""
    frame_rate_hz: float = Field(ge=0.0)
    """Frames delivered per second over the last two seconds; 0 until half a second of frames."""
    frames: int = Field(default=0, ge=0)
    """Complete frames delivered since the daemon started."""
    dropped: dict[str, int] = Field(default_factory=dict)
    """Frames lost before pairing, by cause (``missing-packets``, ``timeout``, ``wrong-size``, ...);
    totals since start."""
    losses: int = Field(default=0, ge=0)
    """Times the camera was marked lost."""
    reconnects: int = Field(default=0, ge=0)
    """Times it was opened again after a loss."""
    last_error: str | None = None
    """The most recent problem, in one line."""
    stream: dict[str, int] = Field(default_factory=dict)
    """(1.2) Aravis stream counters, totals since start, by Aravis's names: ``n_missing_packets``,
    ``n_resend_requests``, ``n_resent_packets``, ``n_underruns`` (no buffer free), ``n_timeouts``,
    ``n_completed_buffers``, ... (docs/acquisition.md); those the camera's stream has. Empty for
    sources without Aravis (a replay)."""
    ptp_state: str | None = None
    """(1.2) The camera's IEEE 1588 port state (``Master``, ``Slave``, ``Listening``, ``Faulty``,
    ...) when the rig enables PTP and the camera supports it; null otherwise."""


class LatencyPart(_Part):
    """Percentiles of capture-to-publish latency over the last status period."""

    samples: int = Field(ge=0)
    """Messages the figures are taken over (0: no pair was processed; the figures are null)."""
    p50_ms: float | None = None
    """Median latency in milliseconds."""
    p90_ms: float | None = None
    """90th percentile."""
    p99_ms: float | None = None
    """99th percentile."""
    max_ms: float | None = None
    """Largest latency."""


class PairingPart(_Part):
    """The frame pairing stage: how many synchronized pairs were formed and how well they line up."""

    pair_rate_hz: float = Field(ge=0.0)
    """Pairs formed per second over the last second or so."""
    pairs: int = Field(default=0, ge=0)
    """Pairs formed since the daemon started."""
    dropped_frames: dict[str, int] = Field(default_factory=dict)
    """Complete frames that never became part of a pair, by cause (``no_partner``, ``queue_full``,
    ``resync``, ``skew``, ``partner_lost``: another camera was lost or not there yet,
    ``clock_warmup``: a camera's first frames while its clock offset settles); totals since start."""
    dropped_pairs: int = Field(default=0, ge=0)
    """Pairs discarded because processing fell behind (the oldest is dropped)."""
    skew_p50_us: float | None = None
    """Median capture-time difference between the frames of a pair, microseconds."""
    skew_p99_us: float | None = None
    """99th percentile pair skew, microseconds."""
    mode: str | None = None
    """(1.2) What frames are paired by: ``trigger count`` (software trigger), ``device time (PTP)``
    (every camera PTP-locked) or ``host time`` (estimated capture times); null when the source does
    not say."""


class SpreadPart(_Part):
    """Percentiles of a quantity over recent fixes."""

    p50: float | None = None
    """Median."""
    p95: float | None = None
    """95th percentile."""
    max: float | None = None
    """Largest."""


class CalibrationHealthPart(_Part):
    """How well the cameras still agree: a bumped camera shows up here as a jump (docs/calibration.md)."""

    fixes: int = Field(ge=0)
    """Recent fixes the figures are taken over."""
    total_fixes: int = Field(ge=0)
    """Fixes measured since start."""
    ray_gap_mm: SpreadPart
    """How far the two cameras' rays through an end miss each other, millimetres."""
    reprojection_px: SpreadPart
    """Distance between each detected end and the projection of its triangulated centre, pixels."""
    suspect: bool
    """True when the figures exceed the limits a sound calibration stays within."""
    reason: str | None = None
    """Why the figures are suspect, or why they cannot be judged yet."""


class ColourFigurePart(_Part):
    """One end's colour against the room, in grey levels of colour excess (docs/detection.md, "The colour watch")."""

    threshold: int
    """The detector's ``min_excess`` for this end."""
    room_excess: int
    """The highest excess anything but the pointer reaches now, over a block of 2 x 2 samples (every camera)."""
    camera: str | None = None
    """The camera that sees it."""
    at_px: tuple[float, float] | None = None
    """Where in that camera's image, pixels (x, y)."""
    ball_excess: int | None = None
    """What the end's paint reaches, as ``trackerd calibrate pointer`` learned it; null without learned colours."""
    baseline_excess: int | None = None
    """The room's excess when the colours were learned, or (without) when the watch first measured it."""


class ColourWatchPart(_Part):
    """(1.4) The room's colours against the pointer's: whether something in view came close to an end's colour."""

    learned: bool
    """Whether the figures compared with are from ``trackerd calibrate pointer`` (else from the daemon's start)."""
    age_s: float = Field(ge=0.0)
    """Seconds since the last measurement (taken every few seconds on a pair where the pointer was located)."""
    red: ColourFigurePart
    """The red end."""
    blue: ColourFigurePart
    """The blue end."""
    warning: str | None = None
    """One line when the margin has shrunk (a new picture on the wall nearly the pointer's colour); else null."""


class InteractionStatusPart(_Part):
    """The interaction stage's figures in a status message (docs/interaction.md)."""

    smoothing: bool
    """Whether hits are smoothed."""
    pointing: bool
    """Whether the pointer is entered on the display now."""
    cursor_id: int | None = None
    """The current pointing session, or the last one."""
    events: dict[str, int] = Field(default_factory=dict)
    """Events and commands sent since start, by topic."""
    gestures: dict[str, int] = Field(default_factory=dict)
    """Gestures recognised since start, by name."""
    templates: int = Field(default=0, ge=0)
    """Gesture templates loaded."""
    strokes_rejected: int = Field(default=0, ge=0)
    """Strokes that were no gesture (too poor a match, ambiguous, or kinematics that do not fit)."""
    hand: bool = False
    """Whether hand poses are looked for."""
    tuio_packets: int | None = None
    """TUIO bundles sent since start; null when TUIO is off."""
    tuio_errors: int | None = None
    """TUIO bundles that could not be sent; null when TUIO is off."""
    cost_p50_us: float | None = None
    """Median time the stage took per pair over the last status period, microseconds."""
    cost_p99_us: float | None = None
    """99th percentile of that time."""
    cost_max_us: float | None = None
    """Largest of that time (a hand look lands on one pair in every_n_pairs)."""


class RecordingStatusPart(_Part):
    """The daemon's recorder (docs/recording.md); present when the rig sets ``[recording] directory``."""

    state: Literal["idle", "recording", "finishing", "stopped", "failed"]
    """idle: available, not recording; recording; finishing: writing what is queued after a stop
    request; stopped: on request or at a limit; failed: a full disk or an error stopped it (see detail)."""
    path: str | None = None
    """The recording being written, or the last one."""
    pairs: int = Field(default=0, ge=0)
    """Pairs written to it."""
    written_mb: float = Field(default=0.0, ge=0.0)
    """Its size so far, MB (10^6 bytes)."""
    write_rate_mb_s: float = Field(default=0.0, ge=0.0)
    """Write rate over the last two seconds, MB/s."""
    pair_rate_hz: float = Field(default=0.0, ge=0.0)
    """Pairs written per second over the last two seconds."""
    dropped_pairs: int = Field(default=0, ge=0)
    """Pairs not recorded because the disk fell behind (the recorder's queue dropped its oldest)."""
    queued_pairs: int = Field(default=0, ge=0)
    """Pairs waiting to be written."""
    recorded_s: float = Field(default=0.0, ge=0.0)
    """Recorded time, from its first pair to the last written, seconds."""
    free_space_mb: float | None = None
    """Free space left on the recording's disk, MB."""
    detail: str | None = None
    """Why it stopped or failed, in one line."""


class StatusMessage(Message):
    """The daemon's health: sent about once a second, on every change, and to every new subscriber."""

    topic: Literal["status"] = "status"
    """Always ``status``."""
    state: DaemonState
    """starting (cameras not all streaming yet), running, degraded (a camera lost), reloading, stopping."""
    version: str
    """trackerd's version."""
    uptime_s: float = Field(ge=0.0)
    """Seconds since the daemon started."""
    rig: str
    """The rig's name (``name`` in the rig file)."""
    cameras: tuple[CameraStatusPart, ...]
    """Every camera of the rig, in rig order."""
    pairing: PairingPart
    """Frame pairing figures."""
    latency: LatencyPart
    """Capture-to-publish latency over the last status period."""
    processing: LatencyPart | None = None
    """The daemon's own latency over the last status period: from the arrival of the last frame
    of a pair to its messages being handed to ZeroMQ."""
    stages: dict[str, LatencyPart] = Field(default_factory=dict)
    """Time spent per pair in each stage (``detect``, ``triangulate``, ``publish``) over the last
    status period."""
    calibration: CalibrationHealthPart | None = None
    """Calibration health from the pointers tracked recently (null before any fix)."""
    fixes: dict[str, int] = Field(default_factory=dict)
    """Processed pairs since start by outcome: hit, off_wall, away, parallel, rejected, not_found."""
    messages: dict[str, int] = Field(default_factory=dict)
    """Messages published since start, by topic; filled in by the publisher."""
    dropped_messages: int = Field(default=0, ge=0)
    """Messages the publisher discarded because its own queue was full (never a subscriber's fault)."""
    detail: str | None = None
    """One line for humans: why the state is what it is (which camera is lost, ...)."""
    interaction: InteractionStatusPart | None = None
    """(1.1) Smoothing, events, gestures, hand poses and TUIO (docs/interaction.md); null when
    the interaction stage is off."""
    recording: RecordingStatusPart | None = None
    """(1.1) The daemon's recorder (docs/recording.md); null when the rig makes no recording available."""
    colours: ColourWatchPart | None = None
    """(1.4) The pointer's colours against the room's (docs/detection.md, "The colour watch"); null until
    first measured."""


class _WallPoint(Message):
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


class EnterMessage(_WallPoint):
    """The pointer started pointing at the display (its hit stayed on it for ``enter_after_ms``)."""

    topic: Literal["enter"] = "enter"
    """Always ``enter``."""


class LeaveMessage(_WallPoint):
    """The pointer stopped pointing at the display: off it (beyond the edge margin) or not seen,
    for ``leave_after_ms``. The position is the last one on the display."""

    topic: Literal["leave"] = "leave"
    """Always ``leave``."""
    reason: Literal["off_display", "lost"]
    """off_display: it points at the wall outside the display (or away); lost: no hit at all (the
    pointer is out of view, hidden, or points away from the wall)."""
    duration_ms: float = Field(ge=0.0)
    """Time from the ``enter`` to this ``leave``."""


class DwellMessage(_WallPoint):
    """Select (click): the hit stayed within ``radius_mm`` for ``time_ms``; once per rest."""

    topic: Literal["dwell"] = "dwell"
    """Always ``dwell``."""
    dwell_ms: float = Field(ge=0.0)
    """How long the hit had been still when the event was sent (at least the configured time)."""


class GestureMessage(_WallPoint):
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


TOPICS: dict[str, type[Message]] = {
    "hit": HitMessage,
    "pointer": PointerMessage,
    "status": StatusMessage,
    "enter": EnterMessage,
    "leave": LeaveMessage,
    "dwell": DwellMessage,
    "gesture": GestureMessage,
    "command": CommandMessage,
    "hand": HandMessage,
}
"""Every topic this version publishes, and its model."""


def _check_topics() -> None:
    names = sorted(TOPICS)
    for name, model in TOPICS.items():
        if model.model_fields["topic"].default != name:
            raise RuntimeError(f"TOPICS['{name}'] is {model.__name__}, whose topic is not '{name}'")
    for a in names:
        for b in names:
            if a != b and b.startswith(a):
                raise RuntimeError(f"topic '{b}' begins with topic '{a}': a subscription to '{a}' would get both")


_check_topics()


def encode(message: Message, update: Mapping[str, Any] | None = None) -> tuple[bytes, bytes]:
    """The two frames of ``message.model_copy(update=update)``: topic and UTF-8 JSON payload, the
    payload byte for byte ``model_dump_json``'s, written without the copy (trackerd.publish.payload)."""
    return message.topic.encode("ascii"), payload_json(message, update)


def decode(topic: bytes, payload: bytes) -> Message:
    """Parse a message this version knows, ignoring fields it does not (a newer MINOR).

    Raises ValueError for an unknown topic, a different MAJOR version or a payload
    that does not validate.
    """
    import json

    name = topic.decode("ascii", errors="replace")
    model = TOPICS.get(name)
    if model is None:
        raise ValueError(f"unknown topic '{name}'")
    data = json.loads(payload)
    version = str(data.get("schema_version", ""))
    if version.split(".")[0] != str(SCHEMA_MAJOR):
        raise ValueError(f"schema_version {version!r} is not {SCHEMA_MAJOR}.x")
    known = _known_only(model, data)
    return model.model_validate(known)


def _known_only(model: type[BaseModel], data: Any) -> Any:
    """Drop keys the model (and its sub-models) do not define: a newer MINOR's additions."""
    if not isinstance(data, dict):
        return data
    out = {}
    for key, value in data.items():
        field = model.model_fields.get(key)
        if field is None:
            continue
        sub = _part_type(field.annotation)
        if sub is not None and isinstance(value, list | tuple):
            out[key] = [_known_only(sub, v) for v in value]
        elif sub is not None and typing.get_origin(field.annotation) is dict and isinstance(value, dict):
            # A dict of parts (status.stages): its keys are names, not the part's fields.
            out[key] = {name: _known_only(sub, v) for name, v in value.items()}
        elif sub is not None:
            out[key] = _known_only(sub, value)
        else:
            out[key] = value
    return out


def _part_type(annotation: Any) -> type[BaseModel] | None:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        found = _part_type(arg)
        if found is not None:
            return found
    return None
