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

The models are split by kind: the envelope (``envelope``), the pointer's topics
(``pointing``), the daemon's health (``status``), the interaction stage's events
(``events``), and the registry of topics with encode/decode (``topics``). Import
them from here.

Adding a topic: subclass :class:`Message` in the module of its kind, give it
``topic: Literal["name"]`` and register it in :data:`TOPICS` (``topics``). A
topic's name must not begin with another topic's name, because ZeroMQ
subscriptions match by prefix.
"""

from __future__ import annotations

from trackerd.publish.messages.envelope import SCHEMA_MAJOR, SCHEMA_VERSION, Message, Part
from trackerd.publish.messages.events import (
    CommandMessage,
    DwellMessage,
    EnterMessage,
    GestureMessage,
    HandMessage,
    LeaveMessage,
    WallPoint,
)
from trackerd.publish.messages.pointing import FixStatus, HitMessage, PointerMessage, Vec3M
from trackerd.publish.messages.status import (
    CalibrationHealthPart,
    CameraState,
    CameraStatusPart,
    ColourFigurePart,
    ColourWatchPart,
    DaemonState,
    InteractionStatusPart,
    LatencyPart,
    PairingPart,
    RecordingStatusPart,
    SpreadPart,
    StatusMessage,
)
from trackerd.publish.messages.topics import TOPICS, decode, encode

__all__ = [
    "SCHEMA_MAJOR",
    "SCHEMA_VERSION",
    "TOPICS",
    "CalibrationHealthPart",
    "CameraState",
    "CameraStatusPart",
    "ColourFigurePart",
    "ColourWatchPart",
    "CommandMessage",
    "DaemonState",
    "DwellMessage",
    "EnterMessage",
    "FixStatus",
    "GestureMessage",
    "HandMessage",
    "HitMessage",
    "InteractionStatusPart",
    "LatencyPart",
    "LeaveMessage",
    "Message",
    "PairingPart",
    "Part",
    "PointerMessage",
    "RecordingStatusPart",
    "SpreadPart",
    "StatusMessage",
    "Vec3M",
    "WallPoint",
    "decode",
    "encode",
]
