"""The in-memory pair source: paced like cameras, every pair served or counted as dropped.

Paced runs use a clock of the test's own (the module's ``time``), so a stall
of the machine cannot change what is checked: the consumer is late exactly
when the test says it is.
"""

from __future__ import annotations

import numpy as np
import pytest

from trackerd.acquisition import memory
from trackerd.acquisition.memory import MemoryPairSource


class _Clock:
    """monotonic_ns and sleep, in nanoseconds the test advances."""

    def __init__(self) -> None:
        self.now_ns = 1_000_000_000

    def monotonic_ns(self) -> int:
        return self.now_ns

    def sleep(self, seconds: float) -> None:
        self.now_ns += round(seconds * 1e9)


@pytest.fixture
def clock(monkeypatch) -> _Clock:
    fake = _Clock()
    monkeypatch.setattr(memory, "time", fake)
    return fake


def _sets(n: int) -> list[list[np.ndarray]]:
    return [[np.full((4, 6), k, np.uint8), np.full((4, 6), 100 + k, np.uint8)] for k in range(n)]


def test_unpaced_every_pair_is_served_in_order_looping_over_the_sets(simulated_rig):
    source = MemoryPairSource(simulated_rig, _sets(3), rate_hz=None, count=7)
    source.start()
    pairs = []
    while (pair := source.next_pair(0.1)) is not None:
        pairs.append(pair)
    assert [p.sequence for p in pairs] == list(range(7))
    assert [int(p.frames[1].image[0, 0]) for p in pairs] == [100, 101, 102, 100, 101, 102, 100]
    assert source.status().dropped_pairs == 0


def test_a_consumer_that_keeps_up_gets_every_pair_when_it_is_due(simulated_rig, clock):
    source = MemoryPairSource(simulated_rig, _sets(3), rate_hz=100.0, count=5)
    source.start()
    start = clock.now_ns
    pairs = []
    while (pair := source.next_pair(0.1)) is not None:
        pairs.append(pair)
        assert clock.now_ns == start + pair.sequence * 10_000_000  # served when due, not earlier
    assert [p.sequence for p in pairs] == list(range(5))
    assert [p.timestamp_ns - start for p in pairs] == [k * 10_000_000 for k in range(5)]
    assert source.status().dropped_pairs == 0


def test_a_late_consumer_loses_pairs_that_are_counted_and_none_past_the_end(simulated_rig, clock):
    source = MemoryPairSource(simulated_rig, _sets(4), rate_hz=100.0, count=10)
    source.start()
    assert source.next_pair(0.1).sequence == 0
    clock.sleep(0.045)  # busy for 4.5 periods: pairs 1-3 come due and go
    late = source.next_pair(0.1)
    assert late.sequence == 4 and int(late.frames[0].image[0, 0]) == 0  # its own images (4 % 4)
    clock.sleep(0.2)  # twenty periods: pairs 5-9 come and go, and then the end
    assert source.next_pair(0.1) is None
    status = source.status()
    # Served or dropped, never both and never neither; the time slept past the end drops nothing.
    assert status.delivered == 2
    assert status.dropped_pairs == 8


def test_a_source_that_never_drops_serves_late_pairs_stamped_when_they_were_due(simulated_rig, clock):
    source = MemoryPairSource(simulated_rig, _sets(2), rate_hz=100.0, count=4, drop_late=False)
    source.start()
    start = clock.now_ns
    source.next_pair(0.1)
    clock.sleep(0.5)
    rest = [source.next_pair(0.1) for _ in range(3)]
    assert [p.sequence for p in rest] == [1, 2, 3]
    assert [p.timestamp_ns - start for p in rest] == [10_000_000, 20_000_000, 30_000_000]
    assert source.next_pair(0.1) is None and source.status().dropped_pairs == 0
