"""`trackerd calibrate check`: how well the cameras still agree, from pointer fixes (docs/calibration.md)."""

from __future__ import annotations

import argparse

from trackerd.calibration import CalibrationError
from trackerd.calibration.health import CalibrationHealth
from trackerd.calibration.inputs import pair_files, read_pair
from trackerd.calibration.pointer_sessions import CheckSession
from trackerd.calibration.report import health_text
from trackerd.calibration.store import open_rig
from trackerd.cli.calibrate.common import Output, check_source, run_live, simulated_pointer
from trackerd.config.rig_geometry import camera_model
from trackerd.locator import Locator


def check_command(args: argparse.Namespace) -> int:
    out = Output(args.json)
    context = open_rig(args.config)
    rig = context.complete()
    mode = check_source(args, "--pairs DIR", args.pairs is not None)
    cameras = [camera_model(c) for c in rig.cameras]
    health = CalibrationHealth.for_rig(rig, cameras, window=max(args.fixes, 10_000))
    frames = 0
    if mode == "live":
        session = CheckSession(Locator(rig, cameras=cameras), health, args.fixes)
        out.say("wave the pointer around in view of both cameras")
        run_live(context, rig, args, session, out, lambda: simulated_pointer(context, args.fixes, seed=13))
        frames = session.frames
    else:
        found = pair_files(args.pairs, [c.id for c in rig.cameras])
        out.say(f"{args.pairs}: {len(found.moments)} pair(s), {found.layout}")
        locator: Locator | None = None
        for moment in found.moments:
            loaded = read_pair(moment.files, list(rig.cameras))
            formats = [fmt for _, _, fmt in loaded]
            if locator is None or locator.pixel_formats != formats:
                locator = Locator(rig, cameras=cameras, pixel_formats=formats)
            locator.reset()
            health.add_fix(locator.locate([image for _, image, _ in loaded]))
            frames += 1
    figures = health.figures()
    out.result(health_text(figures, frames), {"frames": frames, **figures.to_json()})
    if figures.fixes == 0:
        # No data is no evidence that the calibration fits: a failure, not a pass.
        raise CalibrationError(
            f"no pointer fixes in {frames} frame pair(s): nothing to check the calibration against;"
            " show the pointer to both cameras"
        )
    return 1 if figures.suspect else 0
