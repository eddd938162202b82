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

from trackerd.config.loader import load_rig
from trackerd.errors import RecordingError
from trackerd.sim.motion import MOTIONS


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "record", help="record synchronized camera pairs to a recording folder",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--config", required=True, help="rig TOML file")
    parser.add_argument("out", metavar="OUT", help="the new recording (a folder, by convention *.trec)")
    limit = parser.add_mutually_exclusive_group()
    limit.add_argument("--seconds", type=float, help="stop after this many seconds of recorded time")
    limit.add_argument("--pairs", type=int, help="stop after this many pairs")
    parser.add_argument("--compression", choices=("none", "deflate"),
                        help="frame storage (default: the rig's [recording] compression, normally none)")
    parser.add_argument("--virtual", metavar="MOTION", choices=MOTIONS,
                        help=f"record simulated cameras serving a rendered motion ({', '.join(MOTIONS)})")
    parser.set_defaults(handler=record_command)


def record_command(args: argparse.Namespace) -> int:
    from trackerd.recording.cameras import open_cameras
    from trackerd.recording.progress import ProgressLine, describe
    from trackerd.recording.recorder import Recorder

    loaded = load_rig(args.config)
    out = Path(args.out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise RecordingError(f"{out}: already exists; give a new name for the recording")
    if (args.pairs is not None and args.pairs < 1) or (args.seconds is not None and args.seconds <= 0):
        raise RecordingError("--pairs and --seconds must be positive")
    update: dict[str, object] = {"max_pairs": args.pairs, "max_duration_s": args.seconds}
    if args.compression:
        update["compression"] = args.compression
    config = loaded.config.recording.model_copy(update=update)

    stop = threading.Event()

    def on_signal(signum: int, _frame: object) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    progress = ProgressLine()
    recorder = None
    try:
        with open_cameras(loaded.config, virtual_motion=args.virtual, label="trackerd record") as cams:
            recorder = Recorder(out, cams.rig, producer="trackerd record", config=config, camera_info=cams.info,
                                rig_file=loaded.path.resolve(), calibration_file=loaded.calibration_path).start()
            print(f"trackerd record: recording {', '.join(c.id for c in cams.rig.cameras)} to {out}"
                  " (Ctrl-C to stop)", file=sys.stderr, flush=True)
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
    status = recorder.status()
    progress.show(describe(status, source_status.dropped_pairs), force=True)
    progress.done()
    frames_lost = source_status.frames_dropped
    print(f"trackerd record: {status.pairs} pairs ({status.recorded_s:.1f} s) in {out}, {status.written_mb:.0f} MB;"
          f" dropped: {status.dropped_pairs} pairs by the writer, {source_status.dropped_pairs} pairs and"
          f" {frames_lost} unpaired frames at the cameras", file=sys.stderr)
    if recorder.error is not None:
        raise recorder.error
    if status.pairs == 0:
        raise RecordingError(f"{out}: no pair arrived from the cameras; nothing was recorded")
    return 0
