"""The windowed mode's choice, pair by pair, of a keyframe or the windows the tracker reads.

The tracker reads, while it follows the pointer, only small windows around
where each end should be (trackerd/detect/detector.py: the quick measurement
around the previous position plus the motion, then the blob search's near and
tracking windows). A windowed record keeps, for each camera, windows around
the ends' predicted and found positions, and a replay puts them over the last
keyframe (trackerd/recording/codec.py). Which pixels the detector and the
locator's refined path (trackerd/refine.py) read is their own affair, and
changes with them, so the planner does not rely on knowing it: it checks.

:class:`WindowPlanner` keeps two locators fed exactly as the pipeline feeds
its own (reset on a recording's first pair and after a pair with an end not
found, trackerd/pipeline/processing.py):

* ``live`` sees the full frames: what the daemon computes;
* ``replayed`` sees what the replay will see: the frame rebuilt from the last
  keyframe and the pair's windows.

A pair is stored as windows only if ``replayed`` gives, on the rebuilt frame,
exactly what ``live`` gives on the full one: the same messages (every float of
the pointer and the hit), the same status and reason, the same detections, and
the same tracking state carried to the next pair. Otherwise the pair becomes a
keyframe and ``replayed`` takes ``live``'s state (a copy). Because a replay
runs the same deterministic code from the same state on the same pixels as
``replayed`` did, it publishes what ``live`` did, pair for pair. Keyframes are
also written at the configured interval and whenever the tracker searched a
whole frame (tracking lost or starting).

The check costs a second locate per pair (about the pipeline's own cost on the
recording thread); docs/recording.md has the figures.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from trackerd.acquisition.frame import FramePair
from trackerd.locator import COLOURS, Locator, PointerFix
from trackerd.recording.codec import Window, clip_window

DEFAULT_MARGIN_PX = 8


@dataclass(frozen=True, slots=True)
class Plan:
    """One pair: a keyframe (every frame stored whole), or each camera's windows."""

    keyframe: bool
    windows: tuple[list[Window], ...] = ()
    reason: str = ""
    """Why a keyframe: ``first``, ``interval``, ``searching`` (an end looked for in the whole frame),
    ``mismatch`` (the windows did not reproduce the live result)."""


@dataclass
class _End:
    x_px: float
    y_px: float
    vx_px: float
    vy_px: float
    radius_px: float


@dataclass
class WindowPlanner:
    """Decides each pair of a windowed recording; one per recording, fed every pair written, in order."""

    live: Locator
    replayed: Locator
    margin_px: int = DEFAULT_MARGIN_PX
    keyframes: dict[str, int] = field(default_factory=dict)
    """Keyframes written, by reason."""
    _key: list[NDArray[np.uint8]] | None = None
    _ends: list[dict[str, _End] | None] = field(default_factory=list)

    @classmethod
    def for_rig(
        cls, rig: Any, pixel_formats: Sequence[str] | None = None, margin_px: int = DEFAULT_MARGIN_PX
    ) -> WindowPlanner:
        return cls(Locator(rig, pixel_formats=pixel_formats), Locator(rig, pixel_formats=pixel_formats), margin_px)

    @classmethod
    def for_metadata(cls, metadata: Any, margin_px: int = DEFAULT_MARGIN_PX) -> WindowPlanner:
        """A planner for the rig recorded in ``metadata`` (what a replay runs by default)."""
        from pydantic import ValidationError

        from trackerd.config.loader import describe_validation_error
        from trackerd.config.models import RigConfig
        from trackerd.errors import RecordingError

        try:
            rig = RigConfig.model_validate(metadata.rig)
        except ValidationError as err:
            raise RecordingError(
                "the recorded rig does not validate with this trackerd"
                f" ({describe_validation_error(err, RigConfig)}): a windowed recording needs it to track the pointer"
            ) from err
        return cls.for_rig(rig, [cam.pixel_format for cam in metadata.cameras], margin_px)

    def plan(self, pair: FramePair, keyframe_due: bool, pair_index: int) -> Plan:
        """What to store of ``pair`` (record ``pair_index``); ``keyframe_due`` when the interval has passed."""
        images = [np.ascontiguousarray(frame.image) for frame in pair.frames]
        if pair_index == 0 or pair.fresh_start:
            self.live.reset()
            self.replayed.reset()
            self._ends = [None] * len(images)
        live_fix = self.live.locate(images)
        searched = any(d.search != "window" for d in live_fix.detections)
        reason = "first" if self._key is None else "interval" if keyframe_due else "searching" if searched else ""
        windows: tuple[list[Window], ...] = ()
        if not reason:
            windows = tuple(self._windows(i, image, live_fix) for i, image in enumerate(images))
            assert self._key is not None
            rebuilt = [_rebuild(key, image, w) for key, image, w in zip(self._key, images, windows, strict=True)]
            replayed_fix = self.replayed.locate(rebuilt)
            if _outcome(replayed_fix, self.replayed) != _outcome(live_fix, self.live):
                reason = "mismatch"
                # The replay will read this pair whole, from the state both had before it: live's now.
                self.replayed = copy.deepcopy(self.live)
        else:
            self.replayed.locate(images)
        self._follow(live_fix)
        if reason:
            self._key = [image.copy() for image in images]
            self.keyframes[reason] = self.keyframes.get(reason, 0) + 1
            return Plan(True, (), reason)
        return Plan(False, windows)

    def _follow(self, fix: PointerFix) -> None:
        """Remember where each camera's ends were, and how they moved (for the next pair's windows)."""
        ends: list[dict[str, _End] | None] = []
        for k, detection in enumerate(fix.detections):
            previous = self._ends[k] if k < len(self._ends) else None
            if not detection.both_found or fix.status == "not_found":
                ends.append(None)
                continue
            now = {}
            for colour in COLOURS:
                end = detection.end(colour)
                assert end.centroid_px is not None  # both ends found
                x, y = (float(v) for v in end.centroid_px[:2])
                before = previous.get(colour) if previous else None
                vx, vy = (x - before.x_px, y - before.y_px) if before else (0.0, 0.0)
                now[colour] = _End(x, y, vx, vy, math.sqrt(max(end.area_px, 1.0) / math.pi))
            ends.append(now)
        self._ends = ends

    def _windows(self, camera: int, image: NDArray[np.uint8], fix: PointerFix) -> list[Window]:
        """Around each end: where the last pair predicts it (where the tracker looks first) and where it
        is now, each as large as the blob search's near window (detector.py) plus the margin."""
        previous = self._ends[camera] if camera < len(self._ends) else None
        detection = fix.detections[camera]
        boxes = []
        for colour in COLOURS:
            end = detection.end(colour)
            before = previous.get(colour) if previous else None
            centres = []
            radius = before.radius_px if before else 0.0
            speed = math.hypot(before.vx_px, before.vy_px) if before else 0.0
            if before is not None:
                centres.append((before.x_px + before.vx_px, before.y_px + before.vy_px))
            if end.found and end.centroid_px is not None:
                x, y = (float(v) for v in end.centroid_px[:2])
                centres.append((x, y))
                radius = max(radius, math.sqrt(max(end.area_px, 1.0) / math.pi))
                if before is not None:
                    speed = max(speed, math.hypot(x - before.x_px, y - before.y_px))
            half = 2.0 * radius + speed + 8.0 + self.margin_px
            for cx, cy in centres:
                boxes.append((cx - half, cy - half, cx + half, cy + half))
        return _merge([w for box in _union_boxes(boxes) if (w := clip_window(*box, image.shape)) is not None])


def _union_boxes(boxes: list[tuple[float, float, float, float]]) -> list[tuple[float, float, float, float]]:
    """Overlapping boxes joined into their bounding box, until none overlap (a handful of boxes)."""
    out = list(boxes)
    merged = True
    while merged:
        merged = False
        for i in range(len(out)):
            for j in range(i + 1, len(out)):
                a, b = out[i], out[j]
                if a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]:
                    out[i] = (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))
                    del out[j]
                    merged = True
                    break
            if merged:
                break
    return out


def _merge(windows: list[Window]) -> list[Window]:
    """Windows that overlap after rounding to even pixels, joined (each pixel is then stored once)."""
    boxes = _union_boxes([(w.x_px, w.y_px, w.x_px + w.width_px, w.y_px + w.height_px) for w in windows])
    return [Window(int(x0), int(y0), int(x1 - x0), int(y1 - y0)) for x0, y0, x1, y1 in boxes]


def _rebuild(key: NDArray[np.uint8], image: NDArray[np.uint8], windows: list[Window]) -> NDArray[np.uint8]:
    """What a replay reads: the keyframe with this frame's windows put in (codec.Canvases does the same
    from the stored bytes)."""
    frame = key.copy()
    for w in windows:
        frame[w.y_px : w.y_px + w.height_px, w.x_px : w.x_px + w.width_px] = image[
            w.y_px : w.y_px + w.height_px, w.x_px : w.x_px + w.width_px
        ]
    return frame


def _outcome(fix: PointerFix, locator: Locator) -> tuple:
    """Everything of a fix that reaches a subscriber or the next pair: the published messages' fields,
    the status and reason, every detection, and the tracking state carried forward."""
    from trackerd.publish.from_fix import messages_from_fix

    messages = tuple(
        m.model_dump_json() if hasattr(m, "model_dump_json") else repr(m)
        for m in messages_from_fix(fix, locator, sequence=0, capture_ns=0)
    )
    detections = tuple(
        (
            d.search,
            *(
                (
                    e.found,
                    None if e.centroid_px is None else tuple(e.centroid_px.tolist()),
                    e.area_px,
                    e.bbox_px,
                    e.score,
                    e.reason,
                )
                for e in (d.red, d.blue)
            ),
        )
        for d in fix.detections
    )
    centroids = tuple(
        tuple((c, None if v is None else tuple(np.asarray(v).tolist())) for c, v in cam.items())
        for cam in fix.centroids_px
    )
    # The tracking state each detector carries to the next frame (read only; see the module's docstring).
    state = tuple(
        (repr(getattr(d, "_track", None)), tuple(sorted(getattr(d, "_crowded", ())))) for d in locator.detectors
    )
    # And the refined path's (when its slow search last ran), every attribute but its locator.
    refined = getattr(locator, "_refined", None)
    refined_state = None if refined is None else repr(sorted((k, v) for k, v in vars(refined).items() if k != "loc"))
    # And the tracked path's: each end's outline offset, and which estimate it holds to.
    offsets = repr((locator.offsets, getattr(locator, "_tracked_by_fit", None)))
    return (fix.status, fix.reason, messages, detections, centroids, offsets, state, refined_state)
