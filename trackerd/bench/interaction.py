"""Interaction figures: smoothing jitter and lag, gesture recognition and false positives, finger counts, cost.

1. **Smoothing** (One Euro filter, the rig's ``[interaction.smoothing]``):
   jitter of a still pointer (standard deviation on the wall, mm, per axis and
   as an RMS radius), raw vs smoothed, on rendered frames located by the real
   locator, and on scripted hits with white noise of 0.5, 1.5 and 3 mm; lag
   added on a pointer moving at 1 m/s (mm behind the raw hit, and in frames at
   the rig's rate), on rendered frames and scripted hits. Target: jitter down
   at least 5x, at most one frame of added lag at 1 m/s.
2. **Gestures**: recognition rate per gesture on scripted sessions (swipes in
   four directions, circles both ways, with noise and lost pairs) and false
   gestures per minute of random pointing (Fitts-law aimed movements, rests,
   tracing; trackerd/interaction/scripted.py).
3. **Hands**: finger-count accuracy on rendered hands (0-5 fingers, random
   rotation, tilt, scale and distance) in the left camera, with a confusion matrix.
4. **Cost**: the interaction engine's time per pair, and one hand look.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from trackerd.bench.progress import BenchProgress
from trackerd.config.examples import example_rig
from trackerd.config.interaction import InteractionConfig
from trackerd.config.loader import load_rig
from trackerd.config.models import RigConfig
from trackerd.config.rig_geometry import wall_frame
from trackerd.errors import ConfigError
from trackerd.geometry.wall import WallFrame
from trackerd.interaction.engine import Event, InteractionEngine
from trackerd.interaction.scripted import GESTURES, Track, gesture_session, pointing_session
from trackerd.interaction.smoothing import smooth_track
from trackerd.interaction.templates import load_templates


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--config", default=str(example_rig("simulated")), help="rig (default: the bundled config/simulated.toml)"
    )
    parser.add_argument(
        "--rendered-pairs",
        type=int,
        default=60,
        help="rendered pairs for the still and the moving pointer each (default 60; 0: none)",
    )
    parser.add_argument("--sessions", type=int, default=25, help="gesture sessions of six gestures (default 25)")
    parser.add_argument(
        "--pointing-minutes",
        type=float,
        default=20.0,
        help="minutes of random pointing for false positives (default 20)",
    )
    parser.add_argument("--noise-mm", type=float, default=1.5, help="hit noise of the scripted tracks (default 1.5)")
    parser.add_argument("--hands", type=int, default=120, help="rendered hands, 0-5 fingers in turn (default 120)")
    parser.add_argument("--seed", type=int, default=11)


def run(args: argparse.Namespace) -> int:
    rig = load_rig(args.config).config
    rng = np.random.default_rng(args.seed)
    progress = BenchProgress("interaction")
    progress.phase("smoothing: scripted and rendered tracks")
    figures: dict[str, Any] = {"smoothing": smoothing_figures(rig, args, rng)}
    progress.phase(f"gestures: {args.sessions} sessions, {args.pointing_minutes:g} min of random pointing")
    figures["gestures"] = gesture_figures(rig, args, rng)
    if args.hands:
        progress.phase(f"hands: {args.hands} rendered")
        figures["hands"] = hand_figures(rig, args.hands, rng)
    progress.phase("cost per pair")
    figures["cost"] = cost_figures(rig, rng)
    progress.done()
    if args.json:
        print(json.dumps(figures, indent=2))
    else:
        _print(figures)
    return 0


# ----------------------------------------------------------------------------- smoothing


def _jitter(points_m: np.ndarray) -> dict[str, float]:
    centred = points_m - points_m.mean(axis=0)
    sd = centred.std(axis=0) * 1000.0
    return {
        "x_mm": round(float(sd[0]), 3),
        "y_mm": round(float(sd[1]), 3),
        "rms_radius_mm": round(float(np.sqrt(np.mean(np.sum(centred**2, axis=1)))) * 1000.0, 3),
    }


def _lag_mm(times_ns: np.ndarray, raw_m: np.ndarray, smoothed_m: np.ndarray, from_index: int) -> float:
    """Mean distance the smoothed hit trails the raw one along the movement, from ``from_index`` on."""
    direction = raw_m[-1] - raw_m[from_index]
    direction /= np.linalg.norm(direction)
    return float(np.mean((raw_m[from_index:] - smoothed_m[from_index:]) @ direction)) * 1000.0


def smoothing_figures(rig: RigConfig, args: argparse.Namespace, rng: np.random.Generator) -> dict[str, Any]:
    cfg = rig.interaction.smoothing
    rate_hz = 60.0
    frame_mm_at_1m_s = 1000.0 / rate_hz
    out: dict[str, Any] = {"config": cfg.model_dump(), "rate_hz": rate_hz, "scripted": []}
    n = 1200
    times = (np.arange(n) * 1e9 / rate_hz).astype(np.int64)
    for noise_mm in (0.5, 1.5, 3.0):
        still = rng.normal(0.0, noise_mm / 1000.0, (n, 2))
        smoothed = smooth_track(cfg, times, still)[120:]
        truth = np.column_stack([np.arange(n) / rate_hz, np.zeros(n)])  # 1 m/s along x
        moving = truth + rng.normal(0.0, noise_mm / 1000.0, (n, 2))
        lag = _lag_mm(times, truth, smooth_track(cfg, times, moving), 300)
        raw_j, smooth_j = _jitter(still[120:]), _jitter(smoothed)
        out["scripted"].append(
            {
                "noise_mm": noise_mm,
                "raw": raw_j,
                "smoothed": smooth_j,
                "reduction": round(raw_j["rms_radius_mm"] / smooth_j["rms_radius_mm"], 2),
                "lag_at_1_m_s_mm": round(lag, 2),
                "lag_frames": round(lag / frame_mm_at_1m_s, 2),
            }
        )
    if args.rendered_pairs:
        out["rendered"] = _rendered_smoothing(rig, args.rendered_pairs, rate_hz, rng)
    return out


def _rendered_smoothing(rig: RigConfig, pairs: int, rate_hz: float, rng: np.random.Generator) -> dict[str, Any]:
    """The real locator on rendered frames: a still pointer, and one whose hit moves at 1 m/s."""
    from trackerd.locator import Locator
    from trackerd.sim.motion import Stage
    from trackerd.sim.render import SceneRenderer
    from trackerd.sim.scene import pose_aimed_at

    renderer = SceneRenderer(rig)
    locator = Locator(rig)
    stage = Stage.from_rig(rig)
    wall = renderer.wall
    if rig.pointer is None:
        raise ConfigError(f"rig '{rig.name}': no [pointer]; the bench renders one")
    length_m = rig.pointer.length_m

    def hits(targets_m: np.ndarray) -> np.ndarray:
        out = []
        for target in targets_m:
            pose = pose_aimed_at(stage.hand_m, wall.from_wall_m(target), length_m)
            fix = locator.locate([renderer.render(i, pose, rng).image for i in range(len(renderer.cameras))])
            out.append(fix.hit.wall_xy_m[:2] if fix.hit is not None else (np.nan, np.nan))
        return np.array(out, dtype=np.float64)

    cfg = rig.interaction.smoothing
    times = (np.arange(pairs) * 1e9 / rate_hz).astype(np.int64)
    centre = np.array([wall.width_m * 0.4, wall.height_m * 0.5])
    still = hits(np.repeat(centre[None], pairs, axis=0))
    smoothed = smooth_track(cfg, times, still)
    settle = min(pairs // 3, 20)
    raw_j, smooth_j = _jitter(still[settle:]), _jitter(smoothed[settle:])
    path = centre + np.column_stack([np.arange(pairs) / rate_hz - pairs / rate_hz / 2, np.zeros(pairs)])
    moving = hits(path)
    lag = _lag_mm(times, moving, smooth_track(cfg, times, moving), settle)
    return {
        "pairs": pairs,
        "raw": raw_j,
        "smoothed": smooth_j,
        "reduction": round(raw_j["rms_radius_mm"] / max(smooth_j["rms_radius_mm"], 1e-9), 2),
        "lag_at_1_m_s_mm": round(lag, 2),
        "lag_frames": round(lag / (1000.0 / rate_hz), 2),
    }


# ----------------------------------------------------------------------------- gestures


def _wall(rig: RigConfig) -> WallFrame:
    if rig.wall is None:
        raise ConfigError(f"rig '{rig.name}': no [wall]; the bench places its gestures on one")
    return wall_frame(rig.wall)


@dataclass
class _Recognition:
    """How often one gesture was performed, recognised, and taken for another."""

    performed: int = 0
    recognised: int = 0
    confused: dict[str, int] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {
            "performed": self.performed,
            "recognised": self.recognised,
            "confused": self.confused,
            "rate": round(self.recognised / max(self.performed, 1), 3),
        }


def _run(engine: InteractionEngine, track: Track) -> list[Event]:
    events: list[Event] = []
    for t, p in zip(track.times_ns, track.points_m, strict=True):
        events += engine.step(int(t), None if np.isnan(p[0]) else p).events
    return [e for e in events if e.kind == "gesture"]


def gesture_figures(rig: RigConfig, args: argparse.Namespace, rng: np.random.Generator) -> dict[str, Any]:
    wall = _wall(rig)
    cfg: InteractionConfig = rig.interaction
    templates = load_templates(cfg.gestures.template_dir, builtin=cfg.gestures.builtin, only=cfg.gestures.only)
    per = {name: _Recognition() for name in GESTURES}
    for _ in range(args.sessions):
        names = [str(n) for n in rng.permutation(GESTURES)]
        track = gesture_session(names, rng, wall.width_m, wall.height_m, noise_mm=args.noise_mm)
        found = _run(InteractionEngine(cfg, wall.width_m, wall.height_m, templates), track)
        for name, start, end in track.labels:
            per[name].performed += 1
            match = [g for g in found if g.detail["start_ns"] < end and g.detail["end_ns"] > start]
            got = match[0].detail["name"] if match else "none"
            if got == name:
                per[name].recognised += 1
            else:
                per[name].confused[got] = per[name].confused.get(got, 0) + 1
    track = pointing_session(args.pointing_minutes * 60.0, rng, wall.width_m, wall.height_m, noise_mm=args.noise_mm)
    false = _run(InteractionEngine(cfg, wall.width_m, wall.height_m, templates), track)
    by_name: dict[str, int] = {}
    for g in false:
        by_name[g.detail["name"]] = by_name.get(g.detail["name"], 0) + 1
    return {
        "noise_mm": args.noise_mm,
        "per_gesture": {name: f.to_json() for name, f in per.items()},
        "overall_rate": round(
            sum(f.recognised for f in per.values()) / max(sum(f.performed for f in per.values()), 1), 3
        ),
        "random_pointing_minutes": args.pointing_minutes,
        "false_gestures": len(false),
        "false_per_minute": round(len(false) / args.pointing_minutes, 3),
        "false_by_name": by_name,
    }


# ----------------------------------------------------------------------------- hands


def hand_figures(rig: RigConfig, count: int, rng: np.random.Generator) -> dict[str, Any]:
    from trackerd.interaction.hand import HandDetector
    from trackerd.sim.hand import HandRenderer, random_hand_pose
    from trackerd.sim.render import SceneRenderer

    renderer = SceneRenderer(rig)
    hands = HandRenderer(renderer, 0)
    cam = renderer.cameras[0]
    detector = HandDetector(rig.interaction.hand.model_copy(update={"enabled": True}))
    detector.learn_background(hands.empty(rng), hands.pixel_format)
    confusion = np.zeros((6, 7), dtype=int)  # last column: no hand found
    by_distance: dict[str, list[int]] = {}
    for k in range(count):
        pose = random_hand_pose(k % 6, rng, cam.width_px, cam.height_px)
        seen = detector.look(hands.render(pose, rng).image, hands.pixel_format)
        got = 6 if seen is None else seen.fingers
        confusion[pose.fingers, got] += 1
        band = f"{pose.distance_m:.1f}"[:3]
        by_distance.setdefault(f"{float(band):.1f}", []).append(int(got == pose.fingers))
    correct = int(np.trace(confusion[:, :6]))
    return {
        "hands": count,
        "accuracy": round(correct / count, 3),
        "per_count": {str(f): round(float(confusion[f, f] / max(confusion[f].sum(), 1)), 3) for f in range(6)},
        "confusion_rows_true_cols_found_then_none": confusion.tolist(),
        "accuracy_by_distance_m": {k: round(float(np.mean(v)), 3) for k, v in sorted(by_distance.items())},
    }


# ----------------------------------------------------------------------------- cost


def cost_figures(rig: RigConfig, rng: np.random.Generator) -> dict[str, Any]:
    from trackerd.interaction.hand import HandDetector

    wall = _wall(rig)
    engine = InteractionEngine(rig.interaction, wall.width_m, wall.height_m, load_templates())
    track = gesture_session([str(n) for n in GESTURES] * 3, rng, wall.width_m, wall.height_m)
    costs = []
    for t, p in zip(track.times_ns, track.points_m, strict=True):
        start = time.perf_counter_ns()
        engine.step(int(t), None if np.isnan(p[0]) else p)
        costs.append(time.perf_counter_ns() - start)
    costs_us = np.array(costs) / 1e3
    cam = rig.cameras[0]
    image = rng.integers(0, 255, (cam.height_px, cam.width_px), dtype=np.uint8)
    detector = HandDetector(rig.interaction.hand)
    looks = []
    for _ in range(20):
        start = time.perf_counter_ns()
        detector.look(image, cam.pixel_format)
        looks.append(time.perf_counter_ns() - start)
    return {
        "engine_per_pair_us": {
            "p50": round(float(np.percentile(costs_us, 50)), 1),
            "p99": round(float(np.percentile(costs_us, 99)), 1),
            "max": round(float(costs_us.max()), 1),
        },
        "hand_look_ms": {
            "p50": round(float(np.percentile(looks, 50)) / 1e6, 2),
            "max": round(float(np.max(looks)) / 1e6, 2),
        },
        "hand_every_n_pairs": rig.interaction.hand.every_n_pairs,
    }


def _print(f: dict[str, Any]) -> None:
    s = f["smoothing"]
    print(
        f"smoothing (One Euro: min_cutoff {s['config']['min_cutoff_hz']} Hz, beta {s['config']['beta_per_m']}/m,"
        f" derivative cutoff {s['config']['derivative_cutoff_hz']} Hz), {s['rate_hz']:.0f} pairs/s"
    )
    for row in s["scripted"]:
        print(
            f"  scripted noise {row['noise_mm']} mm: jitter {row['raw']['rms_radius_mm']:.2f} -> "
            f"{row['smoothed']['rms_radius_mm']:.2f} mm RMS ({row['reduction']:.1f}x); lag at 1 m/s "
            f"{row['lag_at_1_m_s_mm']:.1f} mm = {row['lag_frames']:.2f} frame"
        )
    if "rendered" in s:
        r = s["rendered"]
        print(
            f"  rendered ({r['pairs']} pairs each): jitter x {r['raw']['x_mm']:.3f} y {r['raw']['y_mm']:.3f} -> "
            f"x {r['smoothed']['x_mm']:.3f} y {r['smoothed']['y_mm']:.3f} mm ({r['reduction']:.1f}x RMS);"
            f" lag at 1 m/s {r['lag_at_1_m_s_mm']:.1f} mm = {r['lag_frames']:.2f} frame"
        )
    g = f["gestures"]
    print(f"gestures (noise {g['noise_mm']} mm): overall {100 * g['overall_rate']:.1f} %")
    for name, row in g["per_gesture"].items():
        confused = ", ".join(f"{k} {v}" for k, v in row["confused"].items())
        print(f"  {name:<12} {row['recognised']}/{row['performed']}" + (f"  (else: {confused})" if confused else ""))
    print(
        f"  random pointing: {g['false_gestures']} false gestures in {g['random_pointing_minutes']:g} min"
        f" ({g['false_per_minute']:.2f}/min) {g['false_by_name']}"
    )
    if "hands" in f:
        h = f["hands"]
        print(
            f"hands: {100 * h['accuracy']:.1f} % of {h['hands']} counted right; per count {h['per_count']};"
            f" by distance {h['accuracy_by_distance_m']}"
        )
        confusion = h["confusion_rows_true_cols_found_then_none"]
        print(f"  confusion (rows: true 0-5; columns: found 0-5, none): {confusion}")
    c = f["cost"]
    print(
        f"cost: engine per pair p50 {c['engine_per_pair_us']['p50']} us, p99 {c['engine_per_pair_us']['p99']} us,"
        f" max {c['engine_per_pair_us']['max']} us; hand look p50 {c['hand_look_ms']['p50']} ms"
        f" (one pair in {c['hand_every_n_pairs']})"
    )
