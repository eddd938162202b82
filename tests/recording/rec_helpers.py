"""Helpers of the recording tests: the CLI as a process, a subscriber, comparisons."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import zmq

DATA = Path(__file__).resolve().parent.parent / "data" / "recording"
BUNDLE = DATA / "figure8-leave.trec"
"""16 rendered 1920x1080 Bayer pairs (scripts/make_test_recording.py); pairs 10 and 11 have no pointer."""


def trackerd(*args: str | Path, timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
    """Run the CLI as a process, as an operator would."""
    return subprocess.run(
        [sys.executable, "-m", "trackerd", *map(str, args)], capture_output=True, text=True, timeout=timeout
    )


def one_line_error(run: subprocess.CompletedProcess[str], command: str, *fragments: str) -> str:
    """The run failed with exit 1 and exactly one error line naming ``fragments``, no traceback."""
    assert run.returncode == 1, (run.returncode, run.stderr)
    assert "Traceback" not in run.stderr, run.stderr
    errors = [line for line in run.stderr.splitlines() if line.startswith(f"trackerd {command}:")]
    assert len(errors) == 1, run.stderr
    for fragment in fragments:
        assert fragment in errors[0], errors[0]
    return errors[0]


def replay_and_listen(
    *args: str | Path, endpoint: str, timeout: float = 120.0
) -> tuple[subprocess.CompletedProcess[str], list[tuple[str, dict[str, Any]]]]:
    """Run `trackerd replay ... --endpoint E` as a process and collect everything it publishes.

    The subscriber connects before the replay binds; replay's --delay (1 s by default) lets the
    connection complete before the first pair, so nothing is lost to ZeroMQ's slow joiner.
    """
    ctx = zmq.Context()
    sub = ctx.socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"")
    sub.setsockopt(zmq.RCVHWM, 0)
    sub.connect(endpoint)
    messages: list[tuple[str, dict[str, Any]]] = []
    process = subprocess.Popen(
        [sys.executable, "-m", "trackerd", "replay", *map(str, args), "--endpoint", endpoint],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )

    def stopped() -> bool:
        return bool(messages) and messages[-1][0] == "status" and messages[-1][1].get("state") == "stopping"

    try:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if sub.poll(50):
                topic, payload = sub.recv_multipart()
                messages.append((topic.decode(), json.loads(payload)))
            elif process.poll() is not None:
                break
        # The process has gone; what it published last may still be on its way. A replay that ran
        # ends with a 'stopping' status: read until it (one that failed may never have published).
        drain_until = time.monotonic() + (5.0 if process.returncode == 0 else 0.3)
        while not stopped() and time.monotonic() < drain_until:
            if sub.poll(50):
                topic, payload = sub.recv_multipart()
                messages.append((topic.decode(), json.loads(payload)))
        out, err = process.communicate(timeout=10)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
        sub.close(0)
        ctx.term()
    return subprocess.CompletedProcess(process.args, process.returncode, out, err), messages


def without_publish_time(messages: list[tuple[str, dict[str, Any]]], topics: tuple[str, ...] = ()) -> list[str]:
    """Every message but status, as canonical JSON without publish_ns (what must repeat bit for bit)."""
    out = []
    for topic, payload in messages:
        if topic == "status" or (topics and topic not in topics):
            continue
        data = {k: v for k, v in payload.items() if k != "publish_ns"}
        out.append(topic + " " + json.dumps(data, sort_keys=True))
    return out


def unsmoothed_xy(hit: dict[str, Any]) -> tuple[float, float]:
    """A hit's wall position as the locator found it (the interaction stage may smooth wall_x_m and
    then publishes the locator's value as raw_wall_x_m)."""
    if hit.get("raw_wall_x_m") is not None:
        return hit["raw_wall_x_m"], hit["raw_wall_y_m"]
    return hit["wall_x_m"], hit["wall_y_m"]


INTERACTION_TOPICS = ("hit", "enter", "leave", "dwell", "gesture", "command")


def interaction_events(messages: list[tuple[str, dict[str, Any]]], shift: int = 0) -> list[tuple[str, int, str]]:
    """The hits and interaction events as (topic, sequence - shift, payload), in order, without what
    differs between a live run and its replay or between loop passes (times and ``cursor_id``,
    which counts sessions since the process started)."""
    strip = {"publish_ns", "capture_ns", "cursor_id", "sequence"}
    return [
        (topic, m["sequence"] - shift, json.dumps({k: v for k, v in m.items() if k not in strip}, sort_keys=True))
        for topic, m in messages
        if topic in INTERACTION_TOPICS
    ]
