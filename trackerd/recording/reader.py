"""Reading a recording: metadata, the intact pairs, and a precise account of any damage.

:meth:`Recording.open` checks the metadata and the version, reads the index,
and scans pairs.dat past the last indexed pair for complete pairs the recorder
wrote before it died but had not indexed yet. Everything it cannot use is
described in :attr:`Recording.problems`, one line each naming the file, the
pair and the byte offset; the pairs before a problem stay readable. Frames are
served as read-only NumPy views into a memory map of pairs.dat (no copy), so
replay costs only the pixels the detector actually looks at.

Reading the index and scanning past it is :mod:`trackerd.recording.index`'s;
rebuilding compressed and windowed frames, :mod:`trackerd.recording.decoding`'s.
"""

from __future__ import annotations

import contextlib
import functools
import json
import mmap
import os
from collections.abc import Callable
from concurrent.futures import Executor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pydantic import ValidationError

from trackerd.acquisition.frame import Frame, FramePair
from trackerd.config.models import RigConfig
from trackerd.errors import ConfigError, RecordingError
from trackerd.files import MAX_DEPTH, NotRegularFile, TooLarge, nesting_depth, open_regular, read_bounded
from trackerd.recording.decoding import FrameDecoder
from trackerd.recording.format import (
    DATA_FILE,
    DATA_MAGIC,
    FILE_HEADER,
    FORMAT_MAJOR,
    FORMAT_NAME,
    INDEX_FILE,
    METADATA_FILE,
    MODES,
    RECORD_MAGIC,
    CameraMeta,
    IndexEntry,
    RecordHeader,
    RecordingMetadata,
    check_major,
    damaged_file_header,
    parse_version,
    unpack_file_header,
    unpack_record_header,
)
from trackerd.recording.index import read_index, scan_unindexed

MAX_METADATA_BYTES = 16 * 1024 * 1024
"""recording.json holds the rig and what the cameras said of themselves: tens of kilobytes."""


def _upgrade_1(data: dict[str, Any]) -> dict[str, Any]:
    """1.x -> 2.x: a 1.0 recording has no ``mode`` and is raw (1.1 says so already)."""
    return {**data, "mode": data.get("mode", "raw")}


UPGRADES: dict[int, Callable[[dict[str, Any]], dict[str, Any]]] = {1: _upgrade_1}
"""Metadata upgrades: ``UPGRADES[n]`` turns MAJOR n's recording.json into MAJOR n+1's; a reader reads an
older MAJOR by applying them in turn."""


@dataclass
class Recording:
    """An open recording. Use :meth:`open`; close() (or ``with``) releases the memory map."""

    path: Path
    metadata: RecordingMetadata
    entries: list[IndexEntry]
    """The intact pairs in order: every valid index entry, then complete pairs found past the index."""
    indexed: int
    """How many of ``entries`` came from the index (the rest were found by scanning)."""
    data_size: int
    problems: list[str] = field(default_factory=list)
    """What is damaged or missing, one line each (empty for a recording closed cleanly and intact)."""
    _map: mmap.mmap | None = None
    out_of_time: dict[int, str] = field(default_factory=dict)
    """Pairs whose capture time cannot be placed in the recording's time line (:func:`capture_time_damage`),
    with what is wrong: :meth:`header` refuses them as damaged, and replay does not wait for their times."""
    _decoder: FrameDecoder = field(init=False)

    def __post_init__(self) -> None:
        self._decoder = FrameDecoder(self)

    # ------------------------------------------------------------------ opening

    @classmethod
    def open(cls, path: str | Path) -> Recording:
        """Open a recording folder; RecordingError when nothing of it can be read."""
        folder = Path(path)
        if not folder.exists():
            raise RecordingError(f"{folder}: no such recording")
        if not folder.is_dir():
            raise RecordingError(
                f"{folder}: not a recording (a recording is a folder holding {METADATA_FILE},"
                f" {DATA_FILE} and {INDEX_FILE})"
            )
        metadata = read_metadata(folder)
        data_path = folder / DATA_FILE
        try:
            data_fd = open_regular(data_path)
        except FileNotFoundError:
            raise RecordingError(f"{data_path}: missing; the recording holds no frames") from None
        except IsADirectoryError:
            raise RecordingError(f"{data_path}: a directory, not the recording's data file") from None
        except NotRegularFile as err:
            raise RecordingError(f"{err}: not the recording's data file") from None
        except OSError as err:
            raise RecordingError(f"{data_path}: cannot read: {err.strerror}") from err
        try:
            size = os.fstat(data_fd).st_size
            head = os.pread(data_fd, FILE_HEADER.size, 0)
            damaged = damaged_file_header(head, DATA_MAGIC, str(data_path))
            if damaged is not None and os.pread(data_fd, len(RECORD_MAGIC), FILE_HEADER.size) != RECORD_MAGIC:
                damaged = None  # no record where the first one begins: a file of something else, refused below
            if damaged is None:
                major, _minor, _ = unpack_file_header(head, DATA_MAGIC, str(data_path))
                check_major(major, str(data_path))
            mapped = mmap.mmap(data_fd, size, prot=mmap.PROT_READ) if size > FILE_HEADER.size else None
        finally:
            os.close(data_fd)
        # Every entry taken counts as indexed, however the index ended (cut short, a damaged entry).
        entries, problems = read_index(folder / INDEX_FILE, size)
        if damaged is not None:
            problems.insert(0, f"{damaged}; its pairs are read by their own checksums")
        recording = cls(folder, metadata, entries, len(entries), size, problems, mapped)
        recording.problems += scan_unindexed(recording.view, folder / DATA_FILE, size, recording.entries)
        recording.out_of_time = capture_time_damage(recording.entries, str(data_path))
        if metadata.end is None:
            recording.problems.append(
                f"{folder / METADATA_FILE}: no end record: the recorder stopped without closing the recording"
                " (killed, crashed or power lost)"
            )
        elif metadata.end.reason.startswith("error:"):
            # A writer that stopped on an error (an import's unreadable image, a conversion's full disk, the
            # daemon's recorder): the pairs it wrote are whole, but the recording is not what was asked for.
            recording.problems.append(
                f"{folder / METADATA_FILE}: the recording ended with an error ({metadata.end.reason}); it holds"
                f" the {metadata.end.pairs} pairs written before it"
            )
        if metadata.end is not None and metadata.end.pairs != len(recording.entries):
            recording.problems.append(
                f"{folder / METADATA_FILE}: says {metadata.end.pairs} pairs were written, {len(recording.entries)}"
                " are readable"
            )
        # No MADV_SEQUENTIAL: the kernel would drop each page once read, so a second replay (a loop,
        # a benchmark, a test) would read the disk again instead of the page cache.
        return recording

    # ------------------------------------------------------------------ reading

    def __len__(self) -> int:
        return len(self.entries)

    @property
    def cameras(self) -> tuple[CameraMeta, ...]:
        return self.metadata.cameras

    @property
    def duration_s(self) -> float:
        """From the first pair's capture to the last's (pairs out of time left out)."""
        timed = self.timed(0, len(self.entries))
        if len(timed) < 2:
            return 0.0
        return (self.entries[timed[-1]].timestamp_ns - self.entries[timed[0]].timestamp_ns) / 1e9

    def timed(self, first: int, stop: int) -> list[int]:
        """The pairs from ``first`` to before ``stop`` whose capture times are in the time line."""
        return [index for index in range(first, stop) if index not in self.out_of_time]

    @functools.cached_property
    def data_name(self) -> str:
        """pairs.dat's path as text, for messages (made once: replay names it for every pair it reads)."""
        return str(self.path / DATA_FILE)

    def view(self, offset: int, length: int) -> memoryview:
        """The data file's bytes from ``offset``, a view into its memory map (no copy)."""
        if self._map is None:
            raise RecordingError(f"{self.path}: the recording is closed")
        return memoryview(self._map)[offset : offset + length]

    def header(self, index: int) -> RecordHeader:
        """Pair ``index``'s record header, checked against the index and the recording's time line;
        RecordingError naming the damage."""
        header = self.record_header(index)
        problem = self.out_of_time.get(index)
        if problem is not None:
            raise RecordingError(problem)
        return header

    def record_header(self, index: int) -> RecordHeader:
        """Pair ``index``'s record header, checked against the index (not its time: a frame stored whole
        builds the frames stored over it whatever its pair's capture time says)."""
        entry = self.entries[index]
        where = f"{self.data_name}: pair {index} at byte {entry.offset}"
        # The whole record as a view (no copy): a newer MINOR's header may be longer than this version's.
        header = unpack_record_header(self.view(entry.offset, entry.record_bytes), where)
        if (header.pair_index, header.record_bytes) != (entry.pair_index, entry.record_bytes):
            raise RecordingError(
                f"{where}: the record (pair {header.pair_index}, {header.record_bytes} bytes) does"
                f" not match its index entry (pair {entry.pair_index}, {entry.record_bytes} bytes)"
            )
        if len(header.frames) != len(self.cameras):
            raise RecordingError(f"{where}: {len(header.frames)} frames, the recording has {len(self.cameras)} cameras")
        return header

    def images(
        self, index: int, header: RecordHeader | None = None, *, verify: bool = True, pool: Executor | None = None
    ) -> list[NDArray[np.uint8]]:
        """Pair ``index``'s frames in camera order, read-only; with ``verify``, checksums are checked
        (RecordingError naming the camera and byte offset of a damaged frame). A frame stored as a
        difference or as windows is rebuilt from the frames it builds on, which are checked too.

        With ``pool``, the second camera's frame on (each camera's in turn) is rebuilt on the pool's
        threads while this thread rebuilds the first's: the same frames, and the same error (the first
        camera's in order) when one is damaged."""
        header = header or self.header(index)
        frame = self._decoder.frame
        if pool is None or len(self.cameras) < 2:
            return [frame(index, k, header, verify) for k in range(len(self.cameras))]
        others = [pool.submit(frame, index, k, header, verify) for k in range(1, len(self.cameras))]
        try:
            first = frame(index, 0, header, verify)
        finally:
            # Not returned nor raised before every camera's work on this pair is done.
            wait(others)
        return [first, *(future.result() for future in others)]

    def pair(self, index: int, *, verify: bool = True) -> FramePair:
        """Pair ``index`` exactly as recorded (timestamps on the recording host's monotonic clock)."""
        header = self.header(index)
        images = self.images(index, header, verify=verify)
        return make_pair(self, header, images)

    def rig(self) -> RigConfig:
        """The rig recorded with the frames; ConfigError when this trackerd cannot read it."""
        try:
            return RigConfig.model_validate(self.metadata.rig)
        except ValidationError as err:
            from trackerd.config.loader import describe_validation_error

            raise ConfigError(
                f"{self.path / METADATA_FILE}: the recorded rig does not validate with this trackerd"
                f" ({describe_validation_error(err, RigConfig)}); give one with --config"
            ) from err

    def close(self) -> None:
        if self._map is not None:
            mapped, self._map = self._map, None
            # Frames handed out may still view it; it then closes when the last one is gone.
            with contextlib.suppress(BufferError):
                mapped.close()

    def __enter__(self) -> Recording:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()


def capture_time_damage(entries: list[IndexEntry], data_name: str) -> dict[int, str]:
    """The pairs whose capture time goes back against the recording's time line, each with a line saying so.

    Capture times are the recording host's monotonic clock (or an import's increasing times), so a writer
    never makes one go back; a file that has them was edited or made by another program, and its checksums do
    not see it. The time line is the longest run of pairs, in order, whose times never go back (found in
    n log n): a single bogus time, even the first pair's, is the one left out, not every pair after it."""
    times = [entry.timestamp_ns for entry in entries]
    # Patience sorting for the longest non-decreasing subsequence: tails[k] is the index of the smallest
    # last time of a run of length k + 1, before[i] the run's previous pair.
    tails: list[int] = []
    before = [-1] * len(times)
    for index, time_ns in enumerate(times):
        low, high = 0, len(tails)
        while low < high:
            middle = (low + high) // 2
            if times[tails[middle]] <= time_ns:
                low = middle + 1
            else:
                high = middle
        before[index] = tails[low - 1] if low > 0 else -1
        if low == len(tails):
            tails.append(index)
        else:
            tails[low] = index
    in_line = [False] * len(times)
    index = tails[-1] if tails else -1
    while index >= 0:
        in_line[index] = True
        index = before[index]
    damage: dict[int, str] = {}
    last_in_line = -1
    for index, entry in enumerate(entries):
        if in_line[index]:
            last_in_line = index
            continue
        where = f"{data_name}: pair {index} at byte {entry.offset}"
        if last_in_line >= 0 and times[index] < times[last_in_line]:
            damage[index] = (
                f"{where}: captured {_span(times[last_in_line] - times[index])} before pair {last_in_line}"
                " (times go back)"
            )
        else:
            following = next(k for k in range(index + 1, len(entries)) if in_line[k])
            damage[index] = (
                f"{where}: captured {_span(times[index] - times[following])} after pair {following}, which"
                " follows it (times go back)"
            )
    return damage


def _span(ns: int) -> str:
    """A time span for a message: seconds, or days when long."""
    seconds = ns / 1e9
    return f"{seconds:.3f} s" if seconds < 86_400 else f"{seconds / 86_400:.1f} days"


def make_pair(
    recording: Recording,
    header: RecordHeader,
    images: list[NDArray[np.uint8]],
    *,
    shift_ns: int = 0,
    host_ns: int | None = None,
    sequence: int | None = None,
) -> FramePair:
    """A FramePair from a record: timestamps moved by ``shift_ns``; ``host_ns`` replaces the frames'
    host timestamps (the replay's delivery time) when given."""
    frames = tuple(
        Frame(
            cam.id,
            entry.frame_id,
            entry.device_timestamp_ns,
            entry.host_timestamp_ns + shift_ns if host_ns is None else host_ns,
            cam.pixel_format,
            image,
        )
        for cam, entry, image in zip(recording.cameras, header.frames, images, strict=True)
    )
    return FramePair(
        frames, header.timestamp_ns + shift_ns, header.skew_ns, header.sequence if sequence is None else sequence
    )


def read_metadata(folder: Path) -> RecordingMetadata:
    """recording.json, version-checked and upgraded; RecordingError naming what is wrong."""
    path = folder / METADATA_FILE
    try:
        data = json.loads(read_bounded(path, MAX_METADATA_BYTES).decode("utf-8"))
    except FileNotFoundError:
        raise RecordingError(
            f"{folder}: not a recording (no {METADATA_FILE}; a recording is a folder holding"
            f" {METADATA_FILE}, {DATA_FILE} and {INDEX_FILE})"
        ) from None
    except (NotRegularFile, TooLarge) as err:
        raise RecordingError(f"{err}: not a recording's metadata") from err
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise RecordingError(f"{path}: not readable JSON ({err})") from err
    except ValueError as err:
        # Not a JSONDecodeError: json reads an integer with int(), which refuses one of more than
        # sys.get_int_max_str_digits() digits (4300) with a plain ValueError.
        raise RecordingError(f"{path}: not readable JSON ({str(err).split(';')[0]})") from err
    except RecursionError as err:
        raise RecordingError(f"{path}: nested too deeply to be a recording's metadata") from err
    if nesting_depth(data) > MAX_DEPTH:
        raise RecordingError(f"{path}: nested more than {MAX_DEPTH} levels deep; not a recording's metadata")
    if not isinstance(data, dict) or data.get("format") != FORMAT_NAME:
        found = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise RecordingError(f"{path}: format is {found!r}, not {FORMAT_NAME!r}: not a trackerd recording")
    major, _minor = parse_version(data.get("format_version", ""), str(path))
    check_major(major, str(path))
    while major < FORMAT_MAJOR:
        upgrade = UPGRADES.get(major)
        if upgrade is None:
            raise RecordingError(f"{path}: format {major}.x is older than any this trackerd reads")
        data = upgrade(data)
        major += 1
    try:
        metadata = RecordingMetadata.model_validate(data)
    except ValidationError as err:
        first = err.errors()[0]
        key = ".".join(str(p) for p in first["loc"])
        message = first["msg"].removeprefix("Value error, ")  # a validator's own words
        raise RecordingError(f"{path}: {key}: {message}") from err
    if metadata.mode not in MODES:
        raise RecordingError(
            f"{path}: recording mode {metadata.mode!r} is newer than this trackerd reads ({', '.join(MODES)});"
            " upgrade trackerd to read it"
        )
    return metadata
