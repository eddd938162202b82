#!/usr/bin/env python3
"""Render the image pairs bundled in tests/data/pairs (run from the repository root).

Each pair is one raw Bayer frame per camera of config/simulated.toml, saved as
a lossless single-channel PNG, plus NN-truth.json with the exact pose, wall hit
and per-view truth. Deterministic: the same renderer gives the same files.

    .venv/bin/python scripts/make_test_data.py
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from trackerd.config.loader import load_rig
from trackerd.sim.render import SceneRenderer
from trackerd.sim.scene import PointerPose, pose_aimed_at, random_pose, true_wall_hit

OUT = Path("tests/data/pairs")


def main() -> None:
    rig = load_rig("config/simulated.toml").config
    renderer = SceneRenderer(rig)
    wall = renderer.wall
    rng = np.random.default_rng(20071)
    poses: dict[str, tuple[PointerPose, str]] = {}
    # 01, 02: ordinary poses aimed at the display.
    poses["01"] = (random_pose(rig, rng, on_wall_fraction=1.0), "aimed at the display")
    poses["02"] = (random_pose(rig, rng, on_wall_fraction=1.0), "aimed at the display")
    # 03: aimed above the top edge of the display, at the wall itself.
    tip = wall.origin_m + 1.4 * wall.x_axis + 2.0 * wall.normal + (0.55 - wall.origin_m[1]) * np.array([0, 1.0, 0])
    poses["03"] = (pose_aimed_at(tip, wall.from_wall_m(np.array([2.4, 1.25])), rig.pointer.length_m),
                   "aimed at the wall above the display")
    OUT.mkdir(parents=True, exist_ok=True)
    for name, (pose, note) in poses.items():
        hit = true_wall_hit(pose, wall)
        truth = {
            "note": note,
            "config": "config/simulated.toml",
            "front_m": pose.front_m.tolist(),
            "back_m": pose.back_m.tolist(),
            "wall_xy_m": None if hit.wall_xy_m is None else hit.wall_xy_m.tolist(),
            "on_wall": hit.on_wall,
            "views": {},
        }
        for index, cam in enumerate(rig.cameras):
            view = renderer.render(index, pose, rng)
            path = OUT / f"{name}-{cam.id}.png"
            cv2.imwrite(str(path), view.image, [cv2.IMWRITE_PNG_COMPRESSION, 9])
            truth["views"][cam.id] = {
                "image": path.name,
                "pixel_format": view.pixel_format,
                **{
                    colour: {
                        "centre_px": view.truth.centre_px[colour].tolist(),
                        "centroid_px": view.truth.centroid_px[colour].tolist(),
                        "area_px": view.truth.area_px[colour],
                    }
                    for colour in ("red", "blue")
                },
            }
        (OUT / f"{name}-truth.json").write_text(json.dumps(truth, indent=2) + "\n")
        print(f"{name}: {note}; wall hit {truth['wall_xy_m']}")


if __name__ == "__main__":
    main()
