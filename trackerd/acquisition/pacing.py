"""Pacing a source that serves pairs when they are due (in-memory image sets, recording replay).

Both wait for the next pair's due time within the consumer's timeout: a pair due
after the timeout is not waited for (the call sleeps out its timeout and the pair
is served by a later call), one due before it is waited for, and one already due
is served at once. Sources pass their own clock and sleep, so tests can run them
on a clock of their own.
"""

from __future__ import annotations

import time
from collections.abc import Callable


def wait_until_due(
    due_ns: int,
    deadline_ns: int,
    *,
    clock_ns: Callable[[], int] = time.monotonic_ns,
    sleep: Callable[[float], None] = time.sleep,
) -> bool:
    """Sleep until ``due_ns`` and return True, or, if it is after ``deadline_ns``, sleep until the
    deadline and return False (times on ``clock_ns``'s clock, ns)."""
    now_ns = clock_ns()
    if due_ns <= now_ns:
        return True
    if due_ns > deadline_ns:
        sleep(max(0.0, (deadline_ns - now_ns) / 1e9))
        return False
    sleep((due_ns - now_ns) / 1e9)
    return True
