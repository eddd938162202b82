"""A recording's frames rebuilt from what pairs.dat stores: whole, as a difference, or as windows.

A frame stored whole (raw) is served as a read-only view into the memory map; a compressed one is
decompressed into its own buffer. A difference (zstd-delta) builds on the frame before it, and
windows build on the last whole frame (docs/recording.md, "Modes"): :class:`FrameDecoder` keeps, per
camera, the last frame it rebuilt, so reading pairs in order decodes each frame once.

Each camera's frames build only on that camera's earlier frames, so each camera has its own lock and
its own zstd decompressor: two threads can rebuild the two cameras' frames of a pair at once (zstd and
NumPy let go of the GIL while they work; :meth:`Recording.images` with a ``pool``).
"""

from __future__ import annotations

import threading
import zlib
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from trackerd.errors import RecordingError
from trackerd.recording.checksum import frame_crc32
from trackerd.recording.format import (
    ENCODING_DEFLATE,
    ENCODING_RAW,
    ENCODING_WINDOWS,
    ENCODING_ZSTD,
    ENCODING_ZSTD_DELTA,
    FULL_ENCODINGS,
    CameraMeta,
    FrameEntry,
    RecordHeader,
)

if TYPE_CHECKING:
    from trackerd.recording.codec import Canvases, ZstdCoder
    from trackerd.recording.reader import Recording


class FrameDecoder:
    """Reads and rebuilds one open recording's frames; safe to call from several threads."""

    def __init__(self, recording: Recording) -> None:
        self._recording = recording
        self._decoded: dict[int, tuple[int, NDArray[np.uint8]]] = {}
        """Per camera, the last frame decoded from a difference or a keyframe (the next one builds on it)."""
        self._canvases: dict[int, Canvases] = {}
        """Per camera, the canvases windowed frames are rebuilt in."""
        self._whole: dict[int, int] = {}
        """Per camera, the last pair whose frame was checked to be whole (windows lie over it)."""
        self._coders: dict[int, ZstdCoder] = {}
        """Per camera: a zstd decompressor serves one thread at a time."""
        self._locks = tuple(threading.Lock() for _ in recording.cameras)
        """Per camera: everything above for camera k is touched under lock k only."""

    def _stored(self, index: int, k: int, header: RecordHeader, verify: bool) -> tuple[memoryview, str]:
        """Camera ``k``'s payload in pair ``index`` (checked) and where it is, for messages."""
        recording = self._recording
        offset = recording.entries[index].offset + header.header_bytes + sum(f.stored_bytes for f in header.frames[:k])
        frame = header.frames[k]
        where = f"{recording.data_name}: pair {index}, camera '{recording.cameras[k].id}' (byte {offset})"
        stored = recording.view(offset, frame.stored_bytes)
        if verify and frame_crc32(stored) != frame.payload_crc32:
            raise RecordingError(f"{where}: frame checksum mismatch (the pixels are damaged)")
        return stored, where

    def frame(self, index: int, k: int, header: RecordHeader, verify: bool) -> NDArray[np.uint8]:
        """Camera ``k``'s frame of pair ``index``, read-only (see :meth:`Recording.images`)."""
        frame = header.frames[k]
        cam = self._recording.cameras[k]
        if frame.encoding in (ENCODING_RAW, ENCODING_DEFLATE):
            stored, where = self._stored(index, k, header, verify)
            return self._full(k, stored, frame, cam, where)
        with self._locks[k]:
            return self._rebuilt(index, k, header, verify)

    def _full(self, k: int, stored: memoryview, frame: FrameEntry, cam: CameraMeta, where: str) -> NDArray[np.uint8]:
        """Camera ``k``'s frame stored whole (raw, deflate, zstd: under lock k)."""
        if frame.encoding == ENCODING_RAW:
            if frame.stored_bytes != cam.frame_bytes:
                raise RecordingError(
                    f"{where}: {frame.stored_bytes} bytes, a {cam.pixel_format}"
                    f" {cam.width_px}x{cam.height_px} frame has {cam.frame_bytes}"
                )
            return np.frombuffer(stored, np.uint8).reshape(cam.shape)  # a view into the memory map
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
            raw = self._zstd(k).decompress(stored, cam.frame_bytes, where)
            return np.frombuffer(raw, np.uint8).reshape(cam.shape)
        raise RecordingError(f"{where}: unknown frame encoding {frame.encoding} (a newer trackerd's?)")

    def _zstd(self, k: int) -> ZstdCoder:
        """Camera ``k``'s decompressor (under lock k)."""
        coder = self._coders.get(k)
        if coder is None:
            from trackerd.recording.codec import ZstdCoder

            coder = self._coders[k] = ZstdCoder()
        return coder

    def _rebuilt(self, index: int, k: int, header: RecordHeader, verify: bool) -> NDArray[np.uint8]:
        """Camera ``k``'s frame of pair ``index`` for the compressed and windowed modes (under lock k)."""
        from trackerd.recording.codec import max_windows_bytes, undelta, unpack_windows

        cached = self._decoded.get(k)
        if cached is not None and cached[0] == index:
            return cached[1]
        cam = self._recording.cameras[k]
        frame = header.frames[k]
        stored, where = self._stored(index, k, header, verify)
        if frame.encoding in FULL_ENCODINGS:
            image = self._full(k, stored, frame, cam, where)
        elif frame.encoding == ENCODING_ZSTD_DELTA:
            if index == 0:
                raise RecordingError(f"{where}: the first pair is stored as a difference to a pair before it")
            previous = self._base(index - 1, k, verify, where)
            difference = np.frombuffer(self._zstd(k).decompress(stored, cam.frame_bytes, where), np.uint8)
            image = undelta(difference.reshape(cam.shape), previous)
        elif frame.encoding == ENCODING_WINDOWS:
            data = self._zstd(k).decompress(stored, max_windows_bytes(cam.frame_bytes), where, at_most=True)
            base_pair, windows = unpack_windows(data, cam.shape, where)
            if base_pair >= index:
                raise RecordingError(f"{where}: its windows lie over pair {base_pair}, not an earlier pair")
            if self._whole.get(k) != base_pair:
                if self._recording.record_header(base_pair).frames[k].encoding not in FULL_ENCODINGS:
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
        while first > 0 and self._recording.record_header(first).frames[k].encoding == ENCODING_ZSTD_DELTA:
            cached = self._decoded.get(k)
            if cached is not None and cached[0] == first - 1:
                break
            first -= 1
        try:
            for j in range(first, index + 1):
                image = self._rebuilt(j, k, self._recording.record_header(j), verify)
        except RecordingError as err:
            raise RecordingError(f"{where}: the frame it builds on cannot be read: {err}") from err
        return image
