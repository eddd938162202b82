"""The envelope every message carries, the base of its parts, and the schema's version."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

SCHEMA_VERSION = "1.4"
"""MAJOR.MINOR of the message set this code writes."""

SCHEMA_MAJOR = int(SCHEMA_VERSION.split(".")[0])


class Part(BaseModel):
    """Base of every message and sub-object: closed for the producer (a misspelt field is a bug
    caught here), while subscribers are told to ignore unknown fields (the exported schemas allow them)."""

    model_config = ConfigDict(
        extra="forbid",
        use_attribute_docstrings=True,
        allow_inf_nan=False,
        json_schema_serialization_defaults_required=True,
    )


class Message(Part):
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
