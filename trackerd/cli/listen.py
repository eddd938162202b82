"""`trackerd listen`: subscribe to a running trackerd and print what it publishes.

One line per message, for operators and application developers::

    hit      #1234  x 1.234 m  y 0.567 m  (2951, 733 px)  on wall  +-1.8 mm  raw 1.235, 0.566 m  gap 0.9 mm

(``raw``: the unsmoothed position, while the daemon smooths hits), or, with --json, each payload as one
JSON line (pipe it into jq). CURVE keys come
from --server-key/--client-key or from the rig file given with --config.
Exit status: 0 after --count messages or on Ctrl-C; 1 when --timeout passes
without a message. On stderr it says where it listens, and, when nothing at all
arrives for a few status periods, what to check.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any, NamedTuple

import zmq

from trackerd.errors import ConfigError, TrackerdError
from trackerd.publish.curve_keys import load_curve_key_pair, load_curve_public_key
from trackerd.publish.messages import SCHEMA_MAJOR, TOPICS

DEFAULT_ENDPOINT = "tcp://127.0.0.1:5560"
DEFAULT_STATUS_INTERVAL_S = 1.0
"""The daemon's status period when no rig file says otherwise ([outputs.zmq] status_interval_ms)."""
SILENT_STATUS_PERIODS = 5
"""Status periods without any message (and at least that many seconds) before the hint: a running
daemon publishes a status every period, so that much silence means nothing is reaching us."""


class ListenTimeout(TrackerdError):
    """Nothing arrived within --timeout."""


class NotTrackerd(TrackerdError):
    """What arrives is not trackerd's messages (two frames: an ASCII topic, a JSON object)."""


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "listen",
        help="subscribe to trackerd's messages and print them",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--endpoint", help=f"where trackerd publishes (default: from --config, else {DEFAULT_ENDPOINT})"
    )
    parser.add_argument("--config", help="rig TOML file: take the endpoint and the server's CURVE key from it")
    parser.add_argument(
        "--topic",
        action="append",
        metavar="T",
        help=f"only this topic (repeatable; default: all). Topics: {', '.join(TOPICS)}",
    )
    parser.add_argument("--count", type=int, metavar="N", help="exit after N messages")
    parser.add_argument("--json", action="store_true", help="print each payload as one JSON line")
    parser.add_argument("--timeout", type=float, metavar="S", help="exit 1 if S seconds pass without a message")
    parser.add_argument("--server-key", metavar="FILE", help="the daemon's CURVE public key (server.key)")
    parser.add_argument(
        "--client-key",
        metavar="FILE",
        help="this subscriber's CURVE key pair (.key_secret); default: a throwaway pair,"
        " enough when the daemon accepts any client",
    )
    parser.set_defaults(handler=listen_command)


def listen_command(args: argparse.Namespace) -> int:
    if args.count is not None and args.count < 1:
        raise ConfigError("--count must be 1 or more")
    if args.timeout is not None and args.timeout <= 0:
        raise ConfigError("--timeout must be a positive number of seconds")
    for topic in args.topic or []:
        if not any(known.startswith(topic) for known in TOPICS):
            # ZeroMQ matches topics by prefix, so a typo ('hits') would wait for ever in silence.
            raise ConfigError(f"--topic {topic}: trackerd publishes no such topic; topics: {', '.join(TOPICS)}")
    endpoint, server_key, status_interval_s = _target(args)
    _check_connectable(endpoint, "--endpoint" if args.endpoint else f"{args.config}: outputs.zmq.endpoints")
    context = zmq.Context()
    sub = context.socket(zmq.SUB)
    sub.setsockopt(zmq.LINGER, 0)
    # IPv6 endpoints (tcp://[::1]:5560) need it; IPv4 ones still work.
    sub.setsockopt(zmq.IPV6, 1)
    try:
        if server_key is not None:
            client = load_curve_key_pair(Path(args.client_key)) if args.client_key else zmq.curve_keypair()
            sub.setsockopt(zmq.CURVE_SERVERKEY, server_key)
            sub.setsockopt(zmq.CURVE_PUBLICKEY, client[0])
            sub.setsockopt(zmq.CURVE_SECRETKEY, client[1])
        elif args.client_key:
            raise ConfigError("--client-key needs --server-key (or a --config with curve_secret_key_file)")
        for topic in args.topic or [""]:
            sub.setsockopt(zmq.SUBSCRIBE, topic.encode("ascii"))
        if args.topic and not any("status".startswith(topic) for topic in args.topic):
            # Heard, never printed or counted: the daemon's heartbeat tells a quiet daemon (no hit
            # while nobody points) from no daemon at all, whatever the topics asked for.
            sub.setsockopt(zmq.SUBSCRIBE, b"status")
        try:
            sub.connect(endpoint)
        except zmq.ZMQError as err:
            raise ConfigError(f"--endpoint {endpoint}: {err.strerror}") from err
        topics = ", ".join(args.topic) if args.topic else "all topics"
        curve = " (CURVE)" if server_key is not None else ""
        print(
            f"trackerd listen: listening to {endpoint}{curve} for {topics}; Ctrl-C to stop", file=sys.stderr, flush=True
        )
        return _receive(sub, args, endpoint, silence_hint(endpoint, server_key is not None, status_interval_s))
    except KeyboardInterrupt:
        return 0
    finally:
        sub.close()
        context.term()


def _check_connectable(endpoint: str, given_by: str) -> None:
    """ConfigError for a tcp endpoint a subscriber cannot connect to: ZeroMQ takes tcp://HOST:99999 and
    waits in silence (the port is checked where the daemon binds, not here)."""
    scheme, _, rest = endpoint.partition("://")
    if scheme != "tcp":
        return
    host, colon, port = rest.rpartition(":")
    if not colon or not host or not (port.isdigit() and 1 <= int(port) <= 65535):
        raise ConfigError(f"{given_by} {endpoint}: connect to tcp://HOST:PORT, PORT a number from 1 to 65535")


def _target(args: argparse.Namespace) -> tuple[str, bytes | None, float]:
    """Endpoint, server public key and the daemon's status period, from the options, falling back
    on the rig file."""
    endpoint, server_key, status_interval_s = args.endpoint, None, DEFAULT_STATUS_INTERVAL_S
    if args.config:
        from trackerd.config.loader import load_rig  # the rig's models: only when a rig file is given

        zmq_config = load_rig(args.config).config.outputs.zmq
        status_interval_s = zmq_config.status_interval_ms / 1000.0
        if endpoint is None:
            endpoint = connectable_endpoint(zmq_config.endpoints[0])
        if zmq_config.curve_secret_key_file is not None and not args.server_key:
            secret = Path(zmq_config.curve_secret_key_file)
            public = secret.with_suffix(".key") if secret.suffix == ".key_secret" else secret
            server_key = load_curve_public_key(public if public.exists() else secret)
    if args.server_key:
        server_key = load_curve_public_key(Path(args.server_key))
    return endpoint or DEFAULT_ENDPOINT, server_key, status_interval_s


def connectable_endpoint(endpoint: str) -> str:
    """A bind endpoint as a local subscriber connects to it ('*' and 0.0.0.0 mean this host)."""
    for wildcard in ("tcp://*:", "tcp://0.0.0.0:"):
        if endpoint.startswith(wildcard):
            return "tcp://127.0.0.1:" + endpoint[len(wildcard) :]
    if endpoint.startswith("tcp://[::]:"):
        return "tcp://[::1]:" + endpoint[len("tcp://[::]:") :]
    return endpoint


class Hint(NamedTuple):
    """What to say on stderr when nothing has arrived ``after_s`` seconds after connecting."""

    text: str
    after_s: float


def silence_hint(endpoint: str, curve: bool, status_interval_s: float) -> Hint:
    """The line to print when nothing at all has arrived for a few status periods: the three usual
    reasons, each with what to check."""
    after_s = max(float(SILENT_STATUS_PERIODS), SILENT_STATUS_PERIODS * status_interval_s)
    keys = (
        "is --server-key the daemon's public key, and does the daemon accept this client's key?"
        if curve
        else "does the daemon use CURVE (then --server-key FILE, or --config with its rig file)?"
    )
    text = (
        f"trackerd listen: nothing from {endpoint} in {after_s:g} s, though a running trackerd publishes"
        f" a status every {status_interval_s:g} s: is the daemon running (systemctl status trackerd)?"
        f" is {endpoint} the endpoint in the rig's [outputs.zmq]? {keys}"
    )
    return Hint(text, after_s)


def _receive(sub: zmq.Socket, args: argparse.Namespace, endpoint: str, hint: Hint) -> int:
    received = 0
    warned_version = False
    started = last_message = time.monotonic()
    hint_due = True  # until anything at all arrives (the heartbeat too), or the hint is printed
    wanted = tuple(args.topic or [""])
    while args.count is None or received < args.count:
        # A short poll keeps Ctrl-C responsive and lets the timeout be checked.
        frames = sub.recv_multipart() if sub.poll(200) else None
        topic = frames[0].decode("ascii", errors="replace") if frames else ""
        if frames:
            hint_due = False
        if frames is None or not topic.startswith(wanted):
            # Nothing, or the heartbeat subscribed for the hint's sake (neither printed nor counted,
            # and checked here too: statuses arriving faster than the poll would hide the timeout).
            now = time.monotonic()
            if hint_due and now - started >= hint.after_s:
                print(hint.text, file=sys.stderr, flush=True)
                hint_due = False
            if args.timeout is not None and now - last_message > args.timeout:
                raise ListenTimeout(
                    f"no message from {endpoint} within {args.timeout:g} s"
                    " (is trackerd running there, publishing these topics, with matching CURVE keys?)"
                )
            continue
        last_message = time.monotonic()
        received += 1
        data = _message(frames, endpoint)
        if args.json:
            print(frames[1].decode("utf-8"), flush=True)
            continue
        version = str(data.get("schema_version", "?"))
        if version.split(".")[0] != str(SCHEMA_MAJOR) and not warned_version:
            print(
                f"trackerd listen: messages are schema {version}; this trackerd reads {SCHEMA_MAJOR}.x,"
                " so fields may be missing below",
                file=sys.stderr,
            )
            warned_version = True
        print(format_message(topic, data), flush=True)
    return 0


def _message(frames: list[bytes], endpoint: str) -> dict[str, Any]:
    """A message's JSON object; NotTrackerd when the frames are not a trackerd message. Something else that
    answers at the endpoint (the console's HTTP port, another program) can look like a publisher to ZeroMQ,
    which then hands its bytes over as messages: garbage printed as hits, and --json lines that are not JSON."""
    why = None
    if len(frames) != 2:
        why = f"{len(frames)} frames, not a topic and a payload"
    else:
        try:
            data = json.loads(frames[1])
        except ValueError:
            why = f"a payload that is not JSON ({frames[1][:40]!r})"
        else:
            if isinstance(data, dict):
                return data
            why = "a payload that is not a JSON object"
    raise NotTrackerd(
        f"{endpoint} sends messages that are not trackerd's ({why}); is it the daemon's ZeroMQ endpoint"
        " ([outputs.zmq] endpoints), not its console?"
    )


# --------------------------------------------------------------------------- formatting


def format_message(topic: str, data: dict[str, Any]) -> str:
    """One readable line for a message; tolerant of missing and unknown fields (an event without
    the field its line is built around is printed raw, like an unknown topic)."""
    head = f"{topic:<8} #{data.get('sequence', '?')}"
    formatter = {
        "hit": _hit,
        "pointer": _pointer,
        "status": _status,
        "enter": _enter,
        "leave": _leave,
        "dwell": _dwell,
        "gesture": _gesture,
        "command": _command,
        "hand": _hand,
    }.get(topic)
    line = None
    if formatter is not None:
        try:
            line = formatter(data)
        except (TypeError, ValueError, KeyError, IndexError):
            return f"{head}  {json.dumps(data, separators=(',', ':'))}"
    if line is None:
        envelope = {"schema_version", "topic", "sequence", "capture_ns", "publish_ns"}
        rest = {k: v for k, v in data.items() if k not in envelope}
        return f"{head}  {json.dumps(rest, separators=(',', ':'))}"
    return f"{head}  {line}"


def _num(value: Any, fmt: str, unit: str = "") -> str:
    return "?" if value is None else f"{value:{fmt}}{unit}"


def _hit(d: dict[str, Any]) -> str:
    parts = [f"x {_num(d.get('wall_x_m'), '.3f', ' m')}", f"y {_num(d.get('wall_y_m'), '.3f', ' m')}"]
    if d.get("display_x_px") is not None and d.get("display_y_px") is not None:
        parts.append(f"({d['display_x_px']:.0f}, {d['display_y_px']:.0f} px)")
    parts.append("on wall" if d.get("on_wall") else "off wall")
    if d.get("uncertainty_mm") is not None:
        parts.append(f"+-{d['uncertainty_mm']:.1f} mm")
    if d.get("raw_wall_x_m") is not None and d.get("raw_wall_y_m") is not None:
        parts.append(f"raw {d['raw_wall_x_m']:.3f}, {d['raw_wall_y_m']:.3f} m")
    parts.append(f"gap {_num(d.get('ray_gap_mm'), '.1f', ' mm')}")
    return "  ".join(parts)


def _where(d: dict[str, Any]) -> str:
    text = f"x {_num(d.get('wall_x_m'), '.3f', ' m')}  y {_num(d.get('wall_y_m'), '.3f', ' m')}"
    if d.get("display_x_px") is not None and d.get("display_y_px") is not None:
        text += f"  ({d['display_x_px']:.0f}, {d['display_y_px']:.0f} px)"
    return text


def _enter(d: dict[str, Any]) -> str | None:
    if "cursor_id" not in d:
        return None
    return f"cursor {d['cursor_id']}  {_where(d)}"


def _leave(d: dict[str, Any]) -> str | None:
    if "cursor_id" not in d:
        return None
    after = _num(d.get("duration_ms"), ".0f", " ms")
    return f"cursor {d['cursor_id']}  {d.get('reason', '?')}  after {after}  {_where(d)}"


def _dwell(d: dict[str, Any]) -> str | None:
    if "cursor_id" not in d:
        return None
    return f"cursor {d['cursor_id']}  {_num(d.get('dwell_ms'), '.0f', ' ms')}  {_where(d)}"


def _gesture(d: dict[str, Any]) -> str | None:
    if "name" not in d:
        return None
    text = (
        f"{d['name']}  score {_num(d.get('score'), '.2f')}  {_num(d.get('duration_ms'), '.0f', ' ms')}"
        f"  {_num(d.get('path_m'), '.2f', ' m')}  cursor {d.get('cursor_id', '?')}  {_where(d)}"
    )
    if d.get("runner_up"):
        text += f"  (next: {d['runner_up']} {_num(d.get('runner_up_score'), '.2f')})"
    return text


def _command(d: dict[str, Any]) -> str | None:
    if "command" not in d:
        return None
    text = f"{d['command']}  <- {d.get('trigger', '?')}"
    if d.get("wall_x_m") is not None:
        text += f"  {_where(d)}"
    return text


def _hand(d: dict[str, Any]) -> str | None:
    if "fingers" not in d:
        return None
    state = "" if d.get("present", True) else "  gone"
    return (
        f"{d['fingers']} fingers (now {d.get('fingers_now', '?')})  {d.get('camera', '?')}"
        f"  ({_num(d.get('image_x_px'), '.0f')}, {_num(d.get('image_y_px'), '.0f')} px){state}"
    )


def _vec(values: Any) -> str:
    return "(" + ", ".join(f"{v:.3f}" for v in values) + ")"


def _pointer(d: dict[str, Any]) -> str:
    return "  ".join(
        [
            str(d.get("status", "?")),
            f"front {_vec(d['front_m'])} m",
            f"back {_vec(d['back_m'])} m",
            f"length {d['length_m'] * 1000:.0f} mm",
            f"gaps {_num(d.get('front_gap_mm'), '.1f')}/{_num(d.get('back_gap_mm'), '.1f')} mm",
        ]
    )


def _status(d: dict[str, Any]) -> str:
    parts = [str(d.get("state", "?")), f"up {_duration(d.get('uptime_s'))}"]
    for cam in d.get("cameras", []):
        text = f"{cam.get('id', '?')} {cam.get('state', '?')} {_num(cam.get('frame_rate_hz'), '.1f', ' Hz')}"
        drops = sum((cam.get("dropped") or {}).values())
        if drops:
            text += f" drops {drops}"
        parts.append(text)
    pairing = d.get("pairing") or {}
    text = f"pairs {_num(pairing.get('pair_rate_hz'), '.1f', ' Hz')}"
    if pairing.get("skew_p99_us") is not None:
        text += f" skew p99 {pairing['skew_p99_us']:.0f} us"
    parts.append(text)
    latency = d.get("latency") or {}
    if latency.get("samples"):
        parts.append(f"latency p50 {_num(latency.get('p50_ms'), '.1f')} p99 {_num(latency.get('p99_ms'), '.1f')} ms")
    if d.get("version"):
        parts.append(f"v{d['version']}")
    if d.get("detail") and d["detail"] != d.get("state"):  # "stopping (stopping)" says it twice
        parts.append(f"({d['detail']})")
    warning = (d.get("colours") or {}).get("warning")
    if warning:
        parts.append(f"COLOUR WARNING: {warning}")
    return "  ".join(parts)


def _duration(seconds: Any) -> str:
    if seconds is None:
        return "?"
    seconds = int(seconds)
    if seconds < 120:
        return f"{seconds} s"
    if seconds < 7200:
        return f"{seconds // 60} min"
    return f"{seconds // 3600} h {seconds % 3600 // 60} min"
