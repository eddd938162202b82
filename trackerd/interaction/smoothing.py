"""Speed-adaptive smoothing of wall hits: the One Euro filter (Casiez, Roussel and Vogel, CHI 2012).

A still pointer's hit jitters by a few millimetres (centroid noise through the
pointer's lever arm, docs/geometry.md); a moving one must not lag. The One Euro
filter is an exponential low-pass filter whose cut-off frequency rises with the
hit's speed:

    fc = min_cutoff_hz + beta_per_m * |v|           (|v| in m/s, filtered at derivative_cutoff_hz)
    alpha = 1 / (1 + 1 / (2 pi fc dt))
    x_hat = x_hat_prev + alpha (x - x_hat_prev)

Still, fc is low and the jitter is averaged away; moving at a steady speed v,
the filter trails the hit by ``v / (2 pi fc)``, which tends to ``1 / (2 pi beta)``
metres as v grows (11 mm for beta = 15 per metre): the lag is a bounded distance,
not a bounded time. The hit is filtered as one 2D point
(the speed is the norm of the 2D velocity), so both axes get the same cut-off and
a diagonal movement is not smoothed differently from a horizontal one.

Times are capture times in nanoseconds (``FramePair.timestamp_ns``), so a replay
filters exactly as the live run did, and an irregular frame interval (a dropped
pair) is handled by the ``dt`` in alpha.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.config.interaction import SmoothingConfig

Array = NDArray[np.float64]


def smoothing_factor(cutoff_hz: float | Array, dt_s: float) -> float | Array:
    """Exponential smoothing factor alpha of a first-order low-pass filter at ``cutoff_hz`` sampled every ``dt_s``."""
    tau_s = 1.0 / (2.0 * math.pi * np.asarray(cutoff_hz))
    return 1.0 / (1.0 + tau_s / dt_s)


@dataclass
class FilterState:
    """What the filter remembers between samples."""

    time_ns: int
    position_m: Array
    """Filtered position (2,)."""
    raw_m: Array
    """Previous raw position (2,), for the speed estimate."""
    velocity_m_s: Array
    """Filtered velocity (2,)."""


class OneEuroFilter:
    """The One Euro filter on 2D positions (metres) stamped in nanoseconds; one per pointer."""

    def __init__(self, config: SmoothingConfig) -> None:
        self.config = config
        self.state: FilterState | None = None

    def reset(self) -> None:
        """Forget the past: the next sample passes through unchanged."""
        self.state = None

    def __call__(self, time_ns: int, position_m: Array) -> Array:
        """The filtered position (2,) for a raw position (2,) taken at ``time_ns``.

        A sample older than or as old as the previous one (a repeated pair) is returned
        as the current filtered position, unchanged.
        """
        x = np.asarray(position_m, dtype=np.float64)[:2]
        state = self.state
        cfg = self.config
        if state is None:
            self.state = FilterState(time_ns, x.copy(), x.copy(), np.zeros(2))
            return x.copy()
        dt_s = (time_ns - state.time_ns) / 1e9
        if dt_s <= 0.0:
            return state.position_m.copy()
        # Speed from raw positions: unbiased for a steady movement (the filtered previous
        # position would lag and inflate it); its noise is what derivative_cutoff_hz removes.
        raw_velocity = (x - state.raw_m) / dt_s
        a_d = smoothing_factor(cfg.derivative_cutoff_hz, dt_s)
        velocity = state.velocity_m_s + a_d * (raw_velocity - state.velocity_m_s)
        cutoff_hz = cfg.min_cutoff_hz + cfg.beta_per_m * float(math.hypot(velocity[0], velocity[1]))
        a = smoothing_factor(cutoff_hz, dt_s)
        position = state.position_m + a * (x - state.position_m)
        self.state = FilterState(time_ns, position, x.copy(), velocity)
        return position.copy()

    @property
    def velocity_m_s(self) -> Array:
        """The filtered velocity (2,), metres per second on the wall; zeros before the first sample."""
        return np.zeros(2) if self.state is None else self.state.velocity_m_s.copy()


def smooth_track(config: SmoothingConfig, times_ns: NDArray[np.int64], positions_m: Array) -> Array:
    """Filter a whole track (N,) times and (N, 2) positions from a fresh filter: (N, 2)."""
    one_euro = OneEuroFilter(config)
    return np.array([one_euro(int(t), p) for t, p in zip(times_ns, positions_m, strict=True)])
