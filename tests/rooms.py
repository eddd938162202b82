"""Rendered rooms the detector's defaults were not tuned on, shared by the colour tests (calibration, watch)."""

from __future__ import annotations

import numpy as np

from trackerd.sim.appearance import Look
from trackerd.sim.randomized import aimed_camera, build_rig
from trackerd.sim.render import SceneRenderer
from trackerd.sim.scene import pose_aimed_at

POINTER = {"length_m": 0.42, "end_diameter_m": 0.036, "rod_diameter_m": 0.012}
PRESENTER = np.array([1.8, 0.5, 1.8])
DIM = Look(red_rgb=(0.5, 0.06, 0.05), blue_rgb=(0.06, 0.10, 0.46), gain=0.45)
BLANK = np.full((256, 768, 3), 0.55, dtype=np.float32)
"""The display showing grey (by default it shows a slide with an orange and a blue block)."""
RED_PICTURE = BLANK.copy()
RED_PICTURE[40:220, 420:700] = (0.92, 0.10, 0.12)


def room(look: Look | None = None, **simulation):
    """Two 720p cameras either side of the presenter, a room with nothing colourful in it."""
    cameras = [
        aimed_camera("left", [-0.8, 1.3, 3.2], PRESENTER, 1280, 720, 60.0),
        aimed_camera("right", [4.4, 1.3, 3.2], PRESENTER, 1280, 720, 60.0),
    ]
    rig = build_rig(
        "room", [(cam, "BayerRG8") for cam in cameras], 3.6, 1.2, 0.9, POINTER, {"seed": 3, "clutter": 0, **simulation}
    )
    return rig, SceneRenderer(rig, cameras, look=Look() if look is None else look, cache_dir=False)


def waved(count: int, offset: float = 0.0):
    """The pointer aimed across the wall from where the presenter stands."""
    for k in range(count):
        x = 0.9 + 1.8 * (k + offset) / count
        yield pose_aimed_at([x + 0.2, 0.45 + 0.04 * (k % 3), 1.7], [x, 0.5, 0.0], POINTER["length_m"])
