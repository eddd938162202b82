"""Robustness: the pointer found and located in randomized rooms trackerd was not tuned on.

Draws ``--rigs`` installations from wide distributions (trackerd/sim/randomized.py:
camera placement, lenses and sensors, lighting, paints, pointer sizes) and renders
``--poses`` frames in each (what the display shows, motion blur, a hand or the
presenter's body in front of an end). Every frame is located two ways on the
same images:

* trackerd: `Locator.locate`, the rig's defaults, tracking reset for every frame
  (each frame is a first sighting, the hardest case);
* floor: no images at all: each ball's true centre in every camera that sees it
  (at least 60 % visible) moved by unbiased noise of 0.1 px (``FLOOR_SIGMA_PX``),
  then the same pointer fit. What the installation's geometry alone allows at
  that precision: cameras looking along the pointer magnify any end error on the
  wall, and no detector can beat this by more than its noise is smaller;
* naive: the bounding-box midpoint of the largest blob of each end's hue in every
  camera (trackerd/detect/reference.py, `naive_ends`), each end triangulated from
  the cameras that found it, the line through the two points.

Printed per factor (placement, content, lighting, blur, occlusion, paint, number
of cameras, resolution) and overall: how many frames were *eligible* (each ball at
least 60 % visible in at least two cameras), the share of those located, the wall
error's median, 95th percentile and worst, the floor's median and 95th percentile, how often the error exceeds 3 and 5
times trackerd's own 1-sigma estimate, how often it is within 1 and 2 sigma, and
the naive method's figures beside them. Frames that are not eligible (an end
truly hidden) count separately: trackerd should say "not found" there, never give
a confidently wrong hit.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import time
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from trackerd.bench.progress import BenchProgress
from trackerd.bench.robustness_follow import follow_figures, follow_rig, format_follow
from trackerd.errors import ConfigError, GeometryError

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from trackerd.config.models import RigConfig
    from trackerd.geometry.camera import CameraModel
    from trackerd.geometry.wall import WallFrame
    from trackerd.sim.randomized import RandomRig
    from trackerd.sim.render import RenderedView, SceneRenderer
    from trackerd.sim.scene import PointerPose

FACTORS = ("placement", "content", "lighting", "blur", "occlusion", "paint", "cameras", "resolution")
MIN_VISIBLE = 0.6
"""A ball counts as visible in a camera when at least this share of its silhouette is seen."""

FLOOR_SIGMA_PX = 0.1
"""The geometric floor's measurement noise: every end's true image centre moved by this much (pixels, 1
sigma per axis, unbiased), about the precision of a ball's outline fit on a clean frame."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--rigs", type=_positive_int, default=30, help="randomized installations (default 30)")
    parser.add_argument("--poses", type=_positive_int, default=40, help="frames per installation (default 40)")
    parser.add_argument("--seed", type=int, default=2026, help="seed of the whole run (default 2026)")
    parser.add_argument(
        "--refine",
        choices=("auto", "always", "never"),
        default=None,
        help="override [locator] refine for trackerd (default: the rig's, auto)",
    )
    parser.add_argument(
        "--learn-colours",
        type=int,
        default=0,
        metavar="PAIRS",
        help="learn each installation's pointer colours first (`trackerd calibrate pointer`) from"
        " this many pairs of shots of its own (not the measured ones), and locate with them"
        " (default 0: the detector's default thresholds)",
    )
    parser.add_argument(
        "--follow",
        type=int,
        default=0,
        metavar="FRAMES",
        help="also follow the pointer through this many consecutive frames per installation, tracking kept"
        " between frames as the daemon does, against the same frames located from scratch (default 0: the"
        " independent frames only)",
    )
    parser.add_argument(
        "--records",
        metavar="FILE",
        default=None,
        help="also write every frame's record (its installation and frame number, factors, status,"
        " reason, error, sigma) as JSON lines, to look into a miss with the same seed",
    )
    parser.add_argument(
        "--workers",
        type=_positive_int,
        default=min(2, multiprocessing.cpu_count()),
        help="processes rendering and locating (default 2)",
    )


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {text}")
    return value


def run(args: argparse.Namespace) -> int:
    start = time.time()
    if args.follow < 0:
        raise ConfigError(f"--follow {args.follow}: must be 0 (off) or a number of frames")
    tasks = [(args.seed, index, args.poses, args.refine, args.learn_colours, args.follow) for index in range(args.rigs)]
    records: list[dict[str, Any]] = []
    progress = BenchProgress("robustness", args.rigs, "installations")
    if args.workers > 1 and args.rigs > 1:
        with multiprocessing.get_context("fork").Pool(args.workers) as pool:
            for result in pool.imap_unordered(run_rig, tasks):
                records.extend(result)
                progress.step()
    else:
        for task in tasks:
            records.extend(run_rig(task))
            progress.step()
    progress.done()
    if args.records:
        with open(args.records, "w", encoding="utf-8") as out:
            for record in sorted(records, key=lambda r: (r["rig"], bool(r.get("sequence")), r["frame"])):
                out.write(json.dumps(record) + "\n")
    followed = [r for r in records if r.get("sequence")]
    summary = summarise([r for r in records if not r.get("sequence")])
    if followed:
        summary["followed"] = follow_figures(followed)
    summary["seconds"] = round(time.time() - start, 1)
    summary["arguments"] = {
        "rigs": args.rigs,
        "poses": args.poses,
        "seed": args.seed,
        "refine": args.refine,
        "learn_colours": args.learn_colours,
        "follow": args.follow,
    }
    if args.learn_colours:
        learned = {r["rig"] for r in records if r.get("learned")}
        summary["colours_learned_in"] = f"{len(learned)} of {args.rigs} installations"
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(format_summary(summary))
    return 0


# --------------------------------------------------------------------------- one installation


@dataclass(frozen=True)
class DrawnFrame:
    """One frame of an installation as the bench renders it."""

    number: int
    factors: dict[str, str]
    """The installation's factors and the shot's."""
    views: list[RenderedView]
    middle: PointerPose
    """The pointer's pose in the middle of the exposure (a blurred frame's truth)."""
    truth_xy_m: NDArray[np.float64] | None
    """Where ``middle`` points on the wall (None: not at the wall's plane)."""


def renderer_for(drawn: RandomRig) -> SceneRenderer:
    """The renderer of a drawn installation, as the bench makes it (each renderer draws its noise field
    from the first generator it is given)."""
    from trackerd.sim.render import SceneRenderer

    widest = max(c.width_px for c in drawn.cameras)
    return SceneRenderer(
        drawn.rig,
        list(drawn.cameras),
        look=drawn.look,
        cache_dir=False,
        background_step=1 if widest <= 2000 else 2,
        noise_field=True,
    )


def draw_installation(seed: int, index: int) -> tuple[RandomRig, np.random.Generator]:
    """Installation ``index`` of a run with ``seed``, and the generator its frames are then drawn from."""
    from trackerd.sim.randomized import random_rig

    rng = np.random.default_rng([seed, index])
    return random_rig(rng, name=f"random-{seed}-{index}"), rng


def drawn_frames(
    drawn: RandomRig,
    renderer: SceneRenderer,
    wall: WallFrame,
    rng: np.random.Generator,
    poses: int,
    wanted: Callable[[int, dict[str, str]], bool] | None = None,
) -> Iterator[DrawnFrame]:
    """The installation's first ``poses`` frames, in order (every frame draws from ``rng`` in turn, so
    frame k is the same only after frames 0..k-1 were drawn: scripts/robustness_frame.py relies on it).

    ``wanted(number, factors)``: only the frames it accepts are rendered and given; the others are drawn
    without rendering their images (:meth:`SceneRenderer.skip`), so the frames given are those of a run
    that rendered every frame, bit for bit, in a fraction of the time."""
    from trackerd.sim.appearance import wall_content
    from trackerd.sim.randomized import random_shot
    from trackerd.sim.scene import true_wall_hit

    for number in range(poses):
        shot = random_shot(drawn, rng, wall)
        content = wall_content(shot.content_kind, rng)
        factors = {**drawn.factors, **shot.factors}
        if wanted is not None and not wanted(number, factors):
            for i in range(len(drawn.cameras)):
                renderer.skip(i, rng)
            continue
        views = [
            renderer.render(
                i,
                shot.pose,
                rng,
                motion_to=shot.motion_to,
                motion_steps=shot.motion_steps,
                occluders=shot.occluders,
                content=content,
            )
            for i in range(len(drawn.cameras))
        ]
        # The truth of a blurred frame is the middle of the exposure.
        middle = shot.pose if shot.motion_to is None else shot.pose.interpolate(shot.motion_to, 0.5)
        truth = true_wall_hit(middle, wall).wall_xy_m
        yield DrawnFrame(number, factors, views, middle, truth)


def run_rig(task: tuple[int, int, int, str | None, int, int]) -> list[dict[str, Any]]:
    """Draw installation ``index`` of a run and locate ``poses`` frames in it, and ``follow`` consecutive
    frames (trackerd/bench/robustness_follow.py); one record per frame."""
    from trackerd.config.rig_geometry import check_rig_geometry, wall_frame
    from trackerd.locator import Locator

    seed, index, poses, refine, learn_pairs, follow = task
    drawn, rng = draw_installation(seed, index)
    # The locator is handed the drawn cameras, not a rig file: make the checks loading one would, so
    # the bench never measures trackerd on an installation it would refuse (a lens folding inside the
    # image was drawn, and rendered wrongly, until 2026-12-05).
    check_rig_geometry(drawn.rig, Path(f"installation {index} of seed {seed}"))
    rig = drawn.rig
    if refine is not None:
        rig = rig.model_copy(update={"locator": rig.locator.model_copy(update={"refine": refine})})
    renderer = renderer_for(drawn)
    assert drawn.rig.wall is not None and drawn.rig.pointer is not None  # a drawn rig has both
    wall = wall_frame(drawn.rig.wall)
    learned = False
    if learn_pairs:
        # Shots of their own, from their own generator and renderer: the measured frames are exactly
        # those of a run without learning.
        learning = renderer_for(drawn)
        rig, learned = _learn_colours(rig, drawn, learning, wall, np.random.default_rng([seed, index, 1]), learn_pairs)
    locator = Locator(rig, cameras=drawn.cameras)
    floor_rng = np.random.default_rng([seed, index, 2])  # its own: the scenes are those of a run without it
    records = []
    for frame in drawn_frames(drawn, renderer, wall, rng, poses):
        views, middle, truth = frame.views, frame.middle, frame.truth_xy_m
        visible = [[v.truth.visible_fraction(c) for c in ("red", "blue")] for v in views]
        seeing = sum(1 for pair in visible if min(pair) >= MIN_VISIBLE)
        images = [v.image for v in views]
        locator.reset()
        began = time.perf_counter()
        fix = locator.locate(images)
        seconds = time.perf_counter() - began
        record: dict[str, Any] = {
            "rig": index,
            "frame": frame.number,
            "factors": frame.factors,
            "eligible": seeing >= 2,
            "visible": visible,
            "status": fix.status,
            "reason": fix.reason,
            "error_m": None,
            "sigma_m": fix.uncertainty_m,
            "seconds": seconds,
            "naive_error_m": None,
            "floor_error_m": None,
            "learned": learned,
        }
        if fix.hit is not None and truth is not None:
            record["error_m"] = float(np.linalg.norm(fix.hit.wall_xy_m - truth))
        if truth is not None and seeing >= 2:
            floor = floor_hit(
                drawn.cameras, [min(pair) >= MIN_VISIBLE for pair in visible], middle, rig, wall, floor_rng
            )
            if floor is not None:
                record["floor_error_m"] = float(np.linalg.norm(floor - truth))
        naive = naive_hit(
            drawn.cameras,
            wall,
            [v.image for v in views],
            [v.pixel_format for v in views],
            drawn.rig.pointer.front_colour,
        )
        if naive is not None and truth is not None:
            record["naive_error_m"] = float(np.linalg.norm(naive - truth))
        records.append(record)
    if follow:
        # A generator and a renderer of their own: the frames above are those of a run without --follow,
        # and the followed frames those of a run without the frames above (scripts/robustness_frame.py
        # --followed renders them alone). A renderer keeps what it drew first (each camera's noise field).
        records += follow_rig(
            drawn,
            rig,
            renderer_for(drawn),
            wall,
            np.random.default_rng([seed, index, 3]),
            follow,
            index,
            np.random.default_rng([seed, index, 4]),
        )
    return records


def _learn_colours(
    rig: RigConfig, drawn: RandomRig, renderer: SceneRenderer, wall: WallFrame, rng: np.random.Generator, pairs: int
) -> tuple[RigConfig, bool]:
    """The rig with its pointer colours learned from ``pairs`` shots, as `trackerd calibrate pointer` learns
    them; the rig unchanged (and False) where they cannot be learned (the operator would be told why)."""
    from trackerd.calibration import CalibrationError
    from trackerd.calibration.colours import ColourLearner
    from trackerd.config.loader import with_learned_colours
    from trackerd.sim.appearance import wall_content
    from trackerd.sim.randomized import random_shot

    learner = ColourLearner(rig, drawn.cameras, wanted=pairs)
    for _ in range(pairs):
        shot = random_shot(drawn, rng, wall)
        content = wall_content(shot.content_kind, rng)
        views = [
            renderer.render(
                i,
                shot.pose,
                rng,
                motion_to=shot.motion_to,
                motion_steps=shot.motion_steps,
                occluders=shot.occluders,
                content=content,
            )
            for i in range(len(drawn.cameras))
        ]
        learner.feed([(cam.camera_id, v.image, v.pixel_format) for cam, v in zip(drawn.cameras, views, strict=True)])
    try:
        colours = learner.result("bench", check_detector=False).colours
    except CalibrationError:
        return rig, False
    return with_learned_colours(rig, colours), True


def floor_hit(
    cameras: Sequence[CameraModel],
    seeing: list[bool],
    pose: PointerPose,
    rig: RigConfig,
    wall: WallFrame,
    rng: np.random.Generator,
) -> np.ndarray | None:
    """The geometric floor's wall hit (see the module): the true ends as every camera in ``seeing`` images
    them, moved by FLOOR_SIGMA_PX of noise, fitted as trackerd fits measured ends."""
    from trackerd.geometry.pointer_fit import EndViews, fit_pointer_robust

    assert rig.pointer is not None  # a rig that tracks
    used = [cam for cam, sees in zip(cameras, seeing, strict=True) if sees]
    front = pose.centre_of(rig.pointer.front_colour, rig.pointer.front_colour)
    back = pose.centre_of("blue" if rig.pointer.front_colour == "red" else "red", rig.pointer.front_colour)
    measured = np.zeros((len(used), 2, 2))
    covariances = np.zeros((len(used), 2, 2, 2))
    for k, cam in enumerate(used):
        sigma = FLOOR_SIGMA_PX / cam.focal_px
        for e, point in enumerate((front, back)):
            in_camera = cam.to_camera_frame(point[None])[0]
            measured[k, e] = in_camera[:2] / in_camera[2] + rng.normal(0.0, sigma, 2)
            covariances[k, e] = np.eye(2) * sigma * sigma
    try:
        views = EndViews.of(
            np.stack([c.rotation for c in used]),
            np.stack([c.translation_m for c in used]),
            measured,
            covariances,
            rig.pointer.length_m,
            rig.locator.length_sigma_m,
        )
        fit = fit_pointer_robust(views, front, back)
        hit = intersect_line_plane_m(fit.back_m, fit.front_m, wall)
    except GeometryError:
        return None
    return hit


def intersect_line_plane_m(back_m: np.ndarray, front_m: np.ndarray, wall: WallFrame) -> NDArray[np.float64] | None:
    """Where the line from ``back_m`` through ``front_m`` meets the wall, in the wall's frame (None when it
    points away)."""
    from trackerd.geometry.wall import intersect_line_plane

    hit = intersect_line_plane(back_m, front_m, wall.plane)
    if float(hit.u) <= 0:
        return None
    on_wall: NDArray[np.float64] = wall.to_wall_m(hit.point_m)
    return on_wall


def naive_hit(
    cameras: Sequence[CameraModel],
    wall: WallFrame,
    images: Sequence[NDArray[np.uint8]],
    pixel_formats: Sequence[str],
    front_colour: str,
) -> np.ndarray | None:
    """The naive method's wall hit: largest blob's box midpoints, each end triangulated, eq. 26-28."""
    from trackerd.detect.reference import naive_ends
    from trackerd.geometry.triangulation import triangulate_least_squares

    found = [naive_ends(image, fmt) for image, fmt in zip(images, pixel_formats, strict=True)]
    ends = {}
    for colour in ("red", "blue"):
        origins, dirs = [], []
        for cam, per_camera in zip(cameras, found, strict=True):
            pixel = per_camera[colour]
            if pixel is not None:
                o, d = cam.pixel_to_ray(pixel[None])
                origins.append(o[0])
                dirs.append(d[0])
        if len(origins) < 2:
            return None
        try:
            ends[colour], _ = triangulate_least_squares(np.array(origins), np.array(dirs))
        except GeometryError:
            return None
    back = ends["blue" if front_colour == "red" else "red"]
    front = ends[front_colour]
    try:
        return intersect_line_plane_m(back, front, wall)
    except GeometryError:
        return None


# --------------------------------------------------------------------------- figures


def figures(records: list[dict[str, Any]]) -> dict[str, Any]:
    """The figures of a set of frames (see the module's docstring)."""
    eligible = [r for r in records if r["eligible"]]
    located = [r for r in eligible if r["error_m"] is not None]
    errors = np.array([r["error_m"] for r in located]) * 1000.0
    with_sigma = [r for r in located if r["sigma_m"]]
    ratios = np.array([r["error_m"] / r["sigma_m"] for r in with_sigma])
    naive = np.array([r["naive_error_m"] for r in eligible if r["naive_error_m"] is not None]) * 1000.0
    floor = np.array([r["floor_error_m"] for r in eligible if r.get("floor_error_m") is not None]) * 1000.0
    hidden = [r for r in records if not r["eligible"]]
    hidden_hits = [r for r in hidden if r["error_m"] is not None]
    wrong_hidden = [r for r in hidden_hits if r["sigma_m"] and r["error_m"] > 5.0 * r["sigma_m"]]

    def stats(values: np.ndarray) -> dict[str, float | None]:
        if values.size == 0:
            return {"median_mm": None, "p95_mm": None, "worst_mm": None}
        return {
            "median_mm": round(float(np.median(values)), 2),
            "p95_mm": round(float(np.percentile(values, 95)), 2),
            "worst_mm": round(float(np.max(values)), 1),
        }

    def share(count: int, total: int) -> float | None:
        return round(100.0 * count / total, 1) if total else None

    return {
        "frames": len(records),
        "eligible": len(eligible),
        "trackerd": {
            "found_percent": share(len(located), len(eligible)),
            **stats(errors),
            "over_3_sigma_percent": share(int(np.sum(ratios > 3.0)), len(ratios)),
            "over_5_sigma_percent": share(int(np.sum(ratios > 5.0)), len(ratios)),
            "within_1_sigma_percent": share(int(np.sum(ratios <= 1.0)), len(ratios)),
            "within_2_sigma_percent": share(int(np.sum(ratios <= 2.0)), len(ratios)),
        },
        "floor": {k: v for k, v in stats(floor).items() if k != "worst_mm"},
        "naive": {"found_percent": share(len(naive), len(eligible)), **stats(naive)},
        "hidden": {"frames": len(hidden), "hits": len(hidden_hits), "confidently_wrong": len(wrong_hidden)},
    }


def summarise(records: list[dict[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {"overall": figures(records), "factors": {}}
    for factor in FACTORS:
        levels = sorted({r["factors"][factor] for r in records})
        out["factors"][factor] = {
            level: figures([r for r in records if r["factors"][factor] == level]) for level in levels
        }
    misses = Counter(_first_clause(r["reason"]) for r in records if r["eligible"] and r["error_m"] is None)
    out["misses"] = dict(misses.most_common(12))
    seconds = np.array([r["seconds"] for r in records]) * 1000.0
    out["locate_ms"] = {
        "median": round(float(np.median(seconds)), 2),
        "p95": round(float(np.percentile(seconds, 95)), 2),
    }
    return out


def _first_clause(reason: str | None) -> str:
    """A miss's reason without the figures that make every one different, to count them; where the
    detector's ends made an impossible pointer and the search found none, the search's reason too."""
    if not reason:
        return "(no reason)"
    reason, _, searched = reason.partition("; searched: ")
    text = reason.split(";")[0]
    if ":" in text:
        text = text.split(":", 1)[1]
    clause = _without_figures(text)[:90]
    return f"{clause} (searched: {_without_figures(searched)[:70]})" if searched else clause


def _without_figures(text: str) -> str:
    return "".join(" N" if ch.isdigit() else ch for ch in text).replace(" N N", " N").replace("NN", "N").strip()


def format_summary(summary: dict[str, Any]) -> str:
    head = (
        f"  {'':<22}{'frames':>7}{'elig.':>6} | {'found':>6}{'median':>8}{'p95':>8}{'worst':>8}"
        f"{'>3s':>6}{'>5s':>6}{'<=1s':>6}{'<=2s':>6} | {'floor':>6}{'p95':>7}"
        f" | {'naive':>6}{'median':>8}{'p95':>8}{'worst':>8} | hidden: hits, wrong"
    )
    lines = [
        "Wall error on randomized installations, trackerd against the naive method (mm; % of eligible frames;"
        " s: trackerd's own sigma; floor: the geometry alone at 0.1 px, median and p95)",
        head,
    ]

    def row(label: str, f: dict[str, Any]) -> str:
        t, n, h, g = f["trackerd"], f["naive"], f["hidden"], f["floor"]

        def cell(value: Any, width: int, fmt: str = ".1f") -> str:
            return f"{'-':>{width}}" if value is None else f"{value:>{width}{fmt}}"

        return (
            f"  {label:<22}{f['frames']:>7}{f['eligible']:>6} | {cell(t['found_percent'], 6)}"
            f"{cell(t['median_mm'], 8, '.2f')}{cell(t['p95_mm'], 8, '.2f')}{cell(t['worst_mm'], 8)}"
            f"{cell(t['over_3_sigma_percent'], 6)}{cell(t['over_5_sigma_percent'], 6)}"
            f"{cell(t['within_1_sigma_percent'], 6, '.0f')}{cell(t['within_2_sigma_percent'], 6, '.0f')} | "
            f"{cell(g['median_mm'], 6, '.2f')}{cell(g['p95_mm'], 7, '.2f')} | "
            f"{cell(n['found_percent'], 6)}{cell(n['median_mm'], 8, '.2f')}{cell(n['p95_mm'], 8, '.2f')}"
            f"{cell(n['worst_mm'], 8)} | {h['hits']:>4} {h['confidently_wrong']:>3}"
        )

    lines.append(row("overall", summary["overall"]))
    for factor, levels in summary["factors"].items():
        lines.append(f"  {factor}:")
        for level, f in levels.items():
            lines.append(row("  " + level, f))
    if summary["misses"]:
        lines.append("eligible frames not located, by reason:")
        lines += [f"  {count:>4}  {reason}" for reason, count in summary["misses"].items()]
    lines.append(
        f"trackerd locate per frame: median {summary['locate_ms']['median']} ms,"
        f" p95 {summary['locate_ms']['p95']} ms (a first sighting: full search)"
    )
    if summary.get("followed"):
        lines += format_follow(summary["followed"], summary["arguments"]["follow"])
    if summary.get("colours_learned_in"):
        lines.append(
            f"pointer colours learned (--learn-colours {summary['arguments']['learn_colours']}) in"
            f" {summary['colours_learned_in']}; the others keep the default thresholds"
        )
    lines.append(
        f"({summary['seconds']} s; --rigs {summary['arguments']['rigs']} --poses"
        f" {summary['arguments']['poses']} --seed {summary['arguments']['seed']}"
        + (f" --follow {summary['arguments']['follow']})" if summary["arguments"].get("follow") else ")")
    )
    return "\n".join(lines)
