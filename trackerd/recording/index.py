"""A recording's index (pairs.idx) read defensively, and pairs past its end found by scanning pairs.dat.

Every problem is one line naming the file, the entry or pair, and the byte offset; the entries
before it stay usable (docs/recording.md, "Damage").
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from trackerd.errors import RecordingError
from trackerd.files import NotRegularFile, TooLarge, read_bounded
from trackerd.recording.format import (
    DATA_FILE,
    FILE_HEADER,
    INDEX_ENTRY,
    INDEX_MAGIC,
    IndexEntry,
    damaged_file_header,
    unpack_file_header,
    unpack_index_entry,
    unpack_record_header,
)


def read_index(index_path: Path, data_size: int) -> tuple[list[IndexEntry], list[str]]:
    """The index's intact entries in order (each where the one before ends, within a data file of
    ``data_size`` bytes), and what stopped the reading or was left out, one line each."""
    entries: list[IndexEntry] = []
    problems: list[str] = []
    try:
        # Never more than the data it indexes (48 bytes per pair, whose record is larger): never a
        # FIFO either, which would wait for a writer, nor a device, which would never end.
        raw = read_bounded(index_path, FILE_HEADER.size + max(data_size, 1 << 20))
    except FileNotFoundError:
        return entries, [f"{index_path}: missing; pairs found by scanning {DATA_FILE}"]
    except (NotRegularFile, TooLarge) as err:
        return entries, [f"{err}; pairs found by scanning {DATA_FILE}"]
    except OSError as err:
        return entries, [f"{index_path}: cannot read ({err.strerror}); pairs found by scanning {DATA_FILE}"]
    damaged = damaged_file_header(raw, INDEX_MAGIC, str(index_path))
    if damaged is not None:
        return entries, [f"{damaged}; pairs found by scanning {DATA_FILE}"]
    try:
        _major, _minor, entry_bytes = unpack_file_header(raw, INDEX_MAGIC, str(index_path))
        if entry_bytes < INDEX_ENTRY.size:
            raise RecordingError(f"{index_path}: entries of {entry_bytes} bytes, fewer than {INDEX_ENTRY.size}")
    except RecordingError as err:
        return entries, [f"{err}; pairs found by scanning {DATA_FILE}"]
    body = memoryview(raw)[FILE_HEADER.size :]
    count = len(body) // entry_bytes
    expected_offset = FILE_HEADER.size
    for k in range(count):
        where = f"{index_path}: entry {k} (byte {FILE_HEADER.size + k * entry_bytes})"
        try:
            entry = unpack_index_entry(body[k * entry_bytes : (k + 1) * entry_bytes], entry_bytes, where)
        except RecordingError as err:
            problems.append(f"{err}; {_used_up_to(k)}")
            return entries, problems
        if entry.pair_index != k or entry.offset != expected_offset:
            problems.append(
                f"{where}: says pair {entry.pair_index} at byte {entry.offset}, expected pair"
                f" {k} at byte {expected_offset}; {_used_up_to(k)}"
            )
            return entries, problems
        if entry.end > data_size:
            problems.append(
                f"{where}: pair {k} ends at byte {entry.end} but {DATA_FILE} has {data_size} bytes (truncated)"
            )
            return entries, problems
        entries.append(entry)
        expected_offset = entry.end
    if len(body) % entry_bytes:
        problems.append(f"{index_path}: ends with a partial entry ({len(body) % entry_bytes} bytes), ignored")
    return entries, problems


def scan_unindexed(
    view: Callable[[int, int], memoryview], data_path: Path, data_size: int, entries: list[IndexEntry]
) -> list[str]:
    """Scan past the last of ``entries`` for complete records (written, not yet indexed), appending
    an entry for each to ``entries``; what was found or ignored, one line each.

    ``view(offset, length)`` is the data file's bytes there (the memory map).
    """
    problems: list[str] = []
    indexed = len(entries)
    offset = entries[-1].end if entries else FILE_HEADER.size
    while offset < data_size:
        k = len(entries)
        where = f"{data_path}: pair {k} at byte {offset}"
        available = data_size - offset
        try:
            header = unpack_record_header(view(offset, min(available, 1 << 16)), where)
        except RecordingError as err:
            if "cut short" in str(err):
                problems.append(f"{where}: incomplete ({available} bytes of its header written); ignored")
            else:
                problems.append(f"{err}; the {available} bytes from there on are ignored")
            return problems
        if header.pair_index != k:
            problems.append(
                f"{where}: the record there says it is pair {header.pair_index}; the"
                f" {available} bytes from there on are ignored"
            )
            return problems
        if header.record_bytes > available:
            problems.append(f"{where}: incomplete ({available} of {header.record_bytes} bytes written); ignored")
            return problems
        entries.append(IndexEntry(offset, header.record_bytes, k, header.sequence, header.timestamp_ns))
        offset += header.record_bytes
    if len(entries) > indexed:
        problems.append(
            f"{data_path}: {len(entries) - indexed} complete pair(s) past the end of"
            f" the index (pairs {indexed}-{len(entries) - 1}), recovered"
        )
    return problems


def _used_up_to(k: int) -> str:
    """How much of the index is used when entry ``k`` is the first bad one."""
    return f"the index is used up to pair {k - 1}" if k > 0 else "the index is not used"
