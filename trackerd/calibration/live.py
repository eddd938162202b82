"""The --live modes: calibration from a running PairSource, with progress and guidance as text.

Each mode is a *session* fed one frame pair at a time (``feed(pair)``); it
keeps what it accepted, says what happened in one line, and knows when it has
enough. :func:`run_session` drives a session from any
:class:`~trackerd.acquisition.source.PairSource`: live Aravis cameras (the
daemon's source), a recording, or rendered frames in tests. The driver always
takes the newest pair (detection is slower than the cameras), stops on
``stop`` (an Event the CLI sets on Ctrl-C), on a time limit, or when the
session is done, and reports a source that stops delivering.

Accepted views are saved as snapshots (``<dir>/<camera>-<NNN>.png``, or
``<NNN>-<camera>.png`` for pairs) so a run can be audited and repeated
offline: ``trackerd calibrate intrinsics IMAGES...`` and ``--pairs DIR`` read them.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.calibration import CalibrationError
from trackerd.calibration.board import BoardSpec, BoardView
from trackerd.calibration.collect import judge_pair, judge_view
from trackerd.calibration.detection import Quality
from trackerd.calibration.intrinsics import MIN_VIEWS, IntrinsicsResult, calibrate_intrinsics
from trackerd.calibration.stereo import StereoPair
from trackerd.calibration.views import ViewSelector
from trackerd.pixelformat import to_bgr

if TYPE_CHECKING:
    from trackerd.acquisition.frame import FramePair
    from trackerd.acquisition.source import PairSource

Array = NDArray[np.float64]

PAIR_DRAIN_TIMEOUT_S = 0.001


@dataclass(frozen=True)
class Event:
    """One line of progress: what happened to a frame pair, and what to do next."""

    text: str
    accepted: bool = False
    finished: bool = False


def save_frame(directory: Path, name: str, frame: NDArray[np.uint8], pixel_format: str) -> Path:
    """Save a raw frame so that trackerd.images.read_frame reads it back as the same frame.

    Bayer mosaics are written as single-channel PNG (read back as raw), RGB8 is
    written as BGR (the order OpenCV writes), BGR8 as is.
    """
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{name}.png"
    image = frame
    if frame.ndim == 3:
        image = frame if pixel_format == "BGR8" else to_bgr(frame, pixel_format)
    if not cv2.imwrite(str(path), image):
        raise CalibrationError(f"{path}: cannot write the snapshot")
    return path


def frame_name(camera_id: str, number: int, pair: bool = False) -> str:
    """The name of a session's ``number``-th frame (from 1): ``left-023`` for one camera's views,
    ``023-left`` for a pair's (the ``--pairs DIR`` naming); its snapshot is that name plus ``.png``."""
    return f"{number:03d}-{camera_id}" if pair else f"{camera_id}-{number:03d}"


class IntrinsicsSession:
    """Collects views of one camera's board until there are enough, with guidance."""

    def __init__(
        self,
        spec: BoardSpec,
        camera_index: int,
        camera_id: str,
        width_px: int,
        height_px: int,
        *,
        wanted_views: int = 20,
        min_views: int = MIN_VIEWS,
        quality: Quality | None = None,
        min_change: float | None = None,
        snapshots: Path | None = None,
        distortion_terms: int = 5,
    ) -> None:
        self.spec = spec
        self.index = camera_index
        self.camera_id = camera_id
        self.wanted = wanted_views
        self.min_views = min_views
        self.quality = quality
        self.selector = (
            ViewSelector(width_px, height_px) if min_change is None else ViewSelector(width_px, height_px, min_change)
        )
        self.snapshots = snapshots
        self.terms = distortion_terms
        self.frames = 0
        self.last_rms_px: float | None = None
        self.rejections: dict[str, int] = {}
        self._last_reason: str | None = None

    @property
    def views(self) -> list[BoardView]:
        return self.selector.views

    @property
    def done(self) -> bool:
        return len(self.views) >= self.wanted and self.selector.coverage.fraction >= 0.75

    def feed(self, frames: Sequence[tuple[str, NDArray[np.uint8], str]]) -> Event | None:
        """Consider one pair's frame of this camera: an Event when something worth saying happened."""
        self.frames += 1
        # One name per frame, used for the view, in every message and as the snapshot's file
        # name, so a view flagged in the report can be traced to its saved image.
        name = frame_name(self.camera_id, self.frames)
        _, image, fmt = frames[self.index]
        view, reason = judge_view((name, image, fmt), self.spec, self.selector, self.quality)
        if view is None:
            key = (reason or "").split(":")[0].split(" (")[0]
            self.rejections[key] = self.rejections.get(key, 0) + 1
            if key == self._last_reason:
                return None
            self._last_reason = key
            return Event(f"  {name}: {reason}")
        self._last_reason = None
        if self.snapshots is not None:
            save_frame(self.snapshots, name, image, fmt)
        if len(self.views) >= self.min_views:
            try:
                self.last_rms_px = calibrate_intrinsics(
                    self.views, distortion_terms=self.terms, min_views=self.min_views
                ).rms_px
            except CalibrationError:
                self.last_rms_px = None
        rms = f", RMS {self.last_rms_px:.3f} px" if self.last_rms_px is not None else ""
        text = (
            f"[{len(self.views):>3}/{self.wanted} views] accepted {name}: {len(view.ids)} corners,"
            f" coverage {self.selector.coverage.fraction * 100:.0f} %{rms}; next: "
            f"{self.selector.guidance(self.wanted)}"
        )
        return Event(text, accepted=True, finished=self.done)

    def result(self, drop_outliers: bool = False) -> IntrinsicsResult:
        return calibrate_intrinsics(
            self.views, distortion_terms=self.terms, min_views=self.min_views, drop_outliers=drop_outliers
        )


class StereoSession:
    """Collects synchronized pairs of the board seen by both cameras."""

    def __init__(
        self,
        spec: BoardSpec,
        camera_ids: tuple[str, str],
        width_px: int,
        height_px: int,
        *,
        wanted_pairs: int = 15,
        quality: Quality | None = None,
        min_change: float | None = None,
        max_skew_ns: int = 2_000_000,
        snapshots: Path | None = None,
    ) -> None:
        self.spec = spec
        self.camera_ids = camera_ids
        self.wanted = wanted_pairs
        self.quality = quality
        self.selector = (
            ViewSelector(width_px, height_px) if min_change is None else ViewSelector(width_px, height_px, min_change)
        )
        self.max_skew_ns = max_skew_ns
        self.snapshots = snapshots
        self.pairs: list[StereoPair] = []
        self.frames = 0
        self._last_reason: str | None = None

    @property
    def done(self) -> bool:
        return len(self.pairs) >= self.wanted

    def feed(self, frames: Sequence[tuple[str, NDArray[np.uint8], str]], skew_ns: int = 0) -> Event | None:
        self.frames += 1
        name = f"{self.frames:03d}"
        reason: str | None
        if skew_ns > self.max_skew_ns:
            reason = (
                f"out of sync: the two frames are {skew_ns / 1e6:.1f} ms apart (limit {self.max_skew_ns / 1e6:.1f} ms)"
            )
        else:
            # As for intrinsics: the pair's name is its snapshots' names (NNN-<camera>.png).
            named = [
                (frame_name(cam_id, self.frames, pair=True), image, fmt)
                for cam_id, (_, image, fmt) in zip(self.camera_ids, frames[:2], strict=True)
            ]
            pair, reason = judge_pair(name, named[0], named[1], self.spec, self.selector, self.quality)
            if pair is not None:
                self._last_reason = None
                self.pairs.append(pair)
                if self.snapshots is not None:
                    for frame_file, image, fmt in named:
                        save_frame(self.snapshots, frame_file, image, fmt)
                text = (
                    f"[{len(self.pairs):>3}/{self.wanted} pairs] accepted {name}:"
                    f" {len(pair.ids)} shared corners; next: {self._guidance()}"
                )
                return Event(text, accepted=True, finished=self.done)
        key = (reason or "").split(":")[0]
        if key == self._last_reason:
            return None
        self._last_reason = key
        return Event(f"  {name}: {reason}")

    def _guidance(self) -> str:
        if self.done:
            return "enough pairs: finish (Ctrl-C) or keep adding pairs"
        missing = self.selector.coverage.missing_regions(below=0.25)
        if missing:
            return f"move the board so that {self.camera_ids[0]} sees it in the {missing[0]} (both cameras must see it)"
        return "move and tip the board to new places in the area both cameras see"


class Session(Protocol):
    """What :func:`run_session` drives: a session fed one pair's frames at a time until done."""

    @property
    def done(self) -> bool: ...

    def feed(self, frames: Sequence[tuple[str, NDArray[np.uint8], str]]) -> Event | None: ...


def pair_frames(pair: FramePair, camera_ids: Sequence[str]) -> list[tuple[str, NDArray[np.uint8], str]]:
    """A FramePair as (name, image, pixel format) per camera."""
    return [
        (f"{cam_id}-{frame.frame_id}", frame.image, frame.pixel_format)
        for cam_id, frame in zip(camera_ids, pair.frames, strict=True)
    ]


def newest_pair(source: PairSource, timeout_s: float) -> FramePair | None:
    """The newest pair available: wait up to ``timeout_s`` for one, then skip to the latest."""
    pair = source.next_pair(timeout_s)
    if pair is None:
        return None
    while True:
        newer = source.next_pair(PAIR_DRAIN_TIMEOUT_S)
        if newer is None:
            return pair
        pair = newer


def run_session(
    source: PairSource,
    session: Session,
    camera_ids: Sequence[str],
    *,
    say: Callable[[str], None],
    stop: threading.Event | None = None,
    max_seconds: float | None = None,
    poll_s: float = 0.5,
    newest: bool = True,
) -> int:
    """Feed a session pairs from a started source until it is done, stopped or out of time.

    Returns the number of pairs fed. Raises CalibrationError when the source stops
    delivering (cameras lost) before the session is done.
    """
    stop = stop or threading.Event()
    deadline = None if max_seconds is None else time.monotonic() + max_seconds
    fed = 0
    idle_since = time.monotonic()
    while not stop.is_set() and not session.done:
        if deadline is not None and time.monotonic() >= deadline:
            say("time is up")
            break
        pair = newest_pair(source, poll_s) if newest else source.next_pair(poll_s)
        if pair is None:
            status = source.status()
            if not status.running:
                if fed:
                    say("the source has no more frames")
                    break
                raise CalibrationError("the cameras delivered no frames (check `trackerd cameras` and the rig)")
            if time.monotonic() - idle_since > 10.0:
                raise CalibrationError("no frame pairs for 10 s: check that both cameras are streaming")
            continue
        idle_since = time.monotonic()
        fed += 1
        frames = pair_frames(pair, camera_ids)
        event = session.feed(frames, pair.skew_ns) if isinstance(session, StereoSession) else session.feed(frames)
        if event is not None:
            say(event.text)
    return fed
