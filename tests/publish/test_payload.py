"""The publisher's payloads (orjson, trackerd.publish.payload) are byte for byte pydantic's ``model_dump_json``.

pydantic's output is the reference: the bytes subscribers got before the hot path stopped going
through it. Held on the wire output of a real replay (data/replay_wire.txt: `trackerd replay` of
tests/data/recording/figure8-leave.trec with pydantic's encoder, every topic it publishes), on the
locator's messages for hundreds of pointer poses, on every example of docs/protocol.md, and on
generated messages of every topic with awkward values (NaN, infinities, subnormal and huge floats,
None, 64-bit integers, any Unicode text).
"""

from __future__ import annotations

import json
import re
import time
import types
import typing
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import BaseModel

from tests.publish.conftest import hit_message, status_message, subscriber
from trackerd.locator import Locator
from trackerd.publish import messages_from_fix
from trackerd.publish.messages import SCHEMA_VERSION, TOPICS, HitMessage, Message, decode, encode

REPLAY_WIRE = Path(__file__).resolve().parent / "data" / "replay_wire.txt"
PROTOCOL = Path(__file__).resolve().parents[2] / "docs" / "protocol.md"
PUBLISH_NS = 1_795_005_000_123_456_789


def _reference(message: Message, update: dict[str, object]) -> bytes:
    """What the publisher sent before: a stamped copy, dumped by pydantic."""
    return message.model_copy(update=update).model_dump_json().encode("utf-8")


def _same_as_pydantic(message: Message, update: dict[str, object] | None = None) -> None:
    update = {"publish_ns": PUBLISH_NS} if update is None else update
    topic, payload = encode(message, update)
    assert topic == message.topic.encode("ascii")
    assert payload == _reference(message, update)


def test_a_real_replay_is_reproduced_byte_for_byte():
    """Each payload the daemon sent, read back and written again with its own publish time, gives the
    same bytes: key order, float text and nested status parts included."""
    lines = REPLAY_WIRE.read_bytes().splitlines()
    topics = set()
    for line in lines:
        topic, payload = line.split(b" ", 1)
        message = decode(topic, payload)
        stamp = {"publish_ns": json.loads(payload)["publish_ns"]}
        assert encode(message, stamp) == (topic, payload)
        topics.add(topic.decode())
    assert topics == {"hit", "pointer", "status", "enter", "leave"}


def test_the_locators_messages_for_many_poses(simulated_rig):
    """Pointers all over the room, at the display, off it and away from the wall, exactly located
    (their ends projected into each camera), and each hit also as the interaction stage rewrites it."""
    locator = Locator(simulated_rig)
    rng = np.random.default_rng(16)
    length_m = simulated_rig.pointer.length_m
    statuses: dict[str, int] = {}
    hits = 0
    for sequence in range(300):
        front = rng.uniform([0.3, 0.1, 1.0], [3.5, 1.3, 2.6])
        direction = rng.normal(size=3) + np.array([0.0, 0.0, 1.5])  # mostly the back end further from the wall
        back = front + length_m * direction / np.linalg.norm(direction)
        centroids = []
        for camera in locator.cameras:
            front_px, back_px = camera.project(np.array([front, back]))
            centroids.append({locator.front_colour: front_px, locator.back_colour: back_px})
        fix = locator.locate_centroids(tuple(centroids))
        locator.reset()
        for message in messages_from_fix(fix, locator, sequence=sequence, capture_ns=PUBLISH_NS - 4_000_000):
            _same_as_pydantic(message)
            if isinstance(message, HitMessage):
                hits += 1
                smoothed = message.model_copy(
                    update={
                        "wall_x_m": message.wall_x_m * 0.999,
                        "wall_y_m": message.wall_y_m + 1e-9,
                        "on_wall": not message.on_wall,
                        "raw_wall_x_m": message.wall_x_m,
                        "raw_wall_y_m": message.wall_y_m,
                        "raw_display_x_px": message.display_x_px,
                        "raw_display_y_px": message.display_y_px,
                        "cursor_id": 3,
                    }
                )
                _same_as_pydantic(smoothed)
            else:
                statuses[message.status] = statuses.get(message.status, 0) + 1
    assert hits >= 50 and {"hit", "off_wall", "away"} <= statuses.keys(), (hits, statuses)


def test_every_example_of_the_protocol_doc():
    examples = re.findall(r"```json\n(.*?)```", PROTOCOL.read_text(), re.S)
    lines = [line for block in examples for line in block.splitlines() if line.startswith("{")]
    assert len(lines) >= 5
    for line in lines:
        data = {"schema_version": SCHEMA_VERSION, "sequence": 1, "capture_ns": 1, "publish_ns": 2, **json.loads(line)}
        _same_as_pydantic(decode(data["topic"].encode(), json.dumps(data).encode()))


def test_the_status_the_publisher_fills_in():
    message = status_message()
    _same_as_pydantic(message, {"publish_ns": PUBLISH_NS, "messages": {"hit": 3, "status": 2}, "dropped_messages": 1})


def test_numpy_scalars_in_an_update_are_written_as_their_values():
    """pydantic writes a NumPy float or bool given to ``model_copy`` as the Python value; so does the encoder."""
    update = {
        "wall_x_m": np.float64(0.1),
        "distance_m": np.float32(0.1),
        "on_wall": np.bool_(False),
        "cursor_id": np.int64(4),
        "front_m": (np.float64(1.0), np.float32(0.2), 3.0),
    }
    _same_as_pydantic(hit_message().model_copy(update=update))
    with pytest.raises(TypeError):  # pydantic refuses an array too
        encode(hit_message(), {"front_m": np.array([1.0, 2.0, 3.0])})


def test_a_misspelt_update_is_refused_and_stray_attributes_are_left_out():
    with pytest.raises(ValueError, match="HitMessage has no field publish_nss"):
        encode(hit_message(), {"publish_nss": 1})
    stray = hit_message().model_copy(update={"wall_z_m": 1.0})  # model_copy does not check names
    _same_as_pydantic(stray)
    assert b"wall_z_m" not in encode(stray)[1]


# ------------------------------------------------------------------ generated messages

AWKWARD_FLOATS = [
    0.0,
    -0.0,
    0.1,
    1 / 3,
    1e-4,
    1e-5,
    1e-7,
    1e15,
    1e16,
    9.999999999999999e15,
    1.5e300,
    5e-324,
    2.2250738585072014e-308,
    1.7976931348623157e308,
    float("nan"),
    float("inf"),
    float("-inf"),
]


def _values(annotation: object) -> st.SearchStrategy:
    """Values of a field's type, NaN and the like included: ``model_construct`` does not validate."""
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is typing.Literal:
        return st.sampled_from(args)
    if origin in (typing.Union, types.UnionType):
        return st.one_of([st.none() if arg is type(None) else _values(arg) for arg in args])
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return st.lists(_values(args[0]), max_size=2).map(tuple)
        return st.tuples(*map(_values, args))
    if origin is dict:
        return st.dictionaries(st.text(max_size=8), _values(args[1]), max_size=2)
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return _model(annotation)
    if annotation is bool:
        return st.booleans()
    if annotation is int:
        return st.integers(-(2**63), 2**64 - 1)
    if annotation is float:
        return st.floats() | st.sampled_from(AWKWARD_FLOATS)
    if annotation is str:
        return st.text(max_size=12)
    raise AssertionError(f"no values for {annotation!r}: teach _values this type")


def _model(model: type[BaseModel]) -> st.SearchStrategy:
    fields = {name: _values(field.annotation) for name, field in model.model_fields.items()}
    return st.fixed_dictionaries(fields).map(lambda values: model.model_construct(**values))


@pytest.mark.parametrize("topic", sorted(TOPICS))
def test_generated_messages_of_every_topic(topic):
    # A status holds a dozen parts: fewer of them, each far larger than a hit.
    @settings(max_examples=30 if topic == "status" else 80, deadline=None)
    @given(message=_model(TOPICS[topic]), publish_ns=st.integers(0, 2**64 - 1))
    def check(message: Message, publish_ns: int) -> None:
        _same_as_pydantic(message, {"publish_ns": publish_ns})

    check()


# ------------------------------------------------------------------ through the publisher


def test_what_a_subscriber_receives(tcp_publisher, context):
    """A hit and a status as they arrive, against pydantic's dump with the stamps the publisher gave them."""
    sub = subscriber(context, tcp_publisher.endpoints[0], b"hit", b"status")
    hit, status = hit_message(7), status_message(2)
    received: dict[bytes, bytes] = {}
    deadline = time.monotonic() + 5.0
    while len(received) < 2 and time.monotonic() < deadline:  # until the subscription is through
        tcp_publisher.publish(hit)
        tcp_publisher.publish_status(status)
        while sub.poll(20):
            topic, payload = sub.recv_multipart()
            received[topic] = payload
    assert received.keys() == {b"hit", b"status"}
    sent_hit = json.loads(received[b"hit"])
    assert received[b"hit"] == _reference(hit, {"publish_ns": sent_hit["publish_ns"]})
    sent_status = json.loads(received[b"status"])
    stamps = {key: sent_status[key] for key in ("publish_ns", "messages", "dropped_messages")}
    assert sent_status["messages"]["status"] >= 1
    assert received[b"status"] == _reference(status, stamps)
