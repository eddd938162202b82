"""What the `trackerd calibrate` steps share: their output, their inputs, writing the result, live sessions."""

from __future__ import annotations

import argparse
import json
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from trackerd.calibration import CalibrationError
from trackerd.calibration.board import BoardSpec
from trackerd.calibration.live import Session, run_session
from trackerd.calibration.stereo import Lens
from trackerd.calibration.store import RigContext, open_rig, require_output, write_calibration
from trackerd.config.models import CalibrationFile, CameraConfig, PointerConfig, PoseExtrinsics, RigConfig, WallConfig
from trackerd.config.rig_geometry import camera_model

if TYPE_CHECKING:
    from trackerd.acquisition.source import PairSource
    from trackerd.sim.board import RenderedPairSource


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


def check_source(args: argparse.Namespace, offline: str, offline_given: bool) -> str:
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
    if chosen[0] == offline and getattr(args, "snapshots", None):
        raise CalibrationError(
            f"--snapshots is for --live and --recording (it saves the frames they accept);"
            f" {offline} are on disk already"
        )
    # A recording is read like the cameras, pair after pair, by the step's live session.
    return "live" if args.live or args.recording is not None else "files"


def rig_camera(rig: RigConfig, camera_id: str) -> tuple[int, CameraConfig]:
    for index, cam in enumerate(rig.cameras):
        if cam.id == camera_id:
            return index, cam
    raise CalibrationError(f"no camera '{camera_id}' in the rig; it has {', '.join(c.id for c in rig.cameras)}")


def rig_wall(rig: RigConfig) -> WallConfig:
    """The rig's [wall] table, which the pointer steps need (an error naming it when missing)."""
    if rig.wall is None:
        raise CalibrationError("the rig has no [wall] table: give the display's size there (docs/calibration.md)")
    return rig.wall


def rig_pointer(rig: RigConfig) -> PointerConfig:
    """The rig's [pointer] table, which the pointer steps need (an error naming it when missing)."""
    if rig.pointer is None:
        raise CalibrationError("the rig has no [pointer] table: give the pointer's balls there (docs/calibration.md)")
    return rig.pointer


def lens_of(cam: CameraConfig) -> Lens:
    if cam.intrinsics is None:
        raise CalibrationError(
            f"camera '{cam.id}' has no intrinsics yet; run `trackerd calibrate intrinsics --camera {cam.id}` first"
        )
    posed = cam.model_copy(update={"extrinsics": PoseExtrinsics(kind="pose", position_m=(0.0, 0.0, 0.0))})
    model = camera_model(posed)
    return Lens(model.matrix.copy(), model.distortion.copy())


def snapshot_dir(args: argparse.Namespace, step: str) -> Path | None:
    """Where --live saves accepted frames: --snapshots, or a new timestamped folder; with
    --dry-run (which writes nothing) none, unless --snapshots names one."""
    if args.snapshots:
        return Path(args.snapshots)
    if args.dry_run:
        return None
    import datetime as dt

    return Path("calibration-snapshots") / f"{step}-{dt.datetime.now():%Y%m%d-%H%M%S}"


def open_rig_to_write(args: argparse.Namespace) -> RigContext:
    """The rig and calibration a step reads (``--config``, ``--output``), refused at once when the step
    would have nowhere to write its result (the rig names no calibration file, no ``--output``, no
    ``--dry-run``): said before the pointer is waved or a board shown, not after."""
    context = open_rig(args.config, args.output)
    if not args.dry_run:
        require_output(context)
    return context


def write_result(
    context: RigContext,
    calibration: CalibrationFile,
    header: str,
    dry_run: bool,
    notes: list[str],
    check_wall: bool = True,
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


def run_live(
    context: RigContext,
    rig_for_source: RigConfig,
    args: argparse.Namespace,
    session: Session,
    out: Output,
    simulated: Callable[[], PairSource] | None,
) -> None:
    """Run a session on the live source; Ctrl-C ends collection and keeps what was collected."""
    if args.recording is not None:
        from trackerd.recording.replay import ReplayPairSource

        source: PairSource = ReplayPairSource(args.recording, speed=None)
        newest = False
    elif args.source == "simulated":
        if simulated is None:
            raise CalibrationError("--source simulated is not available for this step")
        source = simulated()
        newest = False
    else:
        from trackerd.acquisition.live import LivePairSource

        source = LivePairSource(rig_for_source)
        newest = True
    ids = [c.id for c in rig_for_source.cameras]
    stop = threading.Event()
    try:
        with source:
            run_session(source, session, ids, say=out.say, stop=stop, max_seconds=args.duration, newest=newest)
    except KeyboardInterrupt:
        stop.set()
        out.say("stopped (Ctrl-C): using what was collected")


def simulation_truth(context: RigContext) -> RigConfig:
    """The rig file's own inline geometry, which --source simulated renders as the truth."""
    rig = context.rig
    missing = [c.id for c in rig.cameras if c.intrinsics is None or c.extrinsics is None]
    if missing:
        raise CalibrationError(
            f"--source simulated renders the rig file's inline geometry, and camera(s) {', '.join(missing)} have none"
        )
    if rig.wall is None or rig.pointer is None:
        raise CalibrationError("--source simulated renders the rig file's room, which needs [wall] and [pointer]")
    return rig


def simulated_pointer(context: RigContext, count: int, seed: int) -> RenderedPairSource:
    """The pointer waved in a figure eight over the display (trackerd.sim.motion), rendered: ``2 count`` pairs."""
    from trackerd.sim.board import RenderedPairSource
    from trackerd.sim.motion import make_motion
    from trackerd.sim.render import SceneRenderer

    truth = simulation_truth(context)
    scene = SceneRenderer(truth)
    motion = make_motion("figure8", truth)
    rng = np.random.default_rng(seed)
    ids = [c.id for c in truth.cameras]
    frames = count * 2

    def render(k: int) -> list[NDArray[np.uint8]]:
        pose = motion(k * motion.period_s / frames)
        return [scene.render(i, pose, rng).image for i in range(len(ids))]

    return RenderedPairSource(ids, list(scene.pixel_formats), render, frames)


def simulated_boards(context: RigContext, spec: BoardSpec, cameras: list[int], count: int) -> RenderedPairSource:
    from trackerd.sim.board import BoardRenderer, board_pair_source, poses_for_camera, poses_for_pair
    from trackerd.sim.render import SceneRenderer

    truth = simulation_truth(context)
    scene = SceneRenderer(truth)
    rng = np.random.default_rng(7)
    if len(cameras) == 1:
        poses = poses_for_camera(scene, spec, cameras[0], count, rng)
    else:
        poses = poses_for_pair(scene, spec, count, rng)
    return board_pair_source(BoardRenderer(scene, spec), poses, rng)


def no_board_hint(spec: BoardSpec, frame: tuple[str, np.ndarray, str]) -> str:
    """What to say when no image showed the board: a board of a neighbouring size that one of them does
    show (the --board to give), else what else to check. Never a guess presented as the cause."""
    from trackerd.calibration.board import grey_for_calibration
    from trackerd.calibration.chessboard import board_size_hint

    name, image, pixel_format = frame
    other = board_size_hint(grey_for_calibration(image, pixel_format), spec)
    cols, rows = spec.inner_corners
    if other is not None:
        found = BoardSpec.parse(other).inner_corners
        return (
            f" (none shows {cols} x {rows} inner corners, but {name} shows {found[0]} x {found[1]}:"
            f" give --board {other}; --board counts squares)"
        )
    return (
        f" (no detector found {cols} x {rows} inner corners, nor a neighbouring size, in any: is the"
        " board in view, lit and in focus?)"
    )
