"""Rendered pointer scenes served by pylon's emulated cameras (``python -m trackerd.sim.camemu``).

pylon's camera emulation (``PYLON_CAMEMU=<n>``, the pylon backend) serves the
images of a file or a directory when its ``ImageFileMode`` is ``On`` and its test
image is ``Off``: one file per frame, in the order of their names, over and over.
An 8-bit greyscale file is delivered as it is in any 8-bit format, so a Bayer
mosaic written as greyscale arrives as the BayerRG8 frame the renderer made.

This module writes a motion's rendered loop (:func:`trackerd.sim.loops.render_loop`,
cached) as one directory of BMP files per camera (pylon reads a 1080p BMP in
about 9 ms, a PNG in about 30) with the loop's ground truth, and the rig that
opens two emulated cameras on them. Under a software trigger the two cameras
take the same triggers, so frame *n* of either camera shows loop frame *n mod N*;
free running, each camera runs through the loop at its own pace.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

from trackerd.config.loader import dump_rig, load_rig
from trackerd.config.models import RigConfig
from trackerd.errors import TrackerdError
from trackerd.sim.motion import MOTIONS

EMULATED_SERIALS = ("0815-0000", "0815-0001")
"""Serial numbers of the first two cameras pylon's emulation offers (``PYLON_CAMEMU=2``)."""


EMULATED_EXPOSURE_US = 1000.0
"""Exposure given to an emulated camera whose rig sets none: the emulation spends the exposure time on
every frame, and its default (10 ms) plus reading an image file would hold it below 60 fps."""


def emulated_camera_features(image_path: Path | str) -> dict[str, str]:
    """The features that make an emulated camera serve ``image_path`` (a file, or a directory of files)."""
    return {"TestImageSelector": "Off", "ImageFileMode": "On", "ImageFilename": str(image_path)}


def emulated_rig(rig: RigConfig, image_dirs: list[Path] | None = None, **acquisition: object) -> RigConfig:
    """``rig`` with its cameras opened as pylon's emulated cameras, serving ``image_dirs`` (test images if None).

    ``acquisition`` overrides keys of the rig's ``[acquisition]`` table (``trigger``, ``frame_rate_hz``, ...).
    """
    if len(rig.cameras) > len(EMULATED_SERIALS):
        raise TrackerdError(f"pylon's emulation is set up here for {len(EMULATED_SERIALS)} cameras")
    cameras = tuple(
        cam.model_copy(
            update={
                "backend": "pylon",
                "serial": EMULATED_SERIALS[i],
                "address": None,
                "device_id": None,
                "features": emulated_camera_features(image_dirs[i]) if image_dirs else {},
                "acquisition": cam.acquisition.model_copy(
                    update={"exposure_us": cam.acquisition.exposure_us or EMULATED_EXPOSURE_US}
                ),
            }
        )
        for i, cam in enumerate(rig.cameras)
    )
    # Lock-step triggers, as the virtual GigE rig has: an emulated camera is busy reading its next image file
    # for milliseconds after a frame, so a second trigger outstanding waits for it, and the two cameras'
    # triggers go out as each becomes ready, apart by more than the pairing tolerance on a loaded machine.
    settings: dict[str, object] = {"max_outstanding_triggers": 1, **acquisition}
    return rig.model_copy(update={"cameras": cameras, "acquisition": rig.acquisition.model_copy(update=settings)})


def write_scene_files(
    rig: RigConfig, motion: str, out_dir: Path, *, period_s: float = 4.0, content_fps: float = 30.0
) -> tuple[list[Path], list[dict]]:
    """Render (or take from the cache) ``motion``'s loop and write it as BMP files, one directory per camera.

    Returns the directories, in rig order, and the truth of each loop frame (``wall_xy_m``, ...).
    """
    from trackerd.sim.loops import render_loop

    loop = render_loop(rig, motion, period_s=period_s, content_fps=content_fps)
    dirs = []
    for cam, frames_path in zip(rig.cameras, loop.frame_paths, strict=True):
        frames = np.load(frames_path, mmap_mode="r")
        cam_dir = out_dir / cam.id
        cam_dir.mkdir(parents=True, exist_ok=True)
        for old in cam_dir.glob("*.bmp"):
            old.unlink()
        for index in range(frames.shape[0]):
            if not cv2.imwrite(str(cam_dir / f"frame-{index:05d}.bmp"), np.ascontiguousarray(frames[index])):
                raise TrackerdError(f"cannot write {cam_dir / f'frame-{index:05d}.bmp'}")
        dirs.append(cam_dir.resolve())
    truth = loop.truth()
    (out_dir / "truth.json").write_text(json.dumps({"motion": motion, "frames": truth}))
    return dirs, truth


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m trackerd.sim.camemu",
        description="Write a rendered motion for pylon's emulated cameras, and the rig that serves it"
        " (run the daemon on it with PYLON_CAMEMU=2).",
    )
    parser.add_argument("--config", default="config/simulated.toml", help="the rig to render (two cameras)")
    parser.add_argument("--motion", default="figure8", choices=MOTIONS)
    parser.add_argument("--period", type=float, default=4.0, help="seconds of motion in the loop")
    parser.add_argument("--content-fps", type=float, default=30.0, help="loop frames per second of motion")
    parser.add_argument("--trigger", default="software", choices=("software", "free_running"))
    parser.add_argument("--frame-rate", type=float, default=None, help="the rig's frame_rate_hz (default: the rig's)")
    parser.add_argument("--out", default="camemu-out", help="directory for the images, truth.json and daemon-rig.toml")
    args = parser.parse_args(argv)
    try:
        rig = load_rig(args.config).config
        out = Path(args.out)
        dirs, _ = write_scene_files(rig, args.motion, out, period_s=args.period, content_fps=args.content_fps)
        overrides: dict[str, object] = {"trigger": args.trigger}
        if args.frame_rate is not None:
            overrides["frame_rate_hz"] = args.frame_rate
        rig_path = out / "daemon-rig.toml"
        rig_path.write_text(dump_rig(emulated_rig(rig, dirs, **overrides)))
    except (TrackerdError, OSError, ValueError) as err:
        print(f"trackerd.sim.camemu: {err}", file=sys.stderr)
        return 1
    print(f"wrote {rig_path}: PYLON_CAMEMU=2 trackerd run --config {rig_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
