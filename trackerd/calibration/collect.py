"""From frames to calibration input: board views for one camera, matched pairs for two.

Every frame gets a verdict, accepted or rejected with a reason an operator can
act on ('no whole board found by any detector', 'blurred ...', 'too similar to view 3 ...'); the same
functions serve image files, recordings and live cameras.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from trackerd.calibration.board import BoardSpec, BoardView, grey_for_calibration
from trackerd.calibration.detection import Quality, detect_board
from trackerd.calibration.stereo import StereoPair, match_views
from trackerd.calibration.views import ViewSelector

Frame = tuple[str, NDArray[np.uint8], str]
"""(name, frame, pixel format)."""


@dataclass
class Collected:
    """What a run of frames gave: accepted views (or pairs) and every rejection with its reason."""

    views: list[BoardView] = field(default_factory=list)
    pairs: list[StereoPair] = field(default_factory=list)
    rejected: list[tuple[str, str]] = field(default_factory=list)
    frames: int = 0


def judge_view(
    frame: Frame, spec: BoardSpec, selector: ViewSelector, quality: Quality | None = None
) -> tuple[BoardView | None, str | None]:
    """Detect the board in one frame and offer it to the selector: (accepted view, None) or (None, reason)."""
    name, image, pixel_format = frame
    detection = detect_board(grey_for_calibration(image, pixel_format), spec, name, quality)
    if detection.view is None:
        return None, detection.reason
    verdict = selector.consider(detection.view)
    if not verdict.accepted:
        return None, verdict.reason
    return detection.view, None


def collect_views(
    frames: Iterable[Frame], spec: BoardSpec, selector: ViewSelector, quality: Quality | None = None
) -> Collected:
    """Board views of one camera from frames, through the selector."""
    out = Collected()
    for frame in frames:
        out.frames += 1
        view, reason = judge_view(frame, spec, selector, quality)
        if view is None:
            out.rejected.append((frame[0], reason or "rejected"))
        else:
            out.views.append(view)
    return out


def judge_pair(
    name: str, frame1: Frame, frame2: Frame, spec: BoardSpec, selector: ViewSelector, quality: Quality | None = None
) -> tuple[StereoPair | None, str | None]:
    """Detect the board in both frames of a pair; keep the corners both saw if the pair adds something."""
    detections = []
    for frame in (frame1, frame2):
        detection = detect_board(grey_for_calibration(frame[1], frame[2]), spec, frame[0], quality)
        detections.append(detection)
    missing = [
        f"{frame[0]}: {d.reason}" for frame, d in zip((frame1, frame2), detections, strict=True) if d.view is None
    ]
    if missing:
        return None, "; ".join(missing)
    view1, view2 = detections[0].view, detections[1].view
    assert view1 is not None and view2 is not None
    pair = match_views(view1, view2, name)
    if pair is None:
        return None, "the two cameras see too few of the same corners"
    verdict = selector.consider(view1)
    if not verdict.accepted:
        return None, verdict.reason
    return pair, None


def collect_pairs(
    frame_pairs: Iterable[tuple[str, Frame, Frame]],
    spec: BoardSpec,
    selector: ViewSelector,
    quality: Quality | None = None,
) -> Collected:
    """Matched stereo pairs from synchronized frame pairs; ``selector`` judges camera 1's views."""
    out = Collected()
    for name, frame1, frame2 in frame_pairs:
        out.frames += 1
        pair, reason = judge_pair(name, frame1, frame2, spec, selector, quality)
        if pair is None:
            out.rejected.append((name, reason or "rejected"))
        else:
            out.pairs.append(pair)
    return out
