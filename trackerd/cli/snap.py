"""`trackerd snap --config RIG OUT`: one synchronized pair, saved raw and viewable, with what trackerd sees in it.

The report's Snap mode (section 6.2), for aiming cameras and tuning colours:
opens the cameras, lets them settle, takes one pair and writes into the folder
OUT (created if missing):

  <name>-<camera>.png        the raw frame, lossless (a Bayer mosaic stays one channel):
                             `trackerd locate`, `trackerd recording import` and
                             `trackerd calibrate --pairs` read these
  <name>-<camera>-view.png   demosaiced, with each detected end circled and the fix written on it
  <name>.json                timestamps, frame ids, skew, detections and the fix

and prints each camera's detections and the wall hit. <name> is snap-<local time>.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from trackerd.config.loader import load_rig
from trackerd.errors import CameraError, ImageError
from trackerd.recording.cameras import add_virtual_arguments


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "snap", help="take one synchronized pair, save it raw and annotated, print the detections and the hit",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--config", required=True, help="rig TOML file")
    parser.add_argument("out", metavar="OUT", help="folder to save into (created if missing)")
    parser.add_argument("--name", help="file name stem (default snap-<local time>)")
    parser.add_argument("--settle", type=float, default=0.5, metavar="S",
                        help="seconds of pairs to discard first, while exposure settles (default 0.5)")
    parser.add_argument("--timeout", type=float, default=10.0, metavar="S",
                        help="give up if no pair arrives within this many seconds (default 10)")
    add_virtual_arguments(parser, "snap")
    parser.set_defaults(handler=snap_command)


def snap_command(args: argparse.Namespace) -> int:
    from trackerd.recording.cameras import open_cameras
    from trackerd.recording.outputs import output_folder

    loaded = load_rig(args.config)
    # Before the cameras open: a pair taken and then not saved is lost.
    folder = output_folder(args.out)
    name = args.name or f"snap-{dt.datetime.now():%Y%m%d-%H%M%S}"
    with open_cameras(loaded.config, virtual_motion=args.virtual, label="trackerd snap", prefix=args.prefix,
                      subnet=args.subnet) as cams:
        pair = _take(cams.source, args.settle, args.timeout)
        rig = cams.rig
        info = dict(cams.info)
    return save_snap(pair, rig, folder, name, info)


def _take(source, settle_s: float, timeout_s: float):
    """The first pair after ``settle_s`` seconds of pairs (CameraError if none comes in time)."""
    start = time.monotonic()
    deadline = start + settle_s + timeout_s
    while time.monotonic() < deadline:
        pair = source.next_pair(0.1)
        if pair is not None and time.monotonic() - start >= settle_s:
            return pair
    raise CameraError(f"no synchronized pair arrived within {timeout_s:g} s (see `trackerd cameras`)")


def save_snap(pair, rig, folder: Path, name: str, camera_info: dict[str, Any] | None = None) -> int:
    """Locate the pointer in ``pair``, write the files, print what was found."""
    from trackerd.locator import Locator
    from trackerd.recording.annotate import annotate, end_summary, fix_summary
    from trackerd.recording.outputs import output_folder

    formats = [frame.pixel_format for frame in pair.frames]
    locator = Locator(rig, pixel_formats=formats)
    fix = locator.locate(pair.images)
    output_folder(folder)
    summary = fix_summary(fix)
    record: dict[str, Any] = {
        "name": name, "taken_utc": dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds"), "rig": rig.name,
        "timestamp_ns": pair.timestamp_ns, "skew_ns": pair.skew_ns, "sequence": pair.sequence,
        "status": fix.status, "reason": fix.reason, "cameras": [],
    }
    if fix.hit is not None:
        record["wall_xy_m"] = [float(v) for v in fix.hit.wall_xy_m[:2]]
        record["display_px"] = None if fix.hit.display_px is None else [float(v) for v in fix.hit.display_px[:2]]
        record["on_wall"] = bool(fix.hit.on_wall)
        record["distance_m"] = fix.hit.distance_m
    if fix.line is not None:
        record["ray_gap_mm"] = max(fix.line.front_gap_m, fix.line.back_gap_m) * 1000.0
    print(f"snap {name}: {summary}")
    for k, frame in enumerate(pair.frames):
        detections = fix.detections[k] if fix.detections else None
        raw_path = folder / f"{name}-{frame.camera_id}.png"
        view_path = folder / f"{name}-{frame.camera_id}-view.png"
        raw = frame.image if frame.image.ndim == 2 or frame.pixel_format == "BGR8" else frame.image[..., ::-1]
        lines = [f"{name}  {frame.camera_id}  frame {frame.frame_id}", summary]
        ends = end_summary(detections) if detections is not None else "no detections"
        lines.append(ends)
        for path, image in ((raw_path, np.ascontiguousarray(raw)),
                            (view_path, annotate(frame.image, frame.pixel_format, detections, lines))):
            if not cv2.imwrite(str(path), image):
                raise ImageError(f"{path}: cannot write the image")
        print(f"  {frame.camera_id}: {ends}")
        print(f"    saved {raw_path} (raw {frame.pixel_format}) and {view_path}")
        ends_json = {}
        if detections is not None:
            for colour in ("red", "blue"):
                end = detections.end(colour)
                ends_json[colour] = {
                    "found": end.found,
                    "centroid_px": None if end.centroid_px is None else [float(v) for v in end.centroid_px],
                    "area_px": end.area_px, "bbox_px": end.bbox_px, "reason": end.reason,
                }
        record["cameras"].append({
            "id": frame.camera_id, "frame_id": frame.frame_id, "pixel_format": frame.pixel_format,
            "device_timestamp_ns": frame.device_timestamp_ns, "host_timestamp_ns": frame.host_timestamp_ns,
            "raw": raw_path.name, "view": view_path.name, "ends": ends_json,
            **({"camera": camera_info[frame.camera_id]} if camera_info and frame.camera_id in camera_info else {}),
        })
    (folder / f"{name}.json").write_text(json.dumps(record, indent=2) + "\n")
    print(f"  details: {folder / (name + '.json')}", file=sys.stderr)
    return 0
