"""Every topic and its model, and the two frames a message travels as: encode and decode."""

from __future__ import annotations

import json
import typing
from collections.abc import Mapping
from typing import Any

from pydantic import BaseModel

from trackerd.publish.messages.envelope import SCHEMA_MAJOR, Message
from trackerd.publish.messages.events import (
    CommandMessage,
    DwellMessage,
    EnterMessage,
    GestureMessage,
    HandMessage,
    LeaveMessage,
)
from trackerd.publish.messages.pointing import HitMessage, PointerMessage
from trackerd.publish.messages.status import StatusMessage
from trackerd.publish.payload import payload_json

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
    out: dict[str, Any] = {}
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
