"""`trackerd snap --config RIG OUT`: one synchronized pair, saved raw and viewable, with what trackerd sees in it.

The report's Snap mode (section 6.2), for aiming cameras and tuning colours:
opens the cameras, lets them settle, takes one pair and writes into the folder
OUT (created if missing):

  <name>-<camera>.png        the raw frame, lossless (a Bayer mosaic stays one channel):
                             `trackerd locate`, `trackerd recording import` and
                             `trackerd calibrate --pairs` read these
  <name>-<camera>-view.png   demosaiced, with each detected end circled and the fix written on it
  <name>.json                timestamps, frame ids, skew, detections and the fix

and prints each camera's detections and the wall hit. <name> is snap-<local time>.
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
import time
from pathlib import Path
from typing import Any

from trackerd.config.loader import load_rig
from trackerd.errors import CameraError
from trackerd.recording.cameras import add_virtual_arguments


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "snap", help="take one synchronized pair, save it raw and annotated, print the detections and the hit",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--config", required=True, help="rig TOML file")
    parser.add_argument("out", metavar="OUT", help="folder to save into (created if missing)")
    parser.add_argument("--name", help="file name stem (default snap-<local time>)")
    parser.add_argument("--settle", type=float, default=0.5, metavar="S",
                        help="seconds of pairs to discard first, while exposure settles (default 0.5)")
    parser.add_argument("--timeout", type=float, default=10.0, metavar="S",
                        help="give up if no pair arrives within this many seconds (default 10)")
    add_virtual_arguments(parser, "snap")
    parser.set_defaults(handler=snap_command)


def snap_command(args: argparse.Namespace) -> int:
    from trackerd.recording.cameras import open_cameras
    from trackerd.recording.outputs import output_folder

    loaded = load_rig(args.config)
    # Before the cameras open: a pair taken and then not saved is lost.
    folder = output_folder(args.out)
    name = args.name or f"snap-{dt.datetime.now():%Y%m%d-%H%M%S}"
    with open_cameras(loaded.config, virtual_motion=args.virtual, label="trackerd snap", prefix=args.prefix,
                      subnet=args.subnet) as cams:
        pair = _take(cams.source, args.settle, args.timeout)
        rig = cams.rig
        info = dict(cams.info)
    return save_snap(pair, rig, folder, name, info)


def _take(source, settle_s: float, timeout_s: float):
    """The first pair after ``settle_s`` seconds of pairs (CameraError if none comes in time)."""
    start = time.monotonic()
    deadline = start + settle_s + timeout_s
    while time.monotonic() < deadline:
        pair = source.next_pair(0.1)
        if pair is not None and time.monotonic() - start >= settle_s:
            return pair
    raise CameraError(f"no synchronized pair arrived within {timeout_s:g} s (see `trackerd cameras`)")


def save_snap(pair, rig, folder: Path, name: str, camera_info: dict[str, Any] | None = None) -> int:
    """Locate the pointer in ``pair``, write the files (trackerd.recording.snapshot), print what was found."""
    from trackerd.locator import Locator
    from trackerd.recording.outputs import output_folder
    from trackerd.recording.snapshot import write_snapshot

    formats = [frame.pixel_format for frame in pair.frames]
    locator = Locator(rig, pixel_formats=formats)
    fix = locator.locate(pair.images)
    output_folder(folder)
    written = write_snapshot(pair, fix, locator, rig, folder, name, camera_info, say=print)
    print(f"  details: {written[-1]}", file=sys.stderr)
    return 0
