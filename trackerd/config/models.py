"""The rig configuration: pydantic models for everything one TOML file describes.

A *rig* is the cameras, the wall, the pointer, the detector's thresholds and the
outputs of one installation. Calibration (each camera's intrinsics and
extrinsics, and optionally the wall) may live in a separate file that the rig
file names; see :mod:`trackerd.config.loader` for how the two are merged.

Every model forbids unknown keys, so a misspelt key is an error that names the
keys that are allowed rather than a setting silently ignored. Units are in the
field names: ``_m`` metres, ``_mm`` millimetres, ``_px`` pixels, ``_deg``
degrees, ``_us`` microseconds, ``_ms`` milliseconds, ``_hz`` hertz.

World frame used throughout (docs/geometry.md): right-handed, metres. The
example rigs put the origin at the wall's bottom-left corner with x along the
wall to the right, y up and z out of the wall into the room; any other frame
works as long as cameras and wall are given in the same one.

This module holds the top levels (a rig file, a calibration file); each section's models live in
a module of their own (``lens``, ``camera``, ``wall``, ``pointer``, ``outputs``, ``simulation``,
``acquisition``, ``recording``, ``interaction``, ``console``) and are re-exported from here.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, field_validator

from trackerd.config.acquisition import CameraAcquisition, RigAcquisition
from trackerd.config.base import ConfigModel, Vec3
from trackerd.config.camera import (
    CALIBRATION_ONLY_FORMAT,
    COLOUR_PIXEL_FORMATS,
    MONO_PIXEL_FORMATS,
    CameraBackend,
    CameraConfig,
    FeatureValue,
    PixelFormat,
)
from trackerd.config.console import ConsoleConfig
from trackerd.config.interaction import InteractionConfig
from trackerd.config.lens import (
    OPENCV_DISTORTION_LENGTHS,
    Extrinsics,
    FovIntrinsics,
    Intrinsics,
    OpenCVExtrinsics,
    OpenCVIntrinsics,
    PoseExtrinsics,
    horizontal_focal_px,
)
from trackerd.config.outputs import OutputsConfig, ZmqOutput
from trackerd.config.pointer import (
    MIN_LEARNED_EXCESS,
    ColourThreshold,
    DetectorConfig,
    LearnedColour,
    LocatorConfig,
    PointerColours,
    PointerConfig,
)
from trackerd.config.recording import RecordingConfig
from trackerd.config.simulation import SimulationConfig
from trackerd.config.wall import WallConfig

__all__ = [
    "CALIBRATION_ONLY_FORMAT",
    "COLOUR_PIXEL_FORMATS",
    "MIN_LEARNED_EXCESS",
    "MONO_PIXEL_FORMATS",
    "OPENCV_DISTORTION_LENGTHS",
    "CalibrationFile",
    "CameraAcquisition",
    "CameraBackend",
    "CameraCalibration",
    "CameraConfig",
    "ColourThreshold",
    "ConsoleConfig",
    "DetectorConfig",
    "Extrinsics",
    "FeatureValue",
    "FovIntrinsics",
    "InteractionConfig",
    "Intrinsics",
    "LearnedColour",
    "LocatorConfig",
    "OpenCVExtrinsics",
    "OpenCVIntrinsics",
    "OutputsConfig",
    "PixelFormat",
    "PointerColours",
    "PointerConfig",
    "PoseExtrinsics",
    "RecordingConfig",
    "RigAcquisition",
    "RigConfig",
    "SimulationConfig",
    "Vec3",
    "WallConfig",
    "ZmqOutput",
    "horizontal_focal_px",
]


class RigConfig(ConfigModel):
    """A whole installation: the top level of a rig TOML file."""

    version: Literal[1] = 1
    """Format version of the rig file."""
    name: str = "rig"
    """A label shown in logs and status messages."""
    calibration: Path | None = None
    """A calibration TOML file (relative to this file) that supplies intrinsics, extrinsics and
    optionally the wall; its values replace the ones given here."""
    cameras: tuple[CameraConfig, ...] = Field(min_length=2)
    """Two or more cameras; the first two are the stereo pair."""
    wall: WallConfig | None = None
    """The display wall (or from the calibration file). Tracking needs it; `trackerd calibrate
    intrinsics` and `stereo` do not, `calibrate wall` needs its nominal size."""
    pointer: PointerConfig | None = None
    """The pointer. Tracking, `calibrate wall` and `calibrate check` need it; intrinsics and stereo do
    not."""
    acquisition: RigAcquisition = RigAcquisition()
    """Trigger mode, frame pairing and camera-loss handling shared by all cameras."""
    detector: DetectorConfig = DetectorConfig()
    """Colour-end detector settings."""
    pointer_colours: PointerColours | None = None
    """The pointer's colours in this room, from the calibration file (where `trackerd calibrate pointer`
    writes them): the detector's thresholds for each end unless ``[detector.red]`` / ``[detector.blue]``
    is given here, and the figures the daemon's colour watch compares what it sees with."""
    locator: LocatorConfig = LocatorConfig()
    """Line estimation and quality gates."""
    outputs: OutputsConfig = OutputsConfig()
    """Output settings."""
    recording: RecordingConfig = RecordingConfig()
    """Recording from the running daemon (docs/recording.md)."""
    interaction: InteractionConfig = InteractionConfig()
    """Smoothing, pointing events, gestures and TUIO output (docs/protocol.md)."""
    console: ConsoleConfig = ConsoleConfig()
    """The operator's console: live camera views, wall map, status, metrics (docs/console.md)."""
    simulation: SimulationConfig = SimulationConfig()
    """Scene simulator settings (only used when rendering)."""

    @field_validator("cameras")
    @classmethod
    def _unique_ids(cls, cameras: tuple[CameraConfig, ...]) -> tuple[CameraConfig, ...]:
        ids = [c.id for c in cameras]
        duplicates = sorted({i for i in ids if ids.count(i) > 1})
        if duplicates:
            raise ValueError(f"camera ids must be unique; repeated: {', '.join(duplicates)}")
        return cameras

    def camera(self, camera_id: str) -> CameraConfig:
        """The camera with this id (KeyError naming the known ids otherwise)."""
        for cam in self.cameras:
            if cam.id == camera_id:
                return cam
        raise KeyError(f"no camera '{camera_id}'; the rig has {', '.join(c.id for c in self.cameras)}")


# --------------------------------------------------------------------------- calibration file


class CameraCalibration(ConfigModel):
    """One camera's entry in a calibration file."""

    intrinsics: Intrinsics | None = None
    """Lens model, replacing the rig file's."""
    extrinsics: Extrinsics | None = None
    """Camera pose, replacing the rig file's."""
    info: dict[str, str | int | float] = Field(default_factory=dict)
    """Provenance written by `trackerd calibrate`: date, board, number of views, RMS error."""


class CalibrationFile(ConfigModel):
    """The top level of a calibration TOML file: ``[cameras.<id>]`` tables and an optional wall."""

    version: Literal[1] = 1
    """Format version of the calibration file."""
    cameras: dict[str, CameraCalibration] = Field(default_factory=dict)
    """Per camera id."""
    wall: WallConfig | None = None
    """The wall, replacing the rig file's."""
    pointer_colours: PointerColours | None = None
    """The pointer's colours in this room (`trackerd calibrate pointer`)."""
