"""Frame-id unwrapping and device-to-host clock mapping (trackerd/acquisition/clock.py)."""

from __future__ import annotations

import time

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from trackerd.acquisition.clock import (
    DeviceClock,
    FrameIdUnwrapper,
    NonDecreasing,
    realtime_to_monotonic_ns,
)


def unwrap_all(raw: list[int]) -> list[int]:
    unwrap = FrameIdUnwrapper()
    return [unwrap(r) for r in raw]


def test_gige_vision_ids_wrap_from_65535_to_1() -> None:
    """Aravis's fake camera (like GigE Vision 1.x cameras) goes 65534, 65535, 1, 2."""
    assert unwrap_all([65534, 65535, 1, 2]) == [65534, 65535, 65536, 65537]


def test_a_camera_that_counts_through_zero() -> None:
    assert unwrap_all([65535, 0, 1]) == [65535, 65536, 65537]


def test_missing_ids_leave_gaps_across_the_wrap() -> None:
    assert unwrap_all([65533, 65535, 2]) == [65533, 65535, 65537]


def test_extended_ids_never_wrap() -> None:
    assert unwrap_all([70_000, 70_001, 70_005]) == [70_000, 70_001, 70_005]


@settings(max_examples=100, deadline=None)
@given(st.integers(1, 65535), st.lists(st.integers(1, 20), min_size=1, max_size=400))
def test_unwrapped_ids_advance_by_the_true_steps(start: int, steps: list[int]) -> None:
    true = np.cumsum([0, *steps]) + start
    raw = [int((t - 1) % 65535) + 1 for t in true]  # the 16-bit id, skipping 0
    got = unwrap_all(raw)
    assert np.array_equal(np.diff(got), steps)


def test_offset_is_the_smallest_delay_seen() -> None:
    rng = np.random.default_rng(1)
    clock = DeviceClock(window_ns=2_000_000_000)
    offset = -5_000_000_000
    delays = rng.uniform(2e6, 9e6, size=200).astype(int)
    for k, delay in enumerate(delays):
        device = 10**12 + k * 16_666_667
        clock.observe(device, device + offset + int(delay))
    expected = offset + int(delays[np.arange(200) * 16_666_667 >= 199 * 16_666_667 - 2_000_000_000].min())
    assert clock.offset_ns == expected
    assert clock.to_host_ns(10**12, 0) == 10**12 + expected


def test_drift_between_the_clocks_is_followed() -> None:
    clock = DeviceClock(window_ns=1_000_000_000)
    drift = 50e-6
    period = 16_666_667
    for k in range(600):  # 10 s
        host = k * period
        device = int(host * (1 + drift)) + 7_000_000_000
        clock.observe(device, host + 3_000_000)  # constant 3 ms delay
    device_now = int(599 * period * (1 + drift)) + 7_000_000_000
    # Within the drift accumulated over one window (50 us), not the 500 us over the whole run.
    assert abs(clock.to_host_ns(device_now, 0) - (599 * period + 3_000_000)) < 60_000


def test_a_device_clock_step_backwards_restarts_the_estimate() -> None:
    clock = DeviceClock(window_ns=10**10, step_ns=100_000_000, step_frames=3)
    for k in range(10):
        clock.observe(k * 10**7, k * 10**7 + 1_000)
    assert clock.offset_ns == 1_000
    # The camera resets its clock: delays now look 5 s larger.
    for k in range(10, 12):
        clock.observe(k * 10**7 - 5 * 10**9, k * 10**7 + 1_000)
    assert clock.offset_ns == 1_000  # two outliers are not enough
    clock.observe(12 * 10**7 - 5 * 10**9, 12 * 10**7 + 1_000)
    assert clock.offset_ns == 5 * 10**9 + 1_000


def test_without_observations_the_arrival_time_stands() -> None:
    clock = DeviceClock(window_ns=10**9)
    assert clock.offset_ns is None
    assert clock.to_host_ns(123, 456) == 456


def test_published_timestamps_never_go_backwards() -> None:
    stamp = NonDecreasing()
    assert [stamp(t) for t in [5, 3, 7, 7, 6, 9]] == [5, 5, 7, 7, 7, 9]


def test_realtime_instants_land_on_the_monotonic_clock() -> None:
    before = time.monotonic_ns()
    converted = realtime_to_monotonic_ns(time.time_ns())
    after = time.monotonic_ns()
    assert before - 1_000_000 <= converted <= after + 1_000_000
