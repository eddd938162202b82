"""`trackerd calibrate pointer`: the pointer's colours in this room, and the thresholds that find them."""

from __future__ import annotations

import argparse
from typing import Any

from trackerd.calibration.colours import COLOURS, ColourLearner, LearnedFigures
from trackerd.calibration.inputs import pair_files, read_pair
from trackerd.calibration.store import RigContext, open_rig, today, with_pointer_colours
from trackerd.cli.calibrate.common import Output, check_source, run_live, simulated_pointer, write_result
from trackerd.geometry.camera import CameraModel


def pointer_command(args: argparse.Namespace) -> int:
    out = Output(args.json)
    context = open_rig(args.config, args.output)
    rig = context.complete()
    mode = check_source(args, "--pairs DIR", args.pairs is not None)
    cameras = [CameraModel.from_config(c) for c in rig.cameras]
    if mode == "live":
        learner = ColourLearner(rig, cameras, wanted=args.frames)
        out.say("wave the pointer slowly through the room, where every camera sees both ends,"
                " in front of whatever the display shows")
        run_live(context, rig, args, learner, out, lambda: simulated_pointer(context, args.frames, seed=17))
    else:
        found = pair_files(args.pairs, [c.id for c in rig.cameras])
        out.say(f"{args.pairs}: {len(found.moments)} pair(s), {found.layout}")
        learner = ColourLearner(rig, cameras, wanted=len(found.moments) + 1)
        for moment in found.moments:
            loaded = read_pair(moment.files, list(rig.cameras))
            event = learner.feed(loaded)
            if event is not None:
                out.say(event.text)
    figures = learner.result(today())
    notes: list[str] = []
    written: dict[str, Any] = {"written": None, "backup": None}
    calibration = with_pointer_colours(context.calibration, figures.colours)
    written = write_result(context, calibration, "trackerd calibrate pointer", args.dry_run, notes)
    out.result(_text(context, figures, notes), {**_json(figures), **written, "notes": notes})
    return 0


def _text(context: RigContext, figures: LearnedFigures, notes: list[str]) -> str:
    rig = context.rig
    lines = [f"learned from {figures.used} of {figures.frames} pair(s) where the pointer was located well", ""]
    lines.append("                   ball   room  margin  threshold (was)")
    for colour in COLOURS:
        learned = figures.colours.of(colour)
        was = getattr(rig.detector, colour).min_excess
        lines.append(
            f"  {colour:<5} excess  {learned.ball_excess:5.0f}  {learned.background_excess:5.0f}"
            f"  {learned.margin:6.0f}  {learned.min_excess:9d} ({was})"
        )
        for cam in (f for f in figures.per_camera if f.colour == colour):
            ball = "-" if cam.ball_excess is None else f"{cam.ball_excess:.0f}"
            room = "-" if cam.background_excess is None else f"{cam.background_excess}"
            lines.append(f"    camera {cam.camera_id}: ball {ball}, room {room}")
    lines.append("  (grey levels by which the end's channel exceeds the other two: the ball's 10th percentile,"
                 " the room's highest block)")
    check = figures.detector_check
    if check:
        (before, tried), (after, _) = check["before"], check["after"]
        lines.append(f"the detector's own search found both ends in {before} of {tried} views with the thresholds"
                     f" it had, {after} of {tried} with the learned ones")
    given = [c for c in COLOURS if c in rig.detector.model_fields_set]
    if given:
        lines.append(f"note: the rig file sets [detector.{'] and [detector.'.join(given)}], which stays in"
                     " force over the learned threshold (remove it to use the learned one)")
    lines.extend(f"warning: {w}" for w in figures.warnings)
    lines.extend(notes)
    return "\n".join(lines)


def _json(figures: LearnedFigures) -> dict[str, Any]:
    return {
        "pairs": figures.frames,
        "used": figures.used,
        "pointer_colours": figures.colours.model_dump(mode="json"),
        "cameras": [
            {"camera": f.camera_id, "colour": f.colour, "ball_excess": f.ball_excess,
             "background_excess": f.background_excess, "background_pair": f.background_frame,
             "background_at_px": list(f.background_at_px) if f.background_at_px else None}
            for f in figures.per_camera
        ],
        "detector_check": (
            {k: {"found": v[0], "views": v[1]} for k, v in figures.detector_check.items()}
            if figures.detector_check else None
        ),
        "warnings": list(figures.warnings),
    }
