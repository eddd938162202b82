"""Wall-hit accuracy on the simulated DataWall, in the report's three test groups (section 4).

Groups, each over many random pointer poses rendered with sensor noise:

1. placements: the cameras moved to several positions, their orientations kept;
2. rotations: the nominal placement with the cameras rotated (pitch, yaw, roll);
3. lengths: the nominal rig with pointers of several lengths.

Under each variant, its worst tenth of poses is taken apart: their median error,
what the same poses give from the renderer's exact centroids (the geometry's own
share) and the locator's own 1-sigma estimate for them (how much each pose
magnifies the centroids' noise; [locator] centroid_sigma_px per centroid).

Every pose is located three ways on the same images:

* trackerd: `Locator.locate` as the daemon runs it on a first sighting: the
  detector's sub-pixel centres and each ball's fitted outline, full lens model,
  the pointer fitted to both cameras with its length (trackerd/refine.py; with
  [locator] refine = "never", the interpretation planes on the centroids alone);
* two points: the centres trackerd used and the same lens model, but the line
  through the two triangulated ends (the report's construction, eq. 15-17 and 26);
* report: the report's algorithm: bounding-box midpoints (eq. 12), pixels scaled
  by focal length and field of view only (eq. 14, no distortion, centred
  principal point), two triangulated ends, eq. 26-28.

The report's own figure was about 0.06 ft (18 mm). Target for trackerd: median
<= 2 mm and 95th percentile <= 5 mm in every group.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from trackerd.bench.progress import BenchProgress
from trackerd.config.examples import example_rig
from trackerd.config.loader import load_rig
from trackerd.config.models import RigConfig
from trackerd.config.rig_geometry import camera_model
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.pointer_line import pointer_from_points
from trackerd.geometry.rotation import rotation_about_x, rotation_about_y, rotation_about_z
from trackerd.geometry.wall import intersect_line_plane
from trackerd.locator import Locator
from trackerd.sim.render import RenderedView, SceneRenderer
from trackerd.sim.scene import PointerPose, WallHitTruth, random_pose, true_wall_hit

FEET_PER_M = 1.0 / 0.3048
REPORT_FIGURE_FT = 0.06
METHODS = ("trackerd", "two_points", "report")


@dataclass(frozen=True)
class Variant:
    group: str
    label: str
    rig: RigConfig
    cameras: tuple[CameraModel, ...]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--config",
        default=str(example_rig("simulated")),
        help="rig to start from (default: the bundled config/simulated.toml)",
    )
    parser.add_argument("--poses", type=int, default=250, help="random poses per group (default 250)")
    parser.add_argument("--seed", type=int, default=2007, help="seed for poses and noise")
    parser.add_argument(
        "--workers", type=int, default=min(2, multiprocessing.cpu_count()), help="rendering processes (default: 2)"
    )
    parser.add_argument(
        "--groups",
        default="placements,rotations,lengths",
        help="comma-separated subset of placements,rotations,lengths",
    )


def run(args: argparse.Namespace) -> int:
    base = load_rig(args.config).config
    groups = [g.strip() for g in args.groups.split(",") if g.strip()]
    variants = [v for v in build_variants(base) if v.group in groups]
    per_variant = {g: max(1, math.ceil(args.poses / sum(v.group == g for v in variants))) for g in groups}
    tasks = [(v, per_variant[v.group], args.seed + i) for i, v in enumerate(variants)]
    start = time.time()
    progress = BenchProgress("accuracy", sum(count for _, count, _ in tasks), "poses")
    if args.workers > 1:
        with multiprocessing.get_context("fork").Pool(args.workers) as pool:
            results = []
            for task, result in zip(tasks, pool.imap(_run_variant, tasks), strict=True):
                results.append(result)
                progress.step(task[1])
    else:
        results = []
        for task in tasks:
            results.append(_run_variant(task))
            progress.step(task[1])
    progress.done()
    summary = summarise(variants, results)
    summary["seconds"] = round(time.time() - start, 1)
    summary["config"] = args.config
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(format_summary(summary))
    return 0


# --------------------------------------------------------------------------- variants


def build_variants(base: RigConfig) -> list[Variant]:
    """The configurations of the three groups, derived from the base rig."""
    nominal = tuple(camera_model(c) for c in base.cameras)
    # Rendering is the bench's cost; the room's own anti-aliasing does not affect the pointer.
    base = base.model_copy(update={"simulation": base.simulation.model_copy(update={"background_supersampling": 1})})
    variants: list[Variant] = []
    shifts = {
        "nominal": (0.0, 0.0, 0.0),
        "wider (x -+0.4 m)": (-0.4, 0.0, 0.0),
        "higher (+0.5 m)": (0.0, 0.5, 0.0),
        "nearer the wall (z -0.8 m)": (0.0, 0.0, -0.8),
        "further back (z +0.8 m)": (0.0, 0.0, 0.8),
    }
    for label, (dx, dy, dz) in shifts.items():
        cameras = tuple(_moved(cam, np.array([dx if i == 0 else -dx, dy, dz])) for i, cam in enumerate(nominal))
        variants.append(Variant("placements", label, base, cameras))
    # (yaw, pitch, roll) in degrees added to each camera's orientation, about its own axes.
    rotations = {
        "roll +15 / -15": ((0.0, 0.0, 15.0), (0.0, 0.0, -15.0)),
        "roll +30 / -10": ((0.0, 0.0, 30.0), (0.0, 0.0, -10.0)),
        "yaw +4 / -4": ((4.0, 0.0, 0.0), (-4.0, 0.0, 0.0)),
        "pitch +4 / -4": ((0.0, 4.0, 0.0), (0.0, -4.0, 0.0)),
        "pitch, yaw and roll": ((3.0, -3.0, 10.0), (-3.0, 2.0, -8.0)),
    }
    for label, angles in rotations.items():
        cameras = tuple(_rotated(cam, *turn) for cam, turn in zip(nominal, angles, strict=True))
        variants.append(Variant("rotations", label, base, cameras))
    if base.pointer is None:
        raise ValueError(f"rig '{base.name}' has no [pointer]: the bench cannot render one")
    for length in (0.25, 0.35, 0.45, 0.6, 0.8):
        pointer = base.pointer.model_copy(update={"length_m": length})
        rig = base.model_copy(update={"pointer": pointer})
        variants.append(Variant("lengths", f"pointer {length * 1000:.0f} mm", rig, nominal))
    return variants


def _moved(cam: CameraModel, shift: np.ndarray) -> CameraModel:
    return CameraModel.from_pose(
        cam.camera_id,
        cam.width_px,
        cam.height_px,
        cam.matrix,
        cam.distortion,
        cam.centre_m + shift,
        cam.world_from_camera,
    )


def _rotated(cam: CameraModel, yaw_deg: float, pitch_deg: float, roll_deg: float) -> CameraModel:
    """Turn a camera about its own axes (eq. 18-21) by extra yaw, pitch and roll."""
    extra = (
        rotation_about_y(math.radians(yaw_deg))
        @ rotation_about_x(math.radians(pitch_deg))
        @ rotation_about_z(math.radians(roll_deg))
    )
    return CameraModel.from_pose(
        cam.camera_id,
        cam.width_px,
        cam.height_px,
        cam.matrix,
        cam.distortion,
        cam.centre_m,
        cam.world_from_camera @ extra,
    )


def report_camera(cam: CameraModel) -> CameraModel:
    """What the report's method knows of a camera: its field of view and nothing else (eq. 14).

    The focal length in pixels follows from the horizontal field of view, the
    principal point is the image centre, and there is no distortion.
    """
    hfov = 2.0 * math.atan((cam.width_px / 2.0) / cam.matrix[0, 0])
    focal = (cam.width_px / 2.0) / math.tan(hfov / 2.0)
    matrix = np.array(
        [[focal, 0.0, (cam.width_px - 1) / 2.0], [0.0, focal, (cam.height_px - 1) / 2.0], [0.0, 0.0, 1.0]]
    )
    return CameraModel(cam.camera_id, cam.width_px, cam.height_px, matrix, np.zeros(0), cam.rotation, cam.translation_m)


# --------------------------------------------------------------------------- running


def _run_variant(task: tuple[Variant, int, int]) -> dict[str, Any]:
    variant, n_poses, seed = task
    rng = np.random.default_rng(seed)
    renderer = SceneRenderer(variant.rig, list(variant.cameras))
    ours = Locator(variant.rig, cameras=variant.cameras)
    # The report's method: bounding-box centres through its own camera model and line, never trackerd's fit.
    bbox_rig = variant.rig.model_copy(
        update={
            "detector": variant.rig.detector.model_copy(update={"centroid": "bbox"}),
            "locator": variant.rig.locator.model_copy(update={"refine": "never"}),
        }
    )
    report = Locator(bbox_rig, cameras=[report_camera(c) for c in variant.cameras])
    errors: dict[str, list[float]] = {m: [] for m in METHODS}
    failures: dict[str, int] = {m: 0 for m in METHODS}
    bias: dict[str, list[float]] = {"perspective_px": [], "occlusion_px": []}
    # Per pose trackerd located: (error, error from the renderer's exact centroids, the locator's
    # own 1-sigma estimate), in m: what makes the worst poses worst.
    anatomy: list[tuple[float, float, float]] = []
    poses = 0
    while poses < n_poses:
        pose = random_pose(variant.rig, rng, list(variant.cameras), renderer.wall)
        truth = true_wall_hit(pose, renderer.wall)
        if truth.wall_xy_m is None:
            continue
        poses += 1
        views = [renderer.render(i, pose, rng) for i in range(len(variant.cameras))]
        images = [v.image for v in views]
        _collect_bias(variant, pose, views, bias)
        ours.reset()
        fix = ours.locate(images)
        _record(errors, failures, "trackerd", fix.hit.wall_xy_m if fix.hit is not None else None, truth)
        if fix.hit is not None and fix.uncertainty_m is not None:
            exact = ours.locate_centroids(tuple({c: v.truth.centroid_px[c] for c in ("red", "blue")} for v in views))
            if exact.hit is not None:
                anatomy.append(
                    (
                        errors["trackerd"][-1],
                        float(np.linalg.norm(exact.hit.wall_xy_m - truth.wall_xy_m)),
                        float(fix.uncertainty_m),
                    )
                )
        if fix.found:
            centroids = [_both(c) for c in fix.centroids_px]
            _record(errors, failures, "two_points", _two_point_hit(ours, centroids), truth)
        else:
            failures["two_points"] += 1
        report.reset()
        baseline = report.locate(images)
        if baseline.line is not None:
            centroids = [_both(c) for c in baseline.centroids_px]
            _record(errors, failures, "report", _two_point_hit(report, centroids), truth)
        else:
            failures["report"] += 1
    return {"errors_m": errors, "failures": failures, "poses": poses, "bias": bias, "anatomy": anatomy}


def _both(centroids: dict[str, NDArray[np.float64] | None]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A found fix's (red, blue) centroids in one camera (a found fix has both in every camera it used)."""
    red, blue = centroids["red"], centroids["blue"]
    if red is None or blue is None:
        raise ValueError("a found fix without both centroids")
    return red, blue


def _record(
    errors: dict[str, list[float]],
    failures: dict[str, int],
    method: str,
    hit_xy: NDArray[np.float64] | None,
    truth: WallHitTruth,
) -> None:
    if hit_xy is None or truth.wall_xy_m is None:
        failures[method] += 1
    else:
        errors[method].append(float(np.linalg.norm(np.asarray(hit_xy) - truth.wall_xy_m)))


def _two_point_hit(locator: Locator, centroids: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray | None:
    """Triangulate each end and join them (the report's eq. 15-17, 26-28), on given centroids."""
    front_index = 0 if locator.front_colour == "red" else 1
    front = np.array(
        [
            cam.pixel_to_ray(np.asarray(c[front_index])[None])[1][0]
            for cam, c in zip(locator.cameras, centroids, strict=True)
        ]
    )
    back = np.array(
        [
            cam.pixel_to_ray(np.asarray(c[1 - front_index])[None])[1][0]
            for cam, c in zip(locator.cameras, centroids, strict=True)
        ]
    )
    try:
        line = pointer_from_points(locator._centres, front, back)
        hit = intersect_line_plane(line.back_m, line.front_m, locator.wall.plane)
    except Exception:  # noqa: BLE001 - a failed baseline counts as a failure, not a crash
        return None
    return locator.wall.to_wall_m(hit.point_m) if float(hit.u) > 0 else None


def _collect_bias(variant: Variant, pose: PointerPose, views: list[RenderedView], bias: dict[str, list[float]]) -> None:
    """Measure the two known centroid error terms on the rendered truth.

    perspective: distance between a ball's projected centre and the centre of
    its image ellipse (the sphere-projection bias, trackerd corrects it);
    occlusion: distance between the ellipse centre and the centroid of what is
    actually visible (the rod hides part of a ball; along the pointer only).
    """
    pointer = variant.rig.pointer
    assert pointer is not None  # build_variants refuses a rig without one
    radius = pointer.end_diameter_m / 2.0
    for cam, view in zip(variant.cameras, views, strict=True):
        for colour in ("red", "blue"):
            centre = pose.centre_of(colour, pointer.front_colour)
            in_cam = cam.to_camera_frame(centre[None])[0]
            scale = in_cam[2] / (in_cam[2] ** 2 - radius**2)
            ellipse_world = (np.array([in_cam[0] * scale, in_cam[1] * scale, 1.0]) - cam.translation_m) @ cam.rotation
            ellipse_px = cam.project(ellipse_world[None])[0]
            centre_px = view.truth.centre_px[colour]
            bias["perspective_px"].append(float(np.linalg.norm(ellipse_px - centre_px)))
            if np.all(np.isfinite(view.truth.centroid_px[colour])):
                bias["occlusion_px"].append(float(np.linalg.norm(view.truth.centroid_px[colour] - ellipse_px)))


# --------------------------------------------------------------------------- reporting


def _stats(errors_m: list[float]) -> dict[str, float | None]:
    if not errors_m:
        return {"median_mm": None, "p95_mm": None, "max_mm": None}
    e = np.asarray(errors_m) * 1000.0
    return {
        "median_mm": round(float(np.median(e)), 3),
        "p95_mm": round(float(np.percentile(e, 95)), 3),
        "max_mm": round(float(np.max(e)), 3),
        "median_ft": round(float(np.median(e)) / 1000.0 * FEET_PER_M, 4),
        "p95_ft": round(float(np.percentile(e, 95)) / 1000.0 * FEET_PER_M, 4),
        "max_ft": round(float(np.max(e)) / 1000.0 * FEET_PER_M, 4),
    }


def _worst(anatomy: list[tuple[float, float, float]]) -> dict[str, float] | None:
    """The poses at or above the variant's 90th percentile of trackerd's error: their median error, the
    median error the same poses give from exact centroids (the geometry's share), and the median of the
    locator's own 1-sigma estimate (how much the pose magnifies centroid noise)."""
    if len(anatomy) < 5:
        return None
    rows = np.asarray(anatomy) * 1000.0
    worst = rows[rows[:, 0] >= np.percentile(rows[:, 0], 90)]
    return {
        "poses": len(worst),
        "error_mm": round(float(np.median(worst[:, 0])), 2),
        "exact_centroids_mm": round(float(np.median(worst[:, 1])), 2),
        "sigma_mm": round(float(np.median(worst[:, 2])), 2),
        "sigma_all_mm": round(float(np.median(rows[:, 2])), 2),
    }


def summarise(variants: list[Variant], results: list[dict[str, Any]]) -> dict[str, Any]:
    groups: dict[str, Any] = {}
    for variant, result in zip(variants, results, strict=True):
        group = groups.setdefault(
            variant.group,
            {
                "variants": [],
                "errors": {m: [] for m in METHODS},
                "failures": {m: 0 for m in METHODS},
                "poses": 0,
                "bias": {"perspective_px": [], "occlusion_px": []},
            },
        )
        group["variants"].append(
            {
                "label": variant.label,
                "poses": result["poses"],
                **{m: _stats(result["errors_m"][m]) for m in METHODS},
                "worst": _worst(result["anatomy"]),
            }
        )
        for m in METHODS:
            group["errors"][m].extend(result["errors_m"][m])
            group["failures"][m] += result["failures"][m]
        group["poses"] += result["poses"]
        for k in group["bias"]:
            group["bias"][k].extend(result["bias"][k])
    out: dict[str, Any] = {"report_figure_ft": REPORT_FIGURE_FT, "groups": {}}
    for name, group in groups.items():
        stats = {m: _stats(group["errors"][m]) for m in METHODS}
        ours = stats["trackerd"]
        out["groups"][name] = {
            "poses": group["poses"],
            "methods": stats,
            "failures": group["failures"],
            "target_met": (
                ours["median_mm"] is not None
                and ours["median_mm"] <= 2.0
                and ours["p95_mm"] is not None
                and ours["p95_mm"] <= 5.0
            ),
            "variants": group["variants"],
            "centroid_bias_px": {
                k: {"median": round(float(np.median(v)), 4), "max": round(float(np.max(v)), 4)}
                for k, v in group["bias"].items()
                if v
            },
        }
    return out


def format_summary(summary: dict[str, Any]) -> str:
    lines = [
        "Wall-hit error on the simulated DataWall (mm; feet in brackets). Report's figure: about"
        f" {REPORT_FIGURE_FT} ft ({REPORT_FIGURE_FT / FEET_PER_M * 1000:.0f} mm).",
        "",
    ]
    names = {
        "trackerd": "trackerd",
        "two_points": "same centroids, two points",
        "report": "report (eq. 12 + 14)",
    }
    for group_name, group in summary["groups"].items():
        lines.append(
            f"{group_name}: {group['poses']} poses, target (median <= 2, p95 <= 5 mm)"
            f" {'MET' if group['target_met'] else 'NOT MET'}"
        )
        lines.append(f"  {'method':<28}{'median':>16}{'p95':>16}{'max':>16}{'failed':>8}")
        for m in METHODS:
            s = group["methods"][m]
            if s["median_mm"] is None:
                lines.append(f"  {names[m]:<28}{'-':>16}{'-':>16}{'-':>16}{group['failures'][m]:>8}")
                continue
            cells = [f"{s[k + '_mm']:.2f} ({s[k + '_ft']:.4f})" for k in ("median", "p95", "max")]
            lines.append(f"  {names[m]:<28}{cells[0]:>16}{cells[1]:>16}{cells[2]:>16}{group['failures'][m]:>8}")
        for v in group["variants"]:
            t, r = v["trackerd"], v["report"]
            lines.append(
                f"    {v['label']:<30} n={v['poses']:<4} trackerd median {t['median_mm']} p95 {t['p95_mm']}"
                f" | report median {r['median_mm']} p95 {r['p95_mm']}"
            )
            w = v.get("worst")
            if w:
                lines.append(
                    f"      worst tenth ({w['poses']} poses): {w['error_mm']} mm; from exact centroids"
                    f" {w['exact_centroids_mm']} mm; locator's sigma {w['sigma_mm']} mm"
                    f" (all poses {w['sigma_all_mm']})"
                )
        bias = group["centroid_bias_px"]
        if bias:
            lines.append(
                "  centroid error terms (px): sphere perspective median"
                f" {bias['perspective_px']['median']} max {bias['perspective_px']['max']} (corrected);"
                f" rod occlusion median {bias['occlusion_px']['median']} max {bias['occlusion_px']['max']}"
                " (along the pointer only)"
            )
        lines.append("")
    lines.append(f"({summary['seconds']} s)")
    return "\n".join(lines)
