"""A simulated GigE Vision camera that serves pre-rendered frames (``python -m trackerd.sim.gvcamera``).

Aravis's ``GvFakeCamera`` speaks real GVCP/GVSP on one network interface; the
images it sends come from its *fill pattern* callback. PyGObject never calls a
Python fill pattern, so :class:`FillServer` installs a ctypes callback with
``arv_fake_camera_set_fill_pattern``. Aravis calls it on its own thread for
every frame, with the buffer's size already set (the callback's arguments are
buffer, user data, exposure, gain and pixel format). The callback:

* picks the loop frame for the current instant (``content_fps``, from a start
  time shared by every camera of the rig, so all cameras show the same scene);
* copies it into the buffer (cropped or padded to the requested region);
* writes a *tag* along the top-left edge: magic ``TRK1``, loop index, serve
  count and capture time, one bit per 2x2 cell in two nearby greys, so it reads
  the same in any Bayer layout and is never mistaken for the pointer's colours
  (:func:`read_tag` decodes it);
* replaces the device timestamp with this camera's simulated clock (an offset
  and a drift against the host's monotonic clock: the cameras of a real rig do
  not share a clock);
* appends the frame's ground truth to a JSONL file.

Free running, Aravis's fake camera starts every camera's frames at the same
instants (multiples of the frame period on the wall clock); ``phase_us``
delays this camera's capture by a fixed fraction of a period, as independent
free-running cameras would be. Software triggers are answered within about a
millisecond (the fake camera polls for them at ``trigger_frequency_hz``).
"""

from __future__ import annotations

import argparse
import ctypes
import ctypes.util
import json
import os
import signal
import struct
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

TAG_MAGIC = b"TRK1"
_TAG = struct.Struct("<4sIIQ")  # magic, loop index, serve count, capture time (monotonic ns)
TAG_LEVELS = (104, 136)
"""Grey values of a 0 bit and a 1 bit: close enough that demosaicing across two cells makes no
colour a detector threshold (40 levels of excess by default) would take for a ball."""
TAG_WIDTH_PX = 2 * 8 * _TAG.size
TRIGGER_POLL_HZ = 1000.0

_FILL = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_uint32, ctypes.c_uint32, ctypes.c_uint32)


@dataclass(frozen=True)
class FrameTag:
    """What the simulated camera stamped into a frame."""

    loop_index: int
    served: int
    capture_ns: int


def write_tag(image: NDArray[np.uint8], tag: FrameTag) -> None:
    """Stamp ``tag`` into the first two rows of a one-byte-per-pixel image (in place).

    Each bit is a 2x2 cell (one whole Bayer cell, so every colour plane sees the
    same grey) of ``TAG_LEVELS[bit]``; 20 bytes take the first 320 pixels.
    """
    if image.shape[1] < TAG_WIDTH_PX or image.shape[0] < 2:
        return
    payload = np.frombuffer(_TAG.pack(TAG_MAGIC, tag.loop_index, tag.served, tag.capture_ns), np.uint8)
    bits = np.unpackbits(payload)
    cells = np.repeat(np.where(bits, TAG_LEVELS[1], TAG_LEVELS[0]).astype(np.uint8), 2)
    image[0, :TAG_WIDTH_PX] = cells
    image[1, :TAG_WIDTH_PX] = cells


def read_tag(image: NDArray[np.uint8]) -> FrameTag | None:
    """The tag a simulated camera stamped into ``image``, or None if there is none."""
    if image.ndim != 2 or image.shape[1] < TAG_WIDTH_PX or image.shape[0] < 2:
        return None
    bits = image[0, :TAG_WIDTH_PX:2] >= (TAG_LEVELS[0] + TAG_LEVELS[1]) // 2
    magic, loop_index, served, capture_ns = _TAG.unpack(np.packbits(bits).tobytes())
    if magic != TAG_MAGIC:
        return None
    return FrameTag(loop_index, served, capture_ns)


@dataclass(frozen=True)
class FrameLoop:
    """Frames to serve in a loop, and each one's ground truth."""

    frames: NDArray[np.uint8]
    """(N, H, W) one byte per pixel (a memory map of the cached loop, usually)."""
    content_fps: float
    """Loop frames per second of scene time."""
    start_ns: int
    """Monotonic instant of loop frame 0; shared by every camera of a rig."""
    truth: tuple[dict[str, Any], ...] = ()
    """Per loop frame: motion_time_s, present, front_m, back_m, wall_xy_m, on_wall."""

    def index_at(self, now_ns: int) -> int:
        return int((now_ns - self.start_ns) * self.content_fps // 1_000_000_000) % len(self.frames)

    @classmethod
    def load(cls, frames_path: Path, truth_path: Path | None, content_fps: float, start_ns: int) -> FrameLoop:
        frames = np.load(frames_path, mmap_mode="r")
        truth: tuple[dict[str, Any], ...] = ()
        if truth_path is not None:
            truth = tuple(json.loads(truth_path.read_text())["frames"])
        return cls(frames, content_fps, start_ns, truth)

    @classmethod
    def synthetic(cls, width_px: int, height_px: int, start_ns: int, n_frames: int = 8, fps: float = 8.0) -> FrameLoop:
        """A cheap stand-in: a bright square stepping across a grey ramp (no ground truth)."""
        frames = np.empty((n_frames, height_px, width_px), np.uint8)
        ramp = (np.arange(width_px, dtype=np.uint32) * 96 // max(width_px, 1) + 64).astype(np.uint8)
        side = max(8, min(width_px, height_px) // 8)
        for i in range(n_frames):
            frames[i] = ramp[None, :]
            x0 = (i * (width_px - side)) // max(n_frames - 1, 1)
            frames[i, height_px // 2 - side // 2 : height_px // 2 + side // 2, x0 : x0 + side] = 230
        return cls(frames, fps, start_ns)


@dataclass(frozen=True)
class SimClock:
    """A camera clock: ``device = host + offset + drift * (host - origin)`` (host = monotonic ns)."""

    offset_ns: int = 0
    drift_ppm: float = 0.0
    origin_ns: int = 0

    def device_ns(self, host_ns: int) -> int:
        return host_ns + self.offset_ns + int((host_ns - self.origin_ns) * self.drift_ppm * 1e-6)


def _libaravis() -> ctypes.CDLL:
    name = ctypes.util.find_library("aravis-0.8") or "libaravis-0.8.so.0"
    lib = ctypes.CDLL(name)
    vp = ctypes.c_void_p
    lib.arv_buffer_get_data.restype = vp
    lib.arv_buffer_get_data.argtypes = [vp, ctypes.POINTER(ctypes.c_size_t)]
    for fn in ("arv_buffer_get_image_width", "arv_buffer_get_image_height"):
        getattr(lib, fn).restype = ctypes.c_int
        getattr(lib, fn).argtypes = [vp]
    lib.arv_buffer_get_frame_id.restype = ctypes.c_uint64
    lib.arv_buffer_get_frame_id.argtypes = [vp]
    lib.arv_buffer_set_timestamp.restype = None
    lib.arv_buffer_set_timestamp.argtypes = [vp, ctypes.c_uint64]
    lib.arv_fake_camera_set_fill_pattern.restype = None
    lib.arv_fake_camera_set_fill_pattern.argtypes = [vp, vp, vp]
    lib.arv_fake_camera_is_in_free_running_mode.restype = ctypes.c_int
    lib.arv_fake_camera_is_in_free_running_mode.argtypes = [vp]
    return lib


class FillServer:
    """Supplies an ``ArvFakeCamera``'s images (works for GvFakeCamera and the in-process Fake camera)."""

    def __init__(
        self,
        fake_camera: Any,
        loop: FrameLoop,
        *,
        label: str = "camera",
        clock: SimClock = SimClock(),
        phase_us: float = 0.0,
        tag: bool = True,
        truth_out: IO[str] | None = None,
    ) -> None:
        self._lib = _libaravis()
        self._fake = fake_camera  # keeps the camera alive as long as the callback is installed
        self._pointer = hash(fake_camera)  # PyGObject: the wrapped C pointer
        self.loop = loop
        self.label = label
        self.clock = clock
        self.phase_s = phase_us / 1e6
        self.tag = tag
        self._truth_out = truth_out
        self._truth_lock = threading.Lock()
        self.served = 0
        self._callback = _FILL(self._fill)
        fake_camera.set_trigger_frequency(TRIGGER_POLL_HZ)

    def install(self) -> None:
        self._lib.arv_fake_camera_set_fill_pattern(self._pointer, ctypes.cast(self._callback, ctypes.c_void_p), None)

    def uninstall(self) -> None:
        """Back to Aravis's own pattern; call before dropping the server."""
        self._lib.arv_fake_camera_set_fill_pattern(self._pointer, None, None)
        self.flush()

    def flush(self) -> None:
        if self._truth_out is not None:
            with self._truth_lock:
                self._truth_out.flush()

    def _fill(self, buffer: int, _data: int, _exposure_us: int, _gain: int, _pixel_format: int) -> None:
        # Runs on Aravis's camera thread for every frame; any exception would be lost in ctypes.
        try:
            self._serve(buffer)
        except Exception as err:  # noqa: BLE001 - an exception cannot cross into C; report it
            print(f"gvcamera {self.label}: fill failed: {err!r}", file=sys.stderr, flush=True)

    def _serve(self, buffer: int) -> None:
        lib = self._lib
        if self.phase_s > 0 and lib.arv_fake_camera_is_in_free_running_mode(self._pointer):
            time.sleep(self.phase_s)
        now = time.monotonic_ns()
        width, height = (
            lib.arv_buffer_get_image_width(buffer),
            lib.arv_buffer_get_image_height(buffer),
        )
        data = lib.arv_buffer_get_data(buffer, None)
        if not data or width <= 0 or height <= 0:
            return
        target = np.ctypeslib.as_array(ctypes.cast(data, ctypes.POINTER(ctypes.c_uint8)), shape=(height, width))
        index = self.loop.index_at(now)
        source = self.loop.frames[index]
        h, w = min(height, source.shape[0]), min(width, source.shape[1])
        if (h, w) != (height, width):
            target[...] = 0
        target[:h, :w] = source[:h, :w]
        self.served += 1
        if self.tag:
            write_tag(target, FrameTag(index, self.served, now))
        device_ns = self.clock.device_ns(now)
        lib.arv_buffer_set_timestamp(buffer, device_ns)
        if self._truth_out is not None:
            record = {
                "camera": self.label,
                "frame_id": int(lib.arv_buffer_get_frame_id(buffer)),
                "served": self.served,
                "capture_ns": now,
                "device_timestamp_ns": device_ns,
                "loop_index": index,
            }
            if self.loop.truth:
                record.update(self.loop.truth[index])
            with self._truth_lock:
                self._truth_out.write(json.dumps(record) + "\n")


def main(argv: list[str] | None = None) -> int:
    """Serve one simulated camera until SIGTERM or SIGINT (the entry point of a camera process)."""
    parser = argparse.ArgumentParser(prog="python -m trackerd.sim.gvcamera", description=__doc__.splitlines()[0])
    parser.add_argument("--interface", default="lo", help="network interface (name or IPv4 address)")
    parser.add_argument("--serial", required=True, help="serial number the camera reports")
    parser.add_argument("--label", default=None, help="camera id written in the ground truth")
    parser.add_argument("--loop", type=Path, help="frames to serve, an (N, H, W) uint8 .npy file")
    parser.add_argument("--loop-truth", type=Path, help="ground truth of the loop frames (JSON)")
    parser.add_argument("--content-fps", type=float, default=30.0, help="loop frames per second")
    parser.add_argument("--synthetic", metavar="WxH", help="serve a synthetic pattern of this size instead")
    parser.add_argument("--start-ns", type=int, default=None, help="monotonic instant of loop frame 0")
    parser.add_argument("--clock-offset-ns", type=int, default=0)
    parser.add_argument("--clock-drift-ppm", type=float, default=0.0)
    parser.add_argument("--phase-us", type=float, default=0.0, help="capture delay when free running")
    parser.add_argument("--no-tag", action="store_true", help="do not stamp the frame tag")
    parser.add_argument("--truth-out", type=Path, help="append per-frame ground truth (JSONL) here")
    parser.add_argument("--parent-pid", type=int, default=None, help="exit when this process is no longer the parent")
    args = parser.parse_args(argv)

    import gi

    gi.require_version("Aravis", "0.8")
    from gi.repository import Aravis

    start_ns = args.start_ns if args.start_ns is not None else time.monotonic_ns()
    if args.synthetic:
        width, height = (int(v) for v in args.synthetic.lower().split("x"))
        loop = FrameLoop.synthetic(width, height, start_ns)
    elif args.loop:
        loop = FrameLoop.load(args.loop, args.loop_truth, args.content_fps, start_ns)
    else:
        parser.error("give --loop or --synthetic")

    stop = threading.Event()
    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, lambda *_: stop.set())
    truth_out = args.truth_out.open("a", buffering=1 << 16) if args.truth_out else None
    camera = Aravis.GvFakeCamera.new(args.interface, args.serial)
    if not camera.is_running():
        print(f"error: no simulated camera on {args.interface} (address in use?)", flush=True)
        return 1
    server = FillServer(
        camera.get_fake_camera(),
        loop,
        label=args.label or args.serial,
        clock=SimClock(args.clock_offset_ns, args.clock_drift_ppm, start_ns),
        phase_us=args.phase_us,
        tag=not args.no_tag,
        truth_out=truth_out,
    )
    server.install()
    print(f"ready {args.interface} {args.serial}", flush=True)
    # Out of the terminal's process group (trackerd.sim.rig), a camera must not outlive the rig
    # that started it: a parent killed outright leaves the camera with a new parent. The rig names
    # itself, so that a rig killed while this camera was starting is noticed too.
    parent = os.getppid() if args.parent_pid is None else args.parent_pid
    while not stop.wait(0.5) and os.getppid() == parent:
        server.flush()
    server.uninstall()
    del camera
    if truth_out is not None:
        truth_out.close()
    try:
        print(f"served {server.served}", flush=True)
    except BrokenPipeError:  # the rig that would read it is gone; nothing left to flush at exit
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0


if __name__ == "__main__":
    sys.exit(main())
