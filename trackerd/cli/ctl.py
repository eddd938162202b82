"""`trackerd ctl --config RIG ACTION`: the console's actions against the running daemon.

The daemon serves its console where the rig's ``[console] listen`` says (--console ADDR
otherwise); this command makes the requests the page's buttons make:

  status            the daemon's state, cameras, pair rate and latency
  snap OUT          a snapshot from the running pipeline (raw frames, annotated views, JSON),
                    saved on the host and downloaded into the folder OUT
  record start|stop recording on demand (needs [recording] directory in the rig)
  check             a calibration check on the live pointer: wave it in view of both cameras

It fails with one line when no daemon answers there.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from trackerd.cli._args import console_address, positive_int, positive_seconds
from trackerd.config.loader import load_rig
from trackerd.errors import TrackerdError

if TYPE_CHECKING:
    from trackerd.console.client import ConsoleClient


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "ctl",
        help="the console's actions (snapshot, recording, calibration check, status) on the running daemon",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--config", required=True, help="rig TOML file the daemon runs with")
    parser.add_argument(
        "--console", type=console_address, metavar="ADDR", help="the daemon's console HOST:PORT (default: the rig's)"
    )
    actions = parser.add_subparsers(dest="action", required=True, metavar="ACTION")
    status = actions.add_parser("status", help="the daemon's state and figures")
    status.add_argument("--json", action="store_true", help="print the last status message as JSON")
    snap = actions.add_parser("snap", help="a snapshot from the running pipeline, downloaded into OUT")
    snap.add_argument("out", metavar="OUT", help="folder to save into (created if missing)")
    record = actions.add_parser("record", help="start or stop recording on demand")
    record.add_argument("what", choices=["start", "stop"])
    check = actions.add_parser("check", help="calibration check on the live pointer")
    check.add_argument("--fixes", type=check_fixes, default=200, help="fixes to measure, 20 to 5000 (default 200)")
    check.add_argument("--timeout", type=positive_seconds, default=120.0, help="give up after S seconds (default 120)")
    parser.set_defaults(handler=ctl_command)


def check_fixes(text: str) -> int:
    """``--fixes``: as many as the console takes for a check (it refused others only once asked)."""
    from trackerd.console.actions import CHECK_MAX_FIXES, MIN_CHECK_FIXES

    value = positive_int(text)
    if not MIN_CHECK_FIXES <= value <= CHECK_MAX_FIXES:
        raise argparse.ArgumentTypeError(f"must be from {MIN_CHECK_FIXES} to {CHECK_MAX_FIXES}, not {value}")
    return value


class NoDaemon(TrackerdError):
    """No trackerd console answers where the rig says."""


def connect(config: str, listen: str | None) -> tuple[ConsoleClient, dict[str, Any]]:
    from trackerd.console.client import ConsoleClient

    rig = load_rig(config).config
    client = ConsoleClient.for_rig(rig, listen)
    info = client.find()
    if info is None:
        raise NoDaemon(
            f"no trackerd daemon's console answers at {client.base} (is `trackerd run` running,"
            " with [console] enabled?)"
        )
    return client, info


def ctl_command(args: argparse.Namespace) -> int:
    client, info = connect(args.config, args.console)
    if args.action == "status":
        answer = client.get("/api/status")
        status = answer["status"]
        if args.json:
            print(json.dumps(answer, indent=2))
            return 0
        if status is None:
            print(f"{info['rig']}: no status yet")
            return 0
        cams = ", ".join(f"{c['id']} {c['state']} {c['frame_rate_hz']:.1f} fps" for c in status["cameras"])
        latency = status.get("processing") or {}
        print(f"{status['rig']}: {status['state']}" + (f" ({status['detail']})" if status.get("detail") else ""))
        print(f"  cameras: {cams}; pairs {status['pairing']['pair_rate_hz']:.1f}/s")
        if latency.get("p50_ms") is not None:
            print(f"  latency p50 {latency['p50_ms']:.2f} ms, p99 {latency['p99_ms']:.2f} ms")
        recording = status.get("recording")
        if recording is not None:
            what = ", ".join(
                filter(
                    None,
                    [
                        recording.get("path"),
                        f"{recording['pairs']} pairs" if recording.get("pairs") else None,
                        recording.get("detail"),
                    ],
                )
            )
            print(f"  recording: {recording['state']}" + (f" ({what})" if what else ""))
        return 0
    if args.action == "snap":
        answer = client.snapshot_into(Path(args.out))
        print(f"snapshot {answer['name']} from the running daemon (saved on its host in {answer['folder']}):")
        for entry in answer["files"]:
            print(f"  {Path(args.out) / entry['name']}")
        return 0
    if args.action == "record":
        answer = client.post(f"/api/recording/{args.what}")
        print(answer["message"])
        return 0
    answer = client.post(f"/api/check?fixes={args.fixes}")
    print(answer["message"], file=sys.stderr)
    deadline = time.monotonic() + args.timeout
    shown = -1
    while time.monotonic() < deadline:
        progress = client.get("/api/check")
        if progress["state"] == "done":
            print(progress["text"])
            return 1 if progress["figures"].get("suspect") else 0
        if progress.get("fixes", 0) // 25 != shown:
            shown = progress.get("fixes", 0) // 25
            print(f"  {progress.get('fixes', 0)} / {progress.get('wanted')} fixes", file=sys.stderr)
        time.sleep(0.5)
    raise TrackerdError(f"check: fewer than {args.fixes} fixes within {args.timeout:g} s (is the pointer in view?)")
