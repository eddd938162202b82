"""Render one frame of `trackerd bench robustness` again, locate it, and save what each camera saw.

A miss or a slow frame in the bench's records (`--records F`: installation and frame numbers) is looked
into here: the installation is drawn and its frames rendered by the functions `trackerd.bench.robustness.run_rig`
uses (one random generator per installation, shared by all its frames, so every earlier frame is
rendered too), and for each frame asked: the locator's status and reason, the wall error and sigma, each
camera's truth (ball centre, visible centroid, visible fraction) beside the centroid the fix used, and
the locate time. Each camera's frame is saved as OUT/rRIG_fFRAME_camK.npy (as the camera delivers it)
and .png (demosaiced, for looking at).

With ``--followed``, the frames are those of the installation's followed sequence (`bench robustness
--follow N`, trackerd/bench/robustness_follow.py), rendered alone as the bench renders them, and located by
one locator that keeps its tracking state through the sequence, as the bench's "tracking" locator does
(every frame up to the last one asked for is located; the ones asked for are printed and saved).

    .venv/bin/python scripts/robustness_frame.py RIG FRAME [FRAME ...] [--seed 2026] [--out /tmp/frames]
    .venv/bin/python scripts/robustness_frame.py RIG FRAME [FRAME ...] --followed [--seed 2026]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import cv2
import numpy as np

from trackerd.bench.robustness import draw_installation, drawn_frames, renderer_for
from trackerd.bench.robustness_follow import followed_frames
from trackerd.config.rig_geometry import wall_frame
from trackerd.locator import Locator
from trackerd.pixelformat import to_bgr

COLOURS = ("red", "blue")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rig", type=int, help="installation number (the records' 'rig')")
    parser.add_argument("frames", type=int, nargs="+", help="frame numbers (the records' 'frame')")
    parser.add_argument("--seed", type=int, default=2026, help="the bench's --seed (default 2026)")
    parser.add_argument("--out", type=Path, default=Path("/tmp/frames"), help="where the images go")
    parser.add_argument(
        "--followed", action="store_true", help="the frames of the followed sequence, tracking kept through it"
    )
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    drawn, rng = draw_installation(args.seed, args.rig)
    assert drawn.rig.wall is not None
    wall = wall_frame(drawn.rig.wall)
    locator = Locator(drawn.rig, cameras=drawn.cameras)
    print("installation", args.rig, drawn.factors, drawn.rig.pointer)
    last = max(args.frames)
    if args.followed:
        # The bench's generators for the sequence (trackerd/bench/robustness.py, run_rig).
        factors, sequence = followed_frames(
            drawn,
            renderer_for(drawn),
            wall,
            np.random.default_rng([args.seed, args.rig, 3]),
            last + 1,
            np.random.default_rng([args.seed, args.rig, 4]),
        )
        frames = ((f.number, factors, f.views, f.truth_xy_m) for f in sequence)
    else:
        frames = (
            (f.number, f.factors, f.views, f.truth_xy_m)
            for f in drawn_frames(drawn, renderer_for(drawn), wall, rng, last + 1)
        )
    for frame, frame_factors, views, truth in frames:
        if not args.followed:
            locator.reset()
        began = time.perf_counter()
        fix = locator.locate([v.image for v in views])
        took_s = time.perf_counter() - began
        if frame not in args.frames:
            continue
        print(f"\nframe {frame} {frame_factors}: {fix.status} in {took_s:.2f} s; {fix.reason or ''}")
        if fix.hit is not None and truth is not None and fix.uncertainty_m is not None:
            error_mm = 1000 * float(np.linalg.norm(fix.hit.wall_xy_m - truth))
            print(f"  wall error {error_mm:.2f} mm, sigma {1000 * fix.uncertainty_m:.2f} mm")
        for k, view in enumerate(views):
            for colour in COLOURS:
                used = fix.centroids_px[k].get(colour)
                print(
                    f"  camera {k} {colour}: centre {np.round(view.truth.centre_px[colour], 1)},"
                    f" visible centroid {np.round(view.truth.centroid_px[colour], 1)},"
                    f" visible {view.truth.visible_fraction(colour):.2f}; used"
                    f" {None if used is None else np.round(used, 1)}"
                )
            base = args.out / f"r{args.rig}_f{frame}_cam{k}"
            np.save(base.with_suffix(".npy"), view.image)
            cv2.imwrite(str(base.with_suffix(".png")), to_bgr(view.image, view.pixel_format))


if __name__ == "__main__":
    main()
