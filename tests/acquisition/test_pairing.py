"""Pairing frames from several cameras (trackerd/acquisition/pairing.py): pure logic, synthetic frames."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from trackerd.acquisition.frame import Frame
from trackerd.acquisition.pairing import Arrival, Pairer, spread_ns

PERIOD_NS = 16_666_667
TOL_NS = PERIOD_NS // 2
_IMAGE = np.zeros((2, 2), np.uint8)


def arrival(camera: int, time_ns: int, epoch: int = 0, tick: int | None = None, frame_id: int = 0) -> Arrival:
    frame = Frame(f"cam{camera}", frame_id, time_ns, time_ns, "BayerRG8", _IMAGE)
    return Arrival(camera, frame, time_ns, epoch, tick)


def feed(pairer: Pairer, arrivals: list[Arrival]) -> list[tuple[Arrival, ...]]:
    groups = []
    for a in arrivals:
        groups.extend(pairer.add(a))
    return groups


def interleave(times_a: list[int], times_b: list[int], epoch: int = 0) -> list[Arrival]:
    """Two cameras' frames in arrival order (each camera's frames in order)."""
    items = [arrival(0, t, epoch) for t in times_a] + [arrival(1, t, epoch) for t in times_b]
    return sorted(items, key=lambda a: (a.capture_ns, a.camera_index))


def test_free_running_streams_pair_frame_by_frame_with_their_skew() -> None:
    pairer = Pairer(2, TOL_NS, 4, by_tick=False)
    offset = int(0.3 * PERIOD_NS)
    times_a = [k * PERIOD_NS for k in range(50)]
    groups = feed(pairer, interleave(times_a, [t + offset for t in times_a]))
    assert len(groups) == 50
    assert all(spread_ns(g) == offset for g in groups)
    assert all(g[0].camera_index == 0 and g[1].camera_index == 1 for g in groups)
    assert sum(pairer.dropped.values()) == 0


def test_a_frame_missing_from_one_camera_drops_its_partner_only() -> None:
    pairer = Pairer(2, TOL_NS, 4, by_tick=False)
    times_a = [k * PERIOD_NS for k in range(20)]
    times_b = [t + 1000 for i, t in enumerate(times_a) if i != 7]
    groups = feed(pairer, interleave(times_a, times_b))
    assert len(groups) == 19
    assert pairer.dropped["no_partner"] == 1
    assert 7 * PERIOD_NS not in {g[0].capture_ns for g in groups}


def test_frames_further_apart_than_the_tolerance_never_pair() -> None:
    tolerance = PERIOD_NS // 4
    pairer = Pairer(2, tolerance, 4, by_tick=False)
    times_a = [k * PERIOD_NS for k in range(20)]
    groups = feed(pairer, interleave(times_a, [t + int(0.4 * PERIOD_NS) for t in times_a]))
    assert groups == []
    assert pairer.dropped["no_partner"] >= 38


def test_a_silent_camera_cannot_make_the_queue_grow() -> None:
    pairer = Pairer(2, TOL_NS, 3, by_tick=False)
    for k in range(100):
        assert pairer.add(arrival(0, k * PERIOD_NS)) == []
        assert pairer.queued <= 3
    assert pairer.dropped["queue_full"] == 97


def test_a_reconnected_camera_never_pairs_with_frames_from_before() -> None:
    """Regression guard: after a reconnection, no group mixes frames of two epochs."""
    pairer = Pairer(2, TOL_NS, 4, by_tick=True)
    groups = feed(pairer, [arrival(c, 0, 0, 0) for c in (0, 1)])
    assert len(groups) == 1
    for tick in (1, 2):
        feed(pairer, [arrival(0, tick * PERIOD_NS, 0, tick)])
    # Camera 1 comes back (epoch 1); its trigger counts overlap those of camera 0's queued frames.
    groups = feed(pairer, [arrival(1, 2 * PERIOD_NS, 1, 2)])
    assert groups == []
    assert pairer.dropped["resync"] == 2
    groups = feed(pairer, [arrival(0, 3 * PERIOD_NS, 0, 3), arrival(1, 3 * PERIOD_NS, 1, 3)])
    assert [(g[0].tick, g[1].tick) for g in groups] == [(3, 3)]


def test_pairing_by_trigger_count_matches_equal_ticks_only() -> None:
    pairer = Pairer(2, TOL_NS, 4, by_tick=True)
    a = [arrival(0, k * PERIOD_NS + 100, 0, k) for k in range(10)]
    b = [arrival(1, k * PERIOD_NS + 300, 0, k) for k in range(10) if k != 4]
    groups = feed(pairer, sorted(a + b, key=lambda x: x.capture_ns))
    assert [g[0].tick for g in groups] == [0, 1, 2, 3, 5, 6, 7, 8, 9]
    assert all(g[0].tick == g[1].tick for g in groups)
    assert pairer.dropped["no_partner"] == 1


def test_equal_ticks_captured_too_far_apart_are_dropped_as_skew() -> None:
    pairer = Pairer(2, TOL_NS, 4, by_tick=True)
    groups = feed(pairer, [arrival(0, 0, 0, 5), arrival(1, TOL_NS + 10, 0, 5)])
    assert groups == []
    assert pairer.dropped["skew"] == 2


def test_while_a_camera_is_lost_the_others_frames_are_dropped_on_arrival() -> None:
    pairer = Pairer(2, TOL_NS, 4, by_tick=False)
    feed(pairer, [arrival(0, 0)])
    pairer.set_active(1, False)
    assert pairer.dropped["partner_lost"] == 1  # what was queued
    feed(pairer, [arrival(0, PERIOD_NS), arrival(0, 2 * PERIOD_NS)])
    assert pairer.dropped["partner_lost"] == 3
    assert pairer.queued == 0
    pairer.set_active(1, True)
    groups = feed(pairer, [arrival(0, 3 * PERIOD_NS), arrival(1, 3 * PERIOD_NS + 5, 1)])
    assert len(groups) == 1


def test_three_cameras_group_only_when_all_agree() -> None:
    pairer = Pairer(3, TOL_NS, 4, by_tick=False)
    groups = feed(pairer, [arrival(0, 0), arrival(1, 1000), arrival(2, TOL_NS + 10)])
    assert groups == []
    groups = feed(pairer, [arrival(0, PERIOD_NS), arrival(1, PERIOD_NS + 10), arrival(2, PERIOD_NS + 20)])
    assert len(groups) == 1 and spread_ns(groups[0]) == 20


@st.composite
def two_streams(draw: st.DrawFn) -> tuple[list[int], list[int], int]:
    """Two streams at nearly the same rate with random phase, jitter and losses."""
    n = draw(st.integers(5, 60))
    phase = draw(st.integers(0, PERIOD_NS - 1))
    jitter = st.integers(-PERIOD_NS // 8, PERIOD_NS // 8)
    keep = st.booleans()
    times_a = [k * PERIOD_NS + draw(jitter) for k in range(n) if draw(keep) or k % 3]
    times_b = [k * PERIOD_NS + phase + draw(jitter) for k in range(n) if draw(keep) or k % 2]
    return times_a, times_b, draw(st.integers(1, 6))


@settings(max_examples=200, deadline=None)
@given(two_streams())
def test_pairing_invariants(streams: tuple[list[int], list[int], int]) -> None:
    """Every frame is paired at most once, within tolerance, in order; every frame is accounted for."""
    times_a, times_b, queue_length = streams
    pairer = Pairer(2, TOL_NS, queue_length, by_tick=False)
    arrivals = interleave(times_a, times_b)
    groups = feed(pairer, arrivals)
    used = [id(a) for g in groups for a in g]
    assert len(used) == len(set(used))
    assert all(spread_ns(g) <= TOL_NS for g in groups)
    firsts = [g[0].capture_ns for g in groups]
    assert firsts == sorted(firsts)
    assert len(used) + sum(pairer.dropped.values()) + pairer.queued == len(arrivals)
    assert pairer.queued <= 2 * queue_length
