"""`trackerd locate`: the report's program (section 4) on two still images.

Reads one image per camera, finds both coloured ends in each, triangulates the
pointer and prints where on the wall it points. Exit code 0 only when the
pointer points at the display; 1 when an end is missing, the geometry is
impossible, or it points elsewhere; 2 for a bad configuration.

An image that does not look like the camera's raw frame is located all the
same, with a warning on stderr (and in "warnings" with --json): a colour picture
for a Bayer camera (demosaiced, compressed or annotated, such as the -view.png of
`trackerd snap`), or a single channel without a raw mosaic's 2x2 structure (a grey
picture). The hit's stated uncertainty holds only for raw frames.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from trackerd.config.loader import load_rig
from trackerd.detect.result import ImageDetections
from trackerd.errors import ImageError
from trackerd.images import raw_format_doubt, read_frame
from trackerd.locator import Locator, PointerFix


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "locate",
        help="locate the pointer in one image per camera and print its wall hit",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--config", required=True, help="rig TOML file")
    parser.add_argument(
        "images",
        nargs="+",
        metavar="IMAGE",
        help="one image per camera, in the rig's camera order (PNG, JPEG, TIFF or .npy)",
    )
    parser.add_argument("--truth", help="ground-truth JSON (as bundled in tests/data/pairs) to report the error")
    parser.add_argument("--json", action="store_true", help="print the result as one JSON object")
    parser.set_defaults(handler=locate_command)


def locate_command(args: argparse.Namespace) -> int:
    rig = load_rig(args.config).config
    if len(args.images) != len(rig.cameras):
        ids = ", ".join(c.id for c in rig.cameras)
        raise ImageError(f"the rig has {len(rig.cameras)} cameras ({ids}); give one image for each, in that order")
    frames, formats, warnings = [], [], []
    for path, camera in zip(args.images, rig.cameras, strict=True):
        frame, fmt = read_frame(path, camera)
        frames.append(frame)
        formats.append(fmt)
        # An image that is not the camera's raw frame still gives a hit, with an uncertainty that does not
        # hold for it (issue 15: an annotated picture, 51 mm off, claimed +-2.1 mm): say so, not silently.
        doubt = raw_format_doubt(frame, fmt, camera)
        if doubt is not None:
            if (raw := _snap_raw_frame(Path(path))) is not None:
                doubt += f"; here {raw}, which `trackerd snap` saved with this annotated view"
            warnings.append(f"{path}: {doubt}")
            print(f"trackerd locate: warning: {path}: {doubt}", file=sys.stderr)
    locator = Locator(rig, pixel_formats=formats)
    fix = locator.locate(frames)
    truth = _read_truth(args.truth) if args.truth else None
    result = fix_to_json(fix, locator, args.images)
    result["warnings"] = warnings
    if truth is not None:
        result["truth"] = _compare(fix, truth)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(describe(fix, locator, args.images, result.get("truth")))
    if fix.status != "hit":
        if args.json:
            print(f"trackerd locate: {fix.reason}", file=sys.stderr)
        return 1
    return 0


def _snap_raw_frame(path: Path) -> Path | None:
    """The raw ``<name>-<camera>.png`` next to `trackerd snap`'s annotated ``<name>-<camera>-view.png``."""
    if not path.name.endswith("-view.png"):
        return None
    raw = path.with_name(path.name.removesuffix("-view.png") + ".png")
    return raw if raw.exists() else None


def _read_truth(path: str) -> dict[str, Any]:
    try:
        truth: dict[str, Any] = json.loads(Path(path).read_text())
        return truth
    except (OSError, ValueError) as err:
        raise ImageError(f"{path}: cannot read ground truth ({err})") from err


def _compare(fix: PointerFix, truth: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {"wall_xy_m": truth.get("wall_xy_m")}
    if fix.hit is not None and truth.get("wall_xy_m") is not None:
        error = np.asarray(fix.hit.wall_xy_m) - np.asarray(truth["wall_xy_m"])
        out["wall_error_mm"] = float(np.linalg.norm(error) * 1000)
    if fix.line is not None and "front_m" in truth:
        out["front_error_mm"] = float(np.linalg.norm(fix.line.front_m - np.asarray(truth["front_m"])) * 1000)
        out["back_error_mm"] = float(np.linalg.norm(fix.line.back_m - np.asarray(truth["back_m"])) * 1000)
    return out


def _vec(values: Any) -> list[float] | None:
    return None if values is None else [float(v) for v in np.asarray(values).ravel()]


def fix_to_json(fix: PointerFix, locator: Locator, images: list[str]) -> dict[str, Any]:
    cameras = []
    detections: list[ImageDetections | None] = list(fix.detections) if fix.detections else [None] * len(images)
    for cam, path, detection in zip(locator.cameras, images, detections, strict=True):
        entry: dict[str, Any] = {"id": cam.camera_id, "image": str(path)}
        if detection is not None:
            for colour in ("red", "blue"):
                end = detection.end(colour)
                entry[colour] = {
                    "found": end.found,
                    "centroid_px": _vec(end.centroid_px) if end.found else None,
                    "area_px": float(end.area_px) if end.found else None,
                    "score": float(end.score) if end.found else None,
                    "reason": end.reason,
                }
        cameras.append(entry)
    line = fix.line
    hit = fix.hit
    return {
        "status": fix.status,
        "reason": fix.reason,
        "cameras": cameras,
        "pointer": None
        if line is None
        else {
            "front_colour": locator.front_colour,
            "front_m": _vec(line.front_m),
            "back_m": _vec(line.back_m),
            "length_m": line.length_m,
            "front_gap_m": line.front_gap_m,
            "back_gap_m": line.back_gap_m,
            "method": line.method,
        },
        "hit": None
        if hit is None
        else {
            "wall_xy_m": _vec(hit.wall_xy_m),
            "display_px": _vec(hit.display_px),
            "on_wall": hit.on_wall,
            "distance_m": hit.distance_m,
            "uncertainty_mm": None if fix.uncertainty_m is None else fix.uncertainty_m * 1000,
        },
        "timings_ms": {k.removesuffix("_ns"): v / 1e6 for k, v in fix.timings_ns.items()},
    }


def describe(fix: PointerFix, locator: Locator, images: list[str], truth: dict[str, Any] | None) -> str:
    lines = []
    for cam, path, detection in zip(locator.cameras, images, fix.detections or [None] * len(images), strict=True):
        parts = []
        if detection is not None:
            for colour in ("red", "blue"):
                end = detection.end(colour)
                if end.centroid_px is not None:
                    x, y = end.centroid_px
                    parts.append(f"{colour} at ({x:.2f}, {y:.2f}) px, {end.area_px:.0f} px area")
                else:
                    parts.append(f"{colour} not found ({end.reason})")
        lines.append(f"{cam.camera_id:>6} {path}: " + "; ".join(parts))
    line = fix.line
    if line is not None:
        fmt = lambda v: "(" + ", ".join(f"{c:.4f}" for c in v) + ")"  # noqa: E731
        back = locator.back_colour
        lines.append(
            f"pointer: {locator.front_colour} end {fmt(line.front_m)} m, {back} end {fmt(line.back_m)} m,"
            f" length {line.length_m * 1000:.1f} mm, ray gaps {line.front_gap_m * 1000:.2f} /"
            f" {line.back_gap_m * 1000:.2f} mm ({'interpretation planes' if line.method == 'planes' else 'two points'})"
        )
    hit = fix.hit
    if hit is not None:
        x, y = hit.wall_xy_m
        where = "on the display" if hit.on_wall else "OUTSIDE the display"
        text = f"wall hit: x {x:.4f} m, y {y:.4f} m ({x / 0.3048:.3f}, {y / 0.3048:.3f} ft)"
        if hit.display_px is not None:
            text += f", display ({hit.display_px[0]:.1f}, {hit.display_px[1]:.1f}) px"
        text += f", {where}, {hit.distance_m:.2f} m beyond the tip"
        if fix.uncertainty_m is not None:
            text += f", +-{fix.uncertainty_m * 1000:.1f} mm (1 sigma)"
        lines.append(text)
    if fix.status != "hit" and fix.reason:
        lines.append(f"no hit: {fix.reason}")
    if truth is not None:
        if "wall_error_mm" in truth:
            tx, ty = truth["wall_xy_m"]
            lines.append(f"truth: x {tx:.4f} m, y {ty:.4f} m; error {truth['wall_error_mm']:.2f} mm on the wall")
        elif truth.get("wall_xy_m") is None:
            lines.append("truth: the pointer does not point at the wall")
    return "\n".join(lines)
