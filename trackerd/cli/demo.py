"""`trackerd demo`: the whole system on one machine, with no cameras.

Starts the virtual GigE Vision rig (simulated cameras serving a rendered pointer
motion, as `trackerd simrig` does), runs the daemon on it exactly as `trackerd
run` runs on real cameras, and subscribes to its ZeroMQ output like any
application would, printing hits as they arrive, until Ctrl-C or --seconds.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
from collections.abc import Callable
from typing import Any

import zmq

from trackerd.cli._args import add_console_option, positive_seconds
from trackerd.cli.simrig import add_network_options
from trackerd.config.examples import example_rig
from trackerd.config.loader import load_rig, with_console, with_endpoints
from trackerd.config.models import RigConfig
from trackerd.sim import netns
from trackerd.sim.motion import MOTIONS


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "demo",
        help="run the daemon on simulated cameras and print the hits it publishes",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--config",
        default=str(example_rig("simulated")),
        help="rig to simulate (default: the bundled config/simulated.toml)",
    )
    parser.add_argument(
        "--motion", default="figure8", choices=MOTIONS, help="scripted pointer motion (default: figure8)"
    )
    parser.add_argument("--seconds", type=positive_seconds, help="stop after this long (default: until Ctrl-C)")
    parser.add_argument("--every", type=int, default=6, help="print one hit in this many (default 6: ten a second)")
    parser.add_argument(
        "--endpoint",
        help="publish here instead of the rig's endpoint, for example to run"
        " beside a daemon that has it: tcp://127.0.0.1:5561",
    )
    add_console_option(parser)
    add_network_options(parser)
    parser.set_defaults(handler=demo_command)


def demo_command(args: argparse.Namespace) -> int:
    from trackerd.acquisition.live import AravisPairSource
    from trackerd.cli.listen import connectable_endpoint, format_message
    from trackerd.cli.run import serve, zmq_publisher
    from trackerd.publish import Publisher, PublishError
    from trackerd.sim.rig import Network, VirtualRig

    rig = load_rig(args.config).config
    if args.endpoint is not None:
        rig = with_endpoints(rig, [args.endpoint])
    rig = with_console(rig, args.console)
    network: Network = "netns" if netns.netns_missing_reason() is None else "loopback"
    if network == "loopback" and rig.acquisition.trigger == "software":
        rig = rig.model_copy(update={"acquisition": rig.acquisition.model_copy(update={"trigger": "free_running"})})
    print(
        f"trackerd demo: preparing the '{args.motion}' motion for {len(rig.cameras)} simulated cameras"
        " (rendered once, then cached)...",
        file=sys.stderr,
        flush=True,
    )
    virtual_rig = VirtualRig(
        rig, motion=args.motion, network=network, prefix=args.prefix, subnet=args.subnet, mtu=args.mtu
    )
    with virtual_rig as virtual:
        daemon_rig = virtual.daemon_rig
        where = ", ".join(c.address or c.device_id or "?" for c in daemon_rig.cameras)
        print(f"trackerd demo: simulated GigE Vision cameras at {where}", file=sys.stderr)
        stop = threading.Event()
        summary: dict[str, Any] = {"hits": 0, "status": None, "busy_status": None}
        listeners: list[threading.Thread] = []

        def publisher_then_listener(r: RigConfig) -> Publisher:
            # The subscriber connects only once this daemon has bound its endpoint: connecting
            # before, it printed another daemon's hits there until this one failed to bind.
            publisher: Publisher = zmq_publisher(r)
            if not listeners:
                endpoint = connectable_endpoint(publisher.endpoints[0])
                listeners.append(
                    threading.Thread(
                        target=_listen, args=(endpoint, args.every, stop, summary, format_message), daemon=True
                    )
                )
                listeners[0].start()
            return publisher

        try:
            code = serve(
                daemon_rig,
                None,
                lambda r: AravisPairSource(r, on_open=virtual.on_open, wait_for_cameras=True),
                seconds=args.seconds,
                publisher_factory=publisher_then_listener,
                banner=f"trackerd demo: daemon publishing on {', '.join(daemon_rig.outputs.zmq.endpoints)};"
                " hits below (Ctrl-C to stop)",
            )
        except PublishError as err:
            if "in use" not in str(err):
                raise
            raise PublishError(f"{err}; to run beside the daemon there, give {_another_endpoint(daemon_rig)}") from err
        finally:
            stop.set()
            for listener in listeners:
                listener.join(2.0)
    _print_summary(summary)
    return code


def _another_endpoint(rig: Any) -> str:
    """An --endpoint next to the rig's first (the port after it), for a demo beside a daemon."""
    host, _, port = rig.outputs.zmq.endpoints[0].rpartition(":")
    if host.startswith("tcp://") and port.isdigit():
        return f"--endpoint {host}:{int(port) + 1}"
    return "another --endpoint"


def _listen(
    endpoint: str, every: int, stop: threading.Event, summary: dict[str, Any], fmt: Callable[[str, dict[str, Any]], str]
) -> None:
    """A subscriber like any application's: prints every ``every``-th hit and each status."""
    ctx = zmq.Context()
    sub = ctx.socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"hit")
    sub.setsockopt(zmq.SUBSCRIBE, b"status")
    sub.connect(endpoint)
    try:
        while not stop.is_set():
            if not sub.poll(100):
                continue
            topic, payload = sub.recv_multipart()
            data = json.loads(payload)
            name = topic.decode()
            if name == "hit":
                summary["hits"] += 1
                if summary["hits"] % max(every, 1) != 1 and every > 1:
                    continue
            else:
                summary["status"] = data
                summary["busy_status"] = quoted_status(summary.get("busy_status"), data)
            print(fmt(name, data), flush=True)
    finally:
        sub.close(0)
        ctx.term()


def _samples(status: dict[str, Any] | None) -> int:
    return int(((status or {}).get("processing") or {}).get("samples") or 0)


def quoted_status(quoted: dict[str, Any] | None, status: dict[str, Any]) -> dict[str, Any] | None:
    """The status whose latency the summary quotes, after ``status`` arrives: the last period that processed
    at least half as many pairs as the one quoted so far. The period that ends as the demo stops holds a
    handful (2-3 at 60 pairs/s), and its percentiles said little of the run's."""
    samples = _samples(status)
    if samples > 0 and 2 * samples >= _samples(quoted):
        return status
    return quoted


def _print_summary(summary: dict[str, Any]) -> None:
    print(f"trackerd demo: {summary_line(summary)}", file=sys.stderr)


def summary_line(summary: dict[str, Any]) -> str:
    """Hits received, the outcomes, and the daemon's processing latency of the status period
    :func:`quoted_status` kept (``busy_status``): the last that processed pairs, unless it held fewer than
    half as many as the one before it (the final statuses, sent while stopping, cover a few pairs or none).
    """
    status = summary.get("status") or {}
    fixes = status.get("fixes") or {}
    uptime = status.get("uptime_s") or 0.0
    outcomes = ", ".join(f"{name} {count}" for name, count in sorted(fixes.items())) or "none"
    line = f"{summary['hits']} hits received in {uptime:.0f} s; pairs processed by outcome: {outcomes}"
    busy = summary.get("busy_status")
    latency = (busy or {}).get("processing") or {}
    if latency.get("p50_ms") is None:
        return f"{line}; no pair was processed"
    return (
        f"{line}; the daemon's own processing latency (last frame of a pair received to hit published;"
        f" the status lines' latency counts from capture) p50 {latency['p50_ms']:.1f} ms,"
        f" p99 {latency['p99_ms']:.1f} ms over the {latency.get('samples', 0)} pairs of the last status period"
    )
