"""Pairs held back until a test's subscriber is known to be connected.

A ZeroMQ subscriber that connects before the publisher binds joins on its next
reconnection attempt, up to a couple of hundred milliseconds later (and a
loaded machine adds its own delay); whatever is published before then is not
seen. Tests that must see the first pairs' messages (a command published once,
the first sequence number) serve them from a :class:`GatedPairSource` and open
it once :func:`wait_for_status` has received the pipeline's first status.
"""

from __future__ import annotations

import json
import time

import zmq

from trackerd.acquisition.memory import MemoryPairSource


class GatedPairSource(MemoryPairSource):
    """A memory source that the pipeline starts but that serves nothing until :meth:`open`."""

    def start(self) -> None:
        pass  # the test starts it, with open()

    def open(self) -> None:
        """Start serving, paced from now."""
        super().start()


def wait_for_status(sub: zmq.Socket, timeout_s: float = 20.0) -> list[tuple[str, dict]]:
    """Read ``sub`` until a status arrives; every message read, in order. AssertionError on timeout."""
    received = []
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if sub.poll(50):
            topic, payload = sub.recv_multipart()
            received.append((topic.decode(), json.loads(payload)))
            if received[-1][0] == "status":
                return received
    raise AssertionError(f"no status within {timeout_s:g} s: the subscriber never joined")
