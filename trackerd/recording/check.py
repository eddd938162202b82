"""`trackerd recording check`: how much of a recording is intact, and exactly what is not."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

from trackerd.errors import ConfigError, RecordingError
from trackerd.recording.format import FLAG_KEYFRAME
from trackerd.recording.reader import Recording


@dataclass
class CheckReport:
    """What `trackerd recording check` found; ``intact`` when nothing is wrong."""

    path: str
    format_version: str
    mode: str
    """raw, compressed or windowed."""
    keyframes: int
    """Pairs stored whole (every pair of a raw recording)."""
    producer: str
    created_utc: str
    cameras: list[dict[str, Any]]
    pairs: int
    """Readable pairs (indexed plus recovered)."""
    indexed: int
    recovered: int
    duration_s: float
    data_bytes: int
    closed: bool
    end_reason: str | None
    dropped_by_recorder: int | None
    sequence_gaps: int
    """Pairs missing between recorded sequence numbers (dropped by the cameras, the pipeline or the
    recorder before they were recorded). A damaged pair is recorded, not missing: it is counted in
    ``damaged_pairs``, and its sequence number comes from its index entry."""
    verified: bool
    damaged_pairs: list[int] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)

    @property
    def intact(self) -> bool:
        return not self.problems

    @property
    def replayable(self) -> int:
        return self.pairs - len(self.damaged_pairs)

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "intact": self.intact, "replayable": self.replayable}


def check_recording(
    recording: Recording, *, verify: bool = True, progress: Callable[[int, int], None] | None = None
) -> CheckReport:
    """Check every pair's record header (and with ``verify`` every frame's checksum)."""
    meta = recording.metadata
    problems = list(recording.problems)
    try:
        # Replay and export read it: a rig they refuse is the recording's problem too.
        recording.rig()
    except ConfigError as err:
        problems.append(str(err))
    damaged: list[int] = []
    previous_sequence: int | None = None
    gaps = 0
    keyframes = 0
    for index in range(len(recording)):
        try:
            header = recording.header(index)
            if verify:
                recording.images(index, header, verify=True)
            sequence = header.sequence
            keyframes += bool(header.flags & FLAG_KEYFRAME) or meta.mode == "raw"
        except RecordingError as err:
            damaged.append(index)
            problems.append(str(err))
            # The pair is there, only damaged: its index entry (checked apart from the record) still
            # says which pair of the source it was, so it does not count as a gap.
            sequence = recording.entries[index].sequence
        if previous_sequence is not None and sequence > previous_sequence + 1:
            gaps += sequence - previous_sequence - 1
        previous_sequence = sequence
        if progress is not None:
            progress(index + 1, len(recording))
    end = meta.end
    return CheckReport(
        path=str(recording.path),
        format_version=meta.format_version,
        mode=meta.mode,
        keyframes=keyframes,
        producer=meta.producer,
        created_utc=meta.created_utc,
        cameras=[cam.model_dump() for cam in meta.cameras],
        pairs=len(recording),
        indexed=recording.indexed,
        recovered=len(recording) - recording.indexed,
        duration_s=round(recording.duration_s, 3),
        data_bytes=recording.data_size,
        closed=end is not None,
        end_reason=None if end is None else end.reason,
        dropped_by_recorder=None if end is None else end.dropped_pairs,
        sequence_gaps=gaps,
        verified=verify,
        damaged_pairs=damaged,
        problems=problems,
    )


def format_report(report: CheckReport) -> str:
    """The report for a terminal: a few lines, problems last."""
    keys = "" if report.mode == "raw" else f" ({report.keyframes} keyframes)"
    lines = [
        f"{report.path}: trackerd recording format {report.format_version}, {report.mode}{keys}, written by"
        f" {report.producer} at {report.created_utc}"
    ]
    for cam in report.cameras:
        made = " ".join(filter(None, [cam.get("vendor"), cam.get("model")]))
        ident = ", ".join(filter(None, [f"serial {cam['serial']}" if cam.get("serial") else None, made or None]))
        lines.append(
            f"  camera {cam['id']}: {cam['pixel_format']} {cam['width_px']}x{cam['height_px']}"
            + (f" ({ident})" if ident else "")
        )
    rate = (report.pairs - 1) / report.duration_s if report.duration_s > 0 else 0.0
    lines.append(
        f"  pairs: {report.pairs} readable ({report.indexed} indexed, {report.recovered} recovered past the"
        f" index), {report.duration_s:.2f} s at {rate:.1f} pairs/s, {report.data_bytes / 1e6:.1f} MB"
    )
    gaps = f"gaps in the pair sequence: {report.sequence_gaps} (pairs never recorded)"
    if report.closed:
        lines.append(f"  closed: {report.end_reason}; pairs the recorder dropped: {report.dropped_by_recorder}; {gaps}")
    else:
        lines.append(f"  closed: no (the recorder did not finish); {gaps}")
    damaged = f"; {len(report.damaged_pairs)} damaged (recorded, unreadable)" if report.damaged_pairs else ""
    if report.verified:
        lines.append(f"  frames: {report.replayable} of {report.pairs} pairs pass their checksums{damaged}")
    else:
        lines.append(f"  frames: checksums not verified (--no-verify); record headers checked{damaged}")
    if report.intact:
        lines.append("  intact")
    else:
        lines.append(f"  {len(report.problems)} problem(s); {report.replayable} pairs replay:")
        lines.extend(f"    {p}" for p in report.problems)
    return "\n".join(lines)
