"""Publishing results over ZeroMQ: the wire protocol's messages and the publisher (docs/protocol.md).

The pipeline builds messages (``messages_from_fix`` for each processed pair, a
``StatusMessage`` about once a second) and hands them to one :class:`Publisher`
from one thread.
"""

from trackerd.publish.from_fix import messages_from_fix
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
from trackerd.publish.publisher import Publisher, PublishError

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
