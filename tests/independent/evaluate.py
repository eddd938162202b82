"""trackerd, and the naive method beside it, on rooms rendered by make_scenes.py: what `trackerd bench
robustness` measures, on scenes trackerd's own simulator did not draw.

    .venv/bin/python -m tests.independent.make_scenes --out /tmp/rooms/7 --seed 7 --poses 8
    .venv/bin/python -m tests.independent.evaluate /tmp/rooms/* [--json OUT]

Each pose is located as a first sighting (the locator reset before it). A pose is *eligible* when each
ball is at least 60 % visible in at least two cameras (the truth's ``visible_fraction``), as in `bench
robustness`. Printed: found (a hit or off-wall answer on an eligible pose), the wall error's median, 95th
percentile and worst, how often a hit's error exceeds 3 and 5 times its stated sigma, the naive method's
figures, and every *wrong answer*: any pose, eligible or not, where trackerd reported a pointer (a hit, off
the display, away, parallel) with an end more than WRONG_END_MM from the truth. Where an end cannot be seen
the right answer is "not found"; a wrong answer that looks confident is worse.

An eligible pose is also *told by colour* when each ball, in at least two cameras where it is at least 60 %
visible, shows its colour over the inner half of its disc: its own channel's median at least COLOUR_MARGIN
grey levels above each other channel's, and some channel's median as far from the ring of 1.5-2.5 radii around
it (the truth's centre and visible area; the image's own pixels: a dark red ball on a dark red wall is
not told by colour). Many
of these rooms' pointers are not (a navy ball under warm light reads like (4, 4, 10)): no colour tracker
can find those, and the figures for the poses that are told by colour say what trackerd does where it can.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from trackerd.bench.robustness import MIN_VISIBLE, naive_hit
from trackerd.config import load_rig
from trackerd.images import read_frame
from trackerd.locator import Locator

WRONG_END_MM = 100.0
"""A reported pointer with an end this far from the truth is a wrong answer."""

LINE_STATUSES = ("hit", "off_wall", "away", "parallel")

COLOUR_MARGIN = 20.0
"""A ball is told by its colour where its own channel leads the others by this many grey levels (see above)."""


def channel_medians(
    frame: NDArray[np.uint8], pixel_format: str, centre_px: list[float], radii_px: tuple[float, float]
) -> NDArray[np.float64]:
    """Median (red, green, blue) over the ring between two radii about a centre (a disc from radius 0), each
    channel from the pixels that carry it (a Bayer RG mosaic's own sites, or every pixel of an RGB or BGR
    frame); NaN where the ring holds none. Medians: a thin line of another colour (the rod, an edge of a
    picture) does not move them."""
    # Only the window that holds the ring, in the frame's own coordinates (a Bayer site's parity is kept).
    height, width = frame.shape[:2]
    outer = radii_px[1]
    top, bottom = max(0, int(centre_px[1] - outer)), min(height, int(centre_px[1] + outer) + 2)
    left, right = max(0, int(centre_px[0] - outer)), min(width, int(centre_px[0] + outer) + 2)
    ys, xs = np.mgrid[top:bottom, left:right]
    window = frame[top:bottom, left:right]
    squared = (xs - centre_px[0]) ** 2 + (ys - centre_px[1]) ** 2
    inside = (squared >= radii_px[0] ** 2) & (squared <= radii_px[1] ** 2)
    if frame.ndim == 3:
        order = (0, 1, 2) if pixel_format.startswith("RGB") else (2, 1, 0)
        return np.array([np.median(window[..., c][inside]) if inside.any() else np.nan for c in order])
    if not pixel_format.startswith("BayerRG"):
        return np.full(3, np.nan)
    sites = ((ys % 2 == 0) & (xs % 2 == 0), (ys + xs) % 2 == 1, (ys % 2 == 1) & (xs % 2 == 1))
    return np.array([np.median(window[inside & at]) if (inside & at).any() else np.nan for at in sites])


def told_by_colour(truth: dict[str, Any], cameras: list[Any], frames: list[Any], formats: list[str]) -> bool:
    """Each ball shows its colour (COLOUR_MARGIN), and differs by as much in some channel from the ring of
    1.5-2.5 radii around it, in at least two cameras where it is >= MIN_VISIBLE visible."""
    for colour, channel in (("red", 0), ("blue", 2)):
        showing = 0
        for camera, frame, pixel_format in zip(cameras, frames, formats, strict=True):
            ball = truth["views"][camera.id][colour]
            if ball["centre_px"] is None or ball["visible_fraction"] < MIN_VISIBLE:
                continue
            radius_px = max(2.0, float(np.sqrt(ball["visible_area_px"] / np.pi)))
            inner = channel_medians(frame, pixel_format, ball["centre_px"], (0.0, 0.5 * radius_px))
            around = channel_medians(frame, pixel_format, ball["centre_px"], (1.5 * radius_px, 2.5 * radius_px))
            of_its_colour = np.all(inner[channel] - np.delete(inner, channel) >= COLOUR_MARGIN)
            showing += bool(of_its_colour and np.max(np.abs(inner - around)) >= COLOUR_MARGIN)
        if showing < 2:
            return False
    return True


def evaluate_room(folder: Path) -> list[dict[str, Any]]:
    """One record per pose of a room folder (rig.toml, NN-truth.json and the images they name)."""
    rig = load_rig(folder / "rig.toml").config
    locator: Locator | None = None
    records = []
    for truth_path in sorted(folder.glob("*-truth.json")):
        truth = json.loads(truth_path.read_text())
        frames, formats = [], []
        for camera in rig.cameras:
            frame, pixel_format = read_frame(folder / truth["views"][camera.id]["image"], camera)
            frames.append(frame)
            formats.append(pixel_format)
        if locator is None:
            locator = Locator(rig, pixel_formats=formats)
        locator.reset()
        fix = locator.locate(frames)
        views = [truth["views"][camera.id] for camera in rig.cameras]
        visible = [[view[colour]["visible_fraction"] for colour in ("red", "blue")] for view in views]
        true_xy = np.asarray(truth["wall_xy_m"])
        record: dict[str, Any] = {
            "room": folder.name,
            "pose": truth_path.name.removesuffix("-truth.json"),
            "eligible": sum(1 for pair in visible if min(pair) >= MIN_VISIBLE) >= 2,
            "told_by_colour": told_by_colour(truth, rig.cameras, frames, formats),
            "status": fix.status,
            "reason": fix.reason,
            "error_mm": None if fix.hit is None else float(np.linalg.norm(fix.hit.wall_xy_m - true_xy) * 1000),
            "sigma_mm": None if fix.uncertainty_m is None else fix.uncertainty_m * 1000,
            "end_errors_mm": None,
            "naive_mm": None,
        }
        if fix.line is not None and fix.status in LINE_STATUSES:
            record["end_errors_mm"] = [
                float(np.linalg.norm(fix.line.front_m - np.asarray(truth["front_m"])) * 1000),
                float(np.linalg.norm(fix.line.back_m - np.asarray(truth["back_m"])) * 1000),
            ]
        naive = naive_hit(locator.cameras, locator.wall, frames, formats, locator.front_colour)
        if naive is not None:
            record["naive_mm"] = float(np.linalg.norm(naive - true_xy) * 1000)
        records.append(record)
    return records


def is_wrong(record: dict[str, Any]) -> bool:
    """A pointer reported with an end more than WRONG_END_MM from the truth."""
    ends = record["end_errors_mm"]
    return ends is not None and max(ends) > WRONG_END_MM


def figures(records: list[dict[str, Any]]) -> dict[str, Any]:
    """The printed figures (see the module's docstring)."""
    eligible = [r for r in records if r["eligible"]]
    found = [r for r in eligible if r["error_mm"] is not None]
    errors = np.array([r["error_mm"] for r in found])
    stated = [r for r in found if r["sigma_mm"]]
    ratios = np.array([r["error_mm"] / r["sigma_mm"] for r in stated])
    naive = np.array([r["naive_mm"] for r in eligible if r["naive_mm"] is not None])

    def spread(values: np.ndarray) -> dict[str, float | None]:
        if not len(values):
            return {"median_mm": None, "p95_mm": None, "worst_mm": None}
        return {
            "median_mm": float(np.median(values)),
            "p95_mm": float(np.percentile(values, 95)),
            "worst_mm": float(values.max()),
        }

    return {
        "poses": len(records),
        "eligible": len(eligible),
        "trackerd": {
            "found": len(found),
            **spread(errors),
            "over_3_sigma": int(np.sum(ratios > 3)),
            "over_5_sigma": int(np.sum(ratios > 5)),
        },
        "naive": {"found": len(naive), **spread(naive)},
        "told_by_colour": {
            "eligible": sum(1 for r in eligible if r["told_by_colour"]),
            "found": sum(1 for r in found if r["told_by_colour"]),
            **spread(np.array([r["error_mm"] for r in found if r["told_by_colour"]])),
        },
        "wrong": [
            (r["room"], r["pose"], r["status"], [round(e) for e in r["end_errors_mm"]]) for r in records if is_wrong(r)
        ],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("rooms", nargs="+", type=Path, help="folders written by make_scenes.py")
    parser.add_argument("--json", type=Path, help="write every pose's record here")
    args = parser.parse_args(argv)
    records = [record for room in args.rooms for record in evaluate_room(room)]
    summary = figures(records)
    t, n = summary["trackerd"], summary["naive"]

    def cell(value: float | None) -> str:
        return "-" if value is None else f"{value:.1f}"

    print(f"{summary['poses']} poses, {summary['eligible']} eligible (each ball >= 60 % visible in two cameras)")
    print(
        f"trackerd: found {t['found']}, median {cell(t['median_mm'])} mm, p95 {cell(t['p95_mm'])},"
        f" worst {cell(t['worst_mm'])}; beyond 3 / 5 sigma: {t['over_3_sigma']} / {t['over_5_sigma']}"
    )
    print(
        f"naive:    found {n['found']}, median {cell(n['median_mm'])} mm, p95 {cell(n['p95_mm'])},"
        f" worst {cell(n['worst_mm'])}"
    )
    c = summary["told_by_colour"]
    print(
        f"told by colour (its colour and its difference from what is around it {COLOUR_MARGIN:.0f} grey levels,"
        f" each ball in two cameras): {c['eligible']}"
        f" eligible poses; trackerd found {c['found']}, median {cell(c['median_mm'])} mm, p95 {cell(c['p95_mm'])},"
        f" worst {cell(c['worst_mm'])}"
    )
    print(f"wrong answers (an end > {WRONG_END_MM:.0f} mm off): {len(summary['wrong'])}")
    for room, pose, status, ends in summary["wrong"]:
        print(f"  {room} pose {pose}: {status}, ends {ends[0]} / {ends[1]} mm off")
    if args.json is not None:
        args.json.write_text(json.dumps(records, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
