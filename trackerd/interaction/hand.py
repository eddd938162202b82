"""Hand poses (the report's section 3.9, static gestures): extended fingers counted in one camera's image.

The report names "the number of extended fingers" as the hand shapes worth
discriminating. The detector, per look:

1. **half resolution, no demosaicing**: each 2x2 Bayer cell becomes one RGB
   pixel (960x540 from 1080p), the sensor's own colour resolution, in one
   strided NumPy pass;
2. **colour segmentation** in HSV (``hue_range_deg``, ``saturation_range_ratio``,
   ``min_value_ratio``: skin by default, a glove's colour for reliability), and
   optionally only where the image differs from a learnt empty scene
   (``background_difference_ratio``), so skin-coloured things that never move
   are ignored; a morphological opening removes specks;
3. **the largest contour** of at least ``min_area_px`` is the hand;
4. **the palm**: the largest inscribed circle (the distance transform's
   maximum) gives the palm's centre and radius r;
5. **fingers from convexity defects**: a defect (a valley of the contour under
   its convex hull) deeper than ``DEFECT_DEPTH`` r, whose sides meet at less
   than ``DEFECT_ANGLE_DEG``, and whose two hull points lie beyond
   ``TIP_REACH`` r from the palm's centre, separates two extended fingers; n
   such valleys mean n + 1 fingers. With none, the hand shows one finger if a
   narrow part of it reaches beyond ``TIP_REACH`` r (a finger), else none (a
   fist; the wrist is wide, so it does not count);
6. **debouncing**: the count is published once it has been seen on
   ``debounce_pairs`` looks in a row.

OpenCV does the contour work (findContours, convexHull, convexityDefects,
distanceTransform): this is a per-look pass at low resolution, not the
pointer's vectorised hot path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import cast

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.config.interaction import HandConfig
from trackerd.pixelformat import BAYER_LAYOUTS

DEFECT_DEPTH = 0.55
"""A valley between fingers is at least this deep, in palm radii."""
DEFECT_ANGLE_DEG = 95.0
"""The sides of a valley between two fingers meet at less than this angle."""
TIP_REACH = 1.5
"""A finger's tip lies at least this far from the palm's centre, in palm radii."""
FINGER_WIDTH = (0.28, 0.9)
"""Crossing the circle of TIP_REACH radii, a finger is this wide (in palm radii): the wrist and
forearm are wider, a knuckle grazing the circle narrower."""
BACKGROUND_RATE = 0.02
"""Per look, how much of the learnt empty scene is replaced by the current image (away from the hand)."""


@dataclass(frozen=True)
class HandObservation:
    """One look: the largest hand-coloured shape and its finger count (full-resolution pixels)."""

    fingers: int
    centre_px: tuple[float, float]
    """The palm's centre."""
    palm_radius_px: float
    area_px: float


def half_resolution_rgb(image: NDArray[np.uint8], pixel_format: str) -> NDArray[np.uint8]:
    """An (H/2, W/2, 3) RGB image from a Bayer frame (one pixel per 2x2 cell), or an RGB8/BGR8 frame
    subsampled by two: the colour resolution the sensor really has."""
    layout = BAYER_LAYOUTS.get(pixel_format)
    if layout is None:
        rgb = image if pixel_format == "RGB8" else image[..., ::-1]
        return np.ascontiguousarray(rgb[::2, ::2])
    h, w = image.shape[0] // 2 * 2, image.shape[1] // 2 * 2

    def plane(pos: tuple[int, int]) -> NDArray[np.uint8]:
        return image[pos[0] : h : 2, pos[1] : w : 2]

    green = ((plane(layout.green_a).astype(np.uint16) + plane(layout.green_b)) >> 1).astype(np.uint8)
    return np.dstack([plane(layout.red), green, plane(layout.blue)])


def colour_mask(rgb: NDArray[np.uint8], config: HandConfig) -> NDArray[np.uint8]:
    """255 where a pixel has the hand's colour, else 0: (H, W, 3) -> (H, W)."""
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)
    lo_hue, hi_hue = (h / 2.0 for h in config.hue_range_deg)  # OpenCV's 8-bit hue is degrees / 2
    s_lo, s_hi = (round(v * 255) for v in config.saturation_range_ratio)
    v_lo = round(config.min_value_ratio * 255)
    if lo_hue <= hi_hue:
        return _u8(cv2.inRange(hsv, (math.floor(lo_hue), s_lo, v_lo), (math.ceil(hi_hue), s_hi, 255)))
    upper = cv2.inRange(hsv, (math.floor(lo_hue), s_lo, v_lo), (180, s_hi, 255))
    lower = cv2.inRange(hsv, (0, s_lo, v_lo), (math.ceil(hi_hue), s_hi, 255))
    return _u8(cv2.bitwise_or(upper, lower))


def count_fingers(contour: NDArray[np.int32], mask: NDArray[np.uint8]) -> tuple[int, tuple[float, float], float]:
    """(fingers 0-5, palm centre (x, y), palm radius) of one hand contour drawn in ``mask`` (its pixels)."""
    x, y, w, h = cv2.boundingRect(contour)
    pad = 2
    local = np.zeros((h + 2 * pad, w + 2 * pad), np.uint8)
    cv2.drawContours(local, [contour - [x - pad, y - pad]], -1, 255, thickness=cv2.FILLED)
    distance = cv2.distanceTransform(local, cv2.DIST_L2, 5)
    _, radius, _, (cx, cy) = cv2.minMaxLoc(distance)
    centre = np.array([cx + x - pad, cy + y - pad], dtype=np.float64)
    radius = max(float(radius), 1.0)
    hull = cv2.convexHull(contour, returnPoints=False)
    valleys = 0
    if hull is not None and len(hull) > 3:
        try:
            defects = cv2.convexityDefects(contour, np.sort(hull, axis=0))
        except cv2.error:
            defects = None  # a self-intersecting contour: count by reach alone
        for start_i, end_i, far_i, depth in defects.reshape(-1, 4) if defects is not None else ():
            if depth / 256.0 < DEFECT_DEPTH * radius:
                continue
            start, end, far = (contour[i][0].astype(np.float64) for i in (start_i, end_i, far_i))
            a, b = start - far, end - far
            cosine = float(a @ b) / max(float(np.hypot(*a) * np.hypot(*b)), 1e-9)
            if math.degrees(math.acos(min(1.0, max(-1.0, cosine)))) >= DEFECT_ANGLE_DEG:
                continue
            if min(np.hypot(*(start - centre)), np.hypot(*(end - centre))) < TIP_REACH * radius:
                continue
            valleys += 1
    if valleys:
        return min(valleys + 1, 5), (float(centre[0]), float(centre[1])), radius
    return _fingers_by_reach(local, centre - [x - pad, y - pad], radius), (float(centre[0]), float(centre[1])), radius


def _fingers_by_reach(local: NDArray[np.uint8], centre: NDArray[np.float64], radius: float) -> int:
    """1 when a narrow run of the hand crosses the circle of TIP_REACH radii (a finger), else 0."""
    reach = TIP_REACH * radius
    samples = max(64, int(2 * math.pi * reach))
    angles = np.linspace(0.0, 2 * math.pi, samples, endpoint=False)
    xs = np.clip(np.round(centre[0] + reach * np.cos(angles)).astype(int), 0, local.shape[1] - 1)
    ys = np.clip(np.round(centre[1] + reach * np.sin(angles)).astype(int), 0, local.shape[0] - 1)
    inside = local[ys, xs] > 0
    if not np.any(inside) or np.all(inside):
        return 0
    # Runs of the circle inside the hand, rotated so the circle starts outside it (no run wraps).
    inside = np.roll(inside, -int(np.argmin(inside)))
    padded = np.concatenate([[0], inside.astype(np.int8), [0]])
    starts = np.flatnonzero(np.diff(padded) == 1)
    ends = np.flatnonzero(np.diff(padded) == -1)
    widths = (ends - starts) * (2 * math.pi * reach / samples)
    return int(np.any((widths >= FINGER_WIDTH[0] * radius) & (widths <= FINGER_WIDTH[1] * radius)))


def _u8(mask: cv2.typing.MatLike) -> NDArray[np.uint8]:
    """A mask OpenCV made from 8-bit images, typed as such (its stubs say only "a matrix")."""
    return cast(NDArray[np.uint8], mask)


class HandDetector:
    """Finds the hand in frames of one camera and counts its fingers; keeps the learnt empty scene."""

    def __init__(self, config: HandConfig) -> None:
        self.config = config
        self._background: NDArray[np.float32] | None = None
        self._kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))

    def reset(self) -> None:
        self._background = None

    def look(self, image: NDArray[np.uint8], pixel_format: str) -> HandObservation | None:
        """The hand in one full-resolution frame, or None."""
        rgb = half_resolution_rgb(image, pixel_format)
        mask = colour_mask(rgb, self.config)
        threshold = self.config.background_difference_ratio
        if threshold > 0:
            mask = self._moving(rgb, mask, threshold)
        mask = _u8(cv2.morphologyEx(mask, cv2.MORPH_OPEN, self._kernel))
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        if not contours:
            return None
        contour = max(contours, key=cv2.contourArea)
        area_half = float(cv2.contourArea(contour))
        if area_half * 4.0 < self.config.min_area_px:
            return None
        # findContours gives int32 point arrays; OpenCV's stubs say only "a matrix".
        fingers, (cx, cy), radius = count_fingers(cast(NDArray[np.int32], contour), mask)
        # Half-resolution pixel (i, j) covers full-resolution pixels 2i..2i+1: centre at 2i + 0.5.
        return HandObservation(fingers, (2.0 * cx + 0.5, 2.0 * cy + 0.5), 2.0 * radius, 4.0 * area_half)

    def learn_background(self, image: NDArray[np.uint8], pixel_format: str) -> None:
        """Take a frame without a hand as the empty scene."""
        self._background = half_resolution_rgb(image, pixel_format).astype(np.float32)

    def _moving(self, rgb: NDArray[np.uint8], mask: NDArray[np.uint8], threshold: float) -> NDArray[np.uint8]:
        """The colour mask where the image differs from the empty scene; updates the scene elsewhere."""
        if self._background is None:
            self._background = rgb.astype(np.float32)
            return np.zeros_like(mask)
        difference = cv2.absdiff(rgb, cv2.convertScaleAbs(self._background))
        channels = cv2.split(difference)
        largest = cv2.max(cv2.max(channels[0], channels[1]), channels[2])
        _, changed = cv2.threshold(largest, threshold * 255.0, 255, cv2.THRESH_BINARY)
        # Learn slowly, and not where something changed: a hand held still is not absorbed at once.
        still = cv2.bitwise_not(cv2.dilate(changed, self._kernel, iterations=2))
        cv2.accumulateWeighted(rgb, self._background, BACKGROUND_RATE, mask=still)
        return _u8(cv2.bitwise_and(mask, changed))


class FingerDebouncer:
    """Publishes a finger count once it has been seen ``frames`` looks in a row."""

    def __init__(self, frames: int) -> None:
        self.frames = frames
        self.stable: int | None = None
        self._candidate: int | None = None
        self._seen = 0

    def reset(self) -> None:
        self.stable, self._candidate, self._seen = None, None, 0

    def add(self, fingers: int) -> bool:
        """Take one look's count; True when the stable count changed with it."""
        if fingers == self._candidate:
            self._seen += 1
        else:
            self._candidate, self._seen = fingers, 1
        if self._seen >= self.frames and self.stable != fingers:
            self.stable = fingers
            return True
        return False
