"""Rendered sequences for pipeline tests."""

from __future__ import annotations

import numpy as np
import pytest

from trackerd.sim.motion import make_motion
from trackerd.sim.scene import true_wall_hit


@pytest.fixture(scope="session")
def rendered_sweep(simulated_rig, renderer):
    """Twelve consecutive views of the 'sweep' motion in both cameras, with the true wall hits."""
    motion = make_motion("sweep", simulated_rig)
    rng = np.random.default_rng(99)
    image_sets, truths = [], []
    for k in range(12):
        pose = motion(k * 0.25)
        image_sets.append([renderer.render(i, pose, rng).image for i in range(len(renderer.cameras))])
        truths.append(true_wall_hit(pose, renderer.wall) if pose is not None else None)
    return image_sets, truths
