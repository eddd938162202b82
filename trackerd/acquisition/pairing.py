"""Grouping frames from several cameras into synchronized sets (pure logic, no threads).

Every camera's frames arrive in order. Each frame carries a *key*: its software
trigger count (exact: frames of the same trigger share it) or its estimated
capture time on the host clock (approximate: frames of one instant are within a
tolerance). The pairer keeps one short queue per camera and repeatedly looks at
the oldest frame of each queue:

* if the keys agree (equal counts, or capture times spread by at most the
  tolerance), the heads form a group;
* otherwise the head with the smallest key can never be matched, because every
  other camera's later frames have larger keys still; it is dropped and counted
  (``no_partner``);
* if some queue is empty, nothing can be decided yet.

Queues are bounded and drop their oldest frame (``queue_full``), so a camera
that stops delivering cannot make latency grow. A camera that reconnects starts
a new *epoch*: everything queued is discarded (``resync``), so no group ever
mixes frames from before and after a reconnection. While a camera is marked
inactive (lost), frames of the others are dropped on arrival (``partner_lost``).
Groups from trigger counts are also checked against the tolerance (``skew``):
equal counts with capture times far apart mean a mapping gone wrong.
"""

from __future__ import annotations

from collections import Counter, deque
from dataclasses import dataclass

from trackerd.acquisition.frame import Frame


@dataclass(frozen=True, slots=True)
class Arrival:
    """A frame on its way to pairing, with what pairing needs to know about it."""

    camera_index: int
    frame: Frame
    capture_ns: int
    """Estimated capture time on the host's monotonic clock."""
    epoch: int
    """Connection number of the camera: it increases every time the camera is (re)opened."""
    tick: int | None = None
    """Software trigger count the frame answers, when frames are paired by trigger."""


class Pairer:
    """Forms groups of one frame per camera. Not thread-safe: the caller serialises ``add``."""

    def __init__(self, n_cameras: int, tolerance_ns: int, queue_length: int, by_tick: bool) -> None:
        if n_cameras < 1:
            raise ValueError("need at least one camera")
        self.n_cameras = n_cameras
        self.tolerance_ns = int(tolerance_ns)
        self.queue_length = queue_length
        self.by_tick = by_tick
        self.dropped: Counter[str] = Counter()
        self._queues: list[deque[Arrival]] = [deque() for _ in range(n_cameras)]
        self._epochs: list[int | None] = [None] * n_cameras
        self._active = [True] * n_cameras

    def add(self, arrival: Arrival) -> list[tuple[Arrival, ...]]:
        """Queue one frame; returns the groups (in camera order) it completes, oldest first."""
        index = arrival.camera_index
        if self.by_tick and arrival.tick is None:
            raise ValueError("pairing by trigger count needs the frame's tick")
        if self._epochs[index] != arrival.epoch:
            if self._epochs[index] is not None:
                self.flush("resync")
            self._epochs[index] = arrival.epoch
        if not all(self._active):
            self.dropped["partner_lost"] += 1
            return []
        queue = self._queues[index]
        if len(queue) >= self.queue_length:
            queue.popleft()
            self.dropped["queue_full"] += 1
        queue.append(arrival)
        return self._match()

    def set_active(self, camera_index: int, active: bool) -> None:
        """Mark a camera lost (inactive) or back; going inactive discards what is queued."""
        if self._active[camera_index] and not active:
            self.flush("partner_lost")
        self._active[camera_index] = active

    def flush(self, cause: str) -> None:
        """Drop every queued frame, counting them under ``cause``."""
        for queue in self._queues:
            self.dropped[cause] += len(queue)
            queue.clear()

    @property
    def queued(self) -> int:
        return sum(len(q) for q in self._queues)

    def _key(self, arrival: Arrival) -> int:
        return arrival.tick if self.by_tick else arrival.capture_ns  # type: ignore[return-value]

    def _match(self) -> list[tuple[Arrival, ...]]:
        groups: list[tuple[Arrival, ...]] = []
        queues = self._queues
        tolerance = 0 if self.by_tick else self.tolerance_ns
        while all(queues):
            keys = [self._key(q[0]) for q in queues]
            low, high = min(keys), max(keys)
            if high - low > tolerance:
                for queue, key in zip(queues, keys, strict=True):
                    if high - key > tolerance:
                        queue.popleft()
                        self.dropped["no_partner"] += 1
                continue
            group = tuple(q.popleft() for q in queues)
            if self.by_tick and spread_ns(group) > self.tolerance_ns:
                self.dropped["skew"] += len(group)
                continue
            groups.append(group)
        return groups


def spread_ns(group: tuple[Arrival, ...]) -> int:
    """Latest minus earliest capture time in a group."""
    times = [a.capture_ns for a in group]
    return max(times) - min(times)
