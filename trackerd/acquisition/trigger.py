"""Software triggering: a shared tick schedule, an all-or-none gate, and which tick a frame answers.

Every camera thread fires its own camera on the same schedule (tick ``k`` is due
at ``start + k * period`` on the monotonic clock), so a camera that stops
answering delays no one else. Whether tick ``k`` is fired at all is decided once
for every camera by the :class:`TriggerGate`: it is skipped for all when some
camera is not ready (it has not delivered its first frame since connecting, or
has too many triggers unanswered), so the cameras' frame counters advance
together. Each accepted trigger makes the camera expose one frame and advance
its frame counter by one, so the ``n``-th frame id after the first answers the
``n``-th tick fired: :class:`TickMap` keeps that correspondence. To be sure which
frame is the first, a camera that (re)connects fires one tick and waits for its
frame before more are fired.
"""

from __future__ import annotations

import threading
from collections import OrderedDict, deque
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class TickSchedule:
    """Tick ``k`` is due at ``start_ns + k * period_ns`` (monotonic clock)."""

    start_ns: int
    period_ns: int

    def due_ns(self, tick: int) -> int:
        return self.start_ns + tick * self.period_ns

    def next_tick(self, after_tick: int | None, now_ns: int, max_late_ticks: int = 4) -> int:
        """The tick to fire next: the one after ``after_tick``, even if it is a little late.

        Firing every tick in order keeps the cameras' frame counters in step. Only
        a thread that fell more than ``max_late_ticks`` behind (it was stalled)
        jumps to the current tick rather than fire a burst of stale triggers. The
        first tick is the next one due.
        """
        current = (now_ns - self.start_ns) // self.period_ns
        if after_tick is None:
            return max(0, current + 1)
        candidate = after_tick + 1
        return current if current - candidate > max_late_ticks else candidate


class TickMap:
    """Which fired tick each frame id answers, for one connection of one camera (thread-safe).

    A frame that never arrives (not one of its packets reached the host) leaves
    its trigger unanswered until the next frame's id shows the gap; with
    ``max_outstanding`` triggers unanswered the camera takes no more, so a camera
    whose frames stop coming stalls until it is declared lost and reconnected.
    Unanswered triggers are deliberately never given up on: firing another while
    the camera may still hold one risks the camera merging the two into one
    frame, after which every later frame would be matched to the wrong tick.
    """

    def __init__(self, max_outstanding: int = 3) -> None:
        self.max_outstanding = max_outstanding
        self._lock = threading.Lock()
        self._fired: deque[int] = deque()
        self._next_index = 0  # position (frame ids after the first) of _fired[0]
        self._first_id: int | None = None
        self.unmatched = 0
        """Frames whose id has no fired tick (a frame the camera sent unasked, say)."""

    @property
    def started(self) -> bool:
        """Whether the first frame has arrived (until then only one tick may be outstanding)."""
        return self._first_id is not None

    @property
    def outstanding(self) -> int:
        """Ticks fired whose frame has not arrived yet."""
        return len(self._fired)

    def ready(self) -> bool:
        """Whether the camera may take another trigger: its first frame is in (or nothing is
        outstanding yet), and fewer than ``max_outstanding`` triggers are unanswered."""
        with self._lock:
            if self._first_id is None:
                return not self._fired
            return len(self._fired) < self.max_outstanding

    def fired(self, tick: int) -> None:
        with self._lock:
            self._fired.append(tick)

    def frame(self, frame_id: int) -> int | None:
        with self._lock:
            return self._frame(frame_id)

    def _frame(self, frame_id: int) -> int | None:
        """The tick answered by the frame with this (unwrapped) id, or None if it answers none.

        Frames that never arrived (ids skipped) consume their ticks, so later
        frames keep their correspondence.
        """
        if self._first_id is None:
            if not self._fired:
                self.unmatched += 1
                return None
            self._first_id = frame_id
        index = frame_id - self._first_id
        while self._fired and self._next_index < index:
            self._fired.popleft()
            self._next_index += 1
        if index != self._next_index or not self._fired:
            self.unmatched += 1
            return None
        self._next_index += 1
        return self._fired.popleft()


class TriggerGate:
    """Decides once per tick, for every camera, whether the tick is fired (thread-safe).

    A tick is fired when every camera is ready. A camera that has not been ready
    for more than ``stall_ticks`` decisions in a row (it stopped answering, and
    will soon be declared lost) no longer holds the others back.
    """

    def __init__(self, memory: int = 64, stall_ticks: int = 3) -> None:
        self._lock = threading.Lock()
        self.stall_ticks = stall_ticks
        self._members: dict[int, Callable[[], bool]] = {}
        self._not_ready: dict[int, int] = {}
        self._decisions: OrderedDict[int, tuple[bool, frozenset[int]]] = OrderedDict()
        self._memory = memory
        self.skipped = 0
        """Ticks not fired because some camera was not ready."""

    def join(self, camera_index: int, ready: Callable[[], bool]) -> None:
        """Take part from now on; ``ready()`` says whether the camera can take another trigger."""
        with self._lock:
            self._members[camera_index] = ready
            self._not_ready[camera_index] = 0

    def leave(self, camera_index: int) -> None:
        with self._lock:
            self._members.pop(camera_index, None)
            self._not_ready.pop(camera_index, None)

    def decide(self, tick: int, camera_index: int) -> bool:
        """Whether camera ``camera_index`` fires ``tick``; the first camera to ask decides for all.

        A tick is fired by every camera that was ready, or by none; a stalled
        camera (not ready for more than ``stall_ticks`` decisions) is left out.
        """
        with self._lock:
            decision = self._decisions.get(tick)
            if decision is None:
                fire, stalled = True, set[int]()
                for index, ready in self._members.items():
                    if ready():
                        self._not_ready[index] = 0
                        continue
                    self._not_ready[index] += 1
                    stalled.add(index)
                    if self._not_ready[index] <= self.stall_ticks:
                        fire = False
                decision = (fire, frozenset(stalled))
                self._decisions[tick] = decision
                if not fire:
                    self.skipped += 1
                while len(self._decisions) > self._memory:
                    self._decisions.popitem(last=False)
            fire, left_out = decision
            return fire and camera_index not in left_out
