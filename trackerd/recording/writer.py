"""Writing a recording: one pair at a time, append-only, crash-safe, stopping cleanly on a full disk.

:class:`RecordingWriter` is used by one thread (the recorder's writer thread,
or an import). Each pair becomes one ``os.writev`` of its record header and the
frames' own buffers (no copy of the pixels in Python), then one 48-byte write
of its index entry. Nothing is ever rewritten except recording.json, which is
replaced by an atomic rename when the recording is closed. Data is not fsynced:
a recorder that dies (even by SIGKILL) loses nothing the kernel already has, and
what a power cut loses is whatever the kernel had not yet written back (about
the last 30 s by default); `trackerd recording check` reports what survived.
"""

from __future__ import annotations

import contextlib
import ctypes
import datetime as dt
import errno
import json
import os
import zlib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np

import trackerd
from trackerd.acquisition.frame import FramePair
from trackerd.config.models import RigConfig
from trackerd.errors import RecordingError, TrackerdError
from trackerd.recording.checksum import frame_crc32
from trackerd.recording.codec import ZstdCoder, delta, pack_windows
from trackerd.recording.format import (
    DATA_FILE,
    DATA_MAGIC,
    ENCODING_DEFLATE,
    ENCODING_RAW,
    ENCODING_WINDOWS,
    ENCODING_ZSTD,
    ENCODING_ZSTD_DELTA,
    FILE_HEADER,
    FLAG_KEYFRAME,
    INDEX_ENTRY,
    INDEX_FILE,
    INDEX_MAGIC,
    METADATA_FILE,
    MODE_VERSIONS,
    MODES,
    CameraMeta,
    Compression,
    EndMeta,
    FrameEntry,
    IndexEntry,
    Mode,
    RecordHeader,
    RecordingMetadata,
    pack_file_header,
    pack_index_entry,
    pack_record_header,
)

_DISK_FULL_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)
SYNC_FILE_RANGE_WRITE = 2


def _sync_file_range() -> Any:
    """Linux's sync_file_range(2) through ctypes (Python's os module lacks it), or None."""
    try:
        function = ctypes.CDLL(None, use_errno=True).sync_file_range
    except (OSError, AttributeError):
        return None
    function.argtypes = (ctypes.c_int, ctypes.c_int64, ctypes.c_int64, ctypes.c_uint)
    function.restype = ctypes.c_int
    return function


_START_WRITEBACK = _sync_file_range()


class DiskFullError(RecordingError):
    """The disk (or the free-space limit) has no room for the next pair; what was written stays readable."""


def utc_now() -> str:
    return dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def free_space_bytes(path: Path) -> int:
    """Bytes an unprivileged writer may still use on the filesystem holding ``path``."""
    stats = os.statvfs(path)
    return stats.f_bavail * stats.f_frsize


def check_free_space(path: Path, min_free_space_mb: float) -> None:
    """DiskFullError when the filesystem ``path`` would be made on has less than ``min_free_space_mb``
    free (checked before anything is created, so a refused recording leaves nothing behind)."""
    from trackerd.recording.outputs import existing_ancestor

    if min_free_space_mb <= 0:
        return
    try:
        free = free_space_bytes(existing_ancestor(path))
    except OSError:
        return  # the creation that follows says what is wrong with the path
    if free < min_free_space_mb * 1e6:
        raise DiskFullError(
            f"{path}: only {free / 1e6:.0f} MB free, less than the {min_free_space_mb:.0f} MB the recording must"
            " leave (min_free_space_mb); nothing was recorded"
        )


def _remove_recording(folder: Path, and_folder: bool = True) -> None:
    """Remove the files of a recording this writer began but could not set up, and its folder."""
    for name in (METADATA_FILE, METADATA_FILE + ".tmp", DATA_FILE, INDEX_FILE):
        with contextlib.suppress(OSError):
            (folder / name).unlink()
    if and_folder:
        with contextlib.suppress(OSError):
            folder.rmdir()


def rig_snapshot(rig: RigConfig) -> dict[str, Any]:
    """The rig as JSON for recording.json, as a rig file would say it: calibration merged in (so the
    file name is dropped) and defaults left out (so a later trackerd that adds or renames a setting
    still reads it, as it reads the rig file)."""
    return rig.model_copy(update={"calibration": None}).model_dump(mode="json", exclude_defaults=True)


def build_metadata(
    rig: RigConfig,
    pair: FramePair,
    *,
    producer: str,
    clock_offset_ns: int,
    camera_info: Mapping[str, Mapping[str, str | None]] | None = None,
    rig_file: str | Path | None = None,
    calibration_file: str | Path | None = None,
    notes: str | None = None,
) -> RecordingMetadata:
    """Metadata for a recording whose first pair is ``pair``: formats and sizes come from its frames,
    serials from the rig, and vendor/model/serial from ``camera_info`` (by camera id) when known.
    Without ``calibration_file``, the rig's ``calibration`` is taken relative to ``rig_file``, as
    the loader reads it."""
    if calibration_file is None and rig_file is not None and rig.calibration is not None:
        calibration_file = (Path(rig_file).parent / rig.calibration).resolve()
    by_id = {cam.id: cam for cam in rig.cameras}
    cameras = []
    for frame in pair.frames:
        cfg = by_id.get(frame.camera_id)
        info = dict((camera_info or {}).get(frame.camera_id, {}))
        height, width = frame.image.shape[:2]
        cameras.append(
            CameraMeta(
                id=frame.camera_id,
                pixel_format=frame.pixel_format,
                width_px=width,
                height_px=height,
                serial=info.get("serial") or (cfg.serial if cfg else None),
                vendor=info.get("vendor"),
                model=info.get("model"),
                device=info.get("device") or (cfg and (cfg.address or cfg.device_id)) or None,
            )
        )
    return RecordingMetadata(
        created_utc=utc_now(),
        trackerd_version=trackerd.__version__,
        producer=producer,
        clock_offset_ns=clock_offset_ns,
        cameras=tuple(cameras),
        rig=rig_snapshot(rig),
        rig_file=None if rig_file is None else str(rig_file),
        calibration_file=None if calibration_file is None else str(calibration_file),
        notes=notes,
    )


def write_metadata(folder: Path, metadata: RecordingMetadata) -> None:
    """Replace recording.json atomically (a reader sees the old or the new file, never half of one)."""
    text = json.dumps(metadata.model_dump(mode="json"), indent=2) + "\n"
    tmp = folder / (METADATA_FILE + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, folder / METADATA_FILE)


class RecordingWriter:
    """Creates the recording at ``path`` and appends pairs to it; close() finishes it."""

    def __init__(
        self,
        path: str | Path,
        metadata: RecordingMetadata,
        *,
        compression: Compression = "none",
        compression_level: int = 1,
        min_free_space_mb: float = 0.0,
        mode: Mode = "raw",
        keyframe_interval_s: float = 1.0,
        window_margin_px: int = 8,
        planner: Any = None,
    ) -> None:
        """``compression`` applies to the raw mode (frame by frame deflate). The compressed and windowed
        modes write a keyframe (every frame full) at least every ``keyframe_interval_s`` of recorded
        time; the windowed mode takes its windows from ``planner`` (a
        trackerd.recording.windowed.WindowPlanner; by default one for the recorded rig)."""
        if mode not in MODES:
            raise RecordingError(f"{path}: unknown recording mode {mode!r} (one of {', '.join(MODES)})")
        if mode != "raw":
            compression = "none"
            update: dict[str, Any] = {"keyframe_interval_s": keyframe_interval_s}
            if mode == "windowed":
                update["window_margin_px"] = window_margin_px
        else:
            update = {}
        major, minor = MODE_VERSIONS[mode]
        metadata = metadata.model_copy(update={"mode": mode, "format_version": f"{major}.{minor}", **update})
        self.mode = mode
        self._version = (major, minor)
        self._keyframe_ns = int(keyframe_interval_s * 1e9)
        self._last_key_ns: int | None = None
        self._last_key_pair = 0
        self._previous: list[np.ndarray] | None = None
        self._difference: list[np.ndarray] = []
        self._zstd = ZstdCoder() if mode != "raw" else None
        self._planner = planner
        if mode == "windowed" and planner is None:
            from trackerd.recording.windowed import WindowPlanner

            self._planner = WindowPlanner.for_metadata(metadata, margin_px=window_margin_px)
        self.keyframes = 0
        """Records written with every frame full (compressed and windowed modes)."""
        self.path = Path(path)
        self.metadata = metadata
        self._encoding = ENCODING_DEFLATE if compression == "deflate" else ENCODING_RAW
        self._level = compression_level
        self._min_free = int(min_free_space_mb * 1e6)
        self._cameras = metadata.cameras
        self.pairs = 0
        """Pairs written."""
        self.data_bytes = 0
        """Bytes of pairs.dat, file header included."""
        self.payload_bytes = 0
        """Bytes of frames written, as stored."""
        self.closed = False
        if self.path.exists() and (not self.path.is_dir() or any(self.path.iterdir())):
            raise RecordingError(f"{self.path}: already exists; give a new name for the recording")
        check_free_space(self.path, min_free_space_mb)
        created = self._created = not self.path.exists()
        fds: list[int] = []
        try:
            self.path.mkdir(parents=True, exist_ok=True)
            write_metadata(self.path, metadata)
            flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC
            fds.append(os.open(self.path / DATA_FILE, flags, 0o644))
            fds.append(os.open(self.path / INDEX_FILE, flags, 0o644))
            self._data, self._index = fds
            _write_all(self._data, [pack_file_header(DATA_MAGIC, 0, self._version)])
            _write_all(self._index, [pack_file_header(INDEX_MAGIC, INDEX_ENTRY.size, self._version)])
        except OSError as err:
            # Nothing of a recording that could not be begun stays behind: a half-made folder would
            # read as "not a trackerd recording" and make a second attempt say "already exists".
            for fd in fds:
                with contextlib.suppress(OSError):
                    os.close(fd)
            if created:
                _remove_recording(self.path)
            raise _os_error(self.path, "cannot create the recording", err) from err
        self.data_bytes = FILE_HEADER.size
        self._index_bytes = FILE_HEADER.size

    @property
    def compression(self) -> str:
        if self.mode != "raw":
            return "zstd"
        return "deflate" if self._encoding == ENCODING_DEFLATE else "none"

    def write(self, pair: FramePair, dropped_before: int = 0) -> int:
        """Append one pair; returns the bytes it took. DiskFullError when there is no room (the
        recording then ends at the previous pair), RecordingError for a frame that does not fit."""
        if self.closed:
            raise RecordingError(f"{self.path}: the recording is closed")
        payloads, encodings, keyframe = self._payloads(pair)
        entries = tuple(
            FrameEntry(
                frame.frame_id,
                frame.device_timestamp_ns,
                frame.host_timestamp_ns,
                len(payload),
                frame_crc32(payload),
                encoding,
            )
            for frame, payload, encoding in zip(pair.frames, payloads, encodings, strict=True)
        )
        header = RecordHeader(
            self.pairs,
            pair.sequence,
            pair.timestamp_ns,
            pair.skew_ns,
            dropped_before,
            entries,
            FLAG_KEYFRAME if keyframe and self.mode != "raw" else 0,
        )
        record_bytes = header.record_bytes
        if self._min_free:
            free = free_space_bytes(self.path)
            if free - record_bytes < self._min_free:
                raise DiskFullError(
                    f"{self.path}: stopped at {self.pairs} pairs: {free / 1e6:.0f} MB left on the disk, and"
                    f" the recording must leave {self._min_free / 1e6:.0f} MB (min_free_space_mb)"
                )
        start = self.data_bytes
        try:
            _write_all(self._data, [pack_record_header(header), *payloads])
        except OSError as err:
            _truncate(self._data, start)
            raise _os_error(self.path / DATA_FILE, f"stopped at {self.pairs} pairs", err) from err
        entry = IndexEntry(start, record_bytes, self.pairs, pair.sequence, pair.timestamp_ns)
        try:
            _write_all(self._index, [pack_index_entry(entry)])
        except OSError as err:
            _truncate(self._index, self._index_bytes)
            _truncate(self._data, start)
            raise _os_error(self.path / INDEX_FILE, f"stopped at {self.pairs} pairs", err) from err
        self.data_bytes = start + record_bytes
        self._index_bytes += INDEX_ENTRY.size
        if _START_WRITEBACK is not None:
            # Start writing the pair to the disk now rather than when the kernel's dirty-page limit
            # is reached: at ~250 MB/s that limit is hit after some 20 s, and the kernel then stalls
            # the writer for most of a second (47 pairs queued at 60 pairs/s, measured) to catch up.
            _START_WRITEBACK(self._data, start, record_bytes, SYNC_FILE_RANGE_WRITE)
        self.payload_bytes += record_bytes - header.header_bytes
        if keyframe and self.mode != "raw":
            self.keyframes += 1
            self._last_key_ns, self._last_key_pair = pair.timestamp_ns, self.pairs
        self.pairs += 1
        return record_bytes

    def _keyframe_due(self, pair: FramePair) -> bool:
        return self._last_key_ns is None or pair.timestamp_ns - self._last_key_ns >= self._keyframe_ns

    def _payloads(self, pair: FramePair) -> tuple[Sequence[memoryview | bytes], list[int], bool]:
        """Each frame's payload and encoding, and whether the record is a keyframe."""
        raws = self._raw_frames(pair)
        n = len(raws)
        if self.mode == "raw":
            if self._encoding == ENCODING_DEFLATE:
                return [zlib.compress(raw, self._level) for raw in raws], [ENCODING_DEFLATE] * n, True
            return list(raws), [ENCODING_RAW] * n, True
        assert self._zstd is not None
        images = [np.ascontiguousarray(frame.image, dtype=np.uint8) for frame in pair.frames]
        if self.mode == "compressed":
            keyframe = self._keyframe_due(pair) or self._previous is None
            if self._previous is None:
                self._previous = [np.empty_like(image) for image in images]
                self._difference = [np.empty_like(image) for image in images]
            if keyframe:
                payloads = [self._zstd.compress(raw) for raw in raws]
                encodings = [ENCODING_ZSTD] * n
            else:
                payloads = []
                for image, previous, difference in zip(images, self._previous, self._difference, strict=True):
                    payloads.append(self._zstd.compress(delta(image, previous, out=difference)))
                encodings = [ENCODING_ZSTD_DELTA] * n
            for image, previous in zip(images, self._previous, strict=True):
                # A copy (into the same buffer each time): the camera may reuse its buffer once the pair is written.
                np.copyto(previous, image)
            return payloads, encodings, keyframe
        plan = self._planner.plan(pair, self._keyframe_due(pair), self.pairs)
        if plan.keyframe:
            return [self._zstd.compress(raw) for raw in raws], [ENCODING_ZSTD] * n, True
        payloads = [
            self._zstd.compress(pack_windows(image, self._last_key_pair, windows))
            for image, windows in zip(images, plan.windows, strict=True)
        ]
        return payloads, [ENCODING_WINDOWS] * n, False

    def _raw_frames(self, pair: FramePair) -> list[memoryview]:
        if len(pair.frames) != len(self._cameras):
            raise RecordingError(
                f"{self.path}: a pair of {len(pair.frames)} frames; this recording holds {len(self._cameras)} cameras"
            )
        out: list[memoryview] = []
        for frame, cam in zip(pair.frames, self._cameras, strict=True):
            image = frame.image
            if frame.camera_id != cam.id or frame.pixel_format != cam.pixel_format or image.shape != cam.shape:
                height, width = image.shape[:2]
                raise RecordingError(
                    f"{self.path}: camera '{frame.camera_id}' sent a {frame.pixel_format} {width}x{height} frame;"
                    f" this recording holds {cam.pixel_format} {cam.width_px}x{cam.height_px} frames from"
                    f" '{cam.id}' (a reconfigured camera needs a new recording)"
                )
            contiguous = np.ascontiguousarray(image, dtype=np.uint8)
            # ndarray has the buffer protocol; numpy's stubs do not declare it.
            out.append(memoryview(cast("bytes", contiguous)).cast("B"))
        return out

    def close(self, reason: str = "stopped", dropped_pairs: int = 0) -> None:
        """Close the files and record how and why the recording ended; idempotent."""
        if self.closed:
            return
        self.closed = True
        for fd in (self._data, self._index):
            with contextlib.suppress(OSError):
                os.close(fd)
        end = EndMeta(
            closed_utc=utc_now(),
            pairs=self.pairs,
            dropped_pairs=dropped_pairs,
            data_bytes=self.data_bytes,
            reason=reason,
        )
        self.metadata = self.metadata.model_copy(update={"end": end})
        try:
            write_metadata(self.path, self.metadata)
        except OSError:
            # A full disk may not even take the small metadata file: the recording stays readable
            # without its end record (it reads as not closed cleanly).
            (self.path / (METADATA_FILE + ".tmp")).unlink(missing_ok=True)

    def close_after(self, err: TrackerdError, what: str, done: str) -> None:
        """Close the recording after ``err`` stopped ``what`` (an import, a conversion), and say with the error
        what is left, so that a user does not take it for the whole: "the N pairs <done> before it are left in
        OUT", or, a recording that holds no pair being removed, "nothing was <done>"."""
        self.close(f"error: {what} interrupted")
        if self.discard_if_empty():
            err.args = (f"{str(err).removesuffix(KEPT)}; nothing was {done}",)
        else:
            err.args = (f"{err}; the {self.pairs} pairs {done} before it are left in {self.path}",)

    def discard_if_empty(self) -> bool:
        """After :meth:`close`: remove a recording that holds no pair (its first write failed: a full disk),
        as one that could not be begun is, so that "nothing was recorded" leaves nothing behind (an empty
        shell, its end record unwritten on the full disk, read as a recording the recorder did not finish).
        The folder goes only if this writer made it. True when the recording was removed."""
        if not self.closed or self.pairs:
            return False
        _remove_recording(self.path, and_folder=self._created)
        return True


KEPT = "; what was written stays readable"
"""How a disk-full error ends: what the recording holds stays readable."""


def _write_all(fd: int, buffers: Sequence[bytes | memoryview]) -> None:
    """writev until every byte is written (a regular file may take a write in parts)."""
    views = [memoryview(b).cast("B") for b in buffers]
    while views:
        written = os.writev(fd, views)
        while views and written >= len(views[0]):
            written -= len(views[0])
            views.pop(0)
        if views and written:
            views[0] = views[0][written:]


def _truncate(fd: int, size: int) -> None:
    """Cut a file back to its last complete item, so a failed write leaves no torn remains."""
    try:
        os.ftruncate(fd, size)
        os.lseek(fd, size, os.SEEK_SET)
    except OSError:
        pass  # the reader ignores a torn tail anyway


def _os_error(path: Path, doing: str, err: OSError) -> RecordingError:
    if err.errno in _DISK_FULL_ERRNOS:
        return DiskFullError(f"{path}: disk full, {doing} ({err.strerror}){KEPT}")
    return RecordingError(f"{path}: {doing}: {err.strerror or err}")
