"""Publishing results over ZeroMQ: the wire protocol's messages and the publisher (docs/protocol.md).

The pipeline builds messages (``messages_from_fix`` for each processed pair, a
``StatusMessage`` about once a second) and hands them to one :class:`Publisher`
from one thread.

``Publisher`` and ``messages_from_fix`` are imported on first use: the messages alone
are what a subscriber needs, and they load in a fraction of the time the locator and the
rig's configuration models take.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from trackerd.publish.messages import (
    SCHEMA_VERSION,
    TOPICS,
    CameraStatusPart,
    HitMessage,
    LatencyPart,
    Message,
    PairingPart,
    PointerMessage,
    StatusMessage,
    decode,
    encode,
)

if TYPE_CHECKING:
    from trackerd.publish.from_fix import messages_from_fix
    from trackerd.publish.publisher import Publisher, PublishError

_LAZY = {"Publisher": "publisher", "PublishError": "publisher", "messages_from_fix": "from_fix"}

__all__ = [
    "SCHEMA_VERSION",
    "TOPICS",
    "CameraStatusPart",
    "HitMessage",
    "LatencyPart",
    "Message",
    "PairingPart",
    "PointerMessage",
    "PublishError",
    "Publisher",
    "StatusMessage",
    "decode",
    "encode",
    "messages_from_fix",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(f"trackerd.publish.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
