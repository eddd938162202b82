"""`trackerd calibrate intrinsics`: one camera's lens from board views (files, --live, or a recording)."""

from __future__ import annotations

import argparse
from pathlib import Path

from trackerd.calibration import CalibrationError
from trackerd.calibration.board import BoardSpec, BoardView, grey_for_calibration
from trackerd.calibration.collect import Collected, collect_views
from trackerd.calibration.detection import Quality
from trackerd.calibration.inputs import camera_frames, image_files
from trackerd.calibration.intrinsics import MIN_VIEWS, MIN_VIEWS_FLOOR, IntrinsicsResult, calibrate_intrinsics
from trackerd.calibration.live import IntrinsicsSession
from trackerd.calibration.pictures import intrinsics_pictures, write_index
from trackerd.calibration.report import intrinsics_json, intrinsics_text
from trackerd.calibration.update import apply_intrinsics
from trackerd.calibration.views import MIN_VIEW_CHANGE, ViewSelector
from trackerd.cli.calibrate.common import (
    Output,
    check_source,
    no_board_hint,
    open_rig_to_write,
    rig_camera,
    run_live,
    simulated_boards,
    snapshot_dir,
    write_result,
)
from trackerd.config.models import CameraConfig, PoseExtrinsics
from trackerd.config.rig_geometry import MAX_LENS_INVERSION_PX, lens_fold_px


def intrinsics_command(args: argparse.Namespace) -> int:
    out = Output(args.json)
    context = open_rig_to_write(args)
    index, cam = rig_camera(context.rig, args.camera)
    mode = check_source(args, "IMAGE... files", bool(args.images))
    quality = Quality(max_sharpness_px=args.max_blur)
    spec: BoardSpec = args.board
    if args.min_views < MIN_VIEWS_FLOOR and not args.force:
        raise CalibrationError(
            f"--min-views {args.min_views} is under {MIN_VIEWS_FLOOR}: so few views pin a lens poorly (its focal"
            " length and distortion trade off); add views, or give --force to calibrate from so few anyway"
        )
    out.say(f"board: {spec.describe()}")
    image_files_used: list[Path] = []
    snapshots = None
    if mode == "live":
        snapshots = snapshot_dir(args, f"intrinsics-{cam.id}")
        session = IntrinsicsSession(
            spec,
            index,
            cam.id,
            cam.width_px,
            cam.height_px,
            wanted_views=args.views,
            min_views=args.min_views,
            quality=quality,
            min_change=MIN_VIEW_CHANGE if args.min_change is None else args.min_change,
            snapshots=snapshots,
            distortion_terms=args.distortion or 5,
        )
        out.say(f"show the board to camera {cam.id}; next: {session.selector.guidance(args.views)}")
        run_live(
            context, context.rig, args, session, out, lambda: simulated_boards(context, spec, [index], args.views * 2)
        )
        rejected = [("live", kind) for kind, count in session.rejections.items() for _ in range(count)]
        collected = Collected(views=list(session.views), frames=session.frames, rejected=rejected)
    else:
        files, said = image_files(args.images, cam.id, [c.id for c in context.rig.cameras])
        image_files_used = files
        for line in said:
            out.say(line)
        selector = ViewSelector(cam.width_px, cam.height_px, args.min_change or 0.0)
        collected = collect_views(camera_frames(files, cam), spec, selector, quality)
        for name, reason in collected.rejected:
            out.say(f"  {name}: {reason}")
    if not collected.views:
        found_none = all(r.startswith("no whole board") for _, r in collected.rejected)
        hint = ""
        if found_none and mode != "live" and args.images:
            hint = no_board_hint(spec, next(iter(camera_frames(files[:1], cam))))
        raise CalibrationError(f"no usable view of the board in {collected.frames} image(s){hint}")
    result = calibrate_intrinsics(
        collected.views,
        distortion_terms=args.distortion or 5,
        min_views=args.min_views,
        drop_outliers=args.drop_outliers,
    )
    if args.distortion is None:
        result = _without_an_unsupported_k3(result, collected.views, cam, args, out)
    warnings = []
    if len(result.view_names) < MIN_VIEWS:
        warnings.append(
            f"calibrated from {len(result.view_names)} views, fewer than the {MIN_VIEWS} the default asks for"
            " (15 to 30 are better)"
        )
    report = intrinsics_json(result, collected.rejected, warnings)
    text = intrinsics_text(cam.id, result, collected.rejected, warnings)
    if args.report:
        # The views' images: the files given, or the snapshots a live session saved (named as its views).
        sources = image_files_used or (sorted(snapshots.glob("*.png")) if snapshots and snapshots.is_dir() else [])
        wanted = set(result.view_names)
        used = [path for path in sources if Path(path).name in wanted or Path(path).stem in wanted]
        images = {}
        for name, frame, fmt in camera_frames(used, cam):
            images[name] = images[Path(name).stem] = grey_for_calibration(frame, fmt)
        pictures = intrinsics_pictures(Path(args.report), cam.id, result, collected.views, images)
        lines = text.splitlines()
        figures = lines[:3] + [line for line in lines if line.strip().startswith(("not covered", "WARNING"))]
        index_page = write_index(Path(args.report), f"camera {cam.id}", figures, pictures)
        out.say(f"report: {index_page} ({len(pictures)} pictures)")
    if result.rms_px > args.max_rms:
        out.result(text, {"camera": cam.id, **report, "written": None})
        raise CalibrationError(f"RMS {result.rms_px:.2f} px exceeds --max-rms {args.max_rms:.2f} px: not written")
    calibration = apply_intrinsics(
        context.calibration,
        cam.id,
        result,
        spec,
        (args.recording or "live") if mode == "live" else f"{len(files)} images",
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


K3_GAIN_NEEDED = 0.05
"""k3 is kept, where it makes the lens fold over near the image's edge, only if it lowers the RMS by
more than this fraction."""


def _without_an_unsupported_k3(
    result: IntrinsicsResult, views: list[BoardView], cam: CameraConfig, args: argparse.Namespace, out: Output
) -> IntrinsicsResult:
    """The 4-term lens instead of the 5-term one where k3 folds the lens over near the image's edge
    (views that leave the corners uncovered let k3 run away there) and buys almost nothing: such a
    calibration could not be written, and the 4-term one describes the covered image as well."""
    folded, pixel = lens_fold_px(_posed(cam, result))
    if folded <= MAX_LENS_INVERSION_PX:
        return result
    simpler = calibrate_intrinsics(
        views, distortion_terms=4, min_views=args.min_views, drop_outliers=args.drop_outliers
    )
    if lens_fold_px(_posed(cam, simpler))[0] > MAX_LENS_INVERSION_PX:
        return result
    if simpler.rms_px > result.rms_px * (1.0 + K3_GAIN_NEEDED):
        return result
    out.say(
        f"k3 left out (--distortion 4): with it the lens folds over near pixel ({pixel[0]:.0f}, {pixel[1]:.0f})"
        f" at the image's edge, and it lowers the RMS only from {simpler.rms_px:.3f} to {result.rms_px:.3f} px"
    )
    return simpler


def _posed(cam: CameraConfig, result: IntrinsicsResult) -> CameraConfig:
    """The camera with this lens, at the origin (the fold check needs a complete camera)."""
    return cam.model_copy(
        update={
            "intrinsics": result.to_config(),
            "extrinsics": PoseExtrinsics(kind="pose", position_m=(0.0, 0.0, 0.0)),
        }
    )
