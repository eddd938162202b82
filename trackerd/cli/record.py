"""`trackerd record --config RIG OUT`: record the cameras' synchronized pairs, losslessly, for later replay.

Frames are stored in the cameras' own pixel format (Bayer stays Bayer) with
their frame ids and device and host timestamps, each pair's skew, and the rig
and calibration in force (docs/recording.md). The cameras are opened directly,
without tracking, so all the machine's time goes to acquisition and writing; a
writer thread takes the pairs through a bounded queue that drops its oldest
pair (counted) rather than make the cameras wait for the disk.

Stops after --seconds of recorded time or --pairs pairs, on Ctrl-C or SIGTERM,
or when the disk is full (what was written stays readable; exit status 1). A
progress line on stderr shows pairs written, rate, MB/s, drops and disk space.
--virtual MOTION records simulated cameras serving a rendered motion instead.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path

from trackerd.cli._args import console_address, positive_seconds
from trackerd.cli._cameras import add_virtual_arguments
from trackerd.config.loader import load_rig
from trackerd.config.models import RigConfig
from trackerd.errors import ConfigError, RecordingError


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "record",
        help="record synchronized camera pairs to a recording folder",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--config", required=True, help="rig TOML file")
    parser.add_argument("out", metavar="OUT", help="the new recording (a folder, by convention *.trec)")
    limit = parser.add_mutually_exclusive_group()
    limit.add_argument("--seconds", type=positive_seconds, help="stop after this many seconds of recorded time")
    limit.add_argument("--pairs", type=int, help="stop after this many pairs")
    parser.add_argument(
        "--compression",
        choices=("none", "deflate"),
        help="frame storage (default: the rig's [recording] compression, normally none)",
    )
    parser.add_argument(
        "--mode",
        choices=("raw", "compressed", "windowed"),
        help="raw, compressed (lossless zstd) or windowed (the tracker's windows over keyframes);"
        " default: the rig's [recording] mode, normally raw",
    )
    parser.add_argument(
        "--keyframe-interval",
        type=positive_seconds,
        metavar="S",
        help="compressed and windowed: a pair stored whole at least every S seconds (default 1)",
    )
    parser.add_argument(
        "--console",
        type=console_address,
        metavar="ADDR",
        help="the running daemon's console HOST:PORT (default: the rig's [console] listen)",
    )
    add_virtual_arguments(parser, "record")
    parser.set_defaults(handler=record_command)


def record_command(args: argparse.Namespace) -> int:
    from trackerd.cli._cameras import open_cameras
    from trackerd.cli._progress import ProgressLine, describe
    from trackerd.recording.outputs import check_new_recording
    from trackerd.recording.recorder import Recorder
    from trackerd.recording.writer import KEPT, check_free_space

    loaded = load_rig(args.config, for_tracking=False)  # the cameras are what it uses
    out = Path(args.out)
    if args.pairs is not None and args.pairs < 1:  # --seconds is checked by its argument type
        raise RecordingError("--pairs and --seconds must be positive")
    update: dict[str, object] = {"max_pairs": args.pairs, "max_duration_s": args.seconds}
    if args.compression:
        update["compression"] = args.compression
    if args.mode:
        update["mode"] = args.mode
    if args.keyframe_interval:
        update["keyframe_interval_s"] = args.keyframe_interval
    config = loaded.config.recording.model_copy(update=update)
    # Before the cameras open: where the recording goes, and room for it.
    check_new_recording(out)
    check_free_space(out, config.min_free_space_mb)
    if not args.virtual:
        _refuse_if_the_daemon_holds_the_cameras(loaded.config, args.config, args.console)

    stop = threading.Event()

    def on_signal(signum: int, _frame: object) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    progress = ProgressLine()
    recorder = None
    try:
        with open_cameras(
            loaded.config, virtual_motion=args.virtual, label="trackerd record", prefix=args.prefix, subnet=args.subnet
        ) as cams:
            # The recorder's failure is this command's error line below, not a log record as well.
            recorder = Recorder(
                out,
                cams.rig,
                producer="trackerd record",
                config=config,
                camera_info=cams.info,
                rig_file=loaded.path.resolve(),
                calibration_file=loaded.calibration_path,
                log_failure=False,
            ).start()
            print(
                f"trackerd record: recording {', '.join(c.id for c in cams.rig.cameras)} to {out} (Ctrl-C to stop)",
                file=sys.stderr,
                flush=True,
            )
            while not stop.is_set() and not recorder.done:
                pair = cams.source.next_pair(0.1)
                if pair is not None:
                    recorder.put(pair)
                if progress.due():
                    progress.show(describe(recorder.status(), cams.source.status().dropped_pairs))
            source_status = cams.source.status()
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if recorder is not None:
            # Everything queued is still written: the disk may need a moment after the cameras stop.
            recorder.stop(timeout_s=60.0)
        progress.done()
    status = recorder.status()
    kept = (
        f"{status.pairs} pairs ({status.recorded_s:.1f} s, {status.written_mb:.0f} MB) in {out}"
        if status.pairs
        else "nothing was recorded"
    )
    if recorder.error is not None:
        # One line: what stopped it and what was kept (readable: the partial pair is cut off).
        message = str(recorder.error).removesuffix(KEPT)
        if "nothing was recorded" not in message:
            message += f"{KEPT}: {kept}" if status.pairs else f"; {kept}"
        raise RecordingError(message)
    progress.show(describe(status, source_status.dropped_pairs), force=True)
    progress.done()
    if status.pairs == 0:
        raise RecordingError(f"{out}: no pair arrived from the cameras; nothing was recorded")
    print(
        f"trackerd record: {kept}; dropped: {status.dropped_pairs} pairs by the writer,"
        f" {source_status.dropped_pairs} pairs and {source_status.frames_dropped} unpaired frames at the cameras",
        file=sys.stderr,
    )
    return 0


def _refuse_if_the_daemon_holds_the_cameras(rig: RigConfig, rig_file: str, console: str | None) -> None:
    """RecordingError when a daemon runs this rig's cameras: a GigE Vision camera takes one controller, and
    opening it anyway failed deep in Aravis (a register write timing out). The daemon records itself."""
    from trackerd.console.client import ConsoleClient, ConsoleError

    try:
        client = ConsoleClient.for_rig(rig, console)
    except ConfigError:
        # The console's token file is the daemon's group's to read: ask without it (a daemon there answers
        # 401, which is refused below as a daemon that holds the cameras).
        client = ConsoleClient(console or rig.console.listen)
    try:
        info = client.find()
        held, who = info is not None and client.runs_cameras_of(info, rig), "the daemon is running"
    except ConsoleError:  # it answered, and wants a token: a daemon is running there
        held, who = True, "a daemon's console answers and wants its token: the daemon is likely running"
    if held:
        where = f" --console {console}" if console else ""
        raise RecordingError(
            f"{who} and holds the cameras ({client.base}); record from it:"
            f" `trackerd ctl --config {rig_file}{where} record start` with [recording] directory in its rig"
            " (docs/recording.md), or stop it first"
        )
