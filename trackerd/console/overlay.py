"""What the console draws over a camera's image: the ends found, where they are searched for next,
why one is missing, and the display's outline projected from the calibration.

Pure functions from a fix and the calibrated cameras to plain data (full-resolution pixel
coordinates, JSON-ready), drawn by the page over the live image (SVG) and by
:func:`draw_overlay` into a snapshot's annotated view. Drawing the outline from the calibration
beside what the camera sees tells the operator at a glance whether the calibration still fits:
a bumped camera shows the outline off the display's edges.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.geometry.camera import CameraModel
from trackerd.geometry.wall import WallFrame

OUTLINE_SAMPLES = 24
"""Points per edge of the display's outline (lens distortion bends straight edges)."""
CORNER_NAMES = ("bottom-left", "bottom-right", "top-right", "top-left")
END_BGR = {"red": (60, 60, 255), "blue": (255, 120, 40)}
OUTLINE_BGR = (80, 230, 80)


def outline_px(camera: CameraModel, wall: WallFrame) -> tuple[list[list[list[float]]], list[list[float] | None]]:
    """The display's outline in ``camera``'s image, as runs of visible points (each (N, 2) as
    lists of [x, y] px, split where the outline passes behind the camera), and the four corners
    (bottom-left, bottom-right, top-right, top-left; None where behind the camera)."""
    corners_m = wall.corners_m
    steps = np.linspace(0.0, 1.0, OUTLINE_SAMPLES, endpoint=False)[:, None]
    edges = [corners_m[k] + steps * (corners_m[(k + 1) % 4] - corners_m[k]) for k in range(4)]
    points_m = np.vstack([*edges, corners_m[:1]])
    points_px = camera.project(points_m)
    runs: list[list[list[float]]] = []
    current: list[list[float]] = []
    for x, y in points_px:
        if np.isfinite(x) and np.isfinite(y):
            current.append([round(float(x), 1), round(float(y), 1)])
        elif current:
            runs.append(current)
            current = []
    if current:
        runs.append(current)
    corners = [
        [round(float(x), 1), round(float(y), 1)] if np.isfinite(x) and np.isfinite(y) else None
        for x, y in camera.project(corners_m)
    ]
    return runs, corners


def camera_overlay(camera: CameraModel, wall: WallFrame | None, detections: Any, window_px: int) -> dict[str, Any]:
    """One camera's overlay for one fix: per end its centre, radius and box, the window it is
    searched in next (``window_px`` on each side of it, the detector's ``track_window_px``) or
    why it was not found; which search found them; the display's outline and corners."""
    ends: dict[str, Any] = {}
    for colour in ("red", "blue"):
        end = detections.end(colour) if detections is not None else None
        if end is None:
            ends[colour] = {"found": False, "reason": "not measured"}
        elif not end.found or end.centroid_px is None:
            ends[colour] = {"found": False, "reason": end.reason or "no blob"}
        else:
            x, y = (float(v) for v in end.centroid_px)
            ends[colour] = {
                "found": True,
                "x_px": round(x, 2),
                "y_px": round(y, 2),
                "radius_px": round(float(np.sqrt(max(end.area_px, 1.0) / np.pi)), 1),
                "bbox_px": list(end.bbox_px) if end.bbox_px is not None else None,
                "window_px": [round(x - window_px), round(y - window_px), round(x + window_px), round(y + window_px)],
            }
    overlay: dict[str, Any] = {
        "width_px": camera.width_px,
        "height_px": camera.height_px,
        "search": getattr(detections, "search", None),
        "ends": ends,
        "outline_px": [],
        "corners_px": [None] * 4,
    }
    if wall is not None:
        overlay["outline_px"], overlay["corners_px"] = outline_px(camera, wall)
    return overlay


def draw_overlay(image_bgr: NDArray[np.uint8], overlay: dict[str, Any]) -> NDArray[np.uint8]:
    """Draw ``overlay`` (full-resolution coordinates) into a full-resolution BGR image, in place."""
    for run in overlay["outline_px"]:
        points = np.round(np.asarray(run) * 16).astype(np.int32).reshape(-1, 1, 2)
        cv2.polylines(image_bgr, [points], False, OUTLINE_BGR, 2, cv2.LINE_AA, shift=4)
    for name, corner in zip(CORNER_NAMES, overlay["corners_px"], strict=True):
        if corner is None:
            continue
        x, y = round(corner[0]), round(corner[1])
        cv2.drawMarker(image_bgr, (x, y), OUTLINE_BGR, cv2.MARKER_SQUARE, 14, 2, cv2.LINE_AA)
        cv2.putText(image_bgr, name, (x + 10, y - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.6, OUTLINE_BGR, 1, cv2.LINE_AA)
    notes = []
    for colour, end in overlay["ends"].items():
        bgr = END_BGR[colour]
        if not end["found"]:
            notes.append(f"{colour}: {end['reason']}")
            continue
        x0, y0, x1, y1 = end["window_px"]
        cv2.rectangle(image_bgr, (x0, y0), (x1, y1), bgr, 1, cv2.LINE_4)
    y = image_bgr.shape[0] - 16
    for note in reversed(notes):
        cv2.putText(image_bgr, note, (12, y), cv2.FONT_HERSHEY_SIMPLEX, 0.8, (255, 255, 255), 2, cv2.LINE_AA)
        y -= 30
    return image_bgr
