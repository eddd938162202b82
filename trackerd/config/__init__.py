"""Rig configuration: pydantic models (models.py, one module per section) and TOML loading (loader.py)."""

from trackerd.config.loader import LoadedRig, load_calibration, load_rig
from trackerd.config.models import (
    CameraConfig,
    DetectorConfig,
    PointerConfig,
    RigConfig,
    WallConfig,
)

__all__ = [
    "CameraConfig",
    "DetectorConfig",
    "LoadedRig",
    "PointerConfig",
    "RigConfig",
    "WallConfig",
    "load_calibration",
    "load_rig",
]
