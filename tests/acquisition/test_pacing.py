"""Waiting for a pair's due time within a consumer's timeout (trackerd/acquisition/pacing.py), on a test clock."""

from __future__ import annotations

import pytest

from trackerd.acquisition.pacing import wait_until_due


class Clock:
    """monotonic_ns and sleep, in nanoseconds the test controls; records every sleep."""

    def __init__(self) -> None:
        self.now_ns = 1_000_000_000
        self.slept_s: list[float] = []

    def monotonic_ns(self) -> int:
        return self.now_ns

    def sleep(self, seconds: float) -> None:
        self.slept_s.append(seconds)
        self.now_ns += round(seconds * 1e9)


@pytest.fixture
def clock() -> Clock:
    return Clock()


def wait(clock: Clock, due_in_ms: float, timeout_ms: float) -> bool:
    start = clock.now_ns
    return wait_until_due(
        start + round(due_in_ms * 1e6), start + round(timeout_ms * 1e6), clock_ns=clock.monotonic_ns, sleep=clock.sleep
    )


def test_a_pair_due_within_the_timeout_is_waited_for_until_it_is_due(clock) -> None:
    start = clock.now_ns
    assert wait(clock, due_in_ms=10, timeout_ms=100)
    assert clock.now_ns == start + 10_000_000


def test_a_pair_already_due_is_served_without_sleeping(clock) -> None:
    assert wait(clock, due_in_ms=-5, timeout_ms=100)
    assert wait(clock, due_in_ms=0, timeout_ms=0)
    assert clock.slept_s == []


def test_a_pair_due_after_the_timeout_is_not_waited_for_and_the_timeout_is_slept_out(clock) -> None:
    start = clock.now_ns
    assert not wait(clock, due_in_ms=150, timeout_ms=100)
    assert clock.now_ns == start + 100_000_000


def test_a_deadline_already_passed_does_not_sleep_backwards(clock) -> None:
    assert not wait(clock, due_in_ms=10, timeout_ms=-20)
    assert clock.slept_s == [0.0]
