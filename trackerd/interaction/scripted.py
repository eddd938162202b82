"""Scripted wall-hit trajectories with known gestures, for tests, the benchmark and the built-in templates.

These simulate what the locator reports while a presenter gestures or simply
points, sampled at the camera pair rate, with the hit's frame-to-frame noise
added (white, ``noise_mm`` standard deviation per axis; the simulated rig's
rendered frames give about 0.3 mm for a still pointer, the locator's own
uncertainty estimate says a few mm, so tests use 1-2 mm) and a few pairs lost.

Gestures (wall frame: x right, y up, metres; senses as the presenter sees the wall):

* ``swipe``: a fast straight flick, 0.3-0.9 m in 0.15-0.35 s with a minimum-jerk
  speed profile, up to about 6 degrees off its direction and slightly bowed;
* ``circle``: 1.0-1.2 turns of a slightly elliptic loop, 0.2-0.6 m across, in
  0.6-1.4 s, starting anywhere.

Random pointing (what must not trigger gestures): moving from one target to
another with the duration Fitts' law gives for aimed movements (``MT = a + b
log2(D/W + 1)``, a = 0.15 s, b = 0.15 s/bit, targets 5-25 cm wide: fast for
distant pointing), often with a corrective sub-movement at the end, rests of
0.3-2 s with slow drift, and slow tracing along lines of a slide.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from trackerd.interaction.templates import Template

Array = NDArray[np.float64]

RATE_HZ = 60.0
DIRECTIONS = {"swipe_right": 0.0, "swipe_up": 90.0, "swipe_left": 180.0, "swipe_down": 270.0}
CIRCLES = {"circle_ccw": 1.0, "circle_cw": -1.0}
GESTURES = (*DIRECTIONS, *CIRCLES)
FITTS_A_S = 0.15
FITTS_B_S_PER_BIT = 0.15


@dataclass(frozen=True)
class Track:
    """Hit samples: capture times (N,) in ns and wall positions (N, 2) in metres (NaN: no hit)."""

    times_ns: NDArray[np.int64]
    points_m: Array
    labels: tuple[tuple[str, int, int], ...] = ()
    """Gestures performed: (name, start_ns, end_ns)."""


def minimum_jerk(fraction: Array) -> Array:
    """Minimum-jerk position profile s(t) in [0, 1] for t in [0, 1] (Flash and Hogan, 1985)."""
    t = np.clip(fraction, 0.0, 1.0)
    return t**3 * (10.0 - 15.0 * t + 6.0 * t * t)


def _samples(duration_s: float, rate_hz: float) -> Array:
    return np.arange(max(2, round(duration_s * rate_hz) + 1)) / rate_hz


def swipe_path(
    name: str,
    start_m: Array,
    length_m: float,
    duration_s: float,
    rng: np.random.Generator,
    rate_hz: float = RATE_HZ,
    ideal: bool = False,
) -> Array:
    """Positions (N, 2) of one swipe at ``rate_hz``; ``ideal``: straight, exactly on its direction."""
    angle = math.radians(DIRECTIONS[name] + (0.0 if ideal else rng.normal(0.0, 3.0)))
    along = np.array([math.cos(angle), math.sin(angle)])
    across = np.array([-along[1], along[0]])
    s = minimum_jerk(_samples(duration_s, rate_hz) / duration_s)
    bow = 0.0 if ideal else rng.uniform(-0.05, 0.05) * length_m
    return start_m + np.outer(s * length_m, along) + np.outer(4.0 * bow * s * (1.0 - s), across)


def circle_path(
    name: str,
    centre_m: Array,
    diameter_m: float,
    duration_s: float,
    rng: np.random.Generator,
    rate_hz: float = RATE_HZ,
    turns: float = 1.1,
    start_rad: float = 0.0,
    aspect: float = 1.0,
    tilt_rad: float = 0.0,
) -> Array:
    """Positions (N, 2) of a loop: ``turns`` turns in the sense of ``name``, an ellipse of ``aspect``."""
    sense = CIRCLES[name]
    s = minimum_jerk(_samples(duration_s, rate_hz) / duration_s)
    # Minimum jerk on the angle would crawl at both ends; blend it with a constant speed.
    phase = start_rad + sense * 2.0 * math.pi * turns * (0.5 * s + 0.5 * _samples(duration_s, rate_hz) / duration_s)
    ellipse = np.column_stack([np.cos(phase), aspect * np.sin(phase)]) * diameter_m / 2.0
    c, si = math.cos(tilt_rad), math.sin(tilt_rad)
    turned: Array = ellipse @ np.array([[c, si], [-si, c]])
    return centre_m + turned


def random_gesture(
    name: str, rng: np.random.Generator, width_m: float, height_m: float, rate_hz: float = RATE_HZ
) -> Array:
    """One gesture of a kind, with random size, speed, placement and form, on the display."""
    if name in DIRECTIONS:
        length = rng.uniform(0.3, 0.9) if name in ("swipe_left", "swipe_right") else rng.uniform(0.3, 0.6)
        duration = rng.uniform(0.15, 0.35)
        along = np.array([math.cos(math.radians(DIRECTIONS[name])), math.sin(math.radians(DIRECTIONS[name]))])
        centre = np.array([rng.uniform(0.3, width_m - 0.3), rng.uniform(0.25, height_m - 0.25)])
        centre = np.clip(
            centre,
            [length / 2 + 0.05, 0.05 + length / 2 * abs(along[1])],
            [width_m - length / 2 - 0.05, height_m - 0.05 - length / 2 * abs(along[1])],
        )
        return swipe_path(name, centre - along * length / 2, length, duration, rng, rate_hz)
    diameter = rng.uniform(0.2, min(0.6, height_m - 0.1))
    centre = np.array(
        [rng.uniform(diameter, width_m - diameter), rng.uniform(diameter / 2 + 0.05, height_m - diameter / 2 - 0.05)]
    )
    return circle_path(
        name,
        centre,
        diameter,
        rng.uniform(0.6, 1.4),
        rng,
        rate_hz,
        turns=rng.uniform(1.0, 1.2),
        start_rad=rng.uniform(0, 2 * math.pi),
        aspect=rng.uniform(0.8, 1.0),
        tilt_rad=rng.uniform(0, math.pi),
    )


def rest(position_m: Array, duration_s: float, rng: np.random.Generator, rate_hz: float = RATE_HZ) -> Array:
    """A resting hand: slow drift of a few millimetres (N, 2)."""
    n = len(_samples(duration_s, rate_hz))
    drift: Array = np.cumsum(rng.normal(0.0, 0.0004, (n, 2)), axis=0)
    out: Array = position_m + drift - drift[0]
    return out


def aimed_move(
    start_m: Array, target_m: Array, width_m: float, rng: np.random.Generator, rate_hz: float = RATE_HZ
) -> Array:
    """An aimed movement (N, 2) lasting what Fitts' law gives, often with a corrective sub-movement.

    Following the optimised sub-movement model (Meyer et al., 1988), the primary
    movement lands within the target's spread and, the more difficult the target
    (index of difficulty ID), the more often it falls 3-8 % short or long and a
    correction follows (probability 0.1 + 0.15 ID, at most 0.9), overlapping the end of
    the primary movement by up to a third of its own duration.
    """
    distance = float(np.hypot(*(target_m - start_m)))
    difficulty = math.log2(distance / width_m + 1.0)
    duration = FITTS_A_S + FITTS_B_S_PER_BIT * difficulty
    if rng.random() >= min(0.9, 0.1 + 0.15 * difficulty):
        s = minimum_jerk(_samples(duration, rate_hz) / duration)
        end = target_m + rng.normal(0.0, width_m / 8.0, 2)
        return start_m + np.outer(s, end - start_m)
    primary_end = start_m + rng.uniform(0.92, 1.08) * (target_m - start_m) + rng.normal(0.0, width_m / 8.0, 2)
    primary_s = 0.8 * duration
    correction_s = max(0.2 * duration, 0.12)
    correction_start_s = primary_s - rng.uniform(0.0, correction_s / 3.0)
    t = _samples(correction_start_s + correction_s, rate_hz)
    primary = np.outer(minimum_jerk(t / primary_s), primary_end - start_m)
    correction = np.outer(minimum_jerk((t - correction_start_s) / correction_s), target_m - primary_end)
    return start_m + primary + correction


def trace(start_m: Array, rng: np.random.Generator, width_m: float, rate_hz: float = RATE_HZ) -> Array:
    """Slow tracing along a line of text or a chart: 0.1-0.4 m/s for 1-3 s, wavering (N, 2)."""
    speed = rng.uniform(0.1, 0.4)
    duration = rng.uniform(1.0, 3.0)
    direction = 1.0 if start_m[0] < width_m / 2 else -1.0
    t = _samples(duration, rate_hz)
    x = start_m[0] + direction * speed * t
    y = start_m[1] + 0.01 * np.sin(2 * math.pi * 0.7 * t) + np.cumsum(rng.normal(0, 0.0005, len(t)))
    return np.column_stack([x, y])


def random_pointing(
    duration_s: float, rng: np.random.Generator, width_m: float, height_m: float, rate_hz: float = RATE_HZ
) -> Array:
    """Positions (N, 2) of a presenter pointing at things for ``duration_s`` (no gesture intended)."""
    position = np.array([width_m / 2, height_m / 2])
    pieces = [position[None, :]]
    total = 1
    wanted = int(duration_s * rate_hz)
    while total < wanted:
        if rng.random() < 0.15:
            piece = trace(position, rng, width_m, rate_hz)
        else:
            target = np.array([rng.uniform(0.05, width_m - 0.05), rng.uniform(0.05, height_m - 0.05)])
            piece = aimed_move(position, target, rng.uniform(0.05, 0.25), rng, rate_hz)
        piece = np.clip(piece, 0.0, [width_m, height_m])
        pieces.append(piece[1:])
        position = piece[-1]
        hold = rest(position, rng.uniform(0.3, 2.0), rng, rate_hz)
        pieces.append(hold[1:])
        position = hold[-1]
        total += len(piece) + len(hold) - 2
    return np.vstack(pieces)[:wanted]


def gesture_session(
    names: list[str],
    rng: np.random.Generator,
    width_m: float,
    height_m: float,
    *,
    noise_mm: float = 1.5,
    loss: float = 0.02,
    rate_hz: float = RATE_HZ,
    start_ns: int = 10**12,
) -> Track:
    """The pointer enters, then for each name: a rest, the gesture, a rest; then it leaves (NaN).

    ``noise_mm``: white noise per axis; ``loss``: fraction of pairs without a hit.
    """
    pieces: list[Array] = []
    labels = []
    count = 0
    position = np.array([width_m / 2, height_m / 2])
    for name in names:
        path = random_gesture(name, rng, width_m, height_m, rate_hz)
        lead = aimed_move(position, path[0], 0.1, rng, rate_hz) if count else path[:1]
        pieces.append(lead)
        count += len(lead)
        hold = rest(path[0], rng.uniform(0.4, 0.7), rng, rate_hz)
        pieces.append(hold)
        count += len(hold)
        labels.append((name, count, count + len(path)))
        pieces.append(path)
        count += len(path)
        hold = rest(path[-1], rng.uniform(0.4, 0.7), rng, rate_hz)
        pieces.append(hold)
        count += len(hold)
        position = hold[-1]
    return _as_track(np.vstack(pieces), labels, rng, noise_mm, loss, rate_hz, start_ns)


def pointing_session(
    duration_s: float,
    rng: np.random.Generator,
    width_m: float,
    height_m: float,
    *,
    noise_mm: float = 1.5,
    loss: float = 0.02,
    rate_hz: float = RATE_HZ,
    start_ns: int = 10**12,
) -> Track:
    """Random pointing for ``duration_s`` (no gestures), with noise and lost pairs, then the pointer leaves."""
    return _as_track(
        random_pointing(duration_s, rng, width_m, height_m, rate_hz), [], rng, noise_mm, loss, rate_hz, start_ns
    )


def _as_track(
    points: Array,
    labels: list[tuple[str, int, int]],
    rng: np.random.Generator,
    noise_mm: float,
    loss: float,
    rate_hz: float,
    start_ns: int,
) -> Track:
    tail = int(0.5 * rate_hz)  # the pointer leaves: pairs without a hit
    noisy = points + rng.normal(0.0, noise_mm / 1000.0, points.shape)
    noisy[rng.random(len(noisy)) < loss] = np.nan
    noisy = np.vstack([noisy, np.full((tail, 2), np.nan)])
    times = start_ns + (np.arange(len(noisy)) * (1e9 / rate_hz)).astype(np.int64)
    return Track(times, noisy, tuple((n, int(times[a]), int(times[min(b, len(times) - 1)])) for n, a, b in labels))


def builtin_templates() -> list[Template]:
    """The templates shipped in trackerd/interaction/templates/, from ideal strokes.

    Swipes: one straight example each, directional (+-30 degrees), and gated as
    flicks: at least 1.1 m/s on average, at most 350 ms, at least 0.25 m across, one
    speed peak (an aimed movement is slower for its length and often ends in a
    correction; docs/interaction.md has the trade-off measured). Circles:
    examples of 1.0 and 1.15 turns, rotation-invariant, gated at 0.3 m/s, 2.5 s and
    0.12 m.
    """
    from trackerd.interaction.recognizer import prepare
    from trackerd.interaction.templates import Template

    rng = np.random.default_rng(0)
    out: list[Template] = []
    for name in DIRECTIONS:
        path = swipe_path(name, np.zeros(2), 0.6, 0.25, rng, ideal=True)
        out.append(
            Template(
                name,
                (prepare(path, False),),
                rotation_invariant=False,
                max_rotation_deg=30.0,
                min_mean_speed_m_s=1.1,
                max_duration_ms=350.0,
                min_size_m=0.25,
                max_submovements=1,
            )
        )
    for name in CIRCLES:
        examples = tuple(
            prepare(circle_path(name, np.zeros(2), 0.4, 1.0, rng, turns=turns), True) for turns in (1.0, 1.15)
        )
        out.append(
            Template(
                name,
                examples,
                rotation_invariant=True,
                max_rotation_deg=180.0,
                min_mean_speed_m_s=0.3,
                max_duration_ms=2500.0,
                min_size_m=0.12,
            )
        )
    return out
