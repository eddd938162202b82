"""`trackerd recording export`: the frames as viewable PNGs with the detections drawn, and the hits as CSV.

The modern version of the report's text dump (section 6.2). Pairs go through
the locator in recorded order as the pipeline does (started afresh; a pair
without the pointer ends tracking, in the locator itself) and through the rig's extensions, so the
messages are the ones `trackerd replay` publishes for the same recording and
configuration: the CSV's hit columns are the published hit fields, exactly.
"""

from __future__ import annotations

import csv
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from trackerd.config.models import RigConfig
from trackerd.errors import RecordingError
from trackerd.images import write_png
from trackerd.locator import COLOURS, Locator, PointerFix
from trackerd.pipeline.events import NOTHING
from trackerd.pipeline.extensions import ExtensionContext, Located, PipelineExtension
from trackerd.publish.from_fix import pair_messages
from trackerd.publish.messages import HitMessage, Message
from trackerd.recording.annotate import annotate, end_summary, fix_summary
from trackerd.recording.outputs import output_folder
from trackerd.recording.reader import Recording, make_pair

CSV_NAME = "hits.csv"
_ENVELOPE = ("schema_version", "topic", "sequence", "capture_ns", "publish_ns")


@dataclass
class ExportSummary:
    pairs: int
    images: int
    statuses: dict[str, int]
    csv_path: Path
    skipped: list[str]


def hit_columns() -> list[str]:
    """The hit message's own fields as CSV columns (3-vectors split into _x, _y, _z)."""
    out = []
    for name, field in HitMessage.model_fields.items():
        if name in _ENVELOPE:
            continue
        if "tuple" in str(field.annotation):
            stem = name[:-2] if name.endswith("_m") else name
            out += [f"{stem}_{axis}_m" for axis in "xyz"]
        else:
            out.append(name)
    return out


def _hit_values(hit: HitMessage | None, columns: list[str]) -> list[Any]:
    if hit is None:
        return [""] * len(columns)
    values = []
    data = hit.model_dump()
    for name, value in data.items():
        if name in _ENVELOPE:
            continue
        if isinstance(value, tuple | list):
            values += [repr(float(v)) for v in value]
        elif isinstance(value, float):
            values.append(repr(value))
        else:
            values.append("" if value is None else value)
    return values


def export_recording(
    recording: Recording,
    out: str | Path,
    rig: RigConfig,
    *,
    every: int = 1,
    first: int = 0,
    count: int | None = None,
    images: bool = True,
    progress: Callable[[int, int], None] | None = None,
) -> ExportSummary:
    """Write ``out/hits.csv`` (one row per pair) and, with ``images``, ``out/<pair>-<camera>.png`` for
    every ``every``-th pair. ``rig`` must match the recording's cameras (see replay_rig)."""
    from trackerd.interaction.extension import create as interaction_extension
    from trackerd.recording.extension import create as recording_extension

    stop = len(recording) if count is None else min(len(recording), first + count)
    if first >= stop:
        raise RecordingError(f"{recording.path}: no pairs to export from pair {first}")
    folder = output_folder(out)
    tuio = getattr(rig.interaction, "tuio", None)
    if tuio is not None and tuio.enabled:
        # An export computes what would be published; it sends nothing (TUIO is sent by the extension).
        rig = rig.model_copy(
            update={
                "interaction": rig.interaction.model_copy(update={"tuio": tuio.model_copy(update={"enabled": False})})
            }
        )
    locator = Locator(rig)
    # As `trackerd replay` builds them (trackerd/cli/run.py): a replay's, whose results follow from
    # the pairs alone.
    context = ExtensionContext(replay=True)
    extensions: list[PipelineExtension] = [
        e for e in (recording_extension(rig, context), interaction_extension(rig, context)) if e is not None
    ]
    offset = recording.metadata.clock_offset_ns
    columns = hit_columns()
    centroid_columns = [f"{cam.id}_{colour}_{axis}_px" for cam in rig.cameras for colour in COLOURS for axis in "xy"]
    statuses: dict[str, int] = {}
    skipped: list[str] = []
    written = 0
    csv_path = folder / CSV_NAME
    try:
        with csv_path.open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(["pair_index", "sequence", "capture_ns", "status", *columns, *centroid_columns, "reason"])
            for index in range(first, stop):
                try:
                    header = recording.header(index)
                    frames = recording.images(index, header, verify=True)
                except RecordingError as err:
                    skipped.append(f"{err}; pair skipped")
                    continue
                pair = make_pair(recording, header, frames)
                for extension in extensions:
                    extension.on_pair(pair)
                fix = locator.locate(pair.images)
                capture = pair.timestamp_ns + offset
                located = Located(pair, fix, capture)
                events = NOTHING
                for extension in extensions:
                    events = events.then(extension.on_located(located))
                messages: list[Message] = pair_messages(
                    fix, locator.front_colour, sequence=pair.sequence, capture_ns=capture, events=events
                )
                statuses[fix.status] = statuses.get(fix.status, 0) + 1
                hit = next((m for m in messages if isinstance(m, HitMessage)), None)
                writer.writerow(
                    [
                        index,
                        pair.sequence,
                        capture,
                        fix.status,
                        *_hit_values(hit, columns),
                        *_centroids(fix),
                        fix.reason or "",
                    ]
                )
                # Each row on the disk before the next pair: a full disk is then met by the write that
                # meets it (closing the file would otherwise raise it over an image's error), and every
                # row before it stays in the table.
                handle.flush()
                if images and (index - first) % max(every, 1) == 0:
                    for k, (cam, frame) in enumerate(zip(recording.cameras, frames, strict=True)):
                        detections = fix.detections[k] if fix.detections else None
                        lines = [f"pair {index}  seq {pair.sequence}  {cam.id}", fix_summary(fix)]
                        if detections is not None:
                            lines.append(end_summary(detections))
                        path = folder / f"{index:06d}-{cam.id}.png"
                        write_png(path, annotate(frame, cam.pixel_format, detections, lines))
                        written += 1
                if progress is not None:
                    progress(index - first + 1, stop - first)
    except OSError as err:
        # The table so far stays readable (each row is whole up to where the disk filled).
        raise RecordingError(f"{csv_path}: cannot write: {err.strerror or err}") from err
    finally:
        for extension in extensions:
            extension.close()
    return ExportSummary(stop - first - len(skipped), written, statuses, csv_path, skipped)


def _centroids(fix: PointerFix) -> list[str]:
    out = []
    for per_camera in fix.centroids_px:
        for colour in COLOURS:
            point = per_camera.get(colour)
            out += ["", ""] if point is None else [repr(float(point[0])), repr(float(point[1]))]
    return out
