"""`trackerd bench robustness --follow N`: the pointer followed through consecutive frames, tracking kept.

The bench's own frames are independent shots, each located with the tracking state reset: a
first sighting, every time. The daemon spends almost all its frames tracking (the detector's
window search, the locator's tracked path), which those frames never reach. Here each installation
also renders ``N`` consecutive frames of the pointer sweeping between aimed poses at a hand's pace
(MAX_STEP_M per frame at 60 fps, half a frame's motion blurred into each exposure), in front of one
still picture, and locates them twice: with one locator that keeps its tracking state from frame to
frame, as the daemon does, and from scratch. The figures of the two side by side say what tracking
costs or saves in rooms trackerd was not tuned on.

The sequence draws from a generator of its own, so the bench's other frames are those of a run
without it.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from trackerd.config.models import RigConfig
    from trackerd.geometry.wall import WallFrame
    from trackerd.sim.randomized import RandomRig
    from trackerd.sim.render import RenderedView, SceneRenderer
    from trackerd.sim.scene import PointerPose

Array = NDArray[np.float64]

MAX_STEP_M = 0.012
"""How far the ball that moves most travels between frames (0.72 m/s at 60 fps)."""

EXPOSURE_SHARE = 0.5
"""Share of the frame interval the shutter is open: the blur is half a frame's motion."""


def followed_poses(drawn: RandomRig, wall: WallFrame, rng: np.random.Generator, count: int) -> list[PointerPose]:
    """``count`` consecutive poses sweeping from one aimed pose to the next (each of the bench's own
    kind: aimed at the wall from the presenter's area, seen by two cameras), MAX_STEP_M apart at most."""
    from trackerd.sim.randomized import random_shot
    from trackerd.sim.scene import PointerPose

    assert drawn.rig.pointer is not None  # a drawn rig has one
    length_m = drawn.rig.pointer.length_m
    start = random_shot(drawn, rng, wall).pose
    poses: list[PointerPose] = []
    while len(poses) < count:
        goal = random_shot(drawn, rng, wall).pose
        distance = max(
            float(np.linalg.norm(goal.front_m - start.front_m)), float(np.linalg.norm(goal.back_m - start.back_m))
        )
        steps = max(2, math.ceil(distance / MAX_STEP_M))
        for k in range(steps):
            between = start.interpolate(goal, k / steps)
            axis = between.front_m - between.back_m
            # Both ends moved linearly shorten the pointer mid-way: keep its length.
            poses.append(PointerPose(between.front_m, between.front_m - length_m * axis / np.linalg.norm(axis)))
            if len(poses) == count:
                break
        start = goal
    return poses


@dataclass(frozen=True)
class FollowedFrame:
    """One frame of a followed sequence: every camera's view, and the true wall hit at the exposure's middle."""

    number: int
    views: list[RenderedView]
    truth_xy_m: Array | None


def followed_frames(
    drawn: RandomRig, renderer: SceneRenderer, wall: WallFrame, rng: np.random.Generator, count: int
) -> tuple[str, Iterator[FollowedFrame]]:
    """The wall's content kind and ``count`` consecutive frames of installation ``drawn`` (:func:`followed_poses`,
    half of each frame's motion blurred into its exposure), rendered from ``rng`` in order as iterated."""
    from trackerd.sim.appearance import wall_content
    from trackerd.sim.randomized import random_shot
    from trackerd.sim.scene import true_wall_hit

    kind = random_shot(drawn, rng, wall).content_kind
    content = wall_content(kind, rng)
    poses = followed_poses(drawn, wall, rng, count + 1)

    def frames() -> Iterator[FollowedFrame]:
        for number, (pose, following) in enumerate(itertools.pairwise(poses)):
            motion_to = pose.interpolate(following, EXPOSURE_SHARE)
            views = [
                renderer.render(i, pose, rng, motion_to=motion_to, motion_steps=3, occluders=(), content=content)
                for i in range(len(drawn.cameras))
            ]
            yield FollowedFrame(number, views, true_wall_hit(pose.interpolate(motion_to, 0.5), wall).wall_xy_m)

    return kind, frames()


def follow_rig(
    drawn: RandomRig,
    rig: RigConfig,
    renderer: SceneRenderer,
    wall: WallFrame,
    rng: np.random.Generator,
    count: int,
    index: int,
) -> list[dict[str, Any]]:
    """One record per frame of a followed sequence: trackerd tracking, and from scratch, on the same images."""
    from trackerd.bench.robustness import MIN_VISIBLE
    from trackerd.locator import Locator

    kind, frames = followed_frames(drawn, renderer, wall, rng, count)
    tracking = Locator(rig, cameras=drawn.cameras)
    scratch = Locator(rig, cameras=drawn.cameras)
    records = []
    for frame in frames:
        number, views, truth = frame.number, frame.views, frame.truth_xy_m
        visible = [[v.truth.visible_fraction(c) for c in ("red", "blue")] for v in views]
        images = [v.image for v in views]
        record: dict[str, Any] = {
            "rig": index,
            "frame": number,
            "sequence": True,
            "factors": {**drawn.factors, "content": kind},
            "eligible": sum(1 for pair in visible if min(pair) >= MIN_VISIBLE) >= 2,
            "visible": visible,
        }
        for name, locator in (("tracking", tracking), ("scratch", scratch)):
            if name == "scratch":
                locator.reset()
            began = time.perf_counter()
            fix = locator.locate(images)
            record[name] = {
                "status": fix.status,
                "reason": fix.reason,
                "error_m": None
                if fix.hit is None or truth is None
                else float(np.linalg.norm(fix.hit.wall_xy_m - truth)),
                "sigma_m": fix.uncertainty_m,
                "seconds": time.perf_counter() - began,
                "window_searches": sum(1 for d in fix.detections if d.search == "window"),
                # Whether this pair was refined (every end's outline fitted) rather than taken on the
                # tracked path (corrected centroids; trackerd/tracked_ends.py).
                "refined": bool(fix.measurements),
            }
        records.append(record)
    return records


def follow_figures(records: list[dict[str, Any]]) -> dict[str, Any]:
    """Found rate, error and honesty of the tracking locator and of the scratch one on the same frames
    (the bench's own figures of each locator's records), and their locate times."""
    from trackerd.bench.robustness import figures

    eligible = [r for r in records if r["eligible"]]
    out: dict[str, Any] = {"frames": len(records), "eligible": len(eligible)}
    for name in ("tracking", "scratch"):
        own = figures(
            [{**r[name], "eligible": r["eligible"], "naive_error_m": None, "floor_error_m": None} for r in records]
        )
        seconds = np.array([r[name]["seconds"] for r in records]) * 1000.0
        out[name] = {
            **own["trackerd"],
            "locate_ms_median": round(float(np.median(seconds)), 2) if seconds.size else None,
            "hidden_hits": own["hidden"]["hits"],
            "hidden_confidently_wrong": own["hidden"]["confidently_wrong"],
            "refined_percent": round(100.0 * sum(1 for r in records if r[name].get("refined")) / len(records), 1)
            if records
            else None,
        }
    out["lost_by_tracking"] = sum(
        1 for r in eligible if r["scratch"]["error_m"] is not None and r["tracking"]["error_m"] is None
    )
    out["kept_by_tracking"] = sum(
        1 for r in eligible if r["tracking"]["error_m"] is not None and r["scratch"]["error_m"] is None
    )
    cameras = sum(len(r["visible"]) for r in records)
    windowed = sum(r["tracking"]["window_searches"] for r in records)
    out["tracking_window_search_percent"] = round(100.0 * windowed / cameras, 1) if cameras else None
    return out


def format_follow(figures: dict[str, Any], count: int) -> list[str]:
    """The followed sequences' lines of the bench's printout."""

    def cell(value: Any, width: int, fmt: str = ".1f") -> str:
        return f"{'-':>{width}}" if value is None else f"{value:>{width}{fmt}}"

    lines = [
        f"Followed (--follow {count}: consecutive frames at up to {1000 * MAX_STEP_M:.0f} mm per frame, tracking"
        f" kept), {figures['frames']} frames, {figures['eligible']} eligible:",
        f"  {'':<10}{'found':>7}{'median':>8}{'p95':>8}{'worst':>8}{'>3s':>6}{'>5s':>6}{'<1s':>6}{'<2s':>6}"
        f"{'ms':>7}{'refined':>10} | hidden: hits, wrong",
    ]
    for name in ("tracking", "scratch"):
        f = figures[name]
        lines.append(
            f"  {name:<10}{cell(f['found_percent'], 7)}{cell(f['median_mm'], 8, '.2f')}{cell(f['p95_mm'], 8, '.2f')}"
            f"{cell(f['worst_mm'], 8)}{cell(f['over_3_sigma_percent'], 6)}{cell(f['over_5_sigma_percent'], 6)}"
            f"{cell(f['within_1_sigma_percent'], 6, '.0f')}{cell(f['within_2_sigma_percent'], 6, '.0f')}"
            f"{cell(f['locate_ms_median'], 7, '.2f')}{cell(f['refined_percent'], 8, '.0f')} %"
            f" | {f['hidden_hits']:>4} {f['hidden_confidently_wrong']:>3}"
        )
    lines.append(
        f"  eligible frames found from scratch but not while tracking: {figures['lost_by_tracking']};"
        f" the other way round: {figures['kept_by_tracking']}; cameras answered by the window search while"
        f" tracking: {figures['tracking_window_search_percent']} %"
    )
    return lines
