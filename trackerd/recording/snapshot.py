"""A snapshot's files: one synchronized pair saved raw and annotated, with its fix (`trackerd snap`,
the console's snapshot button and `trackerd ctl snap`).

Into a folder, for a stem <name>:

  <name>-<camera>.png        the raw frame, lossless (a Bayer mosaic stays one channel)
  <name>-<camera>-view.png   demosaiced, the detected ends circled, their search windows, why an
                             end was not found, the display's outline and corners projected from
                             the calibration, and the fix written on it
  <name>.json                timestamps, frame ids, skew, detections and the fix
"""

from __future__ import annotations

import contextlib
import datetime as dt
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from trackerd.errors import ImageError
from trackerd.images import write_png


def snapshot_record(pair: Any, fix: Any, rig: Any, name: str) -> dict[str, Any]:
    """The JSON record's top level: when, which pair, the fix."""
    record: dict[str, Any] = {
        "name": name,
        "taken_utc": dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds"),
        "rig": rig.name,
        "timestamp_ns": pair.timestamp_ns,
        "skew_ns": pair.skew_ns,
        "sequence": pair.sequence,
        "status": fix.status,
        "reason": fix.reason,
        "cameras": [],
    }
    if fix.hit is not None:
        record["wall_xy_m"] = [float(v) for v in fix.hit.wall_xy_m[:2]]
        record["display_px"] = None if fix.hit.display_px is None else [float(v) for v in fix.hit.display_px[:2]]
        record["on_wall"] = bool(fix.hit.on_wall)
        record["distance_m"] = fix.hit.distance_m
    if fix.line is not None:
        record["ray_gap_mm"] = max(fix.line.front_gap_m, fix.line.back_gap_m) * 1000.0
    return record


def write_snapshot(
    pair: Any,
    fix: Any,
    locator: Any,
    rig: Any,
    folder: Path,
    name: str,
    camera_info: dict[str, Any] | None = None,
    say: Callable[[str], None] = lambda _line: None,
) -> list[Path]:
    """Write the snapshot's files for ``pair`` located as ``fix`` by ``locator``; the paths written
    (views and raw frames by camera, the JSON last). ``say`` gets a line per camera."""
    from trackerd.console.overlay import camera_overlay, draw_overlay
    from trackerd.recording.annotate import annotate, end_summary, fix_summary

    made_folder = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    summary = fix_summary(fix)
    record = snapshot_record(pair, fix, rig, name)
    say(f"snap {name}: {summary}")
    written: list[Path] = []
    for k, frame in enumerate(pair.frames):
        detections = fix.detections[k] if fix.detections else None
        raw_path = folder / f"{name}-{frame.camera_id}.png"
        view_path = folder / f"{name}-{frame.camera_id}-view.png"
        raw = frame.image if frame.image.ndim == 2 or frame.pixel_format == "BGR8" else frame.image[..., ::-1]
        ends = end_summary(detections) if detections is not None else "no detections"
        lines = [f"{name}  {frame.camera_id}  frame {frame.frame_id}", summary, ends]
        view = annotate(frame.image, frame.pixel_format, detections, lines)
        if k < len(locator.cameras):
            overlay = camera_overlay(locator.cameras[k], locator.wall, detections, rig.detector.track_window_px)
            draw_overlay(view, overlay)
        for path, image in ((raw_path, np.ascontiguousarray(raw)), (view_path, view)):
            try:
                write_png(path, image)
            except ImageError:
                _discard([*written, raw_path], folder if made_folder else None)
                raise
        written += [view_path, raw_path]
        say(f"  {frame.camera_id}: {ends}")
        say(f"    saved {raw_path} (raw {frame.pixel_format}) and {view_path}")
        ends_json = {}
        if detections is not None:
            for colour in ("red", "blue"):
                end = detections.end(colour)
                ends_json[colour] = {
                    "found": end.found,
                    "centroid_px": None if end.centroid_px is None else [float(v) for v in end.centroid_px],
                    "area_px": end.area_px,
                    "bbox_px": end.bbox_px,
                    "reason": end.reason,
                }
        record["cameras"].append(
            {
                "id": frame.camera_id,
                "frame_id": frame.frame_id,
                "pixel_format": frame.pixel_format,
                "device_timestamp_ns": frame.device_timestamp_ns,
                "host_timestamp_ns": frame.host_timestamp_ns,
                "raw": raw_path.name,
                "view": view_path.name,
                "ends": ends_json,
                **({"camera": camera_info[frame.camera_id]} if camera_info and frame.camera_id in camera_info else {}),
            }
        )
    json_path = folder / f"{name}.json"
    try:
        json_path.write_text(json.dumps(record, indent=2) + "\n")
    except OSError as err:
        _discard([*written, json_path], folder if made_folder else None)
        raise ImageError(f"{json_path}: cannot write the snapshot's record: {err.strerror or err}") from err
    written.append(json_path)
    return written


def _discard(paths: list[Path], folder: Path | None) -> None:
    """Half a snapshot is none: remove what it wrote, and ``folder`` (the one it made) if that leaves it empty."""
    for path in paths:
        with contextlib.suppress(OSError):
            path.unlink()
    if folder is not None:
        with contextlib.suppress(OSError):
            folder.rmdir()
