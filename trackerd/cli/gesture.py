"""`trackerd gesture`: gesture templates: record your own, and list them with their gates.

    trackerd gesture record NAME [--examples 5] [--dir DIR] [--config RIG | --endpoint E | --from FILE]
    trackerd gesture list [--dir DIR] [--config RIG]

``record`` follows a running trackerd's ``hit`` messages (or a file of them, one
JSON payload per line, as ``trackerd listen --json --topic hit`` prints),
cuts the hit's path into strokes exactly as the daemon does (a movement between
two pauses), and keeps each stroke as an example. Draw the gesture, hold still
a moment, and repeat. With the examples it writes ``DIR/NAME.json``
(docs/interaction.md: the template format), adding to the examples already
there; the daemon loads it from ``[interaction.gestures] template_dir`` on its
next start or reload. Each example is also matched against the templates
already known, so a gesture too like an existing one is flagged, and against
the gesture's other examples: one the recogniser would not take for them (a
swipe among circles) is refused, and recording goes on. The directory is made
and tried with a file before recording starts.

Exit status: 0 when the template was written; 1 when too few strokes arrived
before --timeout (or in --from), or the directory cannot be written; 2 for bad
arguments.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TypeVar

import numpy as np

from trackerd.config.interaction import RESERVED_TRIGGERS, InteractionConfig
from trackerd.config.loader import load_rig
from trackerd.errors import ConfigError, TrackerdError
from trackerd.interaction.recognizer import Shape, prepare, score_all, score_shape
from trackerd.interaction.smoothing import OneEuroFilter
from trackerd.interaction.strokes import Stroke, StrokeSegmenter
from trackerd.interaction.templates import (
    BUILTIN_DIR,
    NAME_PATTERN,
    Template,
    load_directory,
    load_templates,
    save_template,
    stroke_features,
    template_from_strokes,
)

DEFAULT_ENDPOINT = "tcp://127.0.0.1:5560"
T = TypeVar("T")


class RecordTimeout(TrackerdError):
    """Not enough strokes arrived in time."""


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "gesture",
        help="record and list gesture templates",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="gesture_command", metavar="COMMAND", required=True)
    record = sub.add_parser("record", help="record examples of a gesture into a template")
    record.add_argument("name", help="the gesture's name (letters, digits, _ and -), e.g. zigzag")
    record.add_argument("--examples", type=int, default=5, help="strokes to record (default 5)")
    record.add_argument("--dir", help="template directory (default: the rig's template_dir)")
    record.add_argument("--config", help="rig file: endpoint, template_dir and stroke settings from it")
    record.add_argument(
        "--endpoint", help=f"where trackerd publishes (default: from --config, else {DEFAULT_ENDPOINT})"
    )
    record.add_argument(
        "--from",
        dest="from_file",
        metavar="FILE",
        help="read hit messages from FILE (JSON lines) instead of a running trackerd",
    )
    record.add_argument(
        "--rotation-invariant",
        action="store_true",
        help="the gesture may start anywhere and be drawn turned (like a circle)",
    )
    record.add_argument(
        "--max-rotation-deg",
        type=float,
        default=30.0,
        help="otherwise: how far a stroke may be turned and still match (default 30)",
    )
    record.add_argument("--timeout", type=float, default=120.0, help="give up after S seconds (default 120)")
    record.set_defaults(handler=record_command)
    listing = sub.add_parser("list", help="list the gesture templates the daemon would load")
    listing.add_argument("--dir", help="template directory (default: the rig's template_dir)")
    listing.add_argument("--config", help="rig file")
    listing.set_defaults(handler=list_command)


def _settings(args: argparse.Namespace) -> tuple[InteractionConfig, Path | None, str | None]:
    interaction, directory, endpoint = InteractionConfig(), None, None
    if args.config:
        rig = load_rig(args.config).config
        interaction = rig.interaction
        directory = interaction.gestures.template_dir
        from trackerd.cli.listen import connectable_endpoint

        endpoint = connectable_endpoint(rig.outputs.zmq.endpoints[0])
    if getattr(args, "dir", None):
        directory = Path(args.dir)
    return interaction, directory, endpoint


def list_command(args: argparse.Namespace) -> int:
    interaction, directory, _ = _settings(args)
    templates = load_templates(directory, builtin=interaction.gestures.builtin)
    for name, t in sorted(templates.items()):
        where = "built-in" if Path(t.source).parent == BUILTIN_DIR else t.source
        gates = [
            f"{label} {value:.0f}" if label == "max ms" else f"{label} {round(value, 3):g}"
            for label, value in (
                ("min speed m/s", t.min_mean_speed_m_s),
                ("max ms", t.max_duration_ms),
                ("min size m", t.min_size_m),
                ("max submovements", t.max_submovements),
            )
            if value is not None
        ]
        kind = "any rotation" if t.rotation_invariant else f"+-{t.max_rotation_deg:g} deg"
        print(f"{name:<16} {len(t.examples)} example(s)  {kind}  {', '.join(gates) or 'no gates'}  ({where})")
    return 0


def record_command(args: argparse.Namespace) -> int:
    if not NAME_PATTERN.match(args.name) or args.name in RESERVED_TRIGGERS:
        raise ConfigError(
            f"'{args.name}' cannot name a gesture (letters, digits, _ and -, starting with a letter;"
            f" not {', '.join(RESERVED_TRIGGERS)})"
        )
    if args.examples < 1:
        raise ConfigError("--examples must be 1 or more")
    interaction, directory, endpoint = _settings(args)
    if directory is None:
        raise ConfigError("no template directory: give --dir, or --config with [interaction.gestures] template_dir")
    own = load_directory(directory) if directory.is_dir() else {}
    existing = own.pop(args.name, None)
    if existing is not None and existing.rotation_invariant != args.rotation_invariant:
        raise ConfigError(
            f"{existing.source}: {args.name} is {'' if existing.rotation_invariant else 'not '}"
            f"rotation-invariant; record it {'with' if existing.rotation_invariant else 'without'}"
            " --rotation-invariant, or under another name"
        )
    known = load_templates(None, builtin=interaction.gestures.builtin)
    known.pop(args.name, None)
    known.update(own)
    # Before any recording: examples drawn for nothing are lost examples.
    created = _writable_directory(directory)
    written = False
    try:
        hits = (
            _hits_from_file(Path(args.from_file))
            if args.from_file
            else _hits_from_zmq(args.endpoint or endpoint or DEFAULT_ENDPOINT, args.timeout)
        )
        strokes = _consistent_strokes(args, _strokes(hits, interaction), interaction, known, existing)
        template = template_from_strokes(
            args.name,
            [(s.times_ns, s.points_m) for s in strokes],
            rotation_invariant=args.rotation_invariant,
            max_rotation_deg=args.max_rotation_deg,
        )
        if existing is not None:
            template = _merge(existing, template)
        try:
            path = save_template(template, directory)
        except OSError as err:
            raise TrackerdError(
                f"{directory}: cannot write {template.name}.json: {err.strerror};"
                f" the {len(strokes)} example(s) are not saved"
            ) from err
        written = True
    finally:
        if not written:
            _remove_empty(created)
    print(
        f"wrote {path} ({len(template.examples)} example(s)); reload trackerd (systemctl reload trackerd) to use it",
        flush=True,
    )
    return 0


def _consistent_strokes(
    args: argparse.Namespace,
    strokes: Iterator[Stroke],
    interaction: InteractionConfig,
    known: dict[str, Template],
    existing: Template | None,
) -> list[Stroke]:
    """The first ``args.examples`` strokes that the recogniser takes for the gesture's other examples.

    Each stroke is scored as the daemon would score it against the examples kept so far (those
    of the existing template, then the new ones): below ``min_score_ratio`` the daemon would not
    take one for the others (a swipe among circles), so it is refused, with its score, and
    recording goes on. The first example of a new gesture has nothing to be compared with."""
    minimum = interaction.gestures.min_score_ratio
    kept: list[Stroke] = []
    references = list(existing.examples) if existing is not None else []
    refused = 0
    for stroke in strokes:
        f = stroke_features(stroke.times_ns, stroke.points_m)
        line = f"example {len(kept) + 1}/{args.examples}: {f.path_m:.2f} m in {f.duration_ms:.0f} ms"
        if references:
            own = Shape(args.name, tuple(references), args.rotation_invariant, args.max_rotation_deg)
            score = score_shape(stroke.points_m, own)
            if score < minimum:
                refused += 1
                print(
                    f"{line}: refused, it scores {score:.2f} against the other examples of {args.name}"
                    f" (at least {minimum:.2f} needed): a different gesture? draw it again",
                    flush=True,
                )
                continue
            line += f"; {score:.2f} against the other examples"
        if known:
            best, score = score_all(stroke.points_m, [t.shape for t in known.values()])[0]
            line += f"; nearest existing gesture {best} ({score:.2f})"
            if score >= minimum:
                line += " -- too like it: strokes may be taken for either"
        print(line, flush=True)
        kept.append(stroke)
        references.append(prepare(stroke.points_m, args.rotation_invariant))
        if len(kept) >= args.examples:
            return kept
    unlike = f", {refused} refused as unlike the others" if refused else ""
    raise RecordTimeout(
        f"only {len(kept)} of {args.examples} strokes{unlike}"
        f" {'in ' + args.from_file if args.from_file else f'within {args.timeout:g} s'}"
    )


def _writable_directory(directory: Path) -> list[Path]:
    """Make ``directory`` (and missing parents) and prove a file can be written in it; the folders
    made, newest last. TrackerdError (one line) when it cannot be."""
    if directory.exists() and not directory.is_dir():
        raise TrackerdError(f"--dir {directory}: not a directory")
    missing = [d for d in (directory, *directory.parents) if not d.exists()]
    created: list[Path] = []
    try:
        for folder in reversed(missing):
            folder.mkdir()
            created.append(folder)
        # os.access is not enough: root passes it on read-only mounts and in /proc.
        with tempfile.TemporaryFile(dir=directory, prefix=".trackerd-probe-"):
            pass
    except OSError as err:
        _remove_empty(created)
        where = "" if err.filename in (None, str(directory)) else f" ({err.filename})"
        raise TrackerdError(f"--dir {directory}: cannot write gesture templates there: {err.strerror}{where}") from err
    return created


def _remove_empty(folders: list[Path]) -> None:
    """Remove folders this command made, newest first, as long as they are empty."""
    for folder in reversed(folders):
        try:
            folder.rmdir()
        except OSError:
            return


def _merge(old: Template, new: Template) -> Template:
    """The examples of both; gates wide enough for both."""

    def widest(a: T | None, b: T | None, pick: Callable[[T, T], T]) -> T | None:
        return None if a is None or b is None else pick(a, b)

    return Template(
        new.name,
        old.examples + new.examples,
        new.rotation_invariant,
        new.max_rotation_deg,
        widest(old.min_mean_speed_m_s, new.min_mean_speed_m_s, min),
        widest(old.max_duration_ms, new.max_duration_ms, max),
        widest(old.min_size_m, new.min_size_m, min),
        widest(old.max_submovements, new.max_submovements, max),
    )


def _strokes(hits: Iterator[tuple[int, np.ndarray | None]], interaction: InteractionConfig) -> Iterator[Stroke]:
    """Strokes from (capture_ns, wall position or None) hits, smoothed and cut as the daemon does."""
    smoothing = OneEuroFilter(interaction.smoothing)
    segmenter = StrokeSegmenter(interaction.gestures)
    gap_ns = interaction.smoothing.reset_after_ms * 1e6
    last_ns: int | None = None
    count = 0
    for time_ns, position in hits:
        stroke = None
        if last_ns is not None and (position is None or time_ns - last_ns > gap_ns):
            stroke = segmenter.end()
            smoothing.reset()
            last_ns = None
        if position is not None:
            point = smoothing(time_ns, position) if interaction.smoothing.enabled else position
            stroke = stroke or segmenter.add(time_ns, point)
            last_ns = time_ns
        if stroke is not None:
            count += 1
            print(f"stroke {count}: {stroke.path_m:.2f} m", file=sys.stderr, flush=True)
            yield stroke
    stroke = segmenter.end()
    if stroke is not None:
        yield stroke


def _hit_position(data: dict) -> np.ndarray:
    # A smoothed hit carries the raw position too: record from the raw one and smooth here, as
    # the daemon's stroke cutter sees it.
    raw = data.get("raw_wall_x_m") is not None and data.get("raw_wall_y_m") is not None
    x, y = (data["raw_wall_x_m"], data["raw_wall_y_m"]) if raw else (data["wall_x_m"], data["wall_y_m"])
    return np.array([float(x), float(y)])


def _hits_from_file(path: Path) -> Iterator[tuple[int, np.ndarray | None]]:
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError as err:
        raise ConfigError(f"{path}: cannot read: {err.strerror}") from err
    except UnicodeDecodeError as err:
        raise ConfigError(f"{path}: not text (byte {err.start} is not UTF-8); hits are JSON lines") from None
    for number, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            data = json.loads(line)
            if data.get("topic", "hit") != "hit":
                continue
            yield int(data["capture_ns"]), _hit_position(data)
        except (ValueError, KeyError, TypeError) as err:
            raise ConfigError(f"{path}:{number}: not a hit message ({err})") from err


def _hits_from_zmq(endpoint: str, timeout_s: float) -> Iterator[tuple[int, np.ndarray | None]]:
    import zmq

    context = zmq.Context()
    sub = context.socket(zmq.SUB)
    sub.setsockopt(zmq.LINGER, 0)
    sub.setsockopt(zmq.SUBSCRIBE, b"hit")
    try:
        sub.connect(endpoint)
    except zmq.ZMQError as err:
        sub.close()
        context.term()
        raise ConfigError(f"--endpoint {endpoint}: {err.strerror}") from err
    print(f"recording from {endpoint}: draw the gesture, hold still, repeat", file=sys.stderr, flush=True)
    deadline = time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline:
            if not sub.poll(100):
                yield time.monotonic_ns(), None  # silence: the pointer is gone
                continue
            _, payload = sub.recv_multipart()
            data = json.loads(payload)
            yield int(data["capture_ns"]), _hit_position(data)
    finally:
        sub.close()
        context.term()
