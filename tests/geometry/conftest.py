"""Shared fixtures for the geometry tests: the example rigs' cameras and wall, and lens sets."""

from __future__ import annotations

from pathlib import Path

import pytest

from trackerd.config.loader import load_rig
from trackerd.config.rig_geometry import camera_model, wall_frame
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.wall import WallFrame

REPO_ROOT = Path(__file__).resolve().parents[2]
CONFIG_DIR = REPO_ROOT / "config"


@pytest.fixture(scope="session")
def example_rig_cameras() -> dict[str, list[CameraModel]]:
    """Rig name ('simulated', 'datawall') -> the CameraModels of config/<name>.toml."""
    return {
        name: [camera_model(cam) for cam in load_rig(CONFIG_DIR / f"{name}.toml").config.cameras]
        for name in ("simulated", "datawall")
    }


@pytest.fixture(scope="session")
def simulated_cameras(example_rig_cameras: dict[str, list[CameraModel]]) -> list[CameraModel]:
    """Both cameras of config/simulated.toml (OpenCV lenses with distortion)."""
    return example_rig_cameras["simulated"]


@pytest.fixture(scope="session")
def datawall_wall() -> WallFrame:
    """The DataWall of config/datawall.toml: 3.6576 x 0.9144 m in z = 0, 7680x1920 display px."""
    return wall_frame(load_rig(CONFIG_DIR / "datawall.toml").config.wall)
