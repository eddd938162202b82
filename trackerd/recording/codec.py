"""Frame payloads of the compressed and windowed modes: zstd, differences, windows (docs/recording.md).

Pure functions on bytes and NumPy arrays, used by the writer and the reader.
Every decoder bounds what it produces by what the frame can hold (a crafted
payload cannot make the reader allocate more than one frame) and turns any
defect into a RecordingError naming ``where``.

Why zstd at level 1 on the difference to the previous frame (measured with
scripts/bench_codecs.py, docs/recording.md): on sensor-noisy 1080p Bayer frames
it is the only codec tried that both saves something (1.85-2.05x) and costs
about 3 ms of CPU a frame; zlib level 1 saves 1.5-1.8x for 33-47 ms, lz4 and
zstd's negative levels save nothing on noise (1.00x), zstd level 3 saves less
on differences for five times the CPU.
"""

from __future__ import annotations

import struct
import sys
from dataclasses import dataclass
from typing import cast

import numpy as np
import zstandard
from numpy.typing import NDArray

from trackerd.errors import RecordingError

ZSTD_LEVEL = 1

WINDOWS_HEADER = struct.Struct("<QI")
"""base_pair (u64: the record whose frame of this camera the windows lie over), n_windows (u32)."""
WINDOW = struct.Struct("<HHHH")
"""x_px, y_px, width_px, height_px of one window (top-left corner, in pixels of the frame)."""
MAX_WINDOWS = 64


@dataclass(frozen=True, slots=True)
class Window:
    """A rectangle of a frame, in pixels: columns x_px .. x_px + width_px, rows y_px .. y_px + height_px."""

    x_px: int
    y_px: int
    width_px: int
    height_px: int


class ZstdCoder:
    """A zstd compressor and decompressor (each object is for one thread)."""

    def __init__(self, level: int = ZSTD_LEVEL) -> None:
        self._compressor = zstandard.ZstdCompressor(level=level, write_content_size=True)
        self._decompressor = zstandard.ZstdDecompressor()

    def compress(self, data: bytes | memoryview | NDArray[np.uint8]) -> bytes:
        # An ndarray is a C-contiguous buffer like the others; numpy's stubs do not declare the buffer protocol.
        return self._compressor.compress(cast("memoryview", data))

    def decompress(
        self, stored: bytes | memoryview, expected_bytes: int, where: str, *, at_most: bool = False
    ) -> bytes:
        """The bytes of one zstd frame, which must say it holds ``expected_bytes`` (``at_most``: no
        more than that) before anything is allocated."""
        try:
            size = zstandard.frame_content_size(stored)
        except zstandard.ZstdError as err:
            raise RecordingError(f"{where}: compressed frame is not a zstd frame ({err})") from None
        if size < 0 or (size > expected_bytes if at_most else size != expected_bytes):
            said = "no size" if size < 0 else f"{size} bytes"
            raise RecordingError(
                f"{where}: compressed frame says it holds {said}, expected"
                f" {'at most ' if at_most else ''}{expected_bytes}"
            )
        try:
            out = self._decompressor.decompress(stored, max_output_size=max(size, 1))
        except zstandard.ZstdError as err:
            raise RecordingError(f"{where}: compressed frame does not decompress ({err})") from None
        if len(out) != size:
            raise RecordingError(f"{where}: decompresses to {len(out)} bytes, its header says {size}")
        return out


def delta(
    frame: NDArray[np.uint8], previous: NDArray[np.uint8], out: NDArray[np.uint8] | None = None
) -> NDArray[np.uint8]:
    """``frame - previous`` byte by byte, modulo 256 (same shapes), into ``out`` if given."""
    return np.subtract(frame, previous, out=out, dtype=np.uint8)


def undelta(difference: NDArray[np.uint8], previous: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """The frame whose :func:`delta` to ``previous`` is ``difference``."""
    return np.add(previous, difference, dtype=np.uint8)


def pack_windows(frame: NDArray[np.uint8], base_pair: int, windows: list[Window]) -> bytes:
    """The windows payload before compression: header, rectangles, then each window's pixels (rows
    top to bottom, as in the frame)."""
    parts = [WINDOWS_HEADER.pack(base_pair, len(windows))]
    parts += [WINDOW.pack(w.x_px, w.y_px, w.width_px, w.height_px) for w in windows]
    parts += [
        np.ascontiguousarray(frame[w.y_px : w.y_px + w.height_px, w.x_px : w.x_px + w.width_px]).tobytes()
        for w in windows
    ]
    return b"".join(parts)


def max_windows_bytes(frame_bytes: int) -> int:
    """The most a windows payload may decompress to: no more windows than MAX_WINDOWS, no more pixels
    than the frame has."""
    return WINDOWS_HEADER.size + MAX_WINDOWS * WINDOW.size + frame_bytes


def unpack_windows(data: bytes, shape: tuple[int, ...], where: str) -> tuple[int, list[tuple[Window, memoryview]]]:
    """(base_pair, [(window, its pixels)]) of a decompressed windows payload for frames of ``shape``;
    RecordingError when a window lies outside the frame or the lengths do not add up."""
    if len(data) < WINDOWS_HEADER.size:
        raise RecordingError(f"{where}: windows payload cut short ({len(data)} bytes)")
    base_pair, count = WINDOWS_HEADER.unpack_from(data)
    if count > MAX_WINDOWS:
        raise RecordingError(f"{where}: {count} windows, more than the {MAX_WINDOWS} a frame may have")
    channels = shape[2] if len(shape) == 3 else 1
    height, width = shape[:2]
    offset = WINDOWS_HEADER.size + count * WINDOW.size
    if len(data) < offset:
        raise RecordingError(f"{where}: windows payload cut short ({len(data)} bytes for {count} windows)")
    view = memoryview(data)
    out = []
    for k in range(count):
        window = Window(*WINDOW.unpack_from(data, WINDOWS_HEADER.size + k * WINDOW.size))
        if (
            window.width_px < 1
            or window.height_px < 1
            or window.x_px + window.width_px > width
            or window.y_px + window.height_px > height
        ):
            raise RecordingError(
                f"{where}: window {k} ({window.width_px}x{window.height_px} at {window.x_px},"
                f" {window.y_px}) is not inside the {width}x{height} frame"
            )
        size = window.width_px * window.height_px * channels
        if offset + size > len(data):
            raise RecordingError(f"{where}: window {k}'s pixels are cut short")
        out.append((window, view[offset : offset + size]))
        offset += size
    if offset != len(data):
        raise RecordingError(f"{where}: {len(data) - offset} bytes after the last window")
    return base_pair, out


@dataclass(slots=True)
class _Canvas:
    """One canvas: its pixels, which keyframe they are over (a :class:`Canvases` generation) and the
    windows put in."""

    pixels: NDArray[np.uint8]
    generation: int
    held: list[Window]


class Canvases:
    """Frames rebuilt from one camera's keyframe and windows, without copying the whole frame each time.

    A frame handed out is a read-only view of one of a few canvases. A canvas is used again only when
    nothing but this object refers to it any more (its reference count says so: the pipeline, a
    colour-watch thread or a caller keeping the frame keeps it out of use). A free canvas over the
    same keyframe gets back the keyframe's pixels under the windows it held, then the new windows; a
    free canvas over an earlier keyframe is overwritten with the new one in place (no new memory:
    a new 2 MB array costs its page faults on top of the copy). Only when every canvas is held is a
    new one made. What a caller holds never changes under it.
    """

    MAX_CANVASES = 32

    def __init__(self) -> None:
        self._key_index = -1
        self._key: NDArray[np.uint8] | None = None
        self._generation = 0
        """Counts the keyframes seen: a canvas over the current one has this generation."""
        self._canvases: list[_Canvas] = []
        self.copies = 0
        """Frames made by copying the whole keyframe (a new keyframe, or every canvas held)."""
        self.allocations = 0
        """Canvases made (each also counts as a copy)."""

    def _free(self, shape: tuple[int, ...]) -> _Canvas | None:
        """A canvas nothing else refers to: one over the current keyframe if there is one, else any
        of ``shape``."""
        other = None
        for canvas in self._canvases:
            # Referred to by the _Canvas and getrefcount's argument only: no frame handed out views it.
            if sys.getrefcount(canvas.pixels) <= 2:
                if canvas.generation == self._generation:
                    return canvas
                if other is None and canvas.pixels.shape == shape:
                    other = canvas
        return other

    def frame(
        self, key_index: int, key: NDArray[np.uint8], windows: list[tuple[Window, memoryview]]
    ) -> NDArray[np.uint8]:
        """``key`` (the frame of record ``key_index``) with ``windows`` in place, read-only."""
        if key_index != self._key_index or self._key is not key:
            self._key_index, self._key = key_index, key
            self._generation += 1
        found = self._free(key.shape)
        if found is None:
            canvas = _Canvas(key.copy(), self._generation, [])
            self.copies += 1
            self.allocations += 1
            if len(self._canvases) < self.MAX_CANVASES:
                self._canvases.append(canvas)
        elif found.generation != self._generation:
            canvas = found
            np.copyto(canvas.pixels, key)
            canvas.generation = self._generation
            canvas.held.clear()
            self.copies += 1
        else:
            canvas = found
            pixels = canvas.pixels
            for w in canvas.held:
                pixels[w.y_px : w.y_px + w.height_px, w.x_px : w.x_px + w.width_px] = key[
                    w.y_px : w.y_px + w.height_px, w.x_px : w.x_px + w.width_px
                ]
            canvas.held.clear()
        pixels = canvas.pixels
        for window, data in windows:
            block = np.frombuffer(data, np.uint8).reshape((window.height_px, window.width_px, *key.shape[2:]))
            pixels[window.y_px : window.y_px + window.height_px, window.x_px : window.x_px + window.width_px] = block
            canvas.held.append(window)
        view = pixels.view()
        view.flags.writeable = False
        return view


def clip_window(x0_px: float, y0_px: float, x1_px: float, y1_px: float, shape: tuple[int, ...]) -> Window | None:
    """The window covering [x0, x1) x [y0, y1), widened to even corners (a Bayer mosaic's 2x2 cells)
    and clipped to a frame of ``shape``; None when nothing of it is in the frame."""
    height, width = shape[:2]
    left = max(0, int(np.floor(x0_px)) & ~1)
    top = max(0, int(np.floor(y0_px)) & ~1)
    right = min(width, (int(np.ceil(x1_px)) + 1) & ~1)
    bottom = min(height, (int(np.ceil(y1_px)) + 1) & ~1)
    if right <= left or bottom <= top:
        return None
    return Window(left, top, right - left, bottom - top)
