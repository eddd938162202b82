"""The minimal subscribers shown in docs/protocol.md work against a real publisher."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.publish.conftest import hit_message, status_message
from trackerd.config.models import ZmqOutput
from trackerd.publish import SCHEMA_VERSION, Publisher

PROTOCOL = Path(__file__).resolve().parents[2] / "docs" / "protocol.md"


def _example(name: str) -> str:
    match = re.search(rf"<!-- example:{name} -->\n```\w+\n(.*?)```", PROTOCOL.read_text(), re.S)
    assert match, f"docs/protocol.md has no example:{name}"
    return match.group(1)


def _lines_until_status(command: list[str]) -> list[str]:
    """Run a subscriber against a publisher sending status once, then hits every 20 ms, until it
    printed the status and a hit; its lines in order. The only status sent before the subscriber
    connects, so a status line is the last-value answer to its subscription."""
    with Publisher(ZmqOutput(endpoints=("tcp://127.0.0.1:*",))) as publisher:
        publisher.publish_status(status_message(state="running"))
        process = subprocess.Popen([*command, publisher.endpoints[0]], stdout=subprocess.PIPE, text=True)
        lines: list[str] = []
        try:
            deadline = time.monotonic() + 15
            import selectors

            selector = selectors.DefaultSelector()
            selector.register(process.stdout, selectors.EVENT_READ)
            while time.monotonic() < deadline and not (
                any(line.startswith("status") for line in lines) and any(line.startswith("hit") for line in lines)
            ):
                publisher.publish(hit_message())
                if selector.select(timeout=0.02):
                    lines.append(process.stdout.readline().strip())
        finally:
            process.kill()
            process.wait()
    return lines


def _late_joiner_status(lines: list[str]) -> str:
    """The status line: only one status was published, before the subscriber started, so it is
    the last-value answer. It usually comes first; hits sent while the subscription was on its way
    may come before it, and the same status may come twice (docs/protocol.md, "Late joiners")."""
    statuses = {line for line in lines if line.startswith("status")}
    assert len(statuses) == 1, lines
    return statuses.pop()


def test_python_subscriber(tmp_path):
    script = tmp_path / "subscriber.py"
    script.write_text(_example("python"))
    lines = _lines_until_status([sys.executable, str(script)])
    assert _late_joiner_status(lines) == "status running"
    assert "hit 1.234 0.567 m on_wall=True" in lines


def test_c_subscriber(tmp_path):
    if shutil.which("cc") is None or shutil.which("pkg-config") is None:
        pytest.skip("no C compiler or pkg-config")
    flags = subprocess.run(["pkg-config", "--cflags", "--libs", "libzmq"], capture_output=True, text=True)
    if flags.returncode != 0:
        pytest.skip("libzmq headers are not installed (Debian package libzmq3-dev)")
    source = tmp_path / "subscriber.c"
    source.write_text(_example("c"))
    binary = tmp_path / "subscriber"
    subprocess.run(["cc", "-Wall", "-Werror", str(source), "-o", str(binary), *flags.stdout.split()], check=True)
    lines = _lines_until_status([str(binary)])
    assert _late_joiner_status(lines).startswith(f'status {{"schema_version":"{SCHEMA_VERSION}","topic":"status"')
    hits = [line for line in lines if line.startswith("hit ")]
    assert hits and all(h.startswith(f'hit {{"schema_version":"{SCHEMA_VERSION}","topic":"hit"') for h in hits)


def test_every_json_example_in_the_protocol_doc_decodes_as_the_current_version():
    """The examples are what a subscriber sees: each is valid for its topic, and one that states a
    version states this one (the hit example said 1.0 after the protocol reached 1.2)."""
    import json

    from trackerd.publish import decode

    examples = re.findall(r"```json\n(.*?)```", PROTOCOL.read_text(), re.S)
    lines = [line for block in examples for line in block.splitlines() if line.startswith("{")]
    assert len(lines) >= 5
    for line in lines:
        data = json.loads(line)
        if "schema_version" in data:
            assert data["schema_version"] == SCHEMA_VERSION, line[:80]
        else:
            data["schema_version"] = SCHEMA_VERSION
        defaults = {"sequence": 1, "capture_ns": 1, "publish_ns": 2}
        message = decode(data["topic"].encode(), json.dumps({**defaults, **data}).encode())
        assert message.topic == data["topic"]
