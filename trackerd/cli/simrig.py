"""`trackerd simrig --config RIG`: a virtual GigE Vision stereo rig serving a rendered pointer motion.

One simulated camera per camera of the rig, each in its own network namespace
(root) so it has its own address; trackerd, or any GigE Vision client, opens
them as it would the real cameras. With ``--measure`` this command also
acquires from them through trackerd's own pair source and prints the figures
(pair rate, drops, skew) of the run.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import time
from pathlib import Path
from types import FrameType
from typing import Any

import numpy as np

from trackerd.cli._args import positive_seconds
from trackerd.config.loader import load_rig
from trackerd.errors import TrackerdError
from trackerd.sim import netns
from trackerd.sim.motion import DEFAULT_PERIOD_S, MOTIONS


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "simrig",
        help="serve a rendered pointer motion from simulated GigE Vision cameras",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--config", required=True, help="rig TOML file, for example config/simulated.toml")
    parser.add_argument("--motion", default="sweep", choices=MOTIONS, help="scripted motion (default: sweep)")
    parser.add_argument(
        "--seconds", type=positive_seconds, default=None, help="stop after this long (default: until Ctrl-C)"
    )
    parser.add_argument("--out", type=Path, default=Path("simrig-out"), help="ground truth directory")
    parser.add_argument("--period", type=float, default=DEFAULT_PERIOD_S, help="motion period = loop length, s")
    parser.add_argument("--content-fps", type=float, default=30.0, help="rendered loop frames per second")
    parser.add_argument("--trigger", choices=["free_running", "software", "hardware"], help="override the rig's")
    add_network_options(parser)
    parser.add_argument("--synthetic", action="store_true", help="serve a moving square, no rendering")
    parser.add_argument("--measure", action="store_true", help="also acquire pairs and print the figures")
    parser.add_argument("--json", action="store_true", help="with --measure: print the figures as JSON")
    parser.add_argument(
        "--write-rig",
        type=Path,
        metavar="FILE",
        help="write the rig as the daemon must open it (the simulated cameras' addresses) to FILE,"
        " for `trackerd run --config FILE` in another terminal (default: OUT/daemon-rig.toml)",
    )
    parser.set_defaults(handler=simrig_command)


def add_network_options(parser: argparse.ArgumentParser) -> None:
    """--prefix, --subnet and --mtu of the virtual rig's network namespaces (simrig and demo)."""
    parser.add_argument(
        "--prefix",
        type=_prefix,
        default=netns.DEFAULT_PREFIX,
        help=f"network namespace name prefix (default {netns.DEFAULT_PREFIX}); one rig per prefix",
    )
    parser.add_argument(
        "--subnet",
        type=_subnet,
        default=netns.DEFAULT_SUBNET,
        help=f"addresses for the cameras' links (default {netns.DEFAULT_SUBNET})",
    )
    parser.add_argument(
        "--mtu",
        type=int,
        default=netns.DEFAULT_MTU,
        help=f"MTU of the cameras' links (default {netns.DEFAULT_MTU}: jumbo frames)",
    )


def _prefix(text: str) -> str:
    try:
        netns.plan(0, text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from err
    return text


def _subnet(text: str) -> str:
    import ipaddress

    try:
        network = ipaddress.ip_network(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"'{text}' is not a subnet such as {netns.DEFAULT_SUBNET}") from err
    if network.version != 4:
        raise argparse.ArgumentTypeError(f"'{text}' is not an IPv4 subnet")
    return text


class _Stop(Exception):
    """Raised by the SIGTERM handler so the rig is torn down like on Ctrl-C."""


def _on_sigterm(_signum: int, _frame: FrameType | None) -> None:
    raise _Stop


def simrig_command(args: argparse.Namespace) -> int:
    from trackerd.sim.rig import Network, VirtualRig

    rig = load_rig(args.config).config
    acq = rig.acquisition
    if args.trigger:
        acq = acq.model_copy(update={"trigger": args.trigger})
    rig = rig.model_copy(update={"acquisition": acq})
    missing = netns.netns_missing_reason()
    if missing and not args.measure:
        raise TrackerdError(
            f"simrig gives each simulated camera its own address with network namespaces, which needs"
            f" root ({missing}); without root, the tests and `--measure` use one GigE Vision camera on"
            " 127.0.0.1 plus Aravis's in-process Fake camera (docs/acquisition.md)"
        )
    network: Network = "netns" if not missing else "loopback"
    interrupted = False
    previous = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        virtual = VirtualRig(
            rig,
            motion=args.motion,
            period_s=args.period,
            content_fps=args.content_fps,
            network=network,
            prefix=args.prefix,
            subnet=args.subnet,
            mtu=args.mtu,
            out_dir=args.out,
            synthetic=args.synthetic,
        )
        log = sys.stderr if args.json else sys.stdout
        if not args.synthetic:
            print(f"preparing the '{args.motion}' loop ({args.period:g} s at {args.content_fps:g} fps)...", file=log)
        with virtual:
            print(describe(virtual), file=log, flush=True)
            if args.write_rig is not None or not args.measure:
                # The daemon must open the cameras as daemon_rig says (addresses, packet size,
                # trigger pacing), so the next step is always a written rig, never the rig file itself.
                written = args.write_rig if args.write_rig is not None else virtual.out_dir / "daemon-rig.toml"
                _write_rig(virtual.daemon_rig, written, Path(args.config))
                print(
                    f"the daemon on these cameras, in another terminal: trackerd run --config {written}",
                    file=log,
                    flush=True,
                )
            started = time.monotonic()
            try:
                if args.measure:
                    figures = measure(virtual, args.seconds or 60.0)
                    print(json.dumps(figures) if args.json else format_figures(figures))
                else:
                    _wait(args.seconds)
            except (_Stop, KeyboardInterrupt):
                interrupted = True  # what was served so far is still worth saying
            elapsed = time.monotonic() - started
        print(served_summary(virtual, elapsed), file=log)
    except (_Stop, KeyboardInterrupt):
        return 130
    finally:
        signal.signal(signal.SIGTERM, previous)
    return 130 if interrupted else 0


def _write_rig(rig: Any, path: Path, source: Path) -> None:
    """The daemon's view of the rig, loadable by `trackerd run --config` from anywhere."""
    from trackerd.config.loader import dump_rig

    if rig.calibration is not None:
        rig = rig.model_copy(update={"calibration": (source.parent / rig.calibration).resolve()})
    header = (
        f"Written by `trackerd simrig --config {source}`: the simulated cameras' addresses replace the\n"
        "serials, and acquisition settings are adapted to the simulated cameras (docs/acquisition.md)."
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(dump_rig(rig, header=header))


def _wait(seconds: float | None) -> None:
    deadline = None if seconds is None else time.monotonic() + seconds
    while deadline is None or time.monotonic() < deadline:
        time.sleep(0.2 if deadline is None else max(0.0, min(0.2, deadline - time.monotonic())))


def describe(virtual: Any) -> str:
    rig = virtual.daemon_rig
    lines = []
    if virtual.loop is not None:
        loop = virtual.loop
        source = f"rendered in {loop.rendered_s:.1f} s" if loop.rendered_s else "from the cache"
        lines.append(
            f"scene: '{virtual.motion}' loop of {loop.n_frames} frames per camera ({virtual.period_s:g} s at"
            f" {loop.content_fps:g} fps), {source}: {loop.directory}"
        )
    else:
        lines.append("scene: synthetic moving square")
    lines.append(
        f"serving at the frame rate the client sets (rig: {rig.acquisition.frame_rate_hz:g} fps,"
        f" {rig.acquisition.trigger}); each frame shows the loop frame of its capture instant"
    )
    for index, cam in enumerate(rig.cameras):
        where = cam.address or cam.device_id
        if virtual.network == "netns":
            net = virtual.nets[index]
            where = f"{net.camera_address} (namespace {net.namespace}, host side {net.host_address})"
        lines.append(
            f"  camera {cam.id}: serial {cam.serial or '-'} at {where}, {cam.width_px}x{cam.height_px}"
            f" {cam.pixel_format}"
        )
    lines.append(f"ground truth: {virtual.out_dir}/truth-<camera>.jsonl")
    return "\n".join(lines)


def served_summary(virtual: Any, elapsed_s: float) -> str:
    parts = []
    for index, cam in enumerate(virtual.rig.cameras):
        path = virtual.truth_path(index)
        count = sum(1 for _ in path.open()) if path.exists() else 0
        parts.append(f"{cam.id} {count} frames ({count / elapsed_s:.1f} fps)" if elapsed_s > 0 else cam.id)
    return f"served in {elapsed_s:.1f} s: " + ", ".join(parts)


def measure(virtual: Any, seconds: float) -> dict[str, Any]:
    """Acquire from the virtual rig through AravisPairSource for ``seconds``; the run's figures."""
    from trackerd.acquisition.live import AravisPairSource
    from trackerd.sim.gvcamera import read_tag

    source = AravisPairSource(virtual.daemon_rig, on_open=virtual.on_open)
    true_skews: list[float] = []
    pairs = 0
    with source:
        started = time.monotonic()
        deadline = started + seconds
        while time.monotonic() < deadline:
            pair = source.next_pair(0.5)
            if pair is None:
                continue
            pairs += 1
            tags = [read_tag(frame.image) for frame in pair.frames]
            if all(tag is not None for tag in tags):
                captures = [tag.capture_ns for tag in tags]  # type: ignore[union-attr]
                true_skews.append((max(captures) - min(captures)) / 1000.0)
        elapsed = time.monotonic() - started
        status = source.status()
    frames = sum(c.frames for c in status.cameras)
    in_pairs = pairs * len(status.cameras)
    failed = sum(sum(c.failed_buffers.values()) for c in status.cameras)
    true = np.array(true_skews) if true_skews else np.array([np.nan])
    return {
        "seconds": round(elapsed, 2),
        "trigger": status.trigger,
        "pairing": status.pairing,
        "pairs": pairs,
        "pair_rate_hz": round(pairs / elapsed, 2),
        "frames_per_camera": [c.frames for c in status.cameras],
        "frame_rate_hz": [round(c.frames / elapsed, 2) for c in status.cameras],
        "frames_not_paired": frames - in_pairs,
        "frame_drop_rate": round((frames - in_pairs) / frames, 4) if frames else None,
        "dropped_frames": status.dropped_frames,
        "dropped_pairs": status.dropped_pairs,
        "failed_buffers": failed,
        "skew_p50_us": _round(status.skew_p50_us),
        "skew_p99_us": _round(status.skew_p99_us),
        "true_skew_p50_us": _round(float(np.nanpercentile(true, 50))),
        "true_skew_p99_us": _round(float(np.nanpercentile(true, 99))),
        "stream": [c.stream for c in status.cameras],
    }


def _round(value: float | None) -> float | None:
    return None if value is None or np.isnan(value) else round(value, 1)


def format_figures(f: dict[str, Any]) -> str:
    return "\n".join(
        [
            f"acquired {f['seconds']:g} s ({f['trigger']}, paired by {f['pairing']}):",
            f"  pairs            {f['pairs']} ({f['pair_rate_hz']:g} per s)",
            f"  frames           {', '.join(str(n) for n in f['frames_per_camera'])} per camera"
            f" ({', '.join(f'{r:g}' for r in f['frame_rate_hz'])} fps)",
            f"  not paired       {f['frames_not_paired']} frames ({100 * (f['frame_drop_rate'] or 0):.2f} %):"
            f" {f['dropped_frames'] or 'none'}; pairs dropped unread {f['dropped_pairs']};"
            f" failed buffers {f['failed_buffers']}",
            f"  skew (estimated) median {f['skew_p50_us']} us, 99th percentile {f['skew_p99_us']} us",
            f"  skew (true)      median {f['true_skew_p50_us']} us, 99th percentile {f['true_skew_p99_us']} us"
            " (from the capture times stamped in the frames)",
        ]
    )
