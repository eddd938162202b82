"""`trackerd calibrate stereo`: the second camera's pose relative to the first, from board pairs."""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from trackerd.calibration import CalibrationError
from trackerd.calibration.board import BoardSpec, grey_for_calibration
from trackerd.calibration.collect import Collected, Frame, collect_pairs
from trackerd.calibration.detection import Quality
from trackerd.calibration.inputs import pair_files, read_pair
from trackerd.calibration.live import StereoSession
from trackerd.calibration.pictures import stereo_pictures, write_index
from trackerd.calibration.report import quality_warnings, stereo_json, stereo_text
from trackerd.calibration.stereo import MIN_PAIRS, MIN_PAIRS_FLOOR, baseline_warning, calibrate_stereo
from trackerd.calibration.update import apply_stereo
from trackerd.calibration.views import MIN_VIEW_CHANGE, ViewSelector
from trackerd.cli.calibrate.common import (
    Output,
    check_source,
    lens_of,
    no_board_hint,
    open_rig_to_write,
    run_live,
    simulated_boards,
    snapshot_dir,
    write_result,
)
from trackerd.config.models import CameraConfig
from trackerd.config.rig_geometry import camera_model


def stereo_command(args: argparse.Namespace) -> int:
    out = Output(args.json)
    if args.min_pairs < MIN_PAIRS_FLOOR:
        raise CalibrationError(
            f"--min-pairs {args.min_pairs} is under {MIN_PAIRS_FLOOR}: with fewer pairs one taken out of sync"
            " cannot be told from the others"
        )
    context = open_rig_to_write(args)
    rig = context.merged()
    cam1, cam2 = rig.cameras[0], rig.cameras[1]
    lens1, lens2 = lens_of(cam1), lens_of(cam2)
    mode = check_source(args, "--pairs DIR", args.pairs is not None)
    spec: BoardSpec = args.board
    quality = Quality(max_sharpness_px=args.max_blur)
    out.say(f"board: {spec.describe()}")
    if spec.symmetric:
        raise CalibrationError(
            f"board {spec}: a chessboard with {spec.squares_x} x {spec.squares_y} squares looks the same turned"
            " by 180 degrees, so the two cameras may number its corners differently; use one with an odd"
            " number of squares on one side and even on the other (e.g. 10x7), or a ChArUco board"
        )
    moments: dict[str, dict[str, Path]] = {}
    snapshots = None
    if mode == "live":
        snapshots = snapshot_dir(args, "stereo")
        session = StereoSession(
            spec,
            (cam1.id, cam2.id),
            cam1.width_px,
            cam1.height_px,
            wanted_pairs=args.views,
            quality=quality,
            min_change=MIN_VIEW_CHANGE if args.min_change is None else args.min_change,
            max_skew_ns=int(args.max_skew_ms * 1e6),
            snapshots=snapshots,
        )
        out.say(f"hold the board where both {cam1.id} and {cam2.id} see its printed face")
        run_live(context, rig, args, session, out, lambda: simulated_boards(context, spec, [0, 1], args.views * 2))
        collected = Collected(pairs=list(session.pairs), frames=session.frames)
    else:
        found = pair_files(args.pairs, [cam1.id, cam2.id])
        out.say(f"{args.pairs}: {len(found.moments)} pair(s), {found.layout}")
        moments = {moment.name: moment.files for moment in found.moments}

        def frame_pairs() -> Iterator[tuple[str, Frame, Frame]]:
            for moment in found.moments:
                frames = read_pair(moment.files, [cam1, cam2], grey_ok=True)
                yield moment.name, frames[0], frames[1]

        selector = ViewSelector(cam1.width_px, cam1.height_px, args.min_change or 0.0)
        collected = collect_pairs(frame_pairs(), spec, selector, quality)
        for name, reason in collected.rejected:
            out.say(f"  {name}: {reason}")
    if not collected.pairs and collected.frames:
        hint = ""
        if moments and all("no whole board found" in reason for _, reason in collected.rejected):
            first = next(iter(moments.values()))
            hint = no_board_hint(spec, read_pair(first, [cam1, cam2], grey_ok=True)[0])
        raise CalibrationError(f"no pair in {collected.frames} had the board seen by both cameras{hint}")
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
    if len(result.pair_names) < MIN_PAIRS:
        warnings.append(
            f"calibrated from {len(result.pair_names)} pairs, fewer than the {MIN_PAIRS} the default asks for"
            " (10 to 20 are better)"
        )
    stated = _stated_baseline_m(cam1, cam2)
    if stated is not None:
        warning = baseline_warning(result.baseline_m, stated, spec.square_m * 1000.0)
        if warning is not None:
            warnings.append(warning)
    text = stereo_text((cam1.id, cam2.id), result, collected.rejected, frame_text, warnings)
    report = {
        **stereo_json(result, collected.rejected, frame),
        "warnings": [*quality_warnings(result.rms_px), *warnings],
    }
    if args.report:
        if snapshots is not None and snapshots.is_dir():  # a live session's pairs, saved as <name>-<camera>.png
            moments = {
                name: {cam.id: snapshots / f"{name}-{cam.id}.png" for cam in (cam1, cam2)}
                for name in result.pair_names
                if all((snapshots / f"{name}-{cam.id}.png").exists() for cam in (cam1, cam2))
            }
        images = {}
        for name in result.pair_names:
            if name in moments:
                frames = read_pair(moments[name], [cam1, cam2], grey_ok=True)
                images[name] = (
                    grey_for_calibration(frames[0][1], frames[0][2]),
                    grey_for_calibration(frames[1][1], frames[1][2]),
                )
        pictures = stereo_pictures(Path(args.report), (cam1.id, cam2.id), result, collected.pairs, images)
        lines = text.splitlines()
        figures = lines[:2] + [line for line in lines if line.strip().startswith("WARNING")]
        index = write_index(Path(args.report), f"stereo {cam1.id} -> {cam2.id}", figures, pictures)
        out.say(f"report: {index} ({len(pictures)} pictures)")
    if result.rms_px > args.max_rms:
        out.result(text, {**report, "written": None})
        raise CalibrationError(f"RMS {result.rms_px:.2f} px exceeds --max-rms {args.max_rms:.2f} px: not written")
    notes: list[str] = []
    written = write_result(
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
            + (
                f"{frame}'s frame and the rig's wall (in its own frame) does not match them"
                if context.rig.wall is not None
                else f"{frame}'s frame, with no wall"
            )
        )
    if stated is not None and baseline_warning(result.baseline_m, stated, spec.square_m * 1000.0):
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
    centres = [camera_model(cam).centre_m for cam in (cam1, cam2)]
    return float(np.linalg.norm(centres[1] - centres[0]))
