"""The console's frame thread: takes the newest pair from the pipeline's tap a few times a second
while a page is open (or once for a snapshot), and turns it into what the page shows.

Everything costly happens here, never on the processing thread: demosaicing, scaling down,
JPEG encoding (``cv2.imencode``), projecting the display's outline, writing a snapshot's files.
The processing thread only hands over a reference when :attr:`ConsoleTap.frame_wanted` is set.
"""

from __future__ import annotations

import datetime as dt
import logging
import os
import stat
import threading
import time
from collections.abc import Callable, Collection
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2

from trackerd.console.overlay import camera_overlay, outline_px
from trackerd.pipeline.tap import ConsoleTap
from trackerd.pixelformat import is_bayer, to_rgb

log = logging.getLogger(__name__)

TAKE_WAIT_S = 0.2
"""How long one wait for a pair lasts before the thread looks at its stop flag again."""


def own_directory(path: Path) -> None:
    """Make ``path`` (and its parents) if missing, the leaf readable by its owner only; OSError when it is
    a link or a folder another user owns (in a shared temporary directory, someone else's choice)."""
    path.mkdir(mode=0o700, parents=True, exist_ok=True)
    info = os.lstat(path)
    if stat.S_ISLNK(info.st_mode) or not stat.S_ISDIR(info.st_mode) or info.st_uid != os.getuid():
        raise PermissionError(13, "not a folder of this user's (set [console] snapshot_directory)", str(path))


@dataclass(frozen=True)
class CameraImage:
    """One camera's image for the page: a scaled-down JPEG and what to draw over it."""

    camera_id: str
    sequence: int
    jpeg: bytes
    header: dict[str, Any]
    """The overlay (full-resolution pixel coordinates; trackerd.console.overlay) and the image's
    size, sent with the JPEG."""


@dataclass
class SnapshotRequest:
    """A snapshot asked for; ``done(result)`` is called on the frame thread with the paths
    written, or with the exception that stopped it."""

    name: str
    done: Callable[[list[Path] | BaseException], None]


def scaled_bgr(image: Any, pixel_format: str, width_px: int) -> Any:
    """A raw frame -> a BGR image at most ``width_px`` wide, aspect kept.

    Every step is one OpenCV call (which lets go of the GIL), and the colour order is swapped on
    the small image: ``to_bgr`` on the full frame flips 6 MB with NumPy under the GIL (22 ms of
    CPU a 1080p frame on the development VM, against about 4 ms for the whole of this).
    Bilinear scaling of the demosaiced frame: a third of INTER_AREA's cost, and the picture is
    for aiming, the snapshot has the full frame.
    """
    if is_bayer(pixel_format):
        image, order = to_rgb(image, pixel_format), "rgb"
    elif pixel_format == "RGB8":
        order = "rgb"
    elif pixel_format == "BGR8":
        order = "bgr"
    elif pixel_format == "Mono8":
        order = "gray"
    else:
        raise ValueError(f"unsupported pixel format {pixel_format!r}")
    height, width = image.shape[:2]
    if width > width_px:
        height_px = max(1, round(height * width_px / width))
        image = cv2.resize(image, (width_px, height_px), interpolation=cv2.INTER_LINEAR)
    if order == "rgb":
        return cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    if order == "gray":
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    return image


def scaled_jpeg(image: Any, pixel_format: str, width_px: int, quality: int) -> tuple[bytes, int, int]:
    """A raw frame -> (JPEG bytes, width, height) at most ``width_px`` wide, aspect kept."""
    bgr = scaled_bgr(image, pixel_format, width_px)
    ok, encoded = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise RuntimeError("cv2.imencode refused the image")
    return encoded.tobytes(), bgr.shape[1], bgr.shape[0]


def snapshot_name(directory: Path, stem: str | None = None, taken: Collection[str] = ()) -> str:
    """``stem`` (default ``snap-<local time>``), suffixed -2, -3... if taken in ``directory`` or by a snapshot
    still waiting (``taken``)."""
    stem = stem or f"snap-{dt.datetime.now():%Y%m%d-%H%M%S}"
    name, n = stem, 2
    while name in taken or (directory / name).exists():
        name, n = f"{stem}-{n}", n + 1
    return name


class FrameThread:
    """Serves the page's images and the snapshots from the pairs the pipeline offers."""

    def __init__(
        self,
        tap: ConsoleTap,
        rig: Any,
        on_images: Callable[[list[CameraImage]], None],
        snapshot_directory: Path,
        camera_info: Any = None,
        *,
        private_snapshots: bool = False,
    ) -> None:
        """``private_snapshots``: ``snapshot_directory`` is the default in the shared temporary directory,
        made and checked as the user's own (:func:`own_directory`); one the rig names, or the service's state
        directory, is made as it was asked for."""
        self.tap = tap
        self.rig = rig
        self.period_s = 1.0 / rig.console.frame_rate_hz
        self._on_images = on_images
        self.snapshot_directory = snapshot_directory
        self._private_snapshots = private_snapshots
        self._camera_info = camera_info
        self.viewers = 0
        self._snapshots: list[SnapshotRequest] = []
        self._saving: set[str] = set()
        """Names of the snapshots being saved (taken from the queue, their folder maybe not made yet)."""
        self._wake = threading.Condition()
        self._stopping = False
        self._outlines: tuple[int, list] | None = None
        self.images_sent = 0
        self._thread = threading.Thread(target=self._run, name="trackerd-console-frames", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def begin_stop(self) -> None:
        with self._wake:
            self._stopping = True
            self._wake.notify_all()
        self.tap.frame_wanted = False
        self.tap.wake()

    def stop(self, timeout_s: float = 0.5) -> None:
        self.begin_stop()
        if self._thread.ident is not None:
            self._thread.join(timeout_s)

    def set_viewers(self, count: int) -> None:
        with self._wake:
            self.viewers = count
            self._wake.notify_all()

    def request_snapshot(self, done: Callable[[list[Path] | BaseException], None], name: str | None = None) -> str:
        """Save the next pair the pipeline processes (named ``name``, else snap-<local time>, made
        unique); returns the snapshot's name."""
        with self._wake:
            if self._private_snapshots:
                own_directory(self.snapshot_directory)
            else:
                self.snapshot_directory.mkdir(parents=True, exist_ok=True)
            # Numbered past the snapshots still waiting or being saved too (twenty asked for in one second
            # were named snap-...-b-b-b..., a name growing with every one).
            name = snapshot_name(self.snapshot_directory, name, {r.name for r in self._snapshots} | self._saving)
            self._snapshots.append(SnapshotRequest(name, done))
            self._wake.notify_all()
        return name

    def cancel_snapshot(self, name: str) -> None:
        """Forget a snapshot not taken yet (nobody waits for it any more)."""
        with self._wake:
            self._snapshots = [r for r in self._snapshots if r.name != name]

    # ------------------------------------------------------------------ the thread

    def _run(self) -> None:
        next_due = 0.0
        while True:
            with self._wake:
                self._wake.wait_for(lambda: self._stopping or self.viewers > 0 or bool(self._snapshots))
                if self._stopping:
                    return
                snapshots_waiting = bool(self._snapshots)
                if not snapshots_waiting:
                    # Paced for the page; a snapshot asked for meanwhile ends the wait.
                    delay = next_due - time.monotonic()
                    if delay > 0 and self._wake.wait_for(lambda: self._stopping or bool(self._snapshots), delay):
                        continue
            self.tap.frame_wanted = True
            slot = self.tap.take(TAKE_WAIT_S)
            if slot is None:
                continue
            pair, fix, locator = slot
            with self._wake:
                snapshots, self._snapshots = self._snapshots, []
                self._saving.update(r.name for r in snapshots)
                viewers = self.viewers
            for request in snapshots:
                try:
                    self._save(request, pair, fix, locator)
                finally:
                    with self._wake:
                        self._saving.discard(request.name)
            if viewers > 0 and time.monotonic() >= next_due:
                next_due = max(next_due + self.period_s, time.monotonic())
                try:
                    self._on_images(self._images(pair, fix, locator))
                    self.images_sent += 1
                except Exception:
                    log.exception("console: preparing the camera images failed")

    def _images(self, pair: Any, fix: Any, locator: Any) -> list[CameraImage]:
        console = self.rig.console
        window_px = self.rig.detector.track_window_px
        if self._outlines is None or self._outlines[0] != id(locator):
            # Once per locator (a reload makes a new one): the calibration is fixed in between.
            self._outlines = (id(locator), [outline_px(cam, locator.wall) for cam in locator.cameras])
        images = []
        for k, frame in enumerate(pair.frames):
            jpeg, width, height = scaled_jpeg(
                frame.image, frame.pixel_format, console.image_width_px, console.jpeg_quality
            )
            detections = fix.detections[k] if k < len(fix.detections) else None
            camera = locator.cameras[k]
            overlay = camera_overlay(camera, None, detections, window_px)
            overlay["outline_px"], overlay["corners_px"] = self._outlines[1][k]
            header = {
                "camera": frame.camera_id,
                "sequence": pair.sequence,
                "frame_id": frame.frame_id,
                "image_width_px": width,
                "image_height_px": height,
                "status": fix.status,
                "reason": fix.reason,
                **overlay,
            }
            images.append(CameraImage(frame.camera_id, pair.sequence, jpeg, header))
        return images

    def _save(self, request: SnapshotRequest, pair: Any, fix: Any, locator: Any) -> None:
        from trackerd.recording.snapshot import write_snapshot

        try:
            info = dict(self._camera_info) if self._camera_info is not None else None
            written = write_snapshot(
                pair, fix, locator, self.rig, self.snapshot_directory / request.name, request.name, info
            )
            log.info("console: snapshot %s saved in %s", request.name, self.snapshot_directory / request.name)
        except Exception as err:  # noqa: BLE001 - the page hears why; the daemon runs on
            log.error("console: snapshot %s failed: %s", request.name, err)
            request.done(err)
            return
        request.done(written)
