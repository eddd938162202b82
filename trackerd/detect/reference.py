"""Baselines the detector is measured against: an OpenCV pipeline and the report's own method.

* :func:`opencv_reference`: what a colour tracker built from OpenCV's usual
  steps does: demosaic, convert to HSV, ``inRange`` for each end's hue, and the
  centroid of the whole mask from ``moments``. No blob selection, so every red
  thing in the room pulls on the red end.
* :func:`report_baseline`: the report's section 3.2 taken literally: keep the
  pixels of the end's colour (eq. 10-11, here with the same colour test as the
  detector on the demosaiced image) and take the midpoint of their extent over
  the whole image (eq. 12).

The detector's own eq. 12 on the blob it chose is ``DetectorConfig(centroid="bbox")``.
OpenCV is used here only; the detector itself is NumPy (docs/detection.md).
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.config.models import DetectorConfig
from trackerd.detect.result import EndDetection, ImageDetections
from trackerd.errors import ImageError

# OpenCV 4.10+ and 5.x name Bayer conversions by the full top-left 2x2 pattern
# (BayerRGGB is GenICam's BayerRG8).
_DEMOSAIC_TO_BGR = {
    "BayerRG8": cv2.COLOR_BayerRGGB2BGR,
    "BayerGR8": cv2.COLOR_BayerGRBG2BGR,
    "BayerGB8": cv2.COLOR_BayerGBRG2BGR,
    "BayerBG8": cv2.COLOR_BayerBGGR2BGR,
}

HUE_HALF_WIDTH = 12
"""Half-width of each end's hue band, in OpenCV's 0-180 hue units (red 0, blue 120)."""

MIN_SATURATION = 100
"""Saturation (0-255) a pixel needs to count as coloured."""


def to_bgr(frame: NDArray[np.uint8], pixel_format: str) -> NDArray[np.uint8]:
    """Any supported frame -> (H, W, 3) BGR, demosaicing a Bayer mosaic bilinearly."""
    code = _DEMOSAIC_TO_BGR.get(pixel_format)
    # np.asarray: OpenCV's stubs type its results loosely; they are uint8 arrays (not copied).
    if code is not None:
        return np.asarray(cv2.cvtColor(frame, code), dtype=np.uint8)
    if pixel_format == "BGR8":
        return frame
    if pixel_format == "RGB8":
        return np.asarray(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR), dtype=np.uint8)
    raise ImageError(f"pixel format {pixel_format!r} is not a colour format")


def opencv_reference(frame: NDArray[np.uint8], pixel_format: str, cfg: DetectorConfig) -> ImageDetections:
    """Demosaic, HSV, inRange per end, moments: the centroid of every pixel of each end's hue."""
    hsv = cv2.cvtColor(to_bgr(frame, pixel_format), cv2.COLOR_BGR2HSV)
    ends = {}
    for colour, hue, thr in (("red", 0, cfg.red), ("blue", 120, cfg.blue)):
        low = (max(hue - HUE_HALF_WIDTH, 0), MIN_SATURATION, thr.min_value)
        high = (min(hue + HUE_HALF_WIDTH, 179), 255, 255)
        mask = np.asarray(cv2.inRange(hsv, low, high), dtype=np.uint8)
        if hue - HUE_HALF_WIDTH < 0:  # red wraps around hue 0
            mask |= np.asarray(
                cv2.inRange(hsv, (180 + hue - HUE_HALF_WIDTH, MIN_SATURATION, thr.min_value), (179, 255, 255)),
                dtype=np.uint8,
            )
        m = cv2.moments(mask, binaryImage=True)
        if m["m00"] <= 0:
            ends[colour] = EndDetection.missing(f"no {colour} pixels in the hue band")
            continue
        centre = np.array([m["m10"] / m["m00"], m["m01"] / m["m00"]])
        x, y, w, h = cv2.boundingRect(mask)
        ends[colour] = EndDetection(True, centre, float(m["m00"]), (x, y, x + w - 1, y + h - 1), 1.0, None)
    return ImageDetections(ends["red"], ends["blue"], "full")


def report_baseline(frame: NDArray[np.uint8], pixel_format: str, cfg: DetectorConfig) -> ImageDetections:
    """The report's eq. 10-12: midpoint of the extent of all pixels of each end's colour."""
    rgb = to_bgr(frame, pixel_format)[..., ::-1].astype(np.int16)
    ends = {}
    for colour, own, thr in (("red", 0, cfg.red), ("blue", 2, cfg.blue)):
        others = np.maximum(rgb[..., 1], rgb[..., 2 - own])
        mask = (rgb[..., own] - others >= thr.min_excess) & (rgb[..., own] >= thr.min_value)
        ys, xs = np.nonzero(mask)
        if xs.size == 0:
            ends[colour] = EndDetection.missing(f"no {colour} pixels above threshold")
            continue
        x0, x1, y0, y1 = int(xs.min()), int(xs.max()), int(ys.min()), int(ys.max())
        centre = np.array([x0 + (x1 - x0) / 2.0, y0 + (y1 - y0) / 2.0])  # eq. 12
        ends[colour] = EndDetection(True, centre, float(xs.size), (x0, y0, x1, y1), 1.0, None)
    return ImageDetections(ends["red"], ends["blue"], "full")


def naive_ends(frame: NDArray[np.uint8], pixel_format: str) -> dict[str, NDArray[np.float64] | None]:
    """The naive tracker a newcomer writes first: each end is the bounding-box midpoint of the largest
    connected blob of its hue (demosaic, HSV, ``inRange``, connected components).

    No thresholds tuned to any scene, no shape test, no sub-pixel work: the yardstick
    ``trackerd bench robustness`` holds the detector to on scenes neither was designed for.
    """
    hsv = cv2.cvtColor(to_bgr(frame, pixel_format), cv2.COLOR_BGR2HSV)
    ends: dict[str, NDArray[np.float64] | None] = {}
    for colour, hue in (("red", 0), ("blue", 120)):
        mask = np.asarray(
            cv2.inRange(
                hsv, (max(hue - HUE_HALF_WIDTH, 0), MIN_SATURATION, 40), (min(hue + HUE_HALF_WIDTH, 179), 255, 255)
            ),
            dtype=np.uint8,
        )
        if hue - HUE_HALF_WIDTH < 0:
            mask |= np.asarray(
                cv2.inRange(hsv, (180 + hue - HUE_HALF_WIDTH, MIN_SATURATION, 40), (179, 255, 255)), dtype=np.uint8
            )
        count, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        if count <= 1:
            ends[colour] = None
            continue
        largest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
        x, y, w, h = (int(v) for v in stats[largest, :4])
        ends[colour] = np.array([x + (w - 1) / 2.0, y + (h - 1) / 2.0])
    return ends
