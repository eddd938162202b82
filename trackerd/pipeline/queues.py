"""A bounded queue between pipeline stages that drops its oldest item when full.

Real time means latency stays bounded: when a consumer falls behind, the item
it would have seen last (the oldest) is thrown away and counted, and the newest
is always kept. A silent backlog is never acceptable. The one exception is a
replay as fast as possible, where nothing is late and every pair's messages are
wanted: there the producer waits for room (:meth:`DropOldestQueue.put_waiting`).
"""

from __future__ import annotations

import threading
from collections import deque
from typing import Generic, TypeVar

T = TypeVar("T")


class DropOldestQueue(Generic[T]):
    """Thread-safe, bounded; ``put`` never blocks, ``get`` waits with a timeout."""

    def __init__(self, maxlen: int) -> None:
        if maxlen < 1:
            raise ValueError("maxlen must be at least 1")
        self._items: deque[T] = deque()
        self._maxlen = maxlen
        self._cond = threading.Condition()
        self.dropped = 0
        """Items discarded because the queue was full."""

    def put(self, item: T) -> bool:
        """Append ``item``; returns False when the oldest item had to be dropped to make room."""
        with self._cond:
            kept_all = len(self._items) < self._maxlen
            if not kept_all:
                self._items.popleft()
                self.dropped += 1
            self._items.append(item)
            self._cond.notify()
            return kept_all

    def put_waiting(self, item: T, stop: threading.Event, poll_s: float = 0.05) -> bool:
        """Append ``item`` once there is room, waiting as long as that takes unless ``stop`` is set
        (then as :meth:`put`). For a producer with no deadline: a replay as fast as possible."""
        with self._cond:
            while len(self._items) >= self._maxlen and not stop.is_set():
                self._cond.wait(poll_s)
        return self.put(item)

    def get(self, timeout_s: float) -> T | None:
        """The oldest item, waiting at most ``timeout_s``; None on timeout."""
        with self._cond:
            if not self._items and not self._cond.wait_for(lambda: bool(self._items), timeout=timeout_s):
                return None
            item = self._items.popleft()
            if len(self._items) == self._maxlen - 1:
                self._cond.notify_all()  # a producer may be waiting for room (put_waiting)
            return item

    def __len__(self) -> int:
        with self._cond:
            return len(self._items)
