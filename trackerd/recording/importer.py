"""`trackerd recording import`: a recording from a folder of image pairs, so any images can be replayed.

Pairing by name, as :mod:`trackerd.image_pairs` does it for calibration too: files
``<name>-<camera>.<ext>`` (``07-left.png``; the convention of tests/data/pairs, of
`trackerd snap` and of the calibration snapshots), ``<camera><name>.<ext>``
(``left07.png``, ``left-07.png``), or ``<camera>/<name>.<ext>`` in one sub-folder per
camera. Moments are ordered by name, numbers compared as numbers. Images are read as camera frames by
:func:`trackerd.images.read_frame` (single channel: the camera's Bayer mosaic;
three channels: BGR8; ``.npy``: the raw frame), and must have the camera's size.

Timestamps come from an optional CSV with a header row: a ``name`` column, one
of ``timestamp_ns``, ``timestamp_us``, ``timestamp_ms`` or ``timestamp_s``, and
optionally ``camera`` (then one row per image, else one row per moment). Times
that look like UNIX epoch times (after 2001) keep their date as the capture
time; others count from the import. In name order, each camera's times must
increase. Without a CSV, moments are unrelated stills spaced
:func:`stills_spacing_ns` apart (1 s, and always longer than the interaction's
``reset_after_ms``, so the interaction stage smooths each still on its own
instead of blending it into the one before), or, given ``rate_hz``, frames of a
real sequence at that rate.
"""

from __future__ import annotations

import csv
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from trackerd.acquisition.frame import Frame, FramePair
from trackerd.config.models import RigConfig
from trackerd.errors import ImageError, RecordingError, TrackerdError
from trackerd.image_pairs import Moment, pair_images
from trackerd.images import read_frame
from trackerd.recording.format import Compression, Mode
from trackerd.recording.writer import RecordingWriter, build_metadata

_UNITS_NS = {"timestamp_ns": 1, "timestamp_us": 1_000, "timestamp_ms": 1_000_000, "timestamp_s": 1_000_000_000}
EPOCH_AFTER_NS = 1_000_000_000 * 1_000_000_000
"""Timestamps from this (September 2001, in ns since 1970) on are read as UNIX epoch times."""
STILLS_SPACING_NS = 1_000_000_000
"""Time between unrelated stills when neither timestamps nor a rate are given."""


@dataclass(frozen=True)
class Stamp:
    """One timestamp of the CSV: nanoseconds, and the line and text it came from (for errors)."""

    ns: int
    line: int
    text: str


def stills_spacing_ns(rig: RigConfig) -> int:
    """Spacing of unrelated stills: 1 s, or twice the interaction's reset_after_ms if that is longer.

    The interaction stage starts its smoothing afresh after reset_after_ms without a hit (150 ms
    by default); at a frame rate's spacing it would blend each still into the one before (a hit
    100 mm off its own position, measured on the bundled stills)."""
    reset_ns = round(rig.interaction.smoothing.reset_after_ms * 1e6)
    return max(STILLS_SPACING_NS, 2 * reset_ns)


def find_pairs(folder: Path, camera_ids: Sequence[str]) -> list[Moment]:
    """Group a folder's images into moments (:func:`trackerd.image_pairs.pair_images`); RecordingError
    for no images, two of one camera for a moment, or an incomplete moment."""
    try:
        return pair_images(folder, camera_ids).moments
    except ImageError as err:
        raise RecordingError(str(err)) from err


def read_timestamps(path: Path, camera_ids: Sequence[str]) -> dict[tuple[str, str | None], Stamp]:
    """{(name, camera or None): time} from the CSV; RecordingError naming the line of a bad row."""
    try:
        handle = path.open(newline="")
    except OSError as err:
        raise RecordingError(f"{path}: cannot read ({err.strerror})") from err
    with handle:
        reader = csv.DictReader(handle)
        fields = [f.strip() for f in reader.fieldnames or []]
        unit = next((f for f in fields if f in _UNITS_NS), None)
        if "name" not in fields or unit is None:
            raise RecordingError(
                f"{path}: needs a header with 'name' and one of {', '.join(_UNITS_NS)};"
                f" found {', '.join(fields) or 'none'}"
            )
        out: dict[tuple[str, str | None], Stamp] = {}
        for row in reader:
            row = {k.strip(): (v or "").strip() for k, v in row.items() if k is not None}
            camera = row.get("camera") or None
            if camera is not None and camera not in camera_ids:
                raise RecordingError(
                    f"{path}:{reader.line_num}: camera '{camera}' is not one of {', '.join(camera_ids)}"
                )
            try:
                value = float(row[unit]) if unit == "timestamp_s" else int(row[unit])
            except ValueError:
                what = "a number" if unit == "timestamp_s" else "a whole number"  # 1e300 is a number, not an int
                raise RecordingError(f"{path}:{reader.line_num}: {unit} '{row[unit]}' is not {what}") from None
            if (isinstance(value, float) and not math.isfinite(value)) or abs(value * _UNITS_NS[unit]) >= 2**63:
                raise RecordingError(
                    f"{path}:{reader.line_num}: {unit} '{row[unit]}' is not a time a recording can hold"
                )
            out[(row["name"], camera)] = Stamp(round(value * _UNITS_NS[unit]), reader.line_num, f"{unit} {row[unit]}")
    return out


def import_folder(
    folder: str | Path,
    out: str | Path,
    rig: RigConfig,
    *,
    timestamps: str | Path | None = None,
    rate_hz: float | None = None,
    compression: Compression = "none",
    compression_level: int = 6,
    rig_file: str | Path | None = None,
    progress: Callable[[int, int], None] | None = None,
    mode: Mode = "raw",
) -> RecordingWriter:
    """Write the folder's image pairs as a recording at ``out``; returns the (closed) writer."""
    folder = Path(folder)
    ids = [c.id for c in rig.cameras]
    moments = find_pairs(folder, ids)
    times = read_timestamps(Path(timestamps), ids) if timestamps is not None else None
    if rate_hz is not None and rate_hz <= 0:
        raise RecordingError(f"--rate {rate_hz:g}: must be positive")
    period_ns = stills_spacing_ns(rig) if rate_hz is None else round(1e9 / rate_hz)
    stamps_of = [[_time(times, m.name, cam, k, period_ns, timestamps) for cam in ids] for k, m in enumerate(moments)]
    if timestamps is not None:
        _check_increasing(Path(timestamps), moments, ids, stamps_of)
    capture = [[stamp.ns for stamp in row] for row in stamps_of]
    t0 = min(min(c) for c in capture)
    clock_offset = t0 if t0 >= EPOCH_AFTER_NS else time.time_ns()
    writer: RecordingWriter | None = None
    formats: dict[str, tuple[str, tuple[int, ...]]] = {}
    try:
        for k, moment in enumerate(moments):
            frames = []
            for cam, stamp in zip(rig.cameras, capture[k], strict=True):
                image, fmt = read_frame(moment.files[cam.id], cam)
                first = formats.setdefault(cam.id, (fmt, image.shape))
                if first != (fmt, image.shape):
                    raise ImageError(
                        f"{moment.files[cam.id]}: a {fmt} image, but camera '{cam.id}''s earlier images"
                        f" are {first[0]}; a recording keeps one pixel format per camera"
                    )
                frames.append(Frame(cam.id, k, 0, stamp - t0, fmt, image))
            stamps = capture[k]
            pair = FramePair(tuple(frames), sum(stamps) // len(stamps) - t0, max(stamps) - min(stamps), k)
            if writer is None:
                metadata = build_metadata(
                    rig,
                    pair,
                    producer="trackerd recording import",
                    clock_offset_ns=clock_offset,
                    rig_file=rig_file,
                    notes=f"imported from {folder.resolve()}",
                )
                writer = RecordingWriter(
                    out, metadata, compression=compression, compression_level=compression_level, mode=mode
                )
            writer.write(pair)
            if progress is not None:
                progress(k + 1, len(moments))
    except TrackerdError as err:
        if writer is None:
            raise
        writer.close_after(err, "import", "imported")
        raise
    except BaseException:
        if writer is not None:
            writer.close("error: import interrupted")
        raise
    assert writer is not None
    writer.close("imported")
    return writer


def _time(
    times: dict[tuple[str, str | None], Stamp] | None,
    name: str,
    cam: str,
    k: int,
    period_ns: int,
    path: str | Path | None,
) -> Stamp:
    if times is None:
        return Stamp(k * period_ns, 0, "")
    for key in ((name, cam), (name, None)):
        if key in times:
            return times[key]
    raise RecordingError(f"{path}: no timestamp for '{name}' (camera '{cam}')")


def _check_increasing(
    path: Path, moments: Sequence[Moment], camera_ids: Sequence[str], stamps: Sequence[Sequence[Stamp]]
) -> None:
    """Each camera's times must increase in name order: a recording's pairs follow each other in time
    (replay paces by them, the interaction stage measures speeds and timeouts with them)."""
    for k in range(1, len(moments)):
        for c, cam in enumerate(camera_ids):
            before, now = stamps[k - 1][c], stamps[k][c]
            if now.ns <= before.ns:
                raise RecordingError(
                    f"{path}:{now.line}: '{moments[k].name}' ({cam}) at {now.text} is not after"
                    f" '{moments[k - 1].name}' at {before.text} (line {before.line}); moments are taken in name"
                    " order and their times must increase"
                )
