"""Fixtures for the publisher tests: real publishers on loopback and ipc://, real subscribers."""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import zmq

from trackerd.config.models import ZmqOutput
from trackerd.publish import (
    CameraStatusPart,
    HitMessage,
    LatencyPart,
    PairingPart,
    PointerMessage,
    Publisher,
    StatusMessage,
)

REPO = Path(__file__).resolve().parents[2]
SCHEMA_DIR = REPO / "docs" / "schema"


def hit_message(sequence: int = 1) -> HitMessage:
    return HitMessage(
        sequence=sequence,
        capture_ns=time.time_ns(),
        wall_x_m=1.234,
        wall_y_m=0.567,
        display_x_px=2951.0,
        display_y_px=733.0,
        on_wall=True,
        distance_m=1.8,
        front_m=(1.31, 1.02, 1.95),
        back_m=(1.35, 1.1, 2.39),
        ray_gap_mm=0.9,
        uncertainty_mm=1.8,
    )


def pointer_message(sequence: int = 1) -> PointerMessage:
    return PointerMessage(
        sequence=sequence,
        capture_ns=time.time_ns(),
        status="away",
        front_colour="red",
        front_m=(1.0, 1.0, 2.0),
        back_m=(1.0, 1.0, 1.55),
        direction=(0.0, 0.0, 1.0),
        length_m=0.45,
        front_gap_mm=0.8,
        back_gap_mm=1.1,
        method="planes",
    )


def status_message(sequence: int = 1, state: str = "running") -> StatusMessage:
    return StatusMessage(
        sequence=sequence,
        capture_ns=time.time_ns(),
        state=state,
        version="0.1.0",
        uptime_s=12.5,
        rig="test",
        cameras=(
            CameraStatusPart(id="left", state="streaming", frame_rate_hz=60.0, frames=750),
            CameraStatusPart(
                id="right",
                state="lost",
                frame_rate_hz=0.0,
                frames=700,
                dropped={"timeout": 3},
                losses=1,
                last_error="no frame for 1000 ms",
            ),
        ),
        pairing=PairingPart(
            pair_rate_hz=30.0, pairs=690, dropped_frames={"no_partner": 4}, skew_p50_us=40.0, skew_p99_us=120.0
        ),
        latency=LatencyPart(samples=30, p50_ms=8.1, p90_ms=9.5, p99_ms=12.0, max_ms=13.2),
        fixes={"hit": 600, "not_found": 90},
        detail="right: lost",
    )


@pytest.fixture
def schemas() -> dict[str, dict]:
    """The committed JSON Schemas, by topic."""
    return {path.stem: json.loads(path.read_text()) for path in SCHEMA_DIR.glob("*.json")}


@pytest.fixture
def context() -> Iterator[zmq.Context]:
    ctx = zmq.Context()
    yield ctx
    ctx.destroy(linger=0)


@pytest.fixture
def tcp_publisher() -> Iterator[Publisher]:
    with Publisher(ZmqOutput(endpoints=("tcp://127.0.0.1:*",))) as publisher:
        yield publisher


def subscriber(context: zmq.Context, endpoint: str, *topics: bytes, **options: int) -> zmq.Socket:
    sub = context.socket(zmq.SUB)
    sub.setsockopt(zmq.LINGER, 0)
    for name, value in options.items():
        sub.setsockopt(getattr(zmq, name), value)
    for topic in topics or (b"",):
        sub.subscribe(topic)
    sub.connect(endpoint)
    return sub


def publish_until_received(publisher: Publisher, sub: zmq.Socket, message, timeout_s: float = 5.0) -> list[bytes]:
    """Publish repeatedly until the subscriber's connection is up and one copy arrives (the slow-joiner gap)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        publisher.publish(message)
        if sub.poll(20):
            return sub.recv_multipart()
    raise AssertionError(f"nothing arrived within {timeout_s} s")
