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

When the daemon is running it holds the cameras (a GigE Vision camera has one
controller): snap then asks the daemon's console (where the rig's [console] says,
or --console ADDR) for a snapshot of the pair it is processing, which it saves on
its host, and downloads the files into OUT (`trackerd ctl snap` does the same).
The simulated cameras of --virtual are snap's own.
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from trackerd.cli._args import console_address
from trackerd.cli._cameras import add_virtual_arguments
from trackerd.config.loader import load_rig
from trackerd.errors import CameraError

if TYPE_CHECKING:  # types only: the command imports the acquisition stack when it runs
    from trackerd.acquisition.frame import FramePair
    from trackerd.acquisition.source import PairSource
    from trackerd.config.models import RigConfig


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "snap",
        help="take one synchronized pair, save it raw and annotated, print the detections and the hit",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--config", required=True, help="rig TOML file")
    parser.add_argument("out", metavar="OUT", help="folder to save into (created if missing)")
    parser.add_argument("--name", help="file name stem (default snap-<local time>)")
    parser.add_argument(
        "--settle",
        type=float,
        default=0.5,
        metavar="S",
        help="seconds of pairs to discard first, while exposure settles (default 0.5)",
    )
    parser.add_argument(
        "--timeout",
        type=float,
        default=10.0,
        metavar="S",
        help="give up if no pair arrives within this many seconds (default 10)",
    )
    parser.add_argument(
        "--console",
        type=console_address,
        metavar="ADDR",
        help="the running daemon's console HOST:PORT (default: the rig's [console] listen)",
    )
    add_virtual_arguments(parser, "snap")
    parser.set_defaults(handler=snap_command)


def snap_command(args: argparse.Namespace) -> int:
    from trackerd.cli._cameras import open_cameras
    from trackerd.recording.outputs import output_folder

    loaded = load_rig(args.config)
    # Before the cameras open: a pair taken and then not saved is lost.
    folder = output_folder(args.out)
    if not args.virtual:
        from trackerd.console.client import ConsoleClient

        client = ConsoleClient.for_rig(loaded.config, args.console)
        info = client.find()
        if info is not None and client.runs_cameras_of(info, loaded.config):
            print(
                f"trackerd snap: the daemon is running and holds the cameras; taking the snapshot from it"
                f" ({client.base})",
                file=sys.stderr,
            )
            answer = client.snapshot_into(folder, args.name)
            for entry in answer["files"]:
                print(f"  saved {folder / entry['name']}")
            return 0
    name = args.name or f"snap-{dt.datetime.now():%Y%m%d-%H%M%S}"
    with open_cameras(
        loaded.config, virtual_motion=args.virtual, label="trackerd snap", prefix=args.prefix, subnet=args.subnet
    ) as cams:
        pair = _take(cams.source, args.settle, args.timeout)
        rig = cams.rig
        info = dict(cams.info)
    return save_snap(pair, rig, folder, name, info)


def _take(source: PairSource, settle_s: float, timeout_s: float) -> FramePair:
    """The first pair after ``settle_s`` seconds of pairs (CameraError if none comes in time)."""
    start = time.monotonic()
    deadline = start + settle_s + timeout_s
    while time.monotonic() < deadline:
        pair = source.next_pair(0.1)
        if pair is not None and time.monotonic() - start >= settle_s:
            return pair
    raise CameraError(f"no synchronized pair arrived within {timeout_s:g} s (see `trackerd cameras`)")


def save_snap(
    pair: FramePair, rig: RigConfig, folder: Path, name: str, camera_info: dict[str, Any] | None = None
) -> int:
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
