"""What a camera source hands to the pipeline: frames, and frames grouped into synchronized pairs.

Ownership: ``Frame.image`` is the frame's own read-only copy of the pixels, not
a view into an Aravis buffer. The acquisition thread copies the payload out and
gives the Aravis buffer straight back to the stream, so a consumer may keep a
frame (or a pair) as long as it likes and no buffer is ever held hostage. The
copy costs about 0.1-0.2 ms per 1920x1080 8-bit frame on the development
machine (docs/acquisition.md, "Buffer ownership").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from trackerd.locator import PointerFix


@dataclass(frozen=True, slots=True)
class Frame:
    """One image from one camera."""

    camera_id: str
    """The camera's id in the rig (``left``, ``right``, ...)."""
    frame_id: int
    """The camera's frame counter (GigE Vision block id), unwrapped so it keeps increasing
    across the 16-bit wrap; it restarts when the camera reconnects."""
    device_timestamp_ns: int
    """The camera's timestamp of the exposure, in ns on the camera's own clock (0 if it has none).
    Comparable between cameras only when they are PTP-synchronized."""
    host_timestamp_ns: int
    """When the host finished receiving the frame, ``time.monotonic_ns()`` clock."""
    pixel_format: str
    """GenICam pixel format name of ``image`` (``BayerRG8``, ...)."""
    image: NDArray[np.uint8]
    """The pixels, (H, W) for one byte per pixel or (H, W, 3) for RGB8/BGR8; read-only, owned by the frame."""


@dataclass(frozen=True, slots=True)
class FramePair:
    """Frames of the same instant from every camera of the rig (the first two are the stereo pair)."""

    frames: tuple[Frame, ...]
    """One frame per camera, in the rig's camera order."""
    timestamp_ns: int
    """Capture time of the pair on the host's monotonic clock (the mean of the frames' estimated
    capture times), never smaller than the previous pair's."""
    skew_ns: int
    """Spread of the frames' estimated capture times (latest minus earliest), >= 0."""
    sequence: int
    """Counts pairs formed since the source started; a gap means pairs were dropped before delivery."""
    fresh_start: bool = False
    """True when the pair does not follow from the one before (a looped replay starting its next
    pass): the pipeline's trackers and filters start afresh rather than take the jump for motion."""
    located: PointerFix | None = None
    """The pointer already located in these frames, by a locator that went through the same pairs
    in the same order (a replay at max speed locates in a worker process ahead of the pipeline,
    trackerd.recording.ahead); None: the pipeline's locator locates them."""

    @property
    def images(self) -> list[NDArray[np.uint8]]:
        """The images in camera order, as the locator takes them."""
        return [frame.image for frame in self.frames]
