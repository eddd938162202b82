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

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

SCHEMA_VERSION = "1.0"
"""MAJOR.MINOR of the message set this code writes."""

SCHEMA_MAJOR = int(SCHEMA_VERSION.split(".")[0])

Vec3M = tuple[float, float, float]

FixStatus = Literal["hit", "off_wall", "away", "parallel"]
CameraState = Literal["connecting", "streaming", "lost", "reconnecting", "stopped"]
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
    share it); status: counts status messages. Gaps in hit/pointer are normal (pairs without a pointer)."""
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
    method: Literal["planes", "points"]
    """How the line was estimated: interpretation planes, or the report's two triangulated points
    (used when the planes are ill-conditioned)."""


class CameraStatusPart(_Part):
    """One camera's state in a status message."""

    id: str
    """The camera's id in the rig (``left``, ``right``, ...)."""
    state: CameraState
    """connecting (first open), streaming, lost (no frames, no answer), reconnecting, stopped."""
    frame_rate_hz: float = Field(ge=0.0)
    """Frames delivered per second over the last second or so."""
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
    ``resync``, ``skew``); totals since start."""
    dropped_pairs: int = Field(default=0, ge=0)
    """Pairs discarded because processing fell behind (the oldest is dropped)."""
    skew_p50_us: float | None = None
    """Median capture-time difference between the frames of a pair, microseconds."""
    skew_p99_us: float | None = None
    """99th percentile pair skew, microseconds."""


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


TOPICS: dict[str, type[Message]] = {
    "hit": HitMessage,
    "pointer": PointerMessage,
    "status": StatusMessage,
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


def encode(message: Message) -> tuple[bytes, bytes]:
    """The two frames of a message: topic and UTF-8 JSON payload."""
    return message.topic.encode("ascii"), message.model_dump_json().encode("utf-8")


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
        elif sub is not None:
            out[key] = _known_only(sub, value)
        else:
            out[key] = value
    return out


def _part_type(annotation: Any) -> type[BaseModel] | None:
    from typing import get_args

    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in get_args(annotation):
        found = _part_type(arg)
        if found is not None:
            return found
    return None
