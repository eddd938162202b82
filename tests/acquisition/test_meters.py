"""The rate meter behind the status's frame and pair rates (pure)."""

from __future__ import annotations

import pytest

from trackerd.acquisition.meters import RateMeter

MS = 1_000_000


def test_two_frames_just_after_start_give_no_rate_rather_than_hundreds() -> None:
    meter = RateMeter()
    meter.tick(0)
    meter.tick(6 * MS)  # two frames 6.4 ms apart once read as 156 Hz
    assert meter.rate_hz(6 * MS) == 0.0
    assert meter.rate_hz(400 * MS) == 0.0


def test_the_rate_once_half_a_second_of_frames_is_in() -> None:
    meter = RateMeter()
    period = 1e9 / 60
    for k in range(31):
        meter.tick(round(k * period))
    assert meter.rate_hz(round(30 * period)) == pytest.approx(60.0)


def test_the_rate_decays_once_frames_stop() -> None:
    meter = RateMeter()
    for k in range(60):
        meter.tick(k * 20 * MS)  # 50 Hz for 1.2 s
    assert meter.rate_hz(1180 * MS) == pytest.approx(50.0)
    assert meter.rate_hz(2000 * MS) < 40.0
    assert meter.rate_hz(5000 * MS) == 0.0
