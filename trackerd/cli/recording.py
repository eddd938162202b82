"""`trackerd recording check|import|convert|export`: inspect, build and unpack recordings (docs/recording.md).

check PATH          how much of a recording is intact: pairs readable, recovered past the
                    index after a crash, damaged frames, each problem with its file and byte
import FOLDER OUT   a recording from a folder of image pairs (<name>-<camera>.png ...), with
                    timestamps from an optional CSV, so images from other tools can be replayed
convert REC OUT     the recording rewritten in another mode: compressed (lossless, zstd) or
                    windowed (the tracker's windows over keyframes; replays to the same hits)
export REC OUT      frames as viewable PNGs with the detections drawn, and hits.csv with one
                    row per pair: the hits `trackerd replay` publishes for the same recording
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING

from trackerd.cli._args import pair_number, positive_int, positive_seconds
from trackerd.config.loader import load_rig
from trackerd.errors import RecordingError
from trackerd.recording.reader import Recording

if TYPE_CHECKING:
    from trackerd.cli._progress import ProgressLine


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "recording",
        help="check, import and export recordings",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="recording_command", metavar="ACTION", required=True)

    check = sub.add_parser("check", help="report how much of a recording is intact")
    check.add_argument("path", metavar="PATH", help="a recording folder (*.trec)")
    check.add_argument("--no-verify", action="store_true", help="skip the frame checksums (headers only; fast)")
    check.add_argument("--json", action="store_true", help="print the report as one JSON object")
    check.set_defaults(handler=check_command)

    imp = sub.add_parser("import", help="build a recording from a folder of image pairs")
    imp.add_argument("folder", metavar="FOLDER", help="images named <name>-<camera>.<ext> (or <camera>/<name>.<ext>)")
    imp.add_argument("out", metavar="OUT", help="the new recording (a folder, by convention *.trec)")
    imp.add_argument("--config", required=True, help="rig TOML file the images come from (cameras, calibration)")
    timing = imp.add_mutually_exclusive_group()
    timing.add_argument(
        "--timestamps",
        metavar="CSV",
        help="CSV with name and timestamp_ns|_us|_ms|_s columns (optionally camera); in name order"
        " the times must increase",
    )
    timing.add_argument(
        "--rate",
        type=float,
        metavar="HZ",
        help="without --timestamps: the images are a real sequence at HZ pairs per second. Without"
        " either, they are unrelated stills 1 s apart (longer than the interaction's"
        " reset_after_ms, so each is smoothed on its own)",
    )
    imp.add_argument(
        "--compression",
        choices=("none", "deflate"),
        default="none",
        help="store frames raw (default) or deflated (lossless, smaller, slower to write)",
    )
    imp.add_argument(
        "--mode",
        choices=("raw", "compressed", "windowed"),
        default="raw",
        help="raw (default), compressed (lossless zstd) or windowed (docs/recording.md, Modes)",
    )
    imp.set_defaults(handler=import_command)

    conv = sub.add_parser("convert", help="rewrite a recording in another mode (compressed, windowed, raw)")
    conv.add_argument("recording", metavar="REC", help="a recording folder (*.trec)")
    conv.add_argument("out", metavar="OUT", help="the new recording (a folder, by convention *.trec)")
    conv.add_argument("--mode", required=True, choices=("raw", "compressed", "windowed"), help="the new mode")
    conv.add_argument(
        "--keyframe-interval",
        type=positive_seconds,
        default=1.0,
        metavar="S",
        help="compressed and windowed: a pair stored whole at least every S seconds (default 1)",
    )
    conv.add_argument(
        "--margin", type=int, default=8, metavar="PX", help="windowed: pixels added around each window (default 8)"
    )
    conv.add_argument("--no-verify", action="store_true", help="skip the source's frame checksums")
    conv.set_defaults(handler=convert_command)

    exp = sub.add_parser("export", help="write viewable PNGs with detections drawn, and hits.csv")
    exp.add_argument("recording", metavar="REC", help="a recording folder (*.trec)")
    exp.add_argument("out", metavar="OUT", help="folder to write into (created if missing)")
    exp.add_argument("--config", help="rig TOML file to use instead of the recorded rig")
    exp.add_argument(
        "--every", type=positive_int, default=1, metavar="N", help="write images of every N-th pair (default 1)"
    )
    exp.add_argument("--first", type=pair_number, default=0, metavar="N", help="start at pair N (default 0)")
    exp.add_argument("--count", type=positive_int, metavar="N", help="export N pairs (default: to the end)")
    exp.add_argument("--no-images", action="store_true", help="write hits.csv only")
    exp.set_defaults(handler=export_command)


def _progress(label: str) -> tuple[ProgressLine, Callable[[int, int], None]]:
    from trackerd.cli._progress import ProgressLine

    line = ProgressLine()

    def show(done: int, total: int) -> None:
        line.show(f"{label}: {done}/{total} pairs", force=done == total)

    return line, show


def check_command(args: argparse.Namespace) -> int:
    from trackerd.recording.check import check_recording, format_report

    with Recording.open(args.path) as recording:
        line, show = _progress("checking")
        report = check_recording(recording, verify=not args.no_verify, progress=show)
        line.done()
    print(json.dumps(report.to_dict(), indent=2) if args.json else format_report(report))
    return 0 if report.intact else 1


def import_command(args: argparse.Namespace) -> int:
    from trackerd.recording.importer import import_folder
    from trackerd.recording.outputs import check_new_recording

    loaded = load_rig(args.config, for_tracking=False)  # the cameras are what it uses
    check_new_recording(args.out)
    line, show = _progress("importing")
    writer = import_folder(
        args.folder,
        args.out,
        loaded.config,
        timestamps=args.timestamps,
        rate_hz=args.rate,
        compression=args.compression,
        rig_file=loaded.path,
        progress=show,
        mode=args.mode,
    )
    line.done()
    formats = ", ".join(f"{c.id} {c.pixel_format} {c.width_px}x{c.height_px}" for c in writer.metadata.cameras)
    print(
        f"{writer.path}: {writer.pairs} pairs imported from {args.folder} ({formats}), {writer.data_bytes / 1e6:.1f} MB"
    )
    return 0


def convert_command(args: argparse.Namespace) -> int:
    from trackerd.recording.convert import convert_recording
    from trackerd.recording.outputs import check_new_recording

    if not 0 <= args.margin <= 256:
        raise RecordingError(f"--margin {args.margin}: must be 0 to 256 pixels")
    with Recording.open(args.recording) as recording:
        check_new_recording(args.out)
        for problem in recording.problems:
            print(f"trackerd recording convert: warning: {problem}", file=sys.stderr)
        line, show = _progress("converting")
        summary = convert_recording(
            recording,
            args.out,
            args.mode,
            keyframe_interval_s=args.keyframe_interval,
            window_margin_px=args.margin,
            verify=not args.no_verify,
            progress=show,
        )
        line.done()
    for problem in summary.skipped:
        print(f"trackerd recording convert: error: {problem}", file=sys.stderr)
    writer = summary.writer
    keys = ""
    if writer.mode != "raw":
        reasons = f" ({', '.join(f'{k} {v}' for k, v in summary.keyframes.items())})" if summary.keyframes else ""
        keys = f", {writer.keyframes} keyframes{reasons}"
    print(
        f"{writer.path}: {writer.pairs} pairs, {writer.mode}{keys}, {writer.data_bytes / 1e6:.1f} MB"
        f" ({summary.source_bytes / max(writer.data_bytes, 1):.1f}x smaller than {args.recording})"
    )
    return 1 if summary.skipped else 0


def export_command(args: argparse.Namespace) -> int:
    from trackerd.recording.export import export_recording
    from trackerd.recording.outputs import output_folder
    from trackerd.recording.replay_rig import replay_rig

    with Recording.open(args.recording) as recording:
        rig, notes = replay_rig(recording, args.config, None)
        # Before any pair is exported: a folder that cannot be written is one line, not a traceback.
        output_folder(args.out)
        for problem in recording.problems:
            print(f"trackerd recording export: warning: {problem}", file=sys.stderr)
        for note in notes:
            print(f"  {note}", file=sys.stderr)
        line, show = _progress("exporting")
        summary = export_recording(
            recording,
            args.out,
            rig,
            every=args.every,
            first=args.first,
            count=args.count,
            images=not args.no_images,
            progress=show,
        )
        line.done()
    for problem in summary.skipped:
        print(f"trackerd recording export: error: {problem}", file=sys.stderr)
    print(
        f"{summary.csv_path}: {summary.pairs} pairs ({', '.join(f'{k} {v}' for k, v in summary.statuses.items())});"
        f" {summary.images} images in {args.out}"
    )
    return 1 if summary.skipped else 0
