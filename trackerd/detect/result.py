"""What the detector reports for one image: each end found (where, how big, how sure) or why not."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

COLOURS = ("red", "blue")


@dataclass(frozen=True, slots=True, eq=False)
class EndDetection:
    """One coloured end in one image.

    Positions are full-resolution pixel coordinates in OpenCV's convention: the
    centre of the top-left pixel is (0, 0), x to the right, y down.
    """

    found: bool
    centroid_px: NDArray[np.float64] | None
    """Sub-pixel centre of the end's image, shape (2,) as (x, y); None when not found."""
    area_px: float
    """Visible area of the end's image in full-resolution pixels (0 when not found)."""
    bbox_px: tuple[int, int, int, int] | None
    """(x0, y0, x1, y1), inclusive: the outermost samples of the end's colour in the blob.
    Its midpoint is the report's eq. 12 centre."""
    score: float
    """How well the blob fits a ball and the other end, in [0, 1] (1: a round blob paired with
    a blob of the other colour of the same size at a plausible distance)."""
    reason: str | None
    """Why the end was not found; None when it was."""

    @staticmethod
    def missing(reason: str) -> EndDetection:
        return EndDetection(False, None, 0.0, None, 0.0, reason)


@dataclass(frozen=True, slots=True, eq=False)
class ImageDetections:
    """Both ends in one image, and which search produced them."""

    red: EndDetection
    blue: EndDetection
    search: Literal["window", "full"]
    """'window': found around the previous frame's positions; 'full': the whole frame searched."""

    def end(self, colour: str) -> EndDetection:
        """The detection of ``colour`` ('red' or 'blue')."""
        if colour == "red":
            return self.red
        if colour == "blue":
            return self.blue
        raise ValueError(f"no end coloured {colour!r}; the ends are 'red' and 'blue'")

    @property
    def both_found(self) -> bool:
        return self.red.found and self.blue.found
