"""Viewable images of frames: demosaiced, with the detected ends and the fix drawn on them (export, snap)."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.detect import ImageDetections
from trackerd.locator import PointerFix
from trackerd.pixelformat import to_bgr

# Drawing colours (BGR): each end in a brighter version of its own colour, text in white on a dark box.
_END_BGR = {"red": (60, 60, 255), "blue": (255, 120, 40)}
_TEXT_BGR = (255, 255, 255)
_FONT = cv2.FONT_HERSHEY_SIMPLEX


def viewable(frame: NDArray[np.uint8], pixel_format: str) -> NDArray[np.uint8]:
    """Any supported raw frame -> a BGR image for PNG (Bayer demosaiced bilinearly)."""
    return to_bgr(frame, pixel_format)


def _text(
    image: NDArray[np.uint8], lines: Sequence[str], top_left: tuple[int, int], scale: float = 0.8, thickness: int = 2
) -> None:
    """Lines of white text on a darkened box, legible on any background.

    One pass of plain text: an outline drawn as a thicker pass of the same text does not fit it,
    because a Hershey font's advance per character grows with the thickness (the outline drifts
    right of the text, more with every character). The box is sized by ``cv2.getTextSize`` at the
    thickness drawn, and darkens rather than hides what lies under it.
    """
    if not lines:
        return
    pad, gap = 6, 8
    sizes = [cv2.getTextSize(line, _FONT, scale, thickness) for line in lines]
    ascent = max(h for (_, h), _ in sizes)
    descent = max(b for _, b in sizes)
    pitch = ascent + descent + gap
    x, y = top_left
    x0, y0 = max(x, 0), max(y, 0)
    x1 = x + 2 * pad + max(w for (w, _), _ in sizes)
    y1 = y + 2 * pad + len(lines) * pitch - gap
    region = image[y0 : max(y1, y0), x0 : max(x1, x0)]
    region //= 4
    for k, line in enumerate(lines):
        cv2.putText(
            image, line, (x + pad, y + pad + ascent + k * pitch), _FONT, scale, _TEXT_BGR, thickness, cv2.LINE_AA
        )


def fix_summary(fix: PointerFix) -> str:
    """One line: the fix's status and, for a hit, where on the wall."""
    if fix.hit is not None:
        x_m, y_m = (float(v) for v in fix.hit.wall_xy_m[:2])
        text = f"{fix.status}: wall ({x_m:.3f}, {y_m:.3f}) m"
        if fix.hit.display_px is not None:
            px, py = (float(v) for v in fix.hit.display_px[:2])
            text += f", display ({px:.0f}, {py:.0f}) px"
        return text
    return f"{fix.status}" + (f": {fix.reason}" if fix.reason else "")


def end_summary(detections: ImageDetections) -> str:
    """One line per image: each end's centre and area, or why it was not found."""
    parts = []
    for colour in ("red", "blue"):
        end = detections.end(colour)
        if end.found and end.centroid_px is not None:
            x, y = end.centroid_px
            parts.append(f"{colour} ({x:.2f}, {y:.2f}) px, {end.area_px:.0f} px^2")
        else:
            parts.append(f"{colour} not found ({end.reason or 'no blob'})")
    return "; ".join(parts)


def annotate(
    frame: NDArray[np.uint8],
    pixel_format: str,
    detections: ImageDetections | None,
    lines: Sequence[str] = (),
) -> NDArray[np.uint8]:
    """A BGR image of ``frame`` with each found end circled (its box drawn, its centre crossed)
    and ``lines`` of text in the top-left corner."""
    image = np.ascontiguousarray(viewable(frame, pixel_format)).copy()
    if detections is not None:
        for colour in ("red", "blue"):
            end = detections.end(colour)
            if not end.found or end.centroid_px is None:
                continue
            bgr = _END_BGR[colour]
            x, y = (float(v) for v in end.centroid_px)
            radius = max(6, int(np.sqrt(max(end.area_px, 1.0) / np.pi)) + 6)
            # Sub-pixel drawing: OpenCV takes fixed-point coordinates with `shift` fractional bits.
            centre = (round(x * 16), round(y * 16))
            cv2.circle(image, centre, radius * 16, bgr, 2, cv2.LINE_AA, shift=4)
            cv2.drawMarker(image, (round(x), round(y)), bgr, cv2.MARKER_CROSS, 10, 1, cv2.LINE_AA)
            if end.bbox_px is not None:
                x0, y0, x1, y1 = end.bbox_px
                cv2.rectangle(image, (x0 - 1, y0 - 1), (x1 + 1, y1 + 1), bgr, 1)
            _text(image, [colour], (int(x) + radius + 4, int(y) - 12), 0.6, 1)
    _text(image, lines, (8, 8))
    return image
