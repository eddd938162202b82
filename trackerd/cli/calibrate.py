"""`trackerd calibrate`: camera intrinsics, stereo extrinsics, the wall, and a health check.

The steps of docs/calibration.md, each writing its result into the rig's
calibration file (with a timestamped backup of the previous one) only when it
succeeded, and each printing the figures that say how far to trust it:

  trackerd calibrate intrinsics --config RIG --camera ID --board SPEC (IMAGE... | --live | --recording R)
  trackerd calibrate stereo     --config RIG --board SPEC (--pairs DIR | --live | --recording R)
  trackerd calibrate wall       --config RIG --points FILE
  trackerd calibrate wall       --config RIG (--touch | --point) (--pairs DIR | --live | --recording R)
  trackerd calibrate check      --config RIG (--pairs DIR | --live | --recording R)

Boards: chessboard:COLSxROWS:SQUARE_MM or charuco:COLSxROWS:SQUARE_MM:MARKER_MM[:DICT],
counting squares (chessboard:10x7:60 has 9 x 6 inner corners).
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from trackerd.calibration import CalibrationError
from trackerd.calibration.board import MAX_SHARPNESS_PX, BoardSpec, Quality
from trackerd.calibration.collect import Collected, collect_pairs, collect_views
from trackerd.calibration.health import CalibrationHealth
from trackerd.calibration.inputs import (
    camera_frames,
    default_targets,
    pair_files,
    read_measured_wall,
    read_pair,
    read_targets,
    split_label,
)
from trackerd.calibration.intrinsics import DISTORTION_TERMS, MIN_VIEWS, calibrate_intrinsics
from trackerd.calibration.live import (
    SKIP_AFTER_FRAMES,
    CheckSession,
    IntrinsicsSession,
    StereoSession,
    WallSession,
    run_session,
)
from trackerd.calibration.report import (
    health_text,
    intrinsics_json,
    intrinsics_text,
    measured_wall_text,
    stereo_json,
    stereo_text,
    wall_fit_json,
    wall_fit_text,
)
from trackerd.calibration.stereo import MIN_PAIRS, Lens, baseline_warning, calibrate_stereo
from trackerd.calibration.store import WORLD_FRAME_KEY, RigContext, open_rig, require_output, write_calibration
from trackerd.calibration.update import apply_intrinsics, apply_measured_wall, apply_stereo, apply_wall_fit
from trackerd.calibration.views import MIN_VIEW_CHANGE, ViewSelector
from trackerd.calibration.visibility import common_view_rectangle, touch_seen, view_targets
from trackerd.calibration.wall import DEFAULT_MAX_RMS_MM, Pointing, Target, Touch, fit_problem, fit_wall
from trackerd.config.models import CameraConfig, PoseExtrinsics, RigConfig
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.wall import WallFrame
from trackerd.locator import Locator


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "calibrate",
        help="calibrate cameras, the stereo pair and the wall; check a calibration",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    steps = parser.add_subparsers(dest="calibrate_command", metavar="STEP", required=True)

    p = steps.add_parser(
        "intrinsics",
        help="one camera's lens from views of a board",
        description="Calibrate one camera's focal length, principal point and distortion.",
    )
    _common(p)
    p.add_argument("--camera", required=True, help="camera id, as in the rig file")
    p.add_argument("--board", required=True, type=_board, help="chessboard:10x7:60 or charuco:10x7:60:45[:5X5_100]")
    p.add_argument("images", nargs="*", metavar="IMAGE", help="images of the board from this camera")
    _sources(p)
    p.add_argument("--views", type=int, default=20, help="views to collect in --live mode (default 20)")
    p.add_argument(
        "--min-views", type=int, default=MIN_VIEWS, help=f"fewest views to calibrate from (default {MIN_VIEWS})"
    )
    p.add_argument(
        "--distortion",
        type=int,
        choices=DISTORTION_TERMS,
        default=5,
        help="distortion coefficients: 4 (k1 k2 p1 p2), 5 (and k3, default), 8 (rational)",
    )
    p.add_argument("--drop-outliers", action="store_true", help="drop views whose error stands out, and recalibrate")
    _quality(p)
    p.set_defaults(handler=intrinsics_command)

    p = steps.add_parser(
        "stereo",
        help="camera 2's pose relative to camera 1 from synchronized pairs",
        description="Calibrate the stereo pair (the rig's first two cameras).",
    )
    _common(p)
    p.add_argument("--board", required=True, type=_board, help="chessboard:10x7:100 or charuco:10x7:100:75[:DICT]")
    p.add_argument("--pairs", metavar="DIR", help="folder of pairs named <name>-<camera>.<ext>")
    _sources(p)
    p.add_argument("--views", type=int, default=15, help="pairs to collect in --live mode (default 15)")
    p.add_argument("--min-pairs", type=int, default=MIN_PAIRS, help=f"fewest pairs (default {MIN_PAIRS})")
    p.add_argument(
        "--refine-intrinsics",
        action="store_true",
        help="let the stereo solve adjust both cameras' intrinsics (default: keep them fixed)",
    )
    p.add_argument(
        "--world",
        choices=("keep", "camera1"),
        default="keep",
        help="keep: camera 1 stays where the rig has it, so the rig's frame is kept (default);"
        " camera1: the world becomes camera 1's frame, as in the report",
    )
    p.add_argument(
        "--max-skew-ms",
        type=float,
        default=2.0,
        help="--live: pairs whose frames are further apart in time are out of sync (default 2)",
    )
    _quality(p)
    p.set_defaults(handler=stereo_command)

    p = steps.add_parser(
        "wall",
        help="the wall plane and frame: measured points, touches or pointing",
        description="Calibrate the wall and re-express the cameras in its frame.",
    )
    _common(p)
    method = p.add_mutually_exclusive_group(required=True)
    method.add_argument(
        "--points",
        metavar="FILE",
        help="a TOML file with a [wall] table measured in the cameras' frame (the report's way)",
    )
    method.add_argument("--touch", action="store_true", help="touch targets on the wall with the pointer's tip")
    method.add_argument("--point", action="store_true", help="aim the pointer at targets from several places")
    p.add_argument("--pairs", metavar="DIR", help="folder of images named <target>[-<n>]-<camera>.<ext>")
    _sources(p)
    p.add_argument("--targets", metavar="FILE", help="TOML [targets] table adding marks to the default targets")
    p.add_argument(
        "--use", metavar="LABELS", help="--live: comma-separated targets to visit (default bl,br,tr,tl,centre)"
    )
    p.add_argument(
        "--places", type=int, default=2, help="--point --live: places to aim at each target from (default 2)"
    )
    p.add_argument(
        "--fixed-size", action="store_true", help="keep the configured display size instead of solving for it"
    )
    p.add_argument(
        "--max-rms-mm",
        type=float,
        default=DEFAULT_MAX_RMS_MM,
        help=f"refuse to write a wall whose RMS residual exceeds this (mm, default {DEFAULT_MAX_RMS_MM:g};"
        " a good fit gives a few mm)",
    )
    p.add_argument(
        "--skip-after",
        type=int,
        default=SKIP_AFTER_FRAMES,
        metavar="FRAMES",
        help=f"--live: skip a target (and say so) after this many frames on it without a capture"
        f" (default {SKIP_AFTER_FRAMES}, about 20 s; 0: never)",
    )
    p.set_defaults(handler=wall_command)

    p = steps.add_parser(
        "check",
        help="ray gaps and reprojection errors of the waved pointer",
        description="Check a calibration: wave the pointer around in view of both cameras.",
    )
    p.add_argument("--config", required=True, help="rig TOML file")
    p.add_argument("--pairs", metavar="DIR", help="folder of pointer images named <name>-<camera>.<ext>")
    _sources(p, snapshots=False)
    p.add_argument("--fixes", type=int, default=300, help="--live: fixes to collect (default 300)")
    p.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    p.set_defaults(handler=check_command)


def _board(text: str) -> BoardSpec:
    try:
        return BoardSpec.parse(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from err


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", required=True, help="rig TOML file")
    p.add_argument("--output", metavar="FILE", help="calibration file to update (default: the one the rig names)")
    p.add_argument(
        "--dry-run",
        action="store_true",
        help="report, but write nothing: no calibration file, and no snapshots unless --snapshots DIR is given",
    )
    p.add_argument("--json", action="store_true", help="print the result as one JSON object (progress on stderr)")


def _sources(p: argparse.ArgumentParser, snapshots: bool = True) -> None:
    p.add_argument(
        "--live", action="store_true", help="use the rig's cameras (the daemon's source) and guide the operator"
    )
    p.add_argument("--recording", metavar="R",
                   help="read the pairs of a recording (trackerd record), as --live reads the cameras")
    p.add_argument(
        "--source",
        choices=("cameras", "simulated"),
        default="cameras",
        help="--live: the rig's cameras (default), or frames the simulator renders from the rig's"
        " own (inline) geometry, to try the procedure without cameras",
    )
    p.add_argument("--duration", type=float, help="--live: stop after this many seconds")
    if snapshots:
        p.add_argument(
            "--snapshots",
            metavar="DIR",
            help="--live: save accepted frames here (default calibration-snapshots/<step>-<time>)",
        )


def _quality(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--max-blur",
        type=float,
        default=MAX_SHARPNESS_PX,
        help=f"reject views whose edges rise over more pixels (default {MAX_SHARPNESS_PX})",
    )
    p.add_argument(
        "--min-change",
        type=float,
        default=MIN_VIEW_CHANGE,
        help=f"reject views whose corners moved less than this fraction of the image diagonal"
        f" from an accepted view (default {MIN_VIEW_CHANGE})",
    )
    p.add_argument(
        "--max-rms",
        type=float,
        default=1.0,
        help="refuse to write a result whose RMS reprojection error exceeds this (px, default 1.0)",
    )


# --------------------------------------------------------------------------- helpers


class Output:
    """Progress and reports: on stdout, or on stderr when stdout carries JSON."""

    def __init__(self, as_json: bool) -> None:
        self.as_json = as_json

    def say(self, text: str) -> None:
        print(text, file=sys.stderr if self.as_json else sys.stdout, flush=True)

    def result(self, text: str, data: dict[str, Any]) -> None:
        if self.as_json:
            print(json.dumps(data, indent=2))
        else:
            print(text, flush=True)


def _check_source(args: argparse.Namespace, offline: str, offline_given: bool) -> str:
    """Which input the step reads: 'live' (the cameras or a recording) or 'files'; errors for none or several.

    ``offline`` names the step's own file input (``IMAGE...`` or ``--pairs DIR``), so the
    message lists exactly what this step takes.
    """
    chosen = [
        name
        for name, given in (
            ("--live", args.live),
            ("--recording", args.recording is not None),
            (offline, offline_given),
        )
        if given
    ]
    if not chosen:
        raise CalibrationError(f"give the input: {offline}, --live, or --recording R")
    if len(chosen) > 1:
        raise CalibrationError(f"give one input, not {' and '.join(chosen)}")
    # A recording is read like the cameras, pair after pair, by the step's live session.
    return "live" if args.live or args.recording is not None else "files"


def _camera(rig: RigConfig, camera_id: str) -> tuple[int, CameraConfig]:
    for index, cam in enumerate(rig.cameras):
        if cam.id == camera_id:
            return index, cam
    raise CalibrationError(f"no camera '{camera_id}' in the rig; it has {', '.join(c.id for c in rig.cameras)}")


def _lens(cam: CameraConfig) -> Lens:
    if cam.intrinsics is None:
        raise CalibrationError(
            f"camera '{cam.id}' has no intrinsics yet; run `trackerd calibrate intrinsics --camera {cam.id}` first"
        )
    posed = cam.model_copy(update={"extrinsics": PoseExtrinsics(kind="pose", position_m=(0.0, 0.0, 0.0))})
    model = CameraModel.from_config(posed)
    return Lens(model.matrix.copy(), model.distortion.copy())


def _snapshot_dir(args: argparse.Namespace, step: str) -> Path | None:
    """Where --live saves accepted frames: --snapshots, or a new timestamped folder; with
    --dry-run (which writes nothing) none, unless --snapshots names one."""
    if args.snapshots:
        return Path(args.snapshots)
    if args.dry_run:
        return None
    import datetime as dt

    return Path("calibration-snapshots") / f"{step}-{dt.datetime.now():%Y%m%d-%H%M%S}"


def _write(
    context: RigContext, calibration, header: str, dry_run: bool, notes: list[str], check_wall: bool = True
) -> dict[str, Any]:
    """Write the calibration file (unless a dry run); what happened is appended to ``notes``."""
    if dry_run:
        notes.append("dry run: nothing written")
        return {"written": None, "backup": None}
    path = require_output(context)
    backup = write_calibration(context, calibration, header, check_wall=check_wall)
    notes.append(f"written: {path}" + (f" (previous calibration kept as {backup.name})" if backup else ""))
    if context.rig.calibration is None or (context.rig_path.parent / context.rig.calibration).resolve() != path:
        notes.append(f'note: the rig does not name this file; add calibration = "{path}" to {context.rig_path}')
    return {"written": str(path), "backup": str(backup) if backup else None}


def _live(
    context: RigContext,
    rig_for_source: RigConfig,
    args: argparse.Namespace,
    session,
    out: Output,
    simulated: Callable[[], Any] | None,
) -> None:
    """Run a session on the live source; Ctrl-C ends collection and keeps what was collected."""
    if args.recording is not None:
        from trackerd.recording.replay import ReplayPairSource

        source = ReplayPairSource(args.recording, speed=None)
        newest = False
    elif args.source == "simulated":
        if simulated is None:
            raise CalibrationError("--source simulated is not available for this step")
        source = simulated()
        newest = False
    else:
        from trackerd.acquisition.live import AravisPairSource

        source = AravisPairSource(rig_for_source)
        newest = True
    ids = [c.id for c in rig_for_source.cameras]
    stop = threading.Event()
    try:
        with source:
            run_session(source, session, ids, say=out.say, stop=stop, max_seconds=args.duration, newest=newest)
    except KeyboardInterrupt:
        stop.set()
        out.say("stopped (Ctrl-C): using what was collected")


def _simulation_truth(context: RigContext) -> RigConfig:
    """The rig file's own inline geometry, which --source simulated renders as the truth."""
    rig = context.rig
    missing = [c.id for c in rig.cameras if c.intrinsics is None or c.extrinsics is None]
    if missing:
        raise CalibrationError(
            f"--source simulated renders the rig file's inline geometry, and camera(s) {', '.join(missing)} have none"
        )
    return rig


# --------------------------------------------------------------------------- intrinsics


def intrinsics_command(args: argparse.Namespace) -> int:
    out = Output(args.json)
    context = open_rig(args.config, args.output)
    index, cam = _camera(context.rig, args.camera)
    mode = _check_source(args, "IMAGE... files", bool(args.images))
    quality = Quality(max_sharpness_px=args.max_blur)
    spec: BoardSpec = args.board
    out.say(f"board: {spec.describe()}")
    if mode == "live":
        session = IntrinsicsSession(
            spec,
            index,
            cam.id,
            cam.width_px,
            cam.height_px,
            wanted_views=args.views,
            min_views=args.min_views,
            quality=quality,
            min_change=args.min_change,
            snapshots=_snapshot_dir(args, f"intrinsics-{cam.id}"),
            distortion_terms=args.distortion,
        )
        out.say(f"show the board to camera {cam.id}; next: {session.selector.guidance(args.views)}")
        _live(
            context, context.rig, args, session, out, lambda: _simulated_boards(context, spec, [index], args.views * 2)
        )
        rejected = [("live", kind) for kind, count in session.rejections.items() for _ in range(count)]
        collected = Collected(views=list(session.views), frames=session.frames, rejected=rejected)
    else:
        selector = ViewSelector(cam.width_px, cam.height_px, args.min_change)
        collected = collect_views(camera_frames(args.images, cam), spec, selector, quality)
        for name, reason in collected.rejected:
            out.say(f"  {name}: {reason}")
    if not collected.views:
        raise CalibrationError(
            f"no usable view of the board in {collected.frames} image(s)"
            + (
                " (no board found in any: check --board, which counts squares, not inner corners)"
                if all(r.startswith("no board") for _, r in collected.rejected)
                else ""
            )
        )
    result = calibrate_intrinsics(
        collected.views, distortion_terms=args.distortion, min_views=args.min_views, drop_outliers=args.drop_outliers
    )
    report = intrinsics_json(result, collected.rejected)
    text = intrinsics_text(cam.id, result, collected.rejected)
    if result.rms_px > args.max_rms:
        out.result(text, {"camera": cam.id, **report, "written": None})
        raise CalibrationError(f"RMS {result.rms_px:.2f} px exceeds --max-rms {args.max_rms:.2f} px: not written")
    calibration = apply_intrinsics(
        context.calibration, cam.id, result, spec,
        (args.recording or "live") if mode == "live" else f"{len(args.images)} images"
    )
    entry = context.calibration.cameras.get(cam.id)
    notes: list[str] = []
    written = _write(context, calibration, f"trackerd calibrate intrinsics --camera {cam.id}", args.dry_run, notes)
    if entry is not None and entry.extrinsics is not None and not args.dry_run:
        notes.append(
            f"note: {cam.id}'s extrinsics were found with its old intrinsics; run `trackerd calibrate stereo` again"
        )
    out.result(text, {"camera": cam.id, **report, **written})
    for note in notes:
        out.say(note)
    return 0


def _simulated_boards(context: RigContext, spec: BoardSpec, cameras: list[int], count: int):
    from trackerd.sim.board import BoardRenderer, board_pair_source, poses_for_camera, poses_for_pair
    from trackerd.sim.render import SceneRenderer

    truth = _simulation_truth(context)
    scene = SceneRenderer(truth)
    rng = np.random.default_rng(7)
    if len(cameras) == 1:
        poses = poses_for_camera(scene, spec, cameras[0], count, rng)
    else:
        poses = poses_for_pair(scene, spec, count, rng)
    return board_pair_source(BoardRenderer(scene, spec), poses, rng)


# --------------------------------------------------------------------------- stereo


def stereo_command(args: argparse.Namespace) -> int:
    out = Output(args.json)
    context = open_rig(args.config, args.output)
    rig = context.merged()
    cam1, cam2 = rig.cameras[0], rig.cameras[1]
    lens1, lens2 = _lens(cam1), _lens(cam2)
    mode = _check_source(args, "--pairs DIR", args.pairs is not None)
    spec: BoardSpec = args.board
    quality = Quality(max_sharpness_px=args.max_blur)
    out.say(f"board: {spec.describe()}")
    if spec.symmetric:
        raise CalibrationError(
            f"board {spec}: a chessboard with {spec.squares_x} x {spec.squares_y} squares looks the same turned"
            " by 180 degrees, so the two cameras may number its corners differently; use one with an odd"
            " number of squares on one side and even on the other (e.g. 10x7), or a ChArUco board"
        )
    if mode == "live":
        session = StereoSession(
            spec,
            (cam1.id, cam2.id),
            cam1.width_px,
            cam1.height_px,
            wanted_pairs=args.views,
            quality=quality,
            min_change=args.min_change,
            max_skew_ns=int(args.max_skew_ms * 1e6),
            snapshots=_snapshot_dir(args, "stereo"),
        )
        out.say(f"hold the board where both {cam1.id} and {cam2.id} see its printed face")
        _live(context, rig, args, session, out, lambda: _simulated_boards(context, spec, [0, 1], args.views * 2))
        collected = Collected(pairs=list(session.pairs), frames=session.frames)
    else:
        groups = pair_files(args.pairs, [cam1.id, cam2.id])

        def frame_pairs():
            for name, files in groups:
                frames = read_pair(files, [cam1, cam2])
                yield name, frames[0], frames[1]

        selector = ViewSelector(cam1.width_px, cam1.height_px, args.min_change)
        collected = collect_pairs(frame_pairs(), spec, selector, quality)
        for name, reason in collected.rejected:
            out.say(f"  {name}: {reason}")
    if not collected.pairs and collected.frames:
        raise CalibrationError(f"no pair in {collected.frames} had the board seen by both cameras")
    result = calibrate_stereo(
        collected.pairs,
        lens1,
        lens2,
        (cam1.width_px, cam1.height_px),
        refine_intrinsics=args.refine_intrinsics,
        min_pairs=args.min_pairs,
    )
    calibration, frame = apply_stereo(
        context.calibration,
        rig,
        cam1.id,
        cam2.id,
        result,
        spec,
        (args.recording or "live") if mode == "live" else str(args.pairs),
        keep_frame=args.world == "keep",
    )
    if args.refine_intrinsics:
        from trackerd.calibration.store import with_camera

        for cam, lens in ((cam1, result.lens1), (cam2, result.lens2)):
            calibration = with_camera(
                calibration,
                cam.id,
                intrinsics={
                    "model": "opencv",
                    "fx_px": float(lens.matrix[0, 0]),
                    "fy_px": float(lens.matrix[1, 1]),
                    "cx_px": float(lens.matrix[0, 2]),
                    "cy_px": float(lens.matrix[1, 2]),
                    "distortion": [float(d) for d in lens.distortion],
                },
                info={"intrinsics_refined_by": "stereo"},
            )
    frame_text = {
        "rig": "the rig's frame (camera 1 kept where the rig has it)",
        "wall": "the wall frame (camera 1 kept where the wall calibration put it)",
    }.get(frame, frame)
    if frame.startswith("camera "):
        frame_text = f"{frame}'s frame (as in the report)"
    warnings = []
    stated = _stated_baseline_m(cam1, cam2)
    if stated is not None:
        warning = baseline_warning(result.baseline_m, stated, spec.square_m * 1000.0)
        if warning is not None:
            warnings.append(warning)
    text = stereo_text((cam1.id, cam2.id), result, collected.rejected, frame_text, warnings)
    report = {**stereo_json(result, collected.rejected, frame), "warnings": warnings}
    if result.rms_px > args.max_rms:
        out.result(text, {**report, "written": None})
        raise CalibrationError(f"RMS {result.rms_px:.2f} px exceeds --max-rms {args.max_rms:.2f} px: not written")
    notes: list[str] = []
    written = _write(
        context,
        calibration,
        "trackerd calibrate stereo",
        args.dry_run,
        notes,
        check_wall=not frame.startswith("camera "),
    )
    if frame.startswith("camera ") and not args.dry_run:
        notes.append(
            "next: `trackerd calibrate wall`; until then the cameras are in "
            f"{frame}'s frame and the rig's wall (in its own frame) does not match them"
        )
    if warnings:
        # Said again last, where it is seen (and on stderr with --json).
        notes.append(
            f"WARNING: baseline {result.baseline_m:.4f} m vs the rig's {stated:.4f} m: check the --board square size"
        )
    out.result(text, {**report, **written})
    for note in notes:
        out.say(note)
    return 0


def _stated_baseline_m(cam1: CameraConfig, cam2: CameraConfig) -> float | None:
    """The distance between the two cameras as the rig states it before this step (inline poses
    or an earlier calibration), or None when either camera has no pose yet."""
    if cam1.extrinsics is None or cam2.extrinsics is None or cam1.intrinsics is None or cam2.intrinsics is None:
        return None
    centres = [CameraModel.from_config(cam).centre_m for cam in (cam1, cam2)]
    return float(np.linalg.norm(centres[1] - centres[0]))


# --------------------------------------------------------------------------- wall


def wall_command(args: argparse.Namespace) -> int:
    out = Output(args.json)
    context = open_rig(args.config, args.output)
    if args.points:
        given = (("--pairs", args.pairs), ("--live", args.live), ("--recording", args.recording))
        extra = [name for name, value in given if value]
        if extra:
            raise CalibrationError(f"--points FILE is the whole input; it takes no {' or '.join(extra)}")
        return _measured_wall(context, args, out)
    rig = context.complete()
    nominal = WallFrame.from_config(context.rig.wall)
    size = (nominal.width_m, nominal.height_m)
    display = nominal.display_width_px, nominal.display_height_px
    display_px = display if nominal.has_display else None
    targets = read_targets(args.targets, *size, display_px) if args.targets else default_targets(*size)
    mode = _check_source(args, "--pairs DIR", args.pairs is not None)
    method = "touch" if args.touch else "point"
    radius = rig.pointer.end_diameter_m / 2.0
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
            snapshots=_snapshot_dir(args, f"wall-{method}"),
            camera_ids=[c.id for c in rig.cameras],
            skip_after=args.skip_after,
        )
        out.say(session.prompt())
        _live(context, rig, args, session, out, lambda: _simulated_wall(context, session, args.skip_after))
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
    written = _write(context, calibration, f"trackerd calibrate wall --{method}", args.dry_run, notes)
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
    cameras = [CameraModel.from_config(c) for c in rig.cameras]
    wall = WallFrame.from_config(rig.wall)
    xy = np.array([targets[label].wall_xy_m for label in labels])
    seen = touch_seen(cameras, wall, xy, radius)
    out_of_view = [(label, row) for label, row in zip(labels, seen, strict=True) if not row.all()]
    if not out_of_view:
        return labels
    ids = [c.id for c in rig.cameras]

    def who(row) -> str:
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
    groups = pair_files(folder, [c.id for c in rig.cameras])
    locator: Locator | None = None
    touches: list[Touch] = []
    pointings: list[Pointing] = []
    for name, files in groups:
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
        frame = WallFrame.from_config(wall)
    except Exception as err:  # ConfigError or GeometryError, both one-line TrackerdErrors
        raise CalibrationError(f"{args.points}: {err}") from err
    points = np.array(wall.points_m if wall.points_m is not None else wall.corners_m)
    text = measured_wall_text(frame, points)
    calibration = apply_measured_wall(context.calibration, wall)
    notes: list[str] = []
    written = _write(context, calibration, "trackerd calibrate wall --points", args.dry_run, notes)
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


def _simulated_wall(context: RigContext, session: WallSession, skip_after: int):
    """Frames of a presenter following the session's prompts: the pointer held still at the target
    being asked for (touching it, or aimed at it from a place of its own), as the simulator renders it.

    Like a presenter whose pointer is not being picked up, it shifts its grip (a new pose for
    the same target, from a new place when pointing) every few dozen frames without a capture; a
    target no pose makes visible is eventually skipped by the session (``skip_after``).
    """
    from trackerd.sim.board import RenderedPairSource
    from trackerd.sim.render import SceneRenderer

    truth = _simulation_truth(context)
    scene = SceneRenderer(truth)
    rng = np.random.default_rng(11)
    regrip = 2 * session.steadiness.frames + 2
    poses: dict[tuple[int, int], Any] = {}

    def pose_now():
        current = session.current()
        if current is None:  # pragma: no cover - the driver stops when the session is done
            current = session.plan[-1]
        key = (session.position, session.on_target // regrip)
        if key not in poses:
            poses[key] = _presented_pose(scene, truth, current[0], current[1], session.method, key[1], rng)
        return poses[key]

    ids = [c.id for c in truth.cameras]

    def render(k: int):
        pose = pose_now()
        return [scene.render(i, pose, rng).image for i in range(len(ids))]

    per_target = (skip_after if skip_after > 0 else 10 * regrip) + regrip
    return RenderedPairSource(ids, list(scene.pixel_formats), render, per_target * len(session.plan))


def _presented_pose(scene, truth: RigConfig, target: Target, place: int, method: str, variant: int, rng):
    """The pointer touching ``target`` (tilted into the room), or aimed at it from place ``place``."""
    from trackerd.bench.calibration import aimed_poses
    from trackerd.sim.scene import PointerPose

    wall = scene.wall
    world = wall.from_wall_m(target.wall_xy_m)
    if method == "point":
        # aimed_poses spreads its places along the wall in turn; the place-th of them.
        return aimed_poses(scene, world, place + 1, rng)[-1]
    tip = world + truth.pointer.end_diameter_m / 2.0 * wall.normal
    tilt = np.array([0.0, 0.4]) if variant == 0 else rng.uniform([-0.4, 0.0], [0.4, 0.6])
    direction = wall.normal + tilt[0] * wall.x_axis + tilt[1] * wall.y_axis
    return PointerPose(tip, tip + truth.pointer.length_m * _unit(direction))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


# --------------------------------------------------------------------------- check


def check_command(args: argparse.Namespace) -> int:
    out = Output(args.json)
    context = open_rig(args.config)
    rig = context.complete()
    mode = _check_source(args, "--pairs DIR", args.pairs is not None)
    cameras = [CameraModel.from_config(c) for c in rig.cameras]
    health = CalibrationHealth.for_rig(rig, cameras, window=max(args.fixes, 10_000))
    frames = 0
    if mode == "live":
        session = CheckSession(Locator(rig, cameras=cameras), health, args.fixes)
        out.say("wave the pointer around in view of both cameras")
        _live(context, rig, args, session, out, lambda: _simulated_pointer(context, args.fixes))
        frames = session.frames
    else:
        groups = pair_files(args.pairs, [c.id for c in rig.cameras])
        locator: Locator | None = None
        for _, files in groups:
            loaded = read_pair(files, list(rig.cameras))
            formats = [fmt for _, _, fmt in loaded]
            if locator is None or locator.pixel_formats != formats:
                locator = Locator(rig, cameras=cameras, pixel_formats=formats)
            locator.reset()
            health.add_fix(locator.locate([image for _, image, _ in loaded]))
            frames += 1
    figures = health.figures()
    out.result(health_text(figures, frames), {"frames": frames, **figures.to_json()})
    return 1 if figures.suspect else 0


def _simulated_pointer(context: RigContext, count: int):
    """The pointer waved in a figure eight over the display (trackerd.sim.motion), rendered."""
    from trackerd.sim.board import RenderedPairSource
    from trackerd.sim.motion import make_motion
    from trackerd.sim.render import SceneRenderer

    truth = _simulation_truth(context)
    scene = SceneRenderer(truth)
    motion = make_motion("figure8", truth)
    rng = np.random.default_rng(13)
    ids = [c.id for c in truth.cameras]
    frames = count * 2

    def render(k: int):
        pose = motion(k * motion.period_s / frames)
        return [scene.render(i, pose, rng).image for i in range(len(ids))]

    return RenderedPairSource(ids, list(scene.pixel_formats), render, frames)
