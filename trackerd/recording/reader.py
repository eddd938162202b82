"""Reading a recording: metadata, the intact pairs, and a precise account of any damage.

:meth:`Recording.open` checks the metadata and the version, reads the index,
and scans pairs.dat past the last indexed pair for complete pairs the recorder
wrote before it died but had not indexed yet. Everything it cannot use is
described in :attr:`Recording.problems`, one line each naming the file, the
pair and the byte offset; the pairs before a problem stay readable. Frames are
served as read-only NumPy views into a memory map of pairs.dat (no copy), so
replay costs only the pixels the detector actually looks at.
"""

from __future__ import annotations

import contextlib
import functools
import json
import mmap
import os
import threading
import zlib
from collections.abc import Callable
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
from trackerd.recording.format import (
    DATA_FILE,
    DATA_MAGIC,
    ENCODING_DEFLATE,
    ENCODING_RAW,
    ENCODING_WINDOWS,
    ENCODING_ZSTD,
    ENCODING_ZSTD_DELTA,
    FILE_HEADER,
    FORMAT_MAJOR,
    FORMAT_NAME,
    FORMAT_VERSION,
    FULL_ENCODINGS,
    INDEX_ENTRY,
    INDEX_FILE,
    INDEX_MAGIC,
    METADATA_FILE,
    MODES,
    CameraMeta,
    FrameEntry,
    IndexEntry,
    RecordHeader,
    RecordingMetadata,
    parse_version,
    unpack_file_header,
    unpack_index_entry,
    unpack_record_header,
)

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
    _decoded: dict[int, tuple[int, NDArray[np.uint8]]] = field(default_factory=dict)
    """Per camera, the last frame decoded from a difference or a keyframe (the next one builds on it)."""
    _canvases: dict[int, Any] = field(default_factory=dict)
    """Per camera, the canvases windowed frames are rebuilt in (trackerd.recording.codec.Canvases)."""
    _whole: dict[int, int] = field(default_factory=dict)
    """Per camera, the last pair whose frame was checked to be whole (windows lie over it)."""
    _coder: Any = None
    _decode_lock: threading.Lock = field(default_factory=threading.Lock)

    # ------------------------------------------------------------------ opening

    @classmethod
    def open(cls, path: str | Path) -> Recording:
        """Open a recording folder; RecordingError when nothing of it can be read."""
        folder = Path(path)
        if not folder.exists():
            raise RecordingError(f"{folder}: no such recording")
        if not folder.is_dir():
            raise RecordingError(f"{folder}: not a recording (a recording is a folder holding {METADATA_FILE},"
                                 f" {DATA_FILE} and {INDEX_FILE})")
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
            major, _minor, _ = unpack_file_header(head, DATA_MAGIC, str(data_path))
            _check_major(major, str(data_path))
            mapped = mmap.mmap(data_fd, size, prot=mmap.PROT_READ) if size > FILE_HEADER.size else None
        finally:
            os.close(data_fd)
        recording = cls(folder, metadata, [], 0, size, [], mapped)
        recording._load_index()
        recording._recover_unindexed()
        if metadata.end is None:
            recording.problems.append(
                f"{folder / METADATA_FILE}: no end record: the recorder stopped without closing the recording"
                " (killed, crashed or power lost)"
            )
        elif metadata.end.pairs != len(recording.entries):
            recording.problems.append(
                f"{folder / METADATA_FILE}: says {metadata.end.pairs} pairs were written, {len(recording.entries)}"
                " are readable"
            )
        # No MADV_SEQUENTIAL: the kernel would drop each page once read, so a second replay (a loop,
        # a benchmark, a test) would read the disk again instead of the page cache.
        return recording

    def _load_index(self) -> None:
        try:
            self._read_index()
        finally:
            # Every entry taken counts as indexed, however the index ended (cut short, a damaged entry).
            self.indexed = len(self.entries)

    def _read_index(self) -> None:
        index_path = self.path / INDEX_FILE
        try:
            # Never more than the data it indexes (48 bytes per pair, whose record is larger): never a
            # FIFO either, which would wait for a writer, nor a device, which would never end.
            raw = read_bounded(index_path, FILE_HEADER.size + max(self.data_size, 1 << 20))
        except FileNotFoundError:
            self.problems.append(f"{index_path}: missing; pairs found by scanning {DATA_FILE}")
            return
        except (NotRegularFile, TooLarge) as err:
            self.problems.append(f"{err}; pairs found by scanning {DATA_FILE}")
            return
        except OSError as err:
            self.problems.append(f"{index_path}: cannot read ({err.strerror}); pairs found by scanning {DATA_FILE}")
            return
        try:
            major, _minor, entry_bytes = unpack_file_header(raw, INDEX_MAGIC, str(index_path))
            _check_major(major, str(index_path))
            if entry_bytes < INDEX_ENTRY.size:
                raise RecordingError(f"{index_path}: entries of {entry_bytes} bytes, fewer than {INDEX_ENTRY.size}")
        except RecordingError as err:
            self.problems.append(f"{err}; pairs found by scanning {DATA_FILE}")
            return
        body = memoryview(raw)[FILE_HEADER.size:]
        count = len(body) // entry_bytes
        expected_offset = FILE_HEADER.size
        for k in range(count):
            where = f"{index_path}: entry {k} (byte {FILE_HEADER.size + k * entry_bytes})"
            try:
                entry = unpack_index_entry(body[k * entry_bytes:(k + 1) * entry_bytes], entry_bytes, where)
            except RecordingError as err:
                self.problems.append(f"{err}; the index is used up to pair {k - 1}")
                return
            if entry.pair_index != k or entry.offset != expected_offset:
                self.problems.append(f"{where}: says pair {entry.pair_index} at byte {entry.offset}, expected pair"
                                     f" {k} at byte {expected_offset}; the index is used up to pair {k - 1}")
                return
            if entry.end > self.data_size:
                self.problems.append(f"{where}: pair {k} ends at byte {entry.end} but {DATA_FILE} has"
                                     f" {self.data_size} bytes (truncated)")
                return
            self.entries.append(entry)
            expected_offset = entry.end
        if len(body) % entry_bytes:
            self.problems.append(f"{index_path}: ends with a partial entry ({len(body) % entry_bytes} bytes), ignored")

    def _recover_unindexed(self) -> None:
        """Scan past the last indexed pair for complete records (written, not yet indexed)."""
        offset = self.entries[-1].end if self.entries else FILE_HEADER.size
        data_path = self.path / DATA_FILE
        while offset < self.data_size:
            k = len(self.entries)
            where = f"{data_path}: pair {k} at byte {offset}"
            available = self.data_size - offset
            try:
                header = unpack_record_header(self._view(offset, min(available, 1 << 16)), where)
            except RecordingError as err:
                if "cut short" in str(err):
                    self.problems.append(f"{where}: incomplete ({available} bytes of its header written); ignored")
                else:
                    self.problems.append(f"{err}; the {available} bytes from there on are ignored")
                return
            if header.pair_index != k:
                self.problems.append(f"{where}: the record there says it is pair {header.pair_index}; the"
                                     f" {available} bytes from there on are ignored")
                return
            if header.record_bytes > available:
                self.problems.append(f"{where}: incomplete ({available} of {header.record_bytes} bytes written);"
                                     " ignored")
                return
            self.entries.append(IndexEntry(offset, header.record_bytes, k, header.sequence, header.timestamp_ns))
            offset += header.record_bytes
        if len(self.entries) > self.indexed:
            self.problems.append(f"{data_path}: {len(self.entries) - self.indexed} complete pair(s) past the end of"
                                 f" the index (pairs {self.indexed}-{len(self.entries) - 1}), recovered")

    # ------------------------------------------------------------------ reading

    def __len__(self) -> int:
        return len(self.entries)

    @property
    def cameras(self):
        return self.metadata.cameras

    @property
    def duration_s(self) -> float:
        if len(self.entries) < 2:
            return 0.0
        return (self.entries[-1].timestamp_ns - self.entries[0].timestamp_ns) / 1e9

    @functools.cached_property
    def _data_name(self) -> str:
        """pairs.dat's path as text, for messages (made once: replay names it for every pair it reads)."""
        return str(self.path / DATA_FILE)

    def _view(self, offset: int, length: int) -> memoryview:
        if self._map is None:
            raise RecordingError(f"{self.path}: the recording is closed")
        return memoryview(self._map)[offset:offset + length]

    def header(self, index: int) -> RecordHeader:
        """Pair ``index``'s record header, checked against the index; RecordingError naming the damage."""
        entry = self.entries[index]
        where = f"{self._data_name}: pair {index} at byte {entry.offset}"
        # The whole record as a view (no copy): a newer MINOR's header may be longer than this version's.
        header = unpack_record_header(self._view(entry.offset, entry.record_bytes), where)
        if (header.pair_index, header.record_bytes) != (entry.pair_index, entry.record_bytes):
            raise RecordingError(f"{where}: the record (pair {header.pair_index}, {header.record_bytes} bytes) does"
                                 f" not match its index entry (pair {entry.pair_index}, {entry.record_bytes} bytes)")
        if len(header.frames) != len(self.cameras):
            raise RecordingError(f"{where}: {len(header.frames)} frames, the recording has {len(self.cameras)} cameras")
        return header

    def images(self, index: int, header: RecordHeader | None = None, *, verify: bool = True) -> list[NDArray[np.uint8]]:
        """Pair ``index``'s frames in camera order, read-only; with ``verify``, checksums are checked
        (RecordingError naming the camera and byte offset of a damaged frame). A frame stored as a
        difference or as windows is rebuilt from the frames it builds on, which are checked too."""
        header = header or self.header(index)
        return [self._frame(index, k, header, verify) for k in range(len(self.cameras))]

    def _stored(self, index: int, k: int, header: RecordHeader, verify: bool) -> tuple[memoryview, str, int]:
        """Camera ``k``'s payload in pair ``index`` (checked), where it is, and its offset."""
        offset = self.entries[index].offset + header.header_bytes + sum(f.stored_bytes for f in header.frames[:k])
        frame = header.frames[k]
        where = f"{self._data_name}: pair {index}, camera '{self.cameras[k].id}' (byte {offset})"
        stored = self._view(offset, frame.stored_bytes)
        if verify and zlib.crc32(stored) != frame.payload_crc32:
            raise RecordingError(f"{where}: frame checksum mismatch (the pixels are damaged)")
        return stored, where, offset

    def _frame(self, index: int, k: int, header: RecordHeader, verify: bool) -> NDArray[np.uint8]:
        frame = header.frames[k]
        cam = self.cameras[k]
        if frame.encoding in (ENCODING_RAW, ENCODING_DEFLATE):
            stored, where, offset = self._stored(index, k, header, verify)
            return self._full(stored, frame, cam, where, offset)
        with self._decode_lock:
            return self._rebuilt(index, k, header, verify)

    def _full(self, stored: memoryview, frame: FrameEntry, cam: CameraMeta, where: str, offset: int
              ) -> NDArray[np.uint8]:
        """A frame stored whole (raw, deflate, zstd)."""
        if frame.encoding == ENCODING_RAW:
            if frame.stored_bytes != cam.frame_bytes:
                raise RecordingError(f"{where}: {frame.stored_bytes} bytes, a {cam.pixel_format}"
                                     f" {cam.width_px}x{cam.height_px} frame has {cam.frame_bytes}")
            return np.frombuffer(self._map, np.uint8, cam.frame_bytes, offset).reshape(cam.shape)
        if frame.encoding == ENCODING_DEFLATE:
            try:
                # At most one byte more than a frame: a crafted frame cannot inflate to gigabytes.
                raw = zlib.decompressobj().decompress(stored, cam.frame_bytes + 1)
            except zlib.error as err:
                raise RecordingError(f"{where}: compressed frame does not decompress ({err})") from err
            if len(raw) != cam.frame_bytes:
                raise RecordingError(f"{where}: decompresses to {len(raw)} bytes, expected {cam.frame_bytes}")
            return np.frombuffer(raw, np.uint8).reshape(cam.shape)
        if frame.encoding == ENCODING_ZSTD:
            raw = self._zstd().decompress(stored, cam.frame_bytes, where)
            return np.frombuffer(raw, np.uint8).reshape(cam.shape)
        raise RecordingError(f"{where}: unknown frame encoding {frame.encoding} (a newer trackerd's?)")

    def _zstd(self) -> Any:
        if self._coder is None:
            from trackerd.recording.codec import ZstdCoder

            self._coder = ZstdCoder()
        return self._coder

    def _rebuilt(self, index: int, k: int, header: RecordHeader, verify: bool) -> NDArray[np.uint8]:
        """Camera ``k``'s frame of pair ``index`` for the compressed and windowed modes (under the lock)."""
        from trackerd.recording.codec import max_windows_bytes, undelta, unpack_windows

        cached = self._decoded.get(k)
        if cached is not None and cached[0] == index:
            return cached[1]
        cam = self.cameras[k]
        frame = header.frames[k]
        stored, where, offset = self._stored(index, k, header, verify)
        if frame.encoding in FULL_ENCODINGS:
            image = self._full(stored, frame, cam, where, offset)
        elif frame.encoding == ENCODING_ZSTD_DELTA:
            if index == 0:
                raise RecordingError(f"{where}: the first pair is stored as a difference to a pair before it")
            previous = self._base(index - 1, k, verify, where)
            difference = np.frombuffer(self._zstd().decompress(stored, cam.frame_bytes, where), np.uint8)
            image = undelta(difference.reshape(cam.shape), previous)
        elif frame.encoding == ENCODING_WINDOWS:
            data = self._zstd().decompress(stored, max_windows_bytes(cam.frame_bytes), where, at_most=True)
            base_pair, windows = unpack_windows(data, cam.shape, where)
            if base_pair >= index:
                raise RecordingError(f"{where}: its windows lie over pair {base_pair}, not an earlier pair")
            if self._whole.get(k) != base_pair:
                if self.header(base_pair).frames[k].encoding not in FULL_ENCODINGS:
                    raise RecordingError(f"{where}: its windows lie over pair {base_pair}, whose frame is not whole")
                self._whole[k] = base_pair  # checked once, not for each of the pairs over it
            base = self._base(base_pair, k, verify, where)
            canvases = self._canvases.get(k)
            if canvases is None:
                from trackerd.recording.codec import Canvases

                canvases = self._canvases[k] = Canvases()
            return canvases.frame(base_pair, base, windows)
        else:
            raise RecordingError(f"{where}: unknown frame encoding {frame.encoding} (a newer trackerd's?)")
        image.flags.writeable = False
        self._decoded[k] = (index, image)
        return image

    def _base(self, index: int, k: int, verify: bool, where: str) -> NDArray[np.uint8]:
        """The frame another builds on; RecordingError naming both when it cannot be read."""
        cached = self._decoded.get(k)
        if cached is not None and cached[0] == index:
            return cached[1]
        # Walk back to the nearest frame that is not a difference, then forward (in order, one at a time).
        first = index
        while first > 0 and self.header(first).frames[k].encoding == ENCODING_ZSTD_DELTA:
            cached = self._decoded.get(k)
            if cached is not None and cached[0] == first - 1:
                break
            first -= 1
        try:
            for j in range(first, index + 1):
                image = self._rebuilt(j, k, self.header(j), verify)
        except RecordingError as err:
            raise RecordingError(f"{where}: the frame it builds on cannot be read: {err}") from err
        return image

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


def make_pair(recording: Recording, header: RecordHeader, images: list[NDArray[np.uint8]],
              *, shift_ns: int = 0, host_ns: int | None = None, sequence: int | None = None) -> FramePair:
    """A FramePair from a record: timestamps moved by ``shift_ns``; ``host_ns`` replaces the frames'
    host timestamps (the replay's delivery time) when given."""
    frames = tuple(
        Frame(cam.id, entry.frame_id, entry.device_timestamp_ns,
              entry.host_timestamp_ns + shift_ns if host_ns is None else host_ns, cam.pixel_format, image)
        for cam, entry, image in zip(recording.cameras, header.frames, images, strict=True)
    )
    return FramePair(frames, header.timestamp_ns + shift_ns, header.skew_ns,
                     header.sequence if sequence is None else sequence)


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
    _check_major(major, str(path))
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
        raise RecordingError(f"{path}: {key}: {first['msg']}") from err
    if metadata.mode not in MODES:
        raise RecordingError(
            f"{path}: recording mode {metadata.mode!r} is newer than this trackerd reads ({', '.join(MODES)});"
            " upgrade trackerd to read it"
        )
    return metadata


def _check_major(major: int, where: str) -> None:
    if major > FORMAT_MAJOR:
        raise RecordingError(
            f"{where}: recording format {major}.x is newer than this trackerd reads ({FORMAT_VERSION});"
            " upgrade trackerd to read it"
        )
    if major < 1:
        raise RecordingError(f"{where}: recording format {major}.x does not exist")
