"""The recording format, version 1: byte layouts, their packing and checking (docs/recording.md is the spec).

A recording is a folder (by convention named ``*.trec``) holding three files:

``recording.json``
    metadata (:class:`RecordingMetadata`): format version, cameras, the rig in
    force, the clock offset; written before the first pair and rewritten (by
    an atomic rename) with an ``end`` object when the recording is closed.
``pairs.dat``
    a 16-byte file header, then one record per pair, appended and never
    rewritten: a record header (timestamps, frame ids, lengths, checksums)
    followed by each camera's frame payload in rig order.
``pairs.idx``
    a 16-byte file header, then one fixed-size entry per pair, appended after
    the pair's record is complete: where the record is and its timestamps.

Every integer is little-endian. Each record header and each index entry
carries a CRC-32 (zlib's, the one of PNG and gzip) of its own bytes, and each
payload a CRC-32 of its stored bytes, so a reader can tell a complete pair from
a torn or damaged one. Because records are written before their index entries,
a recorder killed at any instant leaves a recording whose index lists only
complete pairs, possibly followed by complete pairs not yet indexed (found by
scanning) and then the torn remains of the last one (ignored).
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass, field
from typing import Final, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from trackerd.errors import RecordingError

FORMAT_NAME: Final = "trackerd-recording"
FORMAT_MAJOR = 2
FORMAT_MINOR = 0
FORMAT_VERSION = f"{FORMAT_MAJOR}.{FORMAT_MINOR}"
"""MAJOR.MINOR, the newest this trackerd reads. A reader accepts every MINOR of the MAJORs it knows:
a newer MINOR only adds metadata keys (ignored) or bytes that the lengths stored in the file let a
reader skip."""

Mode = Literal["raw", "compressed", "windowed"]
MODES: tuple[str, ...] = ("raw", "compressed", "windowed")
"""How a recording stores its frames (recording.json ``mode``): every frame as the camera sent it
(raw, optionally deflated frame by frame); every frame losslessly compressed (zstd, most of them as
the difference to the camera's previous frame); or only the windows the tracker reads, over full
keyframes (windowed)."""

MODE_VERSIONS: dict[str, tuple[int, int]] = {"raw": (1, 1), "compressed": (2, 0), "windowed": (2, 0)}
"""The version each mode is written as. A raw recording stays MAJOR 1, which every trackerd reads
(1.1 only adds ``mode``); the compressed and windowed modes are MAJOR 2, so a trackerd that knows
only MAJOR 1 refuses them in one line rather than failing on every frame."""

METADATA_FILE = "recording.json"
DATA_FILE = "pairs.dat"
INDEX_FILE = "pairs.idx"

DATA_MAGIC = b"TRKDDATA"
INDEX_MAGIC = b"TRKDINDX"
FILE_HEADER = struct.Struct("<8sHHI")
"""Both binary files begin with: magic (8 bytes), major u16, minor u16, u32 (pairs.dat: 0;
pairs.idx: the size of one index entry)."""

RECORD_MAGIC = b"PAIR"
RECORD_FIXED = struct.Struct("<4sIHHIQQqqII")
"""magic, header_bytes, n_frames, frame_entry_bytes, flags, pair_index, sequence, timestamp_ns,
skew_ns, dropped_before, reserved: 56 bytes."""
FRAME_ENTRY = struct.Struct("<QQqQIB3x")
"""frame_id, device_timestamp_ns, host_timestamp_ns, stored_bytes, payload_crc32, encoding: 40 bytes."""
RECORD_TRAILER = struct.Struct("<II")
"""reserved, header_crc32 (of every header byte before it): 8 bytes; the checksum is always the
header's last four bytes."""

INDEX_ENTRY = struct.Struct("<QQQqqII")
"""offset, record_bytes, pair_index, sequence, timestamp_ns, reserved, entry_crc32 (of the 44
bytes before it): 48 bytes."""

ENCODING_RAW = 0
ENCODING_DEFLATE = 1
ENCODING_ZSTD = 2
ENCODING_ZSTD_DELTA = 3
ENCODING_WINDOWS = 4
ENCODINGS = {
    ENCODING_RAW: "none",
    ENCODING_DEFLATE: "deflate",
    ENCODING_ZSTD: "zstd",
    ENCODING_ZSTD_DELTA: "zstd-delta",
    ENCODING_WINDOWS: "windows",
}
"""Payload encodings: the raw frame bytes; a zlib stream (RFC 1950) of them; a zstd frame (RFC 8878)
of them; a zstd frame of their difference (byte by byte, modulo 256) to the same camera's frame in
the previous record; a zstd frame of windows of the frame over a full frame of an earlier record
(trackerd/recording/codec.py). The first three are full frames."""
FULL_ENCODINGS = (ENCODING_RAW, ENCODING_DEFLATE, ENCODING_ZSTD)

FLAG_KEYFRAME = 1
"""Record header flag: every frame of the record is full (a decoder can start here)."""

Compression = Literal["none", "deflate"]


# --------------------------------------------------------------------------- metadata


STORED_PIXEL_FORMATS: Final = ("BayerRG8", "BayerGB8", "BayerGR8", "BayerBG8", "RGB8", "BGR8", "Mono8")
"""The pixel formats a recording's frames are stored in: the rig's, one byte a pixel (three for RGB8, BGR8)."""


class _Meta(BaseModel):
    """Metadata objects ignore keys they do not know: a newer MINOR may add some."""

    model_config = ConfigDict(extra="ignore", frozen=True)


class CameraMeta(_Meta):
    """One camera of the recording, in rig order (the order of the frames in every record)."""

    id: str
    pixel_format: str
    """GenICam pixel format of the stored frames (BayerRG8, ..., RGB8, BGR8; Mono8 from a rig used to
    calibrate): one of STORED_PIXEL_FORMATS, the formats whose frame size :attr:`frame_bytes` knows."""
    width_px: int = Field(gt=0)
    height_px: int = Field(gt=0)
    serial: str | None = None
    vendor: str | None = None
    model: str | None = None
    device: str | None = None
    """How the camera was reached (address, device id), or where the frames came from."""

    @field_validator("pixel_format")
    @classmethod
    def _stored(cls, value: str) -> str:
        # Another format's frames have another size: checked against it, every frame would seem damaged or
        # (a 16-bit format's) the wrong half of each.
        if value not in STORED_PIXEL_FORMATS:
            raise ValueError(f"{value!r} is not a format a recording stores ({', '.join(STORED_PIXEL_FORMATS)})")
        return value

    @property
    def frame_bytes(self) -> int:
        """Bytes of one raw frame: rows top to bottom, no padding."""
        channels = 3 if self.pixel_format in ("RGB8", "BGR8") else 1
        return self.width_px * self.height_px * channels

    @property
    def shape(self) -> tuple[int, ...]:
        if self.pixel_format in ("RGB8", "BGR8"):
            return (self.height_px, self.width_px, 3)
        return (self.height_px, self.width_px)


class EndMeta(_Meta):
    """Written when the recording is closed; absent when the recorder died."""

    closed_utc: str
    pairs: int = Field(ge=0)
    dropped_pairs: int = Field(ge=0)
    """Pairs the recorder dropped because the disk fell behind."""
    data_bytes: int = Field(ge=0)
    reason: str
    """Why it ended: ``stopped``, ``pair limit``, ``time limit``, ``disk full: ...``, ``error: ...``."""


class RecordingMetadata(_Meta):
    """The contents of recording.json."""

    format: Literal["trackerd-recording"] = FORMAT_NAME
    format_version: str = FORMAT_VERSION
    created_utc: str
    """When the recording began, ISO 8601 UTC."""
    trackerd_version: str
    producer: str
    """What wrote it: ``trackerd record``, ``trackerd run`` (recording on demand), ``trackerd recording import``..."""
    clock_offset_ns: int
    """Add to a recorded monotonic timestamp (``timestamp_ns``, ``host_timestamp_ns``) to get
    nanoseconds since the UNIX epoch; replay publishes capture times with it."""
    cameras: tuple[CameraMeta, ...] = Field(min_length=1)
    rig: dict
    """The rig configuration in force (calibration merged in), as trackerd's RigConfig JSON."""
    rig_file: str | None = None
    """The rig file it was read from, for reference."""
    calibration_file: str | None = None
    notes: str | None = None
    mode: str = "raw"
    """How the frames are stored (MODES); absent in a 1.0 recording, which is raw. A reader refuses
    a mode it does not know, in one line."""
    keyframe_interval_s: float | None = None
    """compressed and windowed: the longest time between two records whose frames are all full."""
    window_margin_px: int | None = None
    """windowed: pixels added around each window the tracker was found to read."""
    end: EndMeta | None = None


def parse_version(text: str, where: str) -> tuple[int, int]:
    """``"1.0"`` -> (1, 0); RecordingError naming ``where`` otherwise."""
    try:
        major, minor = (int(part) for part in str(text).split("."))
    except ValueError:
        raise RecordingError(f"{where}: format_version {text!r} is not MAJOR.MINOR") from None
    return major, minor


# --------------------------------------------------------------------------- records


@dataclass(frozen=True, slots=True)
class FrameEntry:
    """One frame's line in a record header."""

    frame_id: int
    device_timestamp_ns: int
    host_timestamp_ns: int
    stored_bytes: int
    payload_crc32: int
    encoding: int


@dataclass(frozen=True, slots=True)
class RecordHeader:
    """Everything a record says about its pair, besides the pixels."""

    pair_index: int
    """0 for the first pair of the recording, then consecutive."""
    sequence: int
    """The source's pair sequence number (gaps: pairs the source or the pipeline dropped)."""
    timestamp_ns: int
    """Capture time of the pair, host monotonic clock."""
    skew_ns: int
    dropped_before: int
    """Pairs the recorder had to drop between the previous record and this one."""
    frames: tuple[FrameEntry, ...]
    flags: int = 0
    """FLAG_KEYFRAME when every frame of the record is full."""
    stored_header_bytes: int | None = field(default=None, compare=False)
    """``header_bytes`` as the file says, for a header read from a file: a newer MINOR's frame
    entries may be longer than this version's, so the header is; None for a header to be written."""

    @property
    def header_bytes(self) -> int:
        """The whole header, trailer included: where the first payload begins."""
        if self.stored_header_bytes is not None:
            return self.stored_header_bytes
        return header_size(len(self.frames))

    @property
    def record_bytes(self) -> int:
        return self.header_bytes + sum(f.stored_bytes for f in self.frames)


def header_size(n_frames: int) -> int:
    """Bytes of a record header with ``n_frames`` frames (144 for two)."""
    return RECORD_FIXED.size + n_frames * FRAME_ENTRY.size + RECORD_TRAILER.size


def pack_file_header(magic: bytes, extra: int, version: tuple[int, int] = (FORMAT_MAJOR, FORMAT_MINOR)) -> bytes:
    return FILE_HEADER.pack(magic, version[0], version[1], extra)


def unpack_file_header(data: bytes, magic: bytes, where: str) -> tuple[int, int, int]:
    """(major, minor, extra) of a binary file's header; RecordingError when it is not one."""
    if len(data) < FILE_HEADER.size:
        raise RecordingError(f"{where}: {len(data)} bytes, shorter than the {FILE_HEADER.size}-byte file header")
    found, major, minor, extra = FILE_HEADER.unpack_from(data)
    if found != magic:
        raise RecordingError(
            f"{where}: does not begin with {magic.decode()} (found {found!r}): not a trackerd recording file"
        )
    return major, minor, extra


def damaged_file_header(data: bytes, magic: bytes, where: str) -> str | None:
    """Why a binary file's header is damaged, for a recording whose recording.json this trackerd reads (so
    the recording is of a format it reads, whatever the header says); None when the header is sound.

    The header has no checksum of its own: a flipped version field read as a format "newer than this
    trackerd" and told the user to upgrade, and the whole recording was refused, although every record
    carries its own magic and checksums and can be read without it."""
    if len(data) < FILE_HEADER.size:
        return None  # too short to hold records either: the callers say so
    found, major, minor, _ = FILE_HEADER.unpack_from(data)
    if found == magic and 1 <= major <= FORMAT_MAJOR:
        return None
    said = f"begins {found!r}" if found != magic else f"says format {major}.{minor}"
    return f"{where}: its file header is damaged (it {said}; {METADATA_FILE} is of a format this trackerd reads)"


def pack_record_header(header: RecordHeader) -> bytes:
    fixed = RECORD_FIXED.pack(
        RECORD_MAGIC,
        header.header_bytes,
        len(header.frames),
        FRAME_ENTRY.size,
        header.flags,
        header.pair_index,
        header.sequence,
        header.timestamp_ns,
        header.skew_ns,
        header.dropped_before,
        0,
    )
    body = fixed + b"".join(
        FRAME_ENTRY.pack(
            f.frame_id, f.device_timestamp_ns, f.host_timestamp_ns, f.stored_bytes, f.payload_crc32, f.encoding
        )
        for f in header.frames
    )
    body += struct.pack("<I", 0)
    return body + struct.pack("<I", zlib.crc32(body))


def unpack_record_header(data: bytes | memoryview, where: str) -> RecordHeader:
    """Parse and check a record header starting at ``data[0]``; RecordingError naming ``where``.

    ``data`` may extend past the header. The header must be whole and its
    checksum must match; frame entries longer than this version's (a newer
    MINOR) are read up to this version's fields and the rest skipped, and the
    header's stored length (not this version's) says where the payloads begin.
    """
    if len(data) < RECORD_FIXED.size:
        raise RecordingError(f"{where}: record header cut short ({len(data)} of {RECORD_FIXED.size} bytes)")
    (
        magic,
        header_bytes,
        n_frames,
        entry_bytes,
        flags,
        pair_index,
        sequence,
        timestamp_ns,
        skew_ns,
        dropped_before,
        _reserved,
    ) = RECORD_FIXED.unpack_from(data)
    if magic != RECORD_MAGIC:
        raise RecordingError(f"{where}: no record here (expected {RECORD_MAGIC.decode()}, found {bytes(magic)!r})")
    if entry_bytes < FRAME_ENTRY.size or n_frames < 1:
        raise RecordingError(f"{where}: record header is damaged ({n_frames} frames of {entry_bytes} bytes)")
    expected = RECORD_FIXED.size + n_frames * entry_bytes + RECORD_TRAILER.size
    if header_bytes < expected:
        raise RecordingError(f"{where}: record header is damaged (claims {header_bytes} bytes, needs {expected})")
    if len(data) < header_bytes:
        raise RecordingError(f"{where}: record header cut short ({len(data)} of {header_bytes} bytes)")
    crc_at = header_bytes - 4
    (crc,) = struct.unpack_from("<I", data, crc_at)
    if zlib.crc32(memoryview(data)[:crc_at]) != crc:
        raise RecordingError(f"{where}: record header checksum mismatch (the header is damaged)")
    frames = []
    for k in range(n_frames):
        values = FRAME_ENTRY.unpack_from(data, RECORD_FIXED.size + k * entry_bytes)
        frames.append(FrameEntry(*values))
    return RecordHeader(pair_index, sequence, timestamp_ns, skew_ns, dropped_before, tuple(frames), flags, header_bytes)


@dataclass(frozen=True, slots=True)
class IndexEntry:
    """Where one pair's record lies in pairs.dat."""

    offset: int
    record_bytes: int
    pair_index: int
    sequence: int
    timestamp_ns: int

    @property
    def end(self) -> int:
        return self.offset + self.record_bytes


def pack_index_entry(entry: IndexEntry) -> bytes:
    body = INDEX_ENTRY.pack(
        entry.offset, entry.record_bytes, entry.pair_index, entry.sequence, entry.timestamp_ns, 0, 0
    )[:-4]
    return body + struct.pack("<I", zlib.crc32(body))


def unpack_index_entry(data: bytes | memoryview, entry_bytes: int, where: str) -> IndexEntry:
    """Parse and check one index entry (``entry_bytes`` long); RecordingError naming ``where``."""
    offset, record_bytes, pair_index, sequence, timestamp_ns, _reserved, crc = INDEX_ENTRY.unpack_from(data)
    if entry_bytes > INDEX_ENTRY.size:
        # A newer MINOR's longer entry: its checksum is its last four bytes, over all before them.
        (crc,) = struct.unpack_from("<I", data, entry_bytes - 4)
    if zlib.crc32(memoryview(data)[: entry_bytes - 4]) != crc:
        raise RecordingError(f"{where}: index entry checksum mismatch (the entry is damaged)")
    return IndexEntry(offset, record_bytes, pair_index, sequence, timestamp_ns)


def check_major(major: int, where: str) -> None:
    """RecordingError unless this trackerd reads files of format MAJOR ``major``."""
    if major > FORMAT_MAJOR:
        raise RecordingError(
            f"{where}: recording format {major}.x is newer than this trackerd reads ({FORMAT_VERSION});"
            " upgrade trackerd to read it"
        )
    if major < 1:
        raise RecordingError(f"{where}: recording format {major}.x does not exist")
