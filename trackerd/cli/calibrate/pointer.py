"""`trackerd calibrate pointer`: the pointer's colours in this room, and the thresholds that find them."""

from __future__ import annotations

import argparse
from typing import Any

from trackerd.calibration import CalibrationError
from trackerd.calibration.colours import COLOURS, ColourLearner, LearnedFigures
from trackerd.calibration.inputs import pair_files, read_pair
from trackerd.calibration.store import RigContext, today, with_pointer_colours
from trackerd.cli.calibrate.common import (
    Output,
    check_source,
    open_rig_to_write,
    run_live,
    simulated_pointer,
    write_result,
)
from trackerd.config.rig_geometry import camera_model

DEFAULT_FRAMES = 60
"""Pairs with the pointer located to learn from, live."""


def pointer_command(args: argparse.Namespace) -> int:
    out = Output(args.json)
    context = open_rig_to_write(args)
    if context.rig.pointer_colours is not None:
        raise CalibrationError(
            f"{context.rig_path}: the rig file gives [pointer_colours] itself; this step writes them into the"
            " calibration file: remove them from the rig file first"
        )
    rig = context.complete()
    mode = check_source(args, "--pairs DIR", args.pairs is not None)
    if mode == "files":
        live_only = [
            name
            for name, given in (
                ("--frames", args.frames is not None),
                ("--duration", args.duration is not None),
                ("--source", args.source != "cameras"),
            )
            if given
        ]
        if live_only:
            raise CalibrationError(
                f"{' and '.join(live_only)}: only with --live or --recording; --pairs DIR"
                " learns from every pair in the folder"
            )
    cameras = [camera_model(c) for c in rig.cameras]
    if mode == "live":
        learner = ColourLearner(rig, cameras, wanted=args.frames or DEFAULT_FRAMES)
        out.say(
            "wave the pointer slowly through the room, where every camera sees both ends,"
            " in front of whatever the display shows"
        )
        run_live(
            context, rig, args, learner, out, lambda: simulated_pointer(context, args.frames or DEFAULT_FRAMES, seed=17)
        )
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
    notes = _overrides(context)
    calibration = with_pointer_colours(context.calibration, figures.colours)
    written = write_result(context, calibration, "trackerd calibrate pointer", args.dry_run, notes)
    before = {c: getattr(rig.detector, c).min_excess for c in COLOURS}
    out.result(
        _text(figures, before, notes), {**_json(figures), "thresholds_before": before, **written, "notes": notes}
    )
    return 0


def _overrides(context: RigContext) -> list[str]:
    """What the rig file sets that stays in force over the learned thresholds."""
    given = [c for c in COLOURS if c in context.rig.detector.model_fields_set]
    if not given:
        return []
    tables = "] and [detector.".join(given)
    return [
        f"note: the rig file sets [detector.{tables}], which stays in force over the learned threshold"
        " (remove it to use the learned one)"
    ]


def _text(figures: LearnedFigures, before: dict[str, int], notes: list[str]) -> str:
    lines = [f"learned from {figures.used} of {figures.frames} pair(s) where the pointer was located well", ""]
    lines.append("                   ball   room  margin  threshold (was)")
    for colour in COLOURS:
        learned = figures.colours.of(colour)
        was = before[colour]
        lines.append(
            f"  {colour:<5} excess  {learned.ball_excess:5.0f}  {learned.background_excess:5.0f}"
            f"  {learned.margin:6.0f}  {learned.min_excess:9d} ({was})"
        )
        for cam in (f for f in figures.per_camera if f.colour == colour):
            ball = "-" if cam.ball_excess is None else f"{cam.ball_excess:.0f}"
            room = "-" if cam.background_excess is None else f"{cam.background_excess}"
            lines.append(f"    camera {cam.camera_id}: ball {ball}, room {room}")
    lines.append(
        "  (grey levels by which the end's channel exceeds the other two: the ball's 10th percentile,"
        " the room's highest block)"
    )
    check = figures.detector_check
    if check:
        (found_before, tried), (found_after, _) = check["before"], check["after"]
        lines.append(
            f"the detector's own search, on {tried} views of {check['pairs']} of those pairs, found both"
            f" ends in {found_before} with the thresholds it had, {found_after} with the learned ones"
        )
    lines.append(
        f"(min_value, the brightness each end's own channel must reach, is learned too:"
        f" red {figures.colours.red.min_value}, blue {figures.colours.blue.min_value})"
    )
    lines.extend(f"warning: {w}" for w in figures.warnings)
    lines.extend(notes)
    return "\n".join(lines)


def _json(figures: LearnedFigures) -> dict[str, Any]:
    return {
        "pairs": figures.frames,
        "used": figures.used,
        "pointer_colours": figures.colours.model_dump(mode="json"),
        "cameras": [
            {
                "camera": f.camera_id,
                "colour": f.colour,
                "ball_excess": f.ball_excess,
                "background_excess": f.background_excess,
                "background_pair": f.background_frame,
                "background_at_px": list(f.background_at_px) if f.background_at_px else None,
            }
            for f in figures.per_camera
        ],
        "detector_check": (
            {
                "before": {"found": figures.detector_check["before"][0], "views": figures.detector_check["before"][1]},
                "after": {"found": figures.detector_check["after"][0], "views": figures.detector_check["after"][1]},
            }
            if figures.detector_check
            else None
        ),
        "warnings": list(figures.warnings),
    }
