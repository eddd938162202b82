"""`trackerd cpu-latency [--max-us N]`: hold the CPUs awake for as long as it runs (as root).

While it runs, no CPU sleeps in a state it would take more than N µs (default 0)
to leave, so a frame's arrival wakes the daemon at once; it ends the request
when it stops (SIGTERM, SIGINT). On a virtual machine this takes most of the
daemon's latency tail away; on any host it costs power, since idle CPUs poll.
The daemon's sandboxed service cannot make the request itself, so this runs
beside it as the trackerd-cpu-latency service (docs/deployment.md, "Wake-up
latency"). Under systemd it reports READY once the request is in force.
"""

from __future__ import annotations

import argparse
import signal

from trackerd.cpu_latency import MAX_REQUEST_US, current_us, held
from trackerd.sdnotify import SdNotify


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "cpu-latency",
        help="hold the CPUs awake (a PM QoS CPU latency request) until stopped; as root",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--max-us",
        type=_microseconds,
        default=0,
        help="longest a CPU may take to wake, in µs (default 0: idle CPUs poll and never halt)",
    )
    parser.set_defaults(handler=cpu_latency_command)


STOP_SIGNALS = frozenset({signal.SIGTERM, signal.SIGINT})


def cpu_latency_command(args: argparse.Namespace) -> int:
    # The stop signals are blocked from the start and then waited for with sigwait: a signal that
    # comes at any moment, even between READY and the wait, is kept pending and ends the wait at
    # once. A handler with time.sleep had a window: a SIGTERM landing after the last check for
    # signals and before the sleep began was seen only when the hour-long sleep ended (a test's
    # SIGTERM sent right after READY hung it on a loaded machine).
    previous_mask = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
    notifier = SdNotify()
    try:
        with held(args.max_us):
            in_force = current_us()
            text = f"CPU wake-up latency held at {args.max_us} µs"
            if in_force is not None and in_force < args.max_us:
                text += f" ({in_force} µs in force: another request is stricter)"
            print(f"trackerd cpu-latency: {text}; stop with Ctrl-C or SIGTERM", flush=True)
            notifier.ready(text)
            signal.sigwait(STOP_SIGNALS)
            notifier.stopping()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous_mask)
    return 0


def _microseconds(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a whole number of µs") from None
    if not 0 <= value <= MAX_REQUEST_US:
        raise argparse.ArgumentTypeError(f"{value}: give 0 to {MAX_REQUEST_US} µs")
    return value
