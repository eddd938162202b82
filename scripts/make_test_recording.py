#!/usr/bin/env python3
"""Render the recording bundled in tests/data/recording (run from the repository root).

Sixteen 1920x1080 BayerRG8 pairs of config/simulated.toml, rendered by the
scene simulator and written by trackerd's own recording writer: the pointer
traces part of the figure eight for ten pairs, leaves the room for two (so the
locator loses it and starts afresh), and comes back for four. Pairs are 1/15 s
apart, as a camera pair at 15 fps would deliver them. The frames are rendered
without sensor noise and stored deflated (lossless), which keeps the recording
under 3 MB; noisy frames would take over 1 MB each. truth.json beside it holds
each pair's true pointer ends and wall hit.

    .venv/bin/python scripts/make_test_recording.py

Deterministic: the same renderer gives the same frames (recording.json's dates
and trackerd version change, the pixels do not).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np

from trackerd.acquisition.frame import Frame, FramePair
from trackerd.config.loader import load_rig
from trackerd.recording.writer import RecordingWriter, build_metadata
from trackerd.sim.motion import make_motion
from trackerd.sim.render import SceneRenderer
from trackerd.sim.scene import true_wall_hit

OUT = Path("tests/data/recording")
NAME = "figure8-leave.trec"
PERIOD_NS = 66_666_667
"""1/15 s between pairs."""
START_NS = 5_000_000_000_000
"""Recorded monotonic time of the first pair (any value: a camera host's uptime)."""
CLOCK_OFFSET_NS = 1_795_000_000_000_000_000
"""UNIX epoch minus monotonic at the (pretend) recording: November 2026."""
DEVICE_OFFSETS_NS = (7_300_000_000, 14_600_123_456)
"""Each camera's device clock minus host monotonic, as the simulated GigE cameras have."""
SKEW_NS = 41_000
"""The right camera exposes this much after the left."""


def schedule() -> list[float | None]:
    """Motion time of each pair (None: the pointer is out of the room)."""
    times: list[float | None] = [0.4 + k / 15.0 for k in range(10)]
    times += [None, None]
    times += [0.4 + k / 15.0 for k in range(14, 18)]
    return times


def main() -> None:
    rig = load_rig("config/simulated.toml").config
    renderer = SceneRenderer(rig)
    motion = make_motion("figure8", rig)
    folder = OUT / NAME
    if folder.exists():
        shutil.rmtree(folder)
    OUT.mkdir(parents=True, exist_ok=True)
    writer = None
    truth = []
    for k, motion_time in enumerate(schedule()):
        pose = None if motion_time is None else motion(motion_time)
        capture = START_NS + k * PERIOD_NS
        frames = []
        for index, cam in enumerate(rig.cameras):
            view = renderer.render(index, pose, np.random.default_rng([k, index]), noise=False)
            exposure = capture + index * SKEW_NS - SKEW_NS // 2
            frames.append(Frame(cam.id, k + 1, exposure + DEVICE_OFFSETS_NS[index], exposure + 3_100_000,
                                view.pixel_format, view.image))
        pair = FramePair(tuple(frames), capture, SKEW_NS, k + 1)
        if writer is None:
            metadata = build_metadata(
                rig, pair, producer="scripts/make_test_recording.py (frames rendered by trackerd.sim)",
                clock_offset_ns=CLOCK_OFFSET_NS, rig_file="config/simulated.toml",
                notes="figure-eight motion, pointer out of the room for pairs 10-11; no sensor noise",
            )
            writer = RecordingWriter(folder, metadata, compression="deflate", compression_level=9)
        writer.write(pair)
        entry: dict[str, object] = {"pair_index": k, "sequence": k + 1, "motion_time_s": motion_time,
                                    "present": pose is not None}
        if pose is not None:
            hit = true_wall_hit(pose, renderer.wall)
            entry.update(front_m=pose.front_m.tolist(), back_m=pose.back_m.tolist(),
                         wall_xy_m=None if hit.wall_xy_m is None else hit.wall_xy_m.tolist(), on_wall=hit.on_wall)
        truth.append(entry)
    assert writer is not None
    writer.close("rendered")
    (OUT / "truth.json").write_text(json.dumps({"recording": NAME, "motion": "figure8", "pairs": truth}, indent=1)
                                    + "\n")
    size = sum(p.stat().st_size for p in folder.iterdir())
    print(f"wrote {folder}: {writer.pairs} pairs, {size / 1e6:.2f} MB, and {OUT / 'truth.json'}")


if __name__ == "__main__":
    main()
