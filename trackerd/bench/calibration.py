"""Calibration of the simulated DataWall from rendered boards, and wall-hit accuracy on the result.

The whole installation procedure of docs/calibration.md, on rendered images of
a rig whose true geometry is known:

1. intrinsics: each camera sees a chessboard at many poses (rendered through its
   real lens, with noise); ``calibrate_intrinsics`` recovers its lens;
2. stereo: both cameras see a larger board in the presenter's area; camera 2 is
   placed relative to camera 1 with the intrinsics of step 1 held fixed;
3. wall: the pointer is aimed at the display's corners and centre from several
   places (rendered, located by trackerd's own locator with the calibration so
   far); the wall frame and the display's size are solved, and every camera is
   re-expressed in the wall frame;

then the recovered calibration, merged into a rig with no geometry of its own,
locates the pointer in rendered poses side by side with the true calibration.
Printed: each step's own figures, the errors of the recovered parameters
against the truth, and the wall-hit error (median, p95, max) on both.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from trackerd.bench.progress import BenchProgress
from trackerd.calibration.board import BoardSpec
from trackerd.calibration.collect import Frame, collect_pairs, collect_views
from trackerd.calibration.intrinsics import IntrinsicsResult, calibrate_intrinsics, lens_model_difference_px
from trackerd.calibration.stereo import Lens, StereoResult, calibrate_stereo
from trackerd.calibration.store import RigContext, render_calibration
from trackerd.calibration.update import apply_intrinsics, apply_stereo, apply_wall_fit, relative_pose
from trackerd.calibration.views import ViewSelector
from trackerd.calibration.wall import Pointing, Target, WallFit, corner_targets, fit_wall
from trackerd.config.examples import example_rig
from trackerd.config.loader import load_rig, merge_calibration
from trackerd.config.models import CalibrationFile, RigConfig
from trackerd.config.rig_geometry import camera_model
from trackerd.geometry.rotation import rotation_angle_deg
from trackerd.locator import Locator
from trackerd.sim.board import BoardPose, BoardRenderer, poses_for_camera, poses_for_pair
from trackerd.sim.render import SceneRenderer
from trackerd.sim.scene import PointerPose, pose_aimed_at, pose_visible, random_pose, true_wall_hit

PSF_PX = 0.5
"""Optical blur of the rendered boards (Gaussian sigma, pixels): a real lens is never perfectly sharp,
and a perfectly box-filtered edge makes gradient corner finders lock to pixel centres."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--config",
        default=str(example_rig("simulated")),
        help="the true rig to render (default: the bundled config/simulated.toml)",
    )
    parser.add_argument("--board", default="chessboard:10x7:60", help="board for intrinsics")
    parser.add_argument("--stereo-board", default="chessboard:10x7:100", help="board for stereo pairs")
    parser.add_argument("--views", type=int, default=20, help="board views per camera (default 20)")
    parser.add_argument("--pairs", type=int, default=15, help="stereo pairs (default 15)")
    parser.add_argument(
        "--pointing", type=int, default=3, help="places the pointer is aimed at each wall target from (default 3)"
    )
    parser.add_argument("--poses", type=int, default=100, help="pointer poses for the accuracy comparison")
    parser.add_argument("--seed", type=int, default=2026, help="seed for poses and noise")
    parser.add_argument("--write", metavar="FILE", help="also write the recovered calibration file here")


def run(args: argparse.Namespace) -> int:
    start = time.time()
    true_rig = load_rig(args.config).config
    progress = BenchProgress("calibration")
    study = calibrate_simulated(
        true_rig,
        BoardSpec.parse(args.board),
        BoardSpec.parse(args.stereo_board),
        views=args.views,
        pairs=args.pairs,
        pointing=args.pointing,
        seed=args.seed,
        progress=progress.phase,
    )
    progress.phase(f"wall-hit accuracy, true and recovered calibration ({args.poses} poses)")
    accuracy = compare_accuracy(true_rig, study.recovered_rig, study.scene, args.poses, args.seed + 1)
    progress.done()
    summary = summarise(study, accuracy)
    summary["seconds"] = round(time.time() - start, 1)
    summary["config"] = args.config
    if args.write:
        Path(args.write).write_text(render_calibration(study.calibration, "recovered by trackerd bench calibration"))
        summary["written"] = args.write
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(format_summary(summary))
    return 0


# --------------------------------------------------------------------------- the procedure


@dataclass
class SimulatedCalibration:
    scene: SceneRenderer
    blank_rig: RigConfig
    intrinsics: dict[str, IntrinsicsResult]
    stereo: StereoResult
    wall: WallFit
    calibration: CalibrationFile
    recovered_rig: RigConfig
    rejected: dict[str, int]


def blank_rig(rig: RigConfig) -> RigConfig:
    """The rig as a new installation has it: cameras without intrinsics or extrinsics."""
    cameras = tuple(cam.model_copy(update={"intrinsics": None, "extrinsics": None}) for cam in rig.cameras)
    return rig.model_copy(update={"cameras": cameras, "calibration": None})


def calibrate_simulated(
    true_rig: RigConfig,
    board: BoardSpec,
    stereo_board: BoardSpec,
    *,
    views: int,
    pairs: int,
    pointing: int,
    seed: int,
    scene: SceneRenderer | None = None,
    progress: Callable[[str], None] = lambda step: None,
) -> SimulatedCalibration:
    """Run intrinsics, stereo and wall calibration on rendered images of ``true_rig``; ``progress``
    hears of each step as it begins."""
    rng = np.random.default_rng(seed)
    scene = scene or SceneRenderer(true_rig)
    blank = blank_rig(true_rig)
    context = RigContext(blank, Path("simulated.toml"), None, CalibrationFile())
    calibration = CalibrationFile()
    rejected: dict[str, int] = {}
    results: dict[str, IntrinsicsResult] = {}
    renderer = BoardRenderer(scene, board)
    for index, cam in enumerate(true_rig.cameras):
        progress(f"intrinsics of camera {cam.id} ({views} views)")
        poses = poses_for_camera(scene, board, index, views, rng)
        frames = ((f"{cam.id}-{k:02d}", *_render(renderer, index, pose, rng)) for k, pose in enumerate(poses))
        collected = collect_views(frames, board, ViewSelector(cam.width_px, cam.height_px))
        rejected[cam.id] = len(collected.rejected)
        results[cam.id] = calibrate_intrinsics(collected.views)
        calibration = apply_intrinsics(calibration, cam.id, results[cam.id], board, "rendered")
    cam1, cam2 = true_rig.cameras[0], true_rig.cameras[1]
    progress(f"stereo ({pairs} pairs)")
    stereo_renderer = BoardRenderer(scene, stereo_board)
    pair_poses = poses_for_pair(scene, stereo_board, pairs, rng)

    def frame_pairs() -> Iterator[tuple[str, Frame, Frame]]:
        for k, pose in enumerate(pair_poses):
            yield (
                f"pair-{k:02d}",
                (f"{k:02d}-{cam1.id}", *_render(stereo_renderer, 0, pose, rng)),
                (f"{k:02d}-{cam2.id}", *_render(stereo_renderer, 1, pose, rng)),
            )

    collected = collect_pairs(frame_pairs(), stereo_board, ViewSelector(cam1.width_px, cam1.height_px))
    rejected["pairs"] = len(collected.rejected)
    lenses = [Lens(results[c.id].matrix, results[c.id].distortion) for c in (cam1, cam2)]
    stereo = calibrate_stereo(collected.pairs, lenses[0], lenses[1], (cam1.width_px, cam1.height_px))
    calibration, _ = apply_stereo(
        calibration, context.merged(calibration), cam1.id, cam2.id, stereo, stereo_board, "rendered", keep_frame=False
    )
    in_camera_frame = context.merged(calibration)
    progress("the wall, by pointing")
    fit = wall_by_pointing(scene, in_camera_frame, pointing, rng)
    wall_cfg = true_rig.wall
    if wall_cfg is None:
        raise ValueError("the true rig has no [wall] to calibrate")
    width_px, height_px = wall_cfg.display_width_px, wall_cfg.display_height_px
    display = (width_px, height_px) if width_px and height_px is not None else None
    calibration = apply_wall_fit(calibration, in_camera_frame, fit, "pointing (simulated)", display)
    recovered = merge_calibration(blank, calibration, Path("recovered-calibration.toml"))
    return SimulatedCalibration(scene, blank, results, stereo, fit, calibration, recovered, rejected)


def _render(
    renderer: BoardRenderer, index: int, pose: BoardPose, rng: np.random.Generator
) -> tuple[NDArray[np.uint8], str]:
    view = renderer.render(index, pose, rng, blur_px=PSF_PX)
    return view.image, view.pixel_format


def wall_targets(width_m: float, height_m: float) -> list[Target]:
    """A 3 x 3 grid of targets shown on the display: its corners, the middles of its edges, its centre."""
    targets = list(corner_targets(width_m, height_m).values())
    for label, fx, fy in (
        ("bottom", 0.5, 0.0),
        ("top", 0.5, 1.0),
        ("left", 0.0, 0.5),
        ("right", 1.0, 0.5),
        ("centre", 0.5, 0.5),
    ):
        targets.append(Target(label, np.array([fx * width_m, fy * height_m]), True))
    return targets


def aimed_poses(
    scene: SceneRenderer, target_world_m: np.ndarray, count: int, rng: np.random.Generator, max_tries: int = 2000
) -> list[PointerPose]:
    """Pointer poses from varied places in the presenter's area, each aimed exactly at a target.

    The places are spread along the wall (left, middle, right thirds in turn) so
    the lines to one target cross at useful angles.
    """
    rig = scene.rig
    wall = scene.wall
    sim = rig.simulation
    if rig.pointer is None:
        raise ValueError("the simulated rig has no [pointer] to aim")
    length_m = rig.pointer.length_m
    floor_y = float(wall.corners_m[:, 1].min()) - sim.display_height_above_floor_m
    poses: list[PointerPose] = []
    for _ in range(max_tries):
        if len(poses) == count:
            break
        third = len(poses) % 3
        along = rng.uniform(0.15 + 0.25 * third, 0.35 + 0.25 * third) * wall.width_m
        distance = rng.uniform(1.0, 2.2)
        height = rng.uniform(*sim.hand_height_m)
        tip = wall.origin_m + along * wall.x_axis + distance * wall.normal
        tip = tip + (floor_y + height - tip[1]) * np.array([0.0, 1.0, 0.0])
        pose = pose_aimed_at(tip, target_world_m, length_m)
        if pose_visible(pose, scene.cameras, 40.0):
            poses.append(pose)
    if len(poses) < count:
        raise RuntimeError("could not place the pointer aimed at a wall target in view of both cameras")
    return poses


def wall_by_pointing(scene: SceneRenderer, rig_now: RigConfig, per_target: int, rng: np.random.Generator) -> WallFit:
    """Aim the (rendered) pointer at each target from ``per_target`` places; solve the wall.

    ``rig_now`` holds the calibration so far (cameras in camera 1's frame); the
    true scene only renders the images.
    """
    locator = Locator(rig_now)
    nominal = scene.wall
    pointings: list[Pointing] = []
    for target in wall_targets(nominal.width_m, nominal.height_m):
        if target.wall_xy_m is None:  # wall_targets places every target
            continue
        world = nominal.from_wall_m(target.wall_xy_m)
        for pose in aimed_poses(scene, world, per_target, rng):
            images = [scene.render(i, pose, rng).image for i in range(len(scene.cameras))]
            locator.reset()
            fix = locator.locate(images)
            if fix.line is not None and fix.status != "rejected":
                pointings.append(Pointing(target, fix.line.front_m, fix.line.back_m))
    if rig_now.pointer is None:
        raise ValueError("the rig has no [pointer]")
    radius = rig_now.pointer.end_diameter_m / 2.0
    return fit_wall([], pointings, (nominal.width_m, nominal.height_m), radius)


# --------------------------------------------------------------------------- accuracy


def compare_accuracy(
    true_rig: RigConfig, recovered_rig: RigConfig, scene: SceneRenderer, poses: int, seed: int
) -> dict[str, Any]:
    """Wall-hit errors on the same rendered images, located with the true and the recovered calibration."""
    rng = np.random.default_rng(seed)
    truth_locator = Locator(true_rig)
    recovered_locator = Locator(recovered_rig)
    errors: dict[str, list[float]] = {"true": [], "recovered": []}
    failures = {"true": 0, "recovered": 0}
    done = 0
    while done < poses:
        pose = random_pose(true_rig, rng, scene.cameras, scene.wall)
        truth = true_wall_hit(pose, scene.wall)
        if truth.wall_xy_m is None:
            continue
        done += 1
        images = [scene.render(i, pose, rng).image for i in range(len(scene.cameras))]
        for name, locator in (("true", truth_locator), ("recovered", recovered_locator)):
            locator.reset()
            fix = locator.locate(images)
            if fix.hit is None:
                failures[name] += 1
            else:
                errors[name].append(float(np.linalg.norm(fix.hit.wall_xy_m - truth.wall_xy_m)))
    return {name: {**_stats(values), "failures": failures[name], "poses": done} for name, values in errors.items()}


def _stats(errors_m: list[float]) -> dict[str, float | None]:
    if not errors_m:
        return {"median_mm": None, "p95_mm": None, "max_mm": None}
    e = np.asarray(errors_m) * 1000.0
    return {
        "median_mm": round(float(np.median(e)), 3),
        "p95_mm": round(float(np.percentile(e, 95)), 3),
        "max_mm": round(float(e.max()), 3),
    }


# --------------------------------------------------------------------------- figures


def parameter_errors(study: SimulatedCalibration) -> dict[str, Any]:
    """The recovered parameters against the truth."""
    scene = study.scene
    true_cams = scene.cameras
    recovered = [camera_model(c) for c in study.recovered_rig.cameras]
    cameras = {}
    for true_cam, cam in zip(true_cams, recovered, strict=True):
        result = study.intrinsics[cam.camera_id]
        k_true, k = true_cam.matrix, result.matrix
        cameras[cam.camera_id] = {
            "intrinsics_rms_px": round(result.rms_px, 4),
            "views": len(result.view_names),
            "coverage": round(result.coverage.fraction, 3),
            "fx_error_pct": round(float((k[0, 0] / k_true[0, 0] - 1) * 100), 4),
            "fy_error_pct": round(float((k[1, 1] / k_true[1, 1] - 1) * 100), 4),
            "principal_point_error_px": round(float(np.hypot(k[0, 2] - k_true[0, 2], k[1, 2] - k_true[1, 2])), 3),
            **dict(
                zip(
                    ("lens_model_rms_px", "lens_model_max_px"),
                    (
                        round(v, 3)
                        for v in lens_model_difference_px(
                            k_true, true_cam.distortion, k, result.distortion, (true_cam.width_px, true_cam.height_px)
                        )
                    ),
                    strict=True,
                )
            ),
            "centre_error_mm": round(float(np.linalg.norm(cam.centre_m - true_cam.centre_m) * 1000), 2),
            "orientation_error_deg": round(rotation_angle_deg(cam.rotation @ true_cam.rotation.T), 4),
        }
    r_true, t_true = relative_pose(
        true_cams[0].rotation, true_cams[0].translation_m, true_cams[1].rotation, true_cams[1].translation_m
    )
    stereo = study.stereo
    wall = study.wall
    implied = wall.implied_size_m
    nominal = scene.wall
    return {
        "cameras": cameras,
        "stereo": {
            "pairs": len(stereo.pair_names),
            "rms_px": round(stereo.rms_px, 4),
            "epipolar_rms_px": round(stereo.epipolar_rms_px, 4),
            "baseline_m": round(stereo.baseline_m, 5),
            "baseline_error_mm": round((stereo.baseline_m - float(np.linalg.norm(t_true))) * 1000, 3),
            "rotation_error_deg": round(rotation_angle_deg(stereo.rotation @ r_true.T), 4),
            "translation_error_mm": round(float(np.linalg.norm(stereo.translation_m - t_true) * 1000), 3),
        },
        "wall": {
            "observations": len(wall.residuals),
            "rms_mm": round(wall.rms_mm, 3),
            "worst_residual_mm": round(max(r.worst_mm for r in wall.residuals), 3),
            "size_m": [round(wall.width_m, 5), round(wall.height_m, 5)],
            "size_fitted": wall.size_fitted,
            "implied_size_m": None if implied is None else [round(implied[0], 5), round(implied[1], 5)],
            "implied_size_error_mm": None
            if implied is None
            else [round((implied[0] - nominal.width_m) * 1000, 2), round((implied[1] - nominal.height_m) * 1000, 2)],
        },
    }


def summarise(study: SimulatedCalibration, accuracy: dict[str, Any]) -> dict[str, Any]:
    return {"parameters": parameter_errors(study), "wall_hit_error": accuracy, "rejected_frames": study.rejected}


def format_summary(summary: dict[str, Any]) -> str:
    p = summary["parameters"]
    lines = ["Calibration of the simulated rig from rendered boards and pointing, against the truth", ""]
    for cam_id, c in p["cameras"].items():
        lines.append(
            f"{cam_id}: {c['views']} views, RMS {c['intrinsics_rms_px']:.3f} px, coverage {c['coverage'] * 100:.0f} %;"
            f" fx {c['fx_error_pct']:+.3f} %, fy {c['fy_error_pct']:+.3f} %, principal point"
            f" {c['principal_point_error_px']:.2f} px off, lens model RMS {c['lens_model_rms_px']:.2f} px"
            f" (max {c['lens_model_max_px']:.2f}); in the wall frame: centre {c['centre_error_mm']:.1f} mm,"
            f" orientation {c['orientation_error_deg']:.3f} deg"
        )
    s = p["stereo"]
    lines.append(
        f"stereo: {s['pairs']} pairs, RMS {s['rms_px']:.3f} px, epipolar {s['epipolar_rms_px']:.3f} px;"
        f" baseline {s['baseline_m']:.4f} m ({s['baseline_error_mm']:+.2f} mm),"
        f" rotation {s['rotation_error_deg']:.4f} deg off, translation {s['translation_error_mm']:.2f} mm off"
    )
    w = p["wall"]
    lines.append(
        f"wall: {w['observations']} pointings, RMS {w['rms_mm']:.2f} mm, worst {w['worst_residual_mm']:.2f} mm;"
        f" size {w['size_m'][0]:.4f} x {w['size_m'][1]:.4f} m ({'solved' if w['size_fitted'] else 'as configured'})"
        + (
            f"; the targets imply {w['implied_size_m'][0]:.4f} x {w['implied_size_m'][1]:.4f} m"
            f" ({w['implied_size_error_mm'][0]:+.1f}, {w['implied_size_error_mm'][1]:+.1f} mm)"
            if w["implied_size_m"]
            else ""
        )
    )
    lines.append("")
    lines.append(f"wall-hit error (mm)      {'median':>8}{'p95':>8}{'max':>8}{'failed':>8}")
    for name in ("true", "recovered"):
        a = summary["wall_hit_error"][name]
        cells = [f"{a[k]:8.2f}" if a[k] is not None else f"{'-':>8}" for k in ("median_mm", "p95_mm", "max_mm")]
        lines.append(f"  {name + ' calibration':<22}{''.join(cells)}{a['failures']:>8}   ({a['poses']} poses)")
    lines.append("")
    lines.append(f"({summary['seconds']} s)")
    return "\n".join(lines)
