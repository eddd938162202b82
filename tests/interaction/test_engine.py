"""Enter/leave with hysteresis, dwell once per rest, and gestures vs random pointing on scripted hits."""

from __future__ import annotations

import numpy as np

from tests.interaction.conftest import HEIGHT_M, WIDTH_M, run_track
from trackerd.config.interaction import InteractionConfig
from trackerd.interaction.scripted import GESTURES, Track, gesture_session, pointing_session

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
