"""`trackerd calibrate intrinsics`: one camera's lens from board views (files, --live, or a recording)."""

from __future__ import annotations

import argparse

from trackerd.calibration import CalibrationError
from trackerd.calibration.board import BoardSpec, Quality
from trackerd.calibration.collect import Collected, collect_views
from trackerd.calibration.inputs import camera_frames
from trackerd.calibration.intrinsics import calibrate_intrinsics
from trackerd.calibration.live import IntrinsicsSession
from trackerd.calibration.report import intrinsics_json, intrinsics_text
from trackerd.calibration.store import open_rig
from trackerd.calibration.update import apply_intrinsics
from trackerd.calibration.views import ViewSelector
from trackerd.cli.calibrate.common import (
    Output,
    check_source,
    no_board_hint,
    rig_camera,
    run_live,
    simulated_boards,
    snapshot_dir,
    write_result,
)


def intrinsics_command(args: argparse.Namespace) -> int:
    out = Output(args.json)
    context = open_rig(args.config, args.output)
    index, cam = rig_camera(context.rig, args.camera)
    mode = check_source(args, "IMAGE... files", bool(args.images))
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
            snapshots=snapshot_dir(args, f"intrinsics-{cam.id}"),
            distortion_terms=args.distortion,
        )
        out.say(f"show the board to camera {cam.id}; next: {session.selector.guidance(args.views)}")
        run_live(
            context, context.rig, args, session, out, lambda: simulated_boards(context, spec, [index], args.views * 2)
        )
        rejected = [("live", kind) for kind, count in session.rejections.items() for _ in range(count)]
        collected = Collected(views=list(session.views), frames=session.frames, rejected=rejected)
    else:
        selector = ViewSelector(cam.width_px, cam.height_px, args.min_change)
        collected = collect_views(camera_frames(args.images, cam), spec, selector, quality)
        for name, reason in collected.rejected:
            out.say(f"  {name}: {reason}")
    if not collected.views:
        found_none = all(r.startswith("no whole board") for _, r in collected.rejected)
        hint = ""
        if found_none and mode != "live" and args.images:
            hint = no_board_hint(spec, next(iter(camera_frames(args.images[:1], cam))))
        raise CalibrationError(f"no usable view of the board in {collected.frames} image(s){hint}")
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
    header = f"trackerd calibrate intrinsics --camera {cam.id}"
    written = write_result(context, calibration, header, args.dry_run, notes)
    if entry is not None and entry.extrinsics is not None and not args.dry_run:
        notes.append(
            f"note: {cam.id}'s extrinsics were found with its old intrinsics; run `trackerd calibrate stereo` again"
        )
    out.result(text, {"camera": cam.id, **report, **written})
    for note in notes:
        out.say(note)
    return 0

