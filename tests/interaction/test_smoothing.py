"""The One Euro filter: steadier when still, little lag when moving, fresh after a loss."""

from __future__ import annotations

import numpy as np

from trackerd.config.interaction import SmoothingConfig
from trackerd.interaction.smoothing import OneEuroFilter, smooth_track, smoothing_factor

RATE_HZ = 60.0


def _times(n: int) -> np.ndarray:
    return (np.arange(n) * 1e9 / RATE_HZ).astype(np.int64)


def test_smoothing_factor_is_a_first_order_low_pass():
    # alpha = 1 / (1 + tau / dt), tau = 1 / (2 pi fc): at fc = 1/(2 pi dt), alpha = 1/2.
    dt = 1.0 / RATE_HZ
    assert smoothing_factor(1.0 / (2 * np.pi * dt), dt) == 0.5
    assert 0.0 < smoothing_factor(0.3, dt) < smoothing_factor(3.0, dt) < 1.0


def test_still_pointer_jitter_drops_at_least_five_fold(rng):
    cfg = SmoothingConfig()
    noise = rng.normal(0.0, 0.0015, (1200, 2))
    smoothed = smooth_track(cfg, _times(1200), noise)
    assert noise[120:].std() / smoothed[120:].std() >= 5.0


def test_lag_at_one_metre_per_second_is_under_one_frame(rng):
    cfg = SmoothingConfig()
    n = 600
    truth = np.column_stack([np.arange(n) / RATE_HZ, np.zeros(n)])
    smoothed = smooth_track(cfg, _times(n), truth + rng.normal(0.0, 0.0015, (n, 2)))
    lag_m = np.mean(truth[300:, 0] - smoothed[300:, 0])
    assert 0.0 < lag_m < 1.0 / RATE_HZ  # one frame at 1 m/s is 16.7 mm
    # The lag tends to 1 / (2 pi beta) metres for fast movements.
    assert lag_m < 1.0 / (2 * np.pi * cfg.beta_per_m) * 1.1


def test_reset_starts_afresh_and_repeated_samples_change_nothing():
    one_euro = OneEuroFilter(SmoothingConfig())
    one_euro(0, np.array([0.0, 0.0]))
    moved = one_euro(16_666_667, np.array([1.0, 0.0]))
    assert 0.0 < moved[0] < 1.0
    assert np.array_equal(one_euro(16_666_667, np.array([5.0, 5.0])), moved)  # same time: no update
    one_euro.reset()
    assert np.array_equal(one_euro(50_000_000, np.array([2.0, 3.0])), [2.0, 3.0])
