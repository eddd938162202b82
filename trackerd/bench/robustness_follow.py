"""`trackerd bench robustness --follow N`: the pointer followed through consecutive frames, tracking kept.

The bench's own frames are independent shots, each located with the tracking state reset: a
first sighting, every time. The daemon spends almost all its frames tracking (the detector's
window search, the locator's tracked path), which those frames never reach. Here each installation
also renders ``N`` consecutive frames of the pointer sweeping between aimed poses at a hand's pace
(MAX_STEP_M per frame at 60 fps, half a frame's motion blurred into each exposure), in front of one
still picture, with what the bench's shots have in front of an end as often as they have it (a finger on
one ball all along, or the presenter standing between one camera and where an end passes mid-sequence),
and locates them twice: with one locator that keeps its tracking state from frame to
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
    from trackerd.sim.appearance import Occluder
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
class FingerOnBall:
    """A finger (or thumb) resting on one ball through a followed sequence: it moves with the pointer."""

    end: str
    """'front' or 'back'."""
    angle_rad: float
    """Where around the pointer's axis it rests (0: the side towards the world's up, turned about the axis)."""
    radius_m: float
    out_share: float
    """How far out from the ball's surface its centre is, as a share of its radius."""
    rgb: tuple[float, float, float]

    def at(self, pose: PointerPose, ball_radius_m: float) -> Occluder:
        """The finger on the ball in ``pose``."""
        from trackerd.sim.appearance import Occluder

        direction = pose.direction
        across = np.cross(direction, [0.0, 1.0, 0.0])
        if np.linalg.norm(across) < 1e-6:
            across = np.cross(direction, [1.0, 0.0, 0.0])
        across /= np.linalg.norm(across)
        up = np.cross(across, direction)
        side = math.cos(self.angle_rad) * up + math.sin(self.angle_rad) * across
        ball = pose.front_m if self.end == "front" else pose.back_m
        place = ball + side * (ball_radius_m + self.radius_m * self.out_share)
        x, y, z = (float(v) for v in place)
        return Occluder("sphere", (x, y, z), self.radius_m, self.rgb, label="hand")


def followed_occluders(
    drawn: RandomRig, poses: list[PointerPose], rng: np.random.Generator
) -> tuple[str, list[tuple[Occluder, ...]]]:
    """The occlusion level of a followed sequence (drawn as often as the bench's shots draw each) and what
    is in front of the pointer in each of ``poses``: nothing; a finger on one ball (FingerOnBall, drawn as
    the shots' hands are); or the presenter's body, standing still between one camera and where one end
    is mid-sequence, so that the end passes behind it and out again. A body that would touch the pointer
    in some pose is drawn again (20 tries), else the sequence has none ("none")."""
    from trackerd.sim.appearance import Occluder
    from trackerd.sim.randomized import CLOTHES_RGB, OCCLUSION_ODDS, OCCLUSIONS, clear_of_pointer
    from trackerd.sim.scene import scene_pointer

    occlusion = str(rng.choice(OCCLUSIONS, p=list(OCCLUSION_ODDS)))
    ball_r = scene_pointer(drawn.rig).end_diameter_m / 2.0
    if occlusion == "hand":
        radius = ball_r * float(rng.uniform(0.45, 0.8))
        skin = np.clip(np.array([0.80, 0.58, 0.47]) * rng.uniform(0.7, 1.1), 0, 1)
        finger = FingerOnBall(
            "front" if rng.uniform() < 0.5 else "back",
            float(rng.uniform(0.0, 2.0 * math.pi)),
            radius,
            float(rng.uniform(0.2, 0.7)),
            (float(skin[0]), float(skin[1]), float(skin[2])),
        )
        return occlusion, [(finger.at(pose, ball_r),) for pose in poses]
    if occlusion == "body":
        middle = poses[len(poses) // 2]
        camera = drawn.cameras[int(rng.integers(0, len(drawn.cameras)))]
        end = middle.front_m if rng.uniform() < 0.5 else middle.back_m
        to_camera = camera.centre_m - end
        across = np.cross(to_camera, [0.0, 1.0, 0.0])
        if np.linalg.norm(across) > 1e-6:
            across /= np.linalg.norm(across)
            clothes = CLOTHES_RGB[int(rng.integers(0, len(CLOTHES_RGB)))]
            for _ in range(20):
                radius = float(rng.uniform(0.1, 0.18))
                point = (
                    end + float(rng.uniform(0.25, 0.6)) * to_camera + across * radius * float(rng.uniform(-1.3, 1.3))
                )
                centre = np.array([point[0], point[1] - 0.1, point[2]])
                if all(clear_of_pointer(centre, radius, 0.4, pose, ball_r) for pose in poses):
                    x, y, z = (float(v) for v in centre)
                    body = Occluder("cylinder", (x, y, z), radius, clothes, height_m=0.4, label="body")
                    return occlusion, [(body,)] * len(poses)
    return "none", [()] * len(poses)


@dataclass(frozen=True)
class FollowedFrame:
    """One frame of a followed sequence: every camera's view, and the true wall hit at the exposure's middle."""

    number: int
    views: list[RenderedView]
    truth_xy_m: Array | None


def followed_frames(
    drawn: RandomRig,
    renderer: SceneRenderer,
    wall: WallFrame,
    rng: np.random.Generator,
    count: int,
    occlusion_rng: np.random.Generator | None = None,
) -> tuple[dict[str, str], Iterator[FollowedFrame]]:
    """The sequence's factors (what the wall shows, what is in front of the pointer) and ``count``
    consecutive frames of installation ``drawn`` (:func:`followed_poses`, half of each frame's motion blurred
    into its exposure), rendered from ``rng`` in order as iterated. What is in front of the pointer is drawn
    from ``occlusion_rng`` (:func:`followed_occluders`; None: nothing), a generator of its own so that the
    same ``rng`` renders the same pointer, room and noise with or without it."""
    from trackerd.sim.appearance import wall_content
    from trackerd.sim.randomized import random_shot
    from trackerd.sim.scene import true_wall_hit

    kind = random_shot(drawn, rng, wall).content_kind
    content = wall_content(kind, rng)
    poses = followed_poses(drawn, wall, rng, count + 1)
    # Each frame's occluders are placed at the middle of its exposure.
    middles = [pose.interpolate(following, 0.5 * EXPOSURE_SHARE) for pose, following in itertools.pairwise(poses)]
    occlusion, occluders = (
        ("none", [()] * count) if occlusion_rng is None else followed_occluders(drawn, middles, occlusion_rng)
    )

    def frames() -> Iterator[FollowedFrame]:
        for number, (pose, following) in enumerate(itertools.pairwise(poses)):
            motion_to = pose.interpolate(following, EXPOSURE_SHARE)
            views = [
                renderer.render(
                    i, pose, rng, motion_to=motion_to, motion_steps=3, occluders=occluders[number], content=content
                )
                for i in range(len(drawn.cameras))
            ]
            yield FollowedFrame(number, views, true_wall_hit(pose.interpolate(motion_to, 0.5), wall).wall_xy_m)

    return {"content": kind, "occlusion": occlusion}, frames()


def follow_rig(
    drawn: RandomRig,
    rig: RigConfig,
    renderer: SceneRenderer,
    wall: WallFrame,
    rng: np.random.Generator,
    count: int,
    index: int,
    occlusion_rng: np.random.Generator | None = None,
) -> list[dict[str, Any]]:
    """One record per frame of a followed sequence (:func:`followed_frames`): trackerd tracking, and from
    scratch, on the same images."""
    from trackerd.bench.robustness import MIN_VISIBLE
    from trackerd.locator import Locator

    factors, frames = followed_frames(drawn, renderer, wall, rng, count, occlusion_rng)
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
            "factors": {**drawn.factors, **factors},
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
    out["tracking_by_occlusion"] = {}
    for level in sorted({r["factors"].get("occlusion", "none") for r in records}):
        at_level = [r for r in records if r["factors"].get("occlusion", "none") == level]
        shares = figures(
            [
                {**r["tracking"], "eligible": r["eligible"], "naive_error_m": None, "floor_error_m": None}
                for r in at_level
            ]
        )
        out["tracking_by_occlusion"][level] = {
            "frames": shares["frames"],
            "eligible": shares["eligible"],
            **shares["trackerd"],
            "hidden_hits": shares["hidden"]["hits"],
            "hidden_confidently_wrong": shares["hidden"]["confidently_wrong"],
        }
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
    for level, f in figures.get("tracking_by_occlusion", {}).items():
        lines.append(
            f"  {'':<2}{level:<8}{cell(f['found_percent'], 7)}{cell(f['median_mm'], 8, '.2f')}"
            f"{cell(f['p95_mm'], 8, '.2f')}{cell(f['worst_mm'], 8)}{cell(f['over_3_sigma_percent'], 6)}"
            f"{cell(f['over_5_sigma_percent'], 6)}{cell(f['within_1_sigma_percent'], 6, '.0f')}"
            f"{cell(f['within_2_sigma_percent'], 6, '.0f')}{'':>17} | {f['hidden_hits']:>4}"
            f" {f['hidden_confidently_wrong']:>3}   (tracking, {f['eligible']} of {f['frames']} frames eligible)"
        )
    lines.append(
        f"  eligible frames found from scratch but not while tracking: {figures['lost_by_tracking']};"
        f" the other way round: {figures['kept_by_tracking']}; cameras answered by the window search while"
        f" tracking: {figures['tracking_window_search_percent']} %"
    )
    return lines
