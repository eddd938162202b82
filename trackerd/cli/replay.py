"""`trackerd replay RECORDING`: run a recording through the daemon's pipeline and publish what it finds.

The recording takes the place of the cameras behind the same source interface,
and everything else is `trackerd run`: the same pipeline, extensions, ZeroMQ
publishing, signals and systemd notifications. Replaying the same recording
with the same configuration publishes the same messages, bit for bit, apart
from ``publish_ns`` (capture times are the recorded ones).

--speed 1.0 (the default) keeps the recorded pace, 2.0 twice as fast, and
--speed max as fast as the pipeline goes (the summary then gives the
throughput). By default the rig recorded with the frames is used; --config
replaces it (a newer calibration, other detector thresholds), and the output
says so. The frames' pixel formats and sizes always come from the recording.
The first pair is due --delay seconds after the replay starts up (the publisher
binds within it), so subscribers can connect first (ZeroMQ drops what is
published before they are connected).
A replay does not reload its configuration on SIGHUP.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import TYPE_CHECKING, Any

from trackerd.cli._args import add_console_option, delay_seconds, pair_number, positive_int, positive_seconds
from trackerd.config.loader import with_console
from trackerd.config.models import RigConfig
from trackerd.recording.reader import Recording
from trackerd.recording.replay_rig import replay_rig

if TYPE_CHECKING:
    from trackerd.pipeline.daemon import Pipeline
    from trackerd.publish import Publisher
    from trackerd.recording.replay import ReplayPairSource


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "replay",
        help="replay a recording through the daemon's pipeline, publishing as `trackerd run` does",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("recording", metavar="RECORDING", help="a recording folder (*.trec)")
    parser.add_argument("--config", help="rig TOML file to use instead of the recorded rig")
    parser.add_argument(
        "--speed",
        type=parse_speed,
        default=1.0,
        metavar="S",
        help="1.0: recorded pace (default); 2.0: twice as fast; max: as fast as possible",
    )
    parser.add_argument("--loop", action="store_true", help="start again from the first pair at the end")
    parser.add_argument(
        "--passes",
        type=positive_int,
        metavar="N",
        help="loop, and stop after N passes over the recording (--loop alone: until stopped)",
    )
    parser.add_argument("--seconds", type=positive_seconds, help="stop after this many seconds (default: at the end)")
    parser.add_argument(
        "--endpoint",
        action="append",
        metavar="E",
        help="publish on this ZeroMQ endpoint instead of the rig's (repeatable)",
    )
    parser.add_argument(
        "--delay",
        type=delay_seconds,
        default=1.0,
        metavar="S",
        help="seconds from start-up (the publisher binds within them) to the first pair (default 1.0)",
    )
    parser.add_argument("--first", type=pair_number, default=0, metavar="N", help="start at pair N (default 0)")
    parser.add_argument("--count", type=positive_int, metavar="N", help="replay N pairs (default: to the end)")
    parser.add_argument(
        "--no-verify",
        action="store_true",
        help="skip the frame checksums (faster at --speed max; record headers are still checked)",
    )
    parser.add_argument(
        "--one-process",
        action="store_true",
        help="at --speed max, locate in the pipeline as at any other speed, not in a worker process"
        " ahead of it (the same hits, about half the rate; docs/recording.md, 'Replay speed')",
    )
    parser.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    add_console_option(parser)
    parser.set_defaults(handler=replay_command)


def parse_speed(text: str) -> float | None:
    """'max' -> None (as fast as possible), else a positive factor of the recorded pace."""
    if text.strip().lower() == "max":
        return None
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number or 'max'") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError("the speed must be a positive number (or 'max')")
    return value


def replay_command(args: argparse.Namespace) -> int:
    from trackerd.cli._progress import ProgressLine
    from trackerd.cli.run import serve, zmq_publisher
    from trackerd.recording.replay import ReplayPairSource

    recording = Recording.open(args.recording)
    for problem in recording.problems:
        print(f"trackerd replay: warning: {problem}", file=sys.stderr)
    rig, notes = replay_rig(recording, args.config, args.endpoint)
    rig = with_console(rig, args.console)
    source = ReplayPairSource(
        recording,
        speed=args.speed,
        loop=args.loop or args.passes is not None,
        verify=not args.no_verify,
        start_delay_s=args.delay,
        first=args.first,
        count=args.count,
        passes=args.passes,
        locate_with=None if args.one_process else rig,
    )
    pace = "max speed" if args.speed is None else f"{args.speed:g}x the recorded pace"
    meta = recording.metadata
    print(
        f"trackerd replay {recording.path}: pairs {source.first}-{source.stop_at - 1} of {len(recording)}"
        f" ({recording.duration_s:.1f} s recorded {meta.created_utc} by {meta.producer}), {pace}"
        + (f", {args.passes} passes" if args.passes else ", looping" if args.loop else ""),
        file=sys.stderr,
    )
    for note in notes:
        print(f"  {note}", file=sys.stderr)
    publishers: list[Publisher] = []
    progress = ProgressLine()
    total = (source.stop_at - source.first) * (args.passes or 1)  # a --loop without --passes: per pass

    def publisher_factory(r: RigConfig) -> Publisher:
        publishers.append(zmq_publisher(r))
        return publishers[-1]

    pipelines: list[Pipeline] = []

    def until(pipeline: Pipeline) -> bool:
        if not pipelines:
            pipelines.append(pipeline)
        if progress.due():
            hits = publishers[-1].counts.get("hit", 0) if publishers else 0
            rate = source.status().pair_rate_hz
            done = (
                f"{source.delivered}/{total}"
                if args.passes or not args.loop
                else f"{source.delivered} ({total} a pass)"
            )
            progress.show(f"replay: {done} pairs, {rate:.0f} pairs/s, {hits} hits, lag {source.lag_ms:.0f} ms")
        return source.finished and pipeline.pairs_processed >= source.delivered and pipeline.backlog <= 0

    code = serve(
        rig,
        None,
        lambda _r: source,
        seconds=args.seconds,
        publisher_factory=publisher_factory,
        clock_offset_ns=source.pipeline_clock_offset_ns(),
        until=until,
        replay=True,
    )
    progress.done()
    summary = _summary(source, publishers, recording)
    if pipelines:
        # Pairs processed but never handed to the publisher: its queue dropped them (should be 0).
        summary["dropped_before_publishing"] = pipelines[0].pairs_processed - pipelines[0].pairs_published
    for problem in source.problems:
        print(f"trackerd replay: error: {problem}", file=sys.stderr)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(_format(summary))
    recording.close()
    if code == 0 and source.failure is not None:
        return 1  # said above, among the problems
    if code == 0 and source.skipped:
        print(f"trackerd replay: {source.skipped} damaged pair(s) skipped (listed above)", file=sys.stderr)
        return 1
    return code


def _summary(source: ReplayPairSource, publishers: list[Publisher], recording: Recording) -> dict[str, Any]:
    counts: dict[str, int] = {}
    for publisher in publishers:
        for topic, n in publisher.counts.items():
            counts[topic] = counts.get(topic, 0) + n
    first, last = source.first_delivery_ns, source.last_delivery_ns
    elapsed = (last - first) / 1e9 if first is not None and last is not None else 0.0
    rate = (source.delivered - 1) / elapsed if elapsed > 0 else None
    return {
        "recording": str(recording.path),
        "pairs": source.delivered,
        "skipped_damaged": source.skipped,
        "messages": counts,
        "hits": counts.get("hit", 0),
        "seconds": round(elapsed, 3),
        "pair_rate_hz": None if rate is None else round(rate, 1),
        "speed": "max" if source.speed is None else source.speed,
        "max_lag_ms": round(source.max_lag_ms, 1),
        "finished": source.finished,
        "published_dropped": sum(p.dropped for p in publishers),
        "at": time.strftime("%Y-%m-%d %H:%M:%S"),
    }


def _format(s: dict[str, Any]) -> str:
    rate = "-" if s["pair_rate_hz"] is None else f"{s['pair_rate_hz']:.1f}"
    line = (
        f"replayed {s['pairs']} pairs in {s['seconds']:.2f} s ({rate} pairs/s"
        + (" at max speed" if s["speed"] == "max" else f", max lag {s['max_lag_ms']} ms")
        + ")"
        + f"; {s['hits']} hits, messages {s['messages']}"
    )
    if s["skipped_damaged"]:
        line += f"; {s['skipped_damaged']} damaged pairs skipped"
    return line
