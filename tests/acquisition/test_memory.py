"""The in-memory pair source: paced like cameras, every pair served or counted as dropped."""

from __future__ import annotations

import time

import numpy as np

from trackerd.acquisition.memory import MemoryPairSource


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


def test_paced_each_pair_carries_its_own_images_and_due_time(simulated_rig):
    source = MemoryPairSource(simulated_rig, _sets(3), rate_hz=100.0, count=8)
    source.start()
    pairs = []
    while (pair := source.next_pair(0.1)) is not None:
        pairs.append(pair)
    status = source.status()
    assert status.delivered == len(pairs) and status.delivered + status.dropped_pairs == 8
    for pair in pairs:  # a dropped pair shifts nothing: sequence, images and capture time agree
        assert int(pair.frames[0].image[0, 0]) == pair.sequence % 3
        assert pair.timestamp_ns - pairs[0].timestamp_ns == (pair.sequence - pairs[0].sequence) * 10_000_000


def test_a_late_consumer_loses_pairs_that_are_counted_and_none_past_the_end(simulated_rig):
    source = MemoryPairSource(simulated_rig, _sets(4), rate_hz=100.0, count=10)
    source.start()
    first = source.next_pair(0.1)
    time.sleep(0.045)  # pairs 1-3 (at least) come due and go while the consumer is busy
    late = source.next_pair(0.1)
    time.sleep(0.2)  # ten periods: every remaining pair comes due and goes, and then the end
    assert source.next_pair(0.1) is None
    status = source.status()
    assert first.sequence == 0 and late.sequence >= 4
    # Served or dropped, never both and never neither; the time slept past the end drops nothing.
    assert status.delivered == 2
    assert status.dropped_pairs == 8
