"""Software-trigger bookkeeping (trackerd/acquisition/trigger.py): schedule, gate, tick map."""

from __future__ import annotations

from trackerd.acquisition.trigger import TickMap, TickSchedule, TriggerGate

PERIOD = 16_666_667


def test_the_first_tick_is_the_next_one_due() -> None:
    schedule = TickSchedule(1_000_000_000, PERIOD)
    assert schedule.next_tick(None, 0) == 0  # before the start
    assert schedule.next_tick(None, 1_000_000_000 + 3 * PERIOD + 5) == 4


def test_ticks_are_fired_in_order_even_when_a_little_late() -> None:
    schedule = TickSchedule(0, PERIOD)
    assert schedule.next_tick(10, 13 * PERIOD) == 11  # three periods late: still the next one
    assert schedule.next_tick(10, 20 * PERIOD) == 20  # stalled: jump to now


def test_each_frame_answers_the_tick_fired_in_its_turn() -> None:
    ticks = TickMap()
    for tick in (5, 6, 8):
        ticks.fired(tick)
    assert [ticks.frame(i) for i in (100, 101, 102)] == [5, 6, 8]
    assert ticks.outstanding == 0


def test_frames_that_never_arrive_consume_their_ticks() -> None:
    ticks = TickMap()
    for tick in range(5):
        ticks.fired(tick)
    assert ticks.frame(40) == 0
    assert ticks.frame(43) == 3  # ids 41 and 42 were lost on the way
    assert ticks.frame(44) == 4


def test_a_frame_nobody_triggered_is_refused() -> None:
    ticks = TickMap()
    assert ticks.frame(7) is None
    ticks.fired(1)
    assert ticks.frame(8) == 1
    assert ticks.frame(9) is None
    assert ticks.unmatched == 2


def test_a_new_connection_takes_one_trigger_until_its_first_frame() -> None:
    ticks = TickMap(max_outstanding=2)
    assert ticks.ready()
    ticks.fired(0)
    assert not ticks.ready()
    ticks.frame(1)
    assert ticks.ready()
    ticks.fired(1)
    assert ticks.ready()
    ticks.fired(2)
    assert not ticks.ready()


def test_the_gate_fires_every_camera_or_none() -> None:
    gate = TriggerGate(stall_ticks=2)
    ready = {0: True, 1: True}
    gate.join(0, lambda: ready[0])
    gate.join(1, lambda: ready[1])
    assert gate.decide(1, 0) and gate.decide(1, 1)
    ready[1] = False
    assert not gate.decide(2, 0)
    ready[1] = True  # too late: tick 2 was decided for both when camera 0 asked
    assert not gate.decide(2, 1)
    assert gate.skipped == 1


def test_a_stalled_camera_stops_holding_the_others_back() -> None:
    gate = TriggerGate(stall_ticks=2)
    gate.join(0, lambda: True)
    gate.join(1, lambda: False)
    decisions = [(gate.decide(t, 0), gate.decide(t, 1)) for t in range(4)]
    assert decisions == [(False, False), (False, False), (True, False), (True, False)]
    gate.leave(1)
    assert gate.decide(4, 0)


def test_a_frame_lost_on_the_way_is_accounted_for_by_the_next() -> None:
    ticks = TickMap(max_outstanding=2)
    ticks.fired(0)
    assert ticks.frame(10) == 0
    ticks.fired(1)
    ticks.fired(2)
    assert not ticks.ready()  # frame 11 never comes: no more triggers meanwhile
    assert ticks.frame(12) == 2  # ...until frame 12 shows the gap and consumes tick 1
    assert ticks.ready() and ticks.outstanding == 0


def test_the_first_frame_is_waited_for() -> None:
    """It fixes which frame answers which tick."""
    ticks = TickMap(max_outstanding=2)
    ticks.fired(0)
    assert not ticks.ready()
    assert ticks.frame(7) == 0
    assert ticks.ready()
