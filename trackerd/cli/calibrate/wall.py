"""`trackerd calibrate wall`: the wall's plane and display frame, from measured points or pointer touches."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from trackerd.calibration import CalibrationError
from trackerd.calibration.inputs import (
    default_targets,
    pair_files,
    read_measured_wall,
    read_pair,
    read_targets,
    split_label,
)
from trackerd.calibration.pointer_sessions import WallSession
from trackerd.calibration.report import measured_wall_text, wall_fit_json, wall_fit_text
from trackerd.calibration.store import WORLD_FRAME_KEY, RigContext
from trackerd.calibration.update import apply_measured_wall, apply_wall_fit
from trackerd.calibration.visibility import common_view_rectangle, touch_seen, view_targets
from trackerd.calibration.wall import Pointing, Target, Touch, fit_problem, fit_wall
from trackerd.cli.calibrate.common import (
    Output,
    check_source,
    open_rig_to_write,
    rig_pointer,
    rig_wall,
    run_live,
    simulation_truth,
    snapshot_dir,
    write_result,
)
from trackerd.config.models import RigConfig
from trackerd.config.rig_geometry import camera_model, wall_frame
from trackerd.locator import Locator

if TYPE_CHECKING:
    from trackerd.sim.board import RenderedPairSource
    from trackerd.sim.render import SceneRenderer
    from trackerd.sim.scene import PointerPose


def wall_command(args: argparse.Namespace) -> int:
    out = Output(args.json)
    context = open_rig_to_write(args)
    if args.points:
        given = (("--pairs", args.pairs), ("--live", args.live), ("--recording", args.recording))
        extra = [name for name, value in given if value]
        if extra:
            raise CalibrationError(f"--points FILE is the whole input; it takes no {' or '.join(extra)}")
        return _measured_wall(context, args, out)
    rig = context.complete()
    nominal = wall_frame(context.rig.wall or rig_wall(rig))
    size = (nominal.width_m, nominal.height_m)
    width_px, height_px = nominal.display_width_px, nominal.display_height_px
    display_px = (width_px, height_px) if width_px is not None and height_px is not None else None
    targets = read_targets(args.targets, *size, display_px) if args.targets else default_targets(*size)
    mode = check_source(args, "--pairs DIR", args.pairs is not None)
    method = "touch" if args.touch else "point"
    radius = rig_pointer(rig).end_diameter_m / 2.0
    touches: list[Touch] = []
    pointings: list[Pointing] = []
    skipped: list[str] = []
    if mode == "live":
        labels = args.use.split(",") if args.use else list(DEFAULT_LIVE_TARGETS)
        unknown = [label for label in labels if label not in targets]
        if unknown:
            raise CalibrationError(f"unknown target(s) {', '.join(unknown)}; known: {', '.join(targets)}")
        if method == "touch":
            labels = _touch_targets_in_view(context, rig, targets, labels, radius, display_px, args.use is None, out)
        session = WallSession(
            Locator(rig),
            [targets[label] for label in labels],
            method,
            args.places,
            snapshots=snapshot_dir(args, f"wall-{method}"),
            camera_ids=[c.id for c in rig.cameras],
            skip_after=args.skip_after,
        )
        out.say(session.prompt())
        run_live(context, rig, args, session, out, lambda: _simulated_wall(context, session, args.skip_after))
        touches, pointings, skipped = session.touches, session.pointings, session.skipped
        if skipped:
            out.say(f"skipped (no capture): {', '.join(skipped)}")
        remaining = list(dict.fromkeys(t.label for t, _ in session.plan[session.position :]))
        if remaining:
            out.say(f"not captured (collection ended first): {', '.join(remaining)}")
    else:
        touches, pointings = _wall_from_folder(args.pairs, rig, targets, method, out)
    fit = fit_wall(touches, pointings, size, radius, fit_size=False if args.fixed_size else None)
    text = wall_fit_text(fit, size)
    report = {**wall_fit_json(fit, size), "skipped": skipped}
    problem = fit_problem(fit, args.max_rms_mm)
    if problem is not None:
        out.result(text, {**report, "world_frame": None, "written": None, "backup": None})
        raise CalibrationError(problem)
    calibration = apply_wall_fit(context.calibration, rig, fit, method, display_px)
    notes: list[str] = []
    written = write_result(context, calibration, f"trackerd calibrate wall --{method}", args.dry_run, notes)
    if not args.dry_run:
        notes.append(
            "world frame: the wall frame (origin at the display's bottom-left corner, x right, y up,"
            " z into the room); every camera was re-expressed in it"
        )
    out.result(text, {**report, "world_frame": "wall", **written})
    for note in notes:
        out.say(note)
    return 0


DEFAULT_LIVE_TARGETS = ("bl", "br", "tr", "tl", "centre")


def _touch_targets_in_view(
    context: RigContext,
    rig: RigConfig,
    targets: dict[str, Target],
    labels: list[str],
    radius: float,
    display_px: tuple[int, int] | None,
    defaults: bool,
    out: Output,
) -> list[str]:
    """The targets to touch: ``labels`` if both cameras see them all, else (for the defaults) the
    corners and centre of a rectangle both see, added to ``targets``; else a clear error.

    Whether a camera sees a target is judged from the current calibration, which places the wall
    only when the cameras are in the rig's or the wall's frame (not in camera 1's).
    """
    first = context.calibration.cameras.get(rig.cameras[0].id)
    frame = (first.info or {}).get(WORLD_FRAME_KEY) if first is not None else None
    if isinstance(frame, str) and frame.startswith("camera "):
        out.say(
            f"note: the cameras are in {frame}'s frame, so which targets both see cannot be told yet;"
            " touch only targets you can see in both cameras' images"
        )
        return labels
    cameras = [camera_model(c) for c in rig.cameras]
    wall = wall_frame(rig_wall(rig))
    xy = np.array([targets[label].wall_xy_m for label in labels])
    seen = touch_seen(cameras, wall, xy, radius)
    out_of_view = [(label, row) for label, row in zip(labels, seen, strict=True) if not row.all()]
    if not out_of_view:
        return labels
    ids = [c.id for c in rig.cameras]

    def who(row: NDArray[np.bool_]) -> str:
        seeing = [i for i, s in zip(ids, row, strict=True) if s]
        return f"only {seeing[0]} sees it" if len(seeing) == 1 else "neither camera sees it"

    unseen = "; ".join(f"'{label}': {who(row)}" for label, row in out_of_view)
    rectangle = common_view_rectangle(cameras, wall, radius)
    where = (
        f"both cameras see the display only at about x {rectangle[0]:.2f}-{rectangle[2]:.2f} m,"
        f" y {rectangle[1]:.2f}-{rectangle[3]:.2f} m from its bottom-left corner"
        if rectangle is not None
        else "no part of the display is seen by both cameras"
    )
    if not defaults or rectangle is None:
        raise CalibrationError(
            f"--touch: target(s) out of view ({unseen}); {where}: touch targets there (--targets FILE with"
            " marks such as m1 = { x_m = ..., y_m = ... }, then --use m1,m2,...), or aim at these with --point"
        )
    chosen = view_targets(rectangle)
    targets.update(chosen)

    def describe(target: Target) -> str:
        if target.wall_xy_m is None:  # view_targets places every target it makes
            return f"  {target.label}"
        x, y = target.wall_xy_m
        pixels = ""
        if display_px is not None:
            px = (x / wall.width_m * display_px[0], (1.0 - y / wall.height_m) * display_px[1])
            pixels = f"  display pixel ({px[0]:.0f}, {px[1]:.0f})"
        return f"  {target.label:<12} x {x:.2f} m, y {y:.2f} m{pixels}"

    out.say(
        "\n".join(
            [
                f"the default targets are not all in view of both cameras: {unseen}",
                f"{where}; touch these {len(chosen)} targets there instead (show a cross at each on the"
                " display, or tape a mark; --use and --targets choose others):",
                *(describe(t) for t in chosen.values()),
            ]
        )
    )
    return list(chosen)


def _wall_from_folder(
    folder: str, rig: RigConfig, targets: dict[str, Target], method: str, out: Output
) -> tuple[list[Touch], list[Pointing]]:
    moments = pair_files(folder, [c.id for c in rig.cameras]).moments
    locator: Locator | None = None
    touches: list[Touch] = []
    pointings: list[Pointing] = []
    for moment in moments:
        name, files = moment.name, moment.files
        label = split_label(name)
        target = targets.get(label)
        if target is None:
            raise CalibrationError(
                f"{folder}: '{name}': no target '{label}' (known: {', '.join(targets)}; add marks with --targets FILE)"
            )
        frames = read_pair(files, list(rig.cameras))
        formats = [fmt for _, _, fmt in frames]
        if locator is None or locator.pixel_formats != formats:
            locator = Locator(rig, pixel_formats=formats)
        locator.reset()
        fix = locator.locate([image for _, image, _ in frames])
        if fix.line is None or fix.status == "rejected":
            out.say(f"  {name}: pointer not located ({fix.reason}); left out")
            continue
        if method == "touch":
            touches.append(Touch(target, fix.line.front_m, fix.line.back_m))
        else:
            pointings.append(Pointing(target, fix.line.front_m, fix.line.back_m))
    return touches, pointings


def _measured_wall(context: RigContext, args: argparse.Namespace, out: Output) -> int:
    wall = read_measured_wall(args.points)
    try:
        frame = wall_frame(wall)
    except Exception as err:  # ConfigError or GeometryError, both one-line TrackerdErrors
        raise CalibrationError(f"{args.points}: {err}") from err
    points = np.array(wall.points_m if wall.points_m is not None else wall.corners_m)
    text = measured_wall_text(frame, points)
    calibration = apply_measured_wall(context.calibration, wall)
    notes: list[str] = []
    written = write_result(context, calibration, "trackerd calibrate wall --points", args.dry_run, notes)
    residuals = frame.fit_residuals_m if frame.fit_residuals_m is not None else np.zeros(len(points))
    out.result(
        text,
        {
            "points": len(points),
            "residuals_mm": [round(float(r) * 1000, 3) for r in residuals],
            "size_m": [frame.width_m, frame.height_m],
            "world_frame": "unchanged",
            **written,
        },
    )
    for note in notes:
        out.say(note)
    return 0


def _simulated_wall(context: RigContext, session: WallSession, skip_after: int) -> RenderedPairSource:
    """Frames of a presenter following the session's prompts: the pointer held still at the target
    being asked for (touching it, or aimed at it from a place of its own), as the simulator renders it.

    Like a presenter whose pointer is not being picked up, it shifts its grip (a new pose for
    the same target, from a new place when pointing) every few dozen frames without a capture; a
    target no pose makes visible is eventually skipped by the session (``skip_after``).
    """
    from trackerd.sim.board import RenderedPairSource
    from trackerd.sim.render import SceneRenderer

    truth = simulation_truth(context)
    scene = SceneRenderer(truth)
    rng = np.random.default_rng(11)
    regrip = 2 * session.steadiness.frames + 2
    poses: dict[tuple[int, int], PointerPose] = {}

    def pose_now() -> PointerPose:
        current = session.current()
        if current is None:  # pragma: no cover - the driver stops when the session is done
            current = session.plan[-1]
        key = (session.position, session.on_target // regrip)
        if key not in poses:
            poses[key] = _presented_pose(scene, truth, current[0], current[1], session.method, key[1], rng)
        return poses[key]

    ids = [c.id for c in truth.cameras]

    def render(k: int) -> list[NDArray[np.uint8]]:
        pose = pose_now()
        return [scene.render(i, pose, rng).image for i in range(len(ids))]

    per_target = (skip_after if skip_after > 0 else 10 * regrip) + regrip
    return RenderedPairSource(ids, list(scene.pixel_formats), render, per_target * len(session.plan))


def _presented_pose(
    scene: SceneRenderer,
    truth: RigConfig,
    target: Target,
    place: int,
    method: str,
    variant: int,
    rng: np.random.Generator,
) -> PointerPose:
    """The pointer touching ``target`` (tilted into the room), or aimed at it from place ``place``."""
    from trackerd.bench.calibration import aimed_poses
    from trackerd.sim.scene import PointerPose

    wall = scene.wall
    if target.wall_xy_m is None:
        raise CalibrationError(f"target '{target.label}' has no place on the wall to present the pointer at")
    world = wall.from_wall_m(target.wall_xy_m)
    if method == "point":
        # aimed_poses spreads its places along the wall in turn; the place-th of them.
        return aimed_poses(scene, world, place + 1, rng)[-1]
    pointer = rig_pointer(truth)
    tip = world + pointer.end_diameter_m / 2.0 * wall.normal
    tilt = np.array([0.0, 0.4]) if variant == 0 else rng.uniform([-0.4, 0.0], [0.4, 0.6])
    direction = wall.normal + tilt[0] * wall.x_axis + tilt[1] * wall.y_axis
    return PointerPose(tip, tip + pointer.length_m * _unit(direction))


def _unit(v: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.asarray(v / np.linalg.norm(v), dtype=np.float64)
