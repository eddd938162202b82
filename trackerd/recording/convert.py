"""`trackerd recording convert`: a recording rewritten in another mode (raw, compressed, windowed).

Every readable pair is rewritten in order with its timestamps, frame ids and
sequence numbers; the metadata is the source's (cameras, rig, clock offset,
producer) with the new mode and a note of where it came from. A damaged pair of
the source is skipped and reported: the converted recording then has a gap in
its pair sequence where the source had a damaged pair.

A windowed recording needs the tracker's view of every pair
(trackerd/recording/windowed.py), so converting to it runs the locator over
the source the way `trackerd replay` would: the windowed recording replays to
exactly the hits the source replays to.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from trackerd.errors import RecordingError, TrackerdError
from trackerd.recording.format import Mode
from trackerd.recording.reader import Recording
from trackerd.recording.writer import RecordingWriter


@dataclass
class ConvertSummary:
    writer: RecordingWriter
    source_bytes: int
    skipped: list[str] = field(default_factory=list)
    keyframes: dict[str, int] = field(default_factory=dict)


def convert_recording(
    source: Recording,
    out: str | Path,
    mode: Mode,
    *,
    keyframe_interval_s: float = 1.0,
    window_margin_px: int = 8,
    verify: bool = True,
    progress: Callable[[int, int], None] | None = None,
) -> ConvertSummary:
    """Write ``source``'s readable pairs as a new recording at ``out`` in ``mode``; returns the summary
    (the writer closed). RecordingError when nothing of the source can be read."""
    metadata = source.metadata.model_copy(
        update={
            "end": None,
            "notes": "; ".join(
                filter(
                    None, [source.metadata.notes, f"converted from {source.path.resolve()} ({source.metadata.mode})"]
                )
            ),
        }
    )
    writer = RecordingWriter(
        out, metadata, mode=mode, keyframe_interval_s=keyframe_interval_s, window_margin_px=window_margin_px
    )
    summary = ConvertSummary(writer, source.data_size)
    total = len(source)
    try:
        for index in range(total):
            try:
                pair = source.pair(index, verify=verify)
            except RecordingError as err:
                summary.skipped.append(f"{err}; pair skipped")
                continue
            writer.write(pair, dropped_before=source.header(index).dropped_before)
            if progress is not None:
                progress(index + 1, total)
    except TrackerdError as err:
        writer.close_after(err, "conversion", "converted")
        raise
    except BaseException:
        writer.close("error: conversion interrupted")
        raise
    end = source.metadata.end
    writer.close(
        f"converted ({end.reason if end else 'source not closed'})", dropped_pairs=end.dropped_pairs if end else 0
    )
    if writer.discard_if_empty():
        raise RecordingError(f"{source.path}: no pair of it could be read; nothing was converted")
    planner = getattr(writer, "_planner", None)
    if planner is not None:
        summary.keyframes = dict(planner.keyframes)
    return summary
