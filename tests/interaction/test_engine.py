"""Enter/leave with hysteresis, dwell once per rest, gestures vs random pointing, and a reset, on scripted hits."""

from __future__ import annotations

import numpy as np

from tests.interaction.conftest import HEIGHT_M, WIDTH_M, run_track
from trackerd.config.interaction import InteractionConfig
from trackerd.interaction.engine import InteractionEngine
from trackerd.interaction.scripted import (
    GESTURES,
    Track,
    circle_path,
    gesture_session,
    pointing_session,
    rest,
    swipe_path,
)
from trackerd.interaction.templates import load_templates

RATE_HZ = 60.0


def _track(points: np.ndarray) -> Track:
    return Track((10**12 + np.arange(len(points)) * 1e9 / RATE_HZ).astype(np.int64), points)


def _kinds(events) -> list[str]:
    return [e.kind for e in events]


def test_a_pointer_held_at_the_edge_does_not_flicker(rng):
    # Hovering across the right edge: 10 mm either side of it, with 3 mm noise.
    n = 600
    x = WIDTH_M + 0.010 * np.sin(np.arange(n) / 7.0) + rng.normal(0, 0.003, n)
    points = np.column_stack([x, np.full(n, 0.5)])
    _, events = run_track(_track(np.vstack([[[WIDTH_M - 0.2, 0.5]] * 10, points])))
    assert _kinds(events).count("enter") == 1 and "leave" not in _kinds(events)


def test_leave_after_the_margin_or_a_loss_and_not_for_a_dropped_pair():
    inside = np.tile([[1.0, 0.5]], (30, 1))
    dropped = inside.copy()
    dropped[10:13] = np.nan  # 50 ms without a hit
    _, events = run_track(_track(np.vstack([dropped, np.full((30, 2), np.nan)])))
    assert _kinds(events)[:1] == ["enter"] and _kinds(events).count("leave") == 1
    leave = events[-1]
    assert leave.detail["reason"] == "lost" and leave.cursor_id == events[0].cursor_id
    outside = np.tile([[WIDTH_M + 0.2, 0.5]], (30, 1))
    _, events = run_track(_track(np.vstack([inside, outside, inside])))
    events = [e for e in events if e.kind in ("enter", "leave")]
    assert _kinds(events) == ["enter", "leave", "enter"] and events[1].detail["reason"] == "off_display"
    assert events[2].cursor_id == events[0].cursor_id + 1


def test_one_dwell_per_rest(rng):
    cfg = InteractionConfig()
    rest = np.tile([[1.0, 0.5]], (120, 1)) + rng.normal(0, 0.001, (120, 2))  # 2 s within 20 mm
    move = np.column_stack([np.linspace(1.0, 1.5, 60), np.full(60, 0.5)])  # 0.5 m/s: no swipe
    moved = np.tile([[1.5, 0.5]], (90, 1))
    _, events = run_track(_track(np.vstack([rest, move, moved])), cfg)
    assert "gesture" not in _kinds(events)
    dwells = [e for e in events if e.kind == "dwell"]
    assert len(dwells) == 2
    assert np.hypot(*(dwells[0].position_m - [1.0, 0.5])) < 0.002
    assert dwells[0].detail["dwell_ms"] >= cfg.dwell.time_ms
    assert np.allclose(dwells[1].position_m, [1.5, 0.5], atol=0.01)


def test_gestures_are_recognised_and_random_pointing_is_not_a_gesture(rng):
    # The full figures come from `trackerd bench interaction`; here a smaller run must hold.
    performed = recognised = 0
    for _ in range(4):
        track = gesture_session([str(n) for n in rng.permutation(GESTURES)], rng, WIDTH_M, HEIGHT_M, noise_mm=2.0)
        _, events = run_track(track)
        gestures = [e for e in events if e.kind == "gesture"]
        for name, start, end in track.labels:
            performed += 1
            match = [g for g in gestures if g.detail["start_ns"] < end and g.detail["end_ns"] > start]
            recognised += bool(match) and match[0].detail["name"] == name
            if match:
                g = match[0]
                assert g.detail["start_ns"] < g.detail["end_ns"] == g.time_ns and 0.8 <= g.detail["score"] <= 1.0
    assert recognised / performed >= 0.9
    engine, events = run_track(pointing_session(180.0, rng, WIDTH_M, HEIGHT_M, noise_mm=2.0))
    assert sum(e.kind == "gesture" for e in events) <= 3  # at most one a minute
    assert engine.rejected_total > 50  # the strokes were seen and turned down, not missed


def _loop_track(rng) -> np.ndarray:
    """Rest, swipe right, rest, counter-clockwise loop, rest: 3.7 s that end 0.75 m right of where they began."""
    start = np.array([1.0, 0.5])
    swipe = swipe_path("swipe_right", start, 0.8, 0.25, rng)
    loop = circle_path("circle_ccw", np.zeros(2), 0.45, 1.2, rng)
    loop = loop - loop[0] + swipe[-1]
    points = np.vstack([rest(start, 1.0, rng), swipe, rest(swipe[-1], 0.6, rng), loop, rest(loop[-1], 0.6, rng)])
    return points + rng.normal(0, 0.0015, points.shape)


def _replayed_twice(points: np.ndarray, reset: bool):
    """The points fed twice, back to back at 60 pairs/s (a looped replay), with or without a reset between."""
    engine = InteractionEngine(InteractionConfig(), WIDTH_M, HEIGHT_M, load_templates())
    passes, ending = [], []
    for index in range(2):
        if index and reset:
            ending = engine.reset()
        start_ns = 10**12 + index * len(points) * 1e9 / RATE_HZ
        times = (start_ns + np.arange(len(points)) * 1e9 / RATE_HZ).astype(np.int64)
        passes.append(
            [(e, int(t - times[0])) for t, p in zip(times, points, strict=True) for e in engine.step(int(t), p).events]
        )
    return passes, ending


def test_after_a_reset_the_same_hits_give_the_same_events_and_the_jump_is_no_gesture(rng):
    points = _loop_track(rng)
    # Without a reset the wrap from the last pair back to the first is a fast straight stroke: a swipe.
    (first, second), _ = _replayed_twice(points, reset=False)
    assert next(e.detail.get("name") for e, _ in second if e.kind == "gesture") == "swipe_left"

    (first, second), ending = _replayed_twice(points, reset=True)
    assert _kinds(e for e, _ in first) == ["enter", "dwell", "gesture", "gesture"]
    assert [e.detail["name"] for e, _ in first if e.kind == "gesture"] == ["swipe_right", "circle_ccw"]
    # The session in progress ends with a leave at the last pair; the next one has the next id.
    (leave,) = ending
    assert leave.kind == "leave" and leave.cursor_id == 1 and leave.detail["reason"] == "lost"
    assert leave.time_ns == 10**12 + int((len(points) - 1) * 1e9 / RATE_HZ)
    assert np.allclose(leave.position_m, points[-1], atol=0.01)
    assert len(second) == len(first)
    for (a, at), (b, bt) in zip(first, second, strict=True):
        assert (a.kind, at, a.cursor_id + 1) == (b.kind, bt, b.cursor_id)
        assert np.allclose(a.position_m, b.position_m, atol=1e-9)
        assert a.detail.keys() == b.detail.keys()
        for key, value in a.detail.items():
            if key.endswith("_ns"):
                assert value - a.time_ns == b.detail[key] - b.time_ns
            elif isinstance(value, float | np.ndarray):
                assert np.allclose(value, b.detail[key], atol=1e-9)
            else:
                assert value == b.detail[key]
