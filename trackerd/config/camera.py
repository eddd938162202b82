"""One camera of the rig (a ``[[cameras]]`` entry): how to find it, what it delivers, its calibration."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator, model_validator

from trackerd.config.acquisition import CameraAcquisition
from trackerd.config.base import ConfigModel
from trackerd.config.lens import Extrinsics, Intrinsics, OpenCVIntrinsics

COLOUR_PIXEL_FORMATS = ("BayerRG8", "BayerGB8", "BayerGR8", "BayerBG8", "RGB8", "BGR8")
MAX_SIDE_PX = 65_535
"""The largest image side a rig may state: well beyond any machine-vision sensor (the largest are about
20,000 px wide), so that a typo (an extra zero or six) is refused where it is made rather than blamed later on
the lens model or met as an allocation of gigabytes."""
MONO_PIXEL_FORMATS = ("Mono8", "Mono10", "Mono12", "Mono16")
CALIBRATION_ONLY_FORMAT = "Mono8"
"""A monochrome format a camera may have in a rig used only to calibrate: tracking needs colour."""
CameraBackend = Literal["aravis", "pylon", "gentl"]
"""The acquisition backends a camera can be reached through (docs/acquisition.md)."""
FeatureValue = bool | int | float | str
PixelFormat = Literal["BayerRG8", "BayerGB8", "BayerGR8", "BayerBG8", "RGB8", "BGR8"]


class CameraConfig(ConfigModel):
    """One camera of the rig: how to find it, what it delivers, and (optionally) its calibration."""

    id: str = Field(pattern=r"^[A-Za-z0-9_-]{1,32}$")
    """Short name used in logs, messages and the calibration file, for example ``left``."""
    serial: str | None = None
    """Serial number, the usual way to find a GigE Vision camera."""
    address: str | None = None
    """IP address of the camera, an alternative to the serial number."""
    device_id: str | None = None
    """Device id as `trackerd cameras` lists it (Aravis's device id, or pylon's full name with
    ``backend = "pylon"``, the producer's device id with ``backend = "gentl"``), an alternative to
    serial and address."""
    width_px: int = Field(gt=0, le=MAX_SIDE_PX)
    """Image width delivered by the camera."""
    height_px: int = Field(gt=0, le=MAX_SIDE_PX)
    """Image height delivered by the camera."""
    pixel_format: str
    """GenICam pixel format: BayerRG8, BayerGB8, BayerGR8, BayerBG8, RGB8 or BGR8; Mono8 in a rig used
    only to calibrate (`trackerd calibrate` takes it, every tracking command refuses it)."""
    intrinsics: Intrinsics | None = None
    """Lens model; may instead come from the calibration file."""
    extrinsics: Extrinsics | None = None
    """Camera pose; may instead come from the calibration file."""
    acquisition: CameraAcquisition = CameraAcquisition()
    """How this camera is driven: exposure, gain, region, GigE transport (docs/acquisition.md)."""
    backend: CameraBackend = "aravis"
    """How the camera is reached: ``aravis`` (GigE Vision and USB3 Vision through Aravis) or
    ``pylon`` (Basler pylon through pypylon, the ``trackerd[gentl]`` extra: pylon's camera emulation,
    Basler GigE and USB cameras, and CoaXPress frame grabbers whose GenTL producer pylon loads) or
    ``gentl`` (any vendor's GenTL producer, named by ``producer``, through harvesters, the same extra:
    CameraLink and CoaXPress frame grabbers; docs/acquisition.md). A rig may mix them."""
    producer: str | None = None
    """Path of the GenTL producer (the frame grabber vendor's ``.cti`` file) that reaches the camera;
    ``gentl`` backend only, and required there. Absolute, or relative to the working directory; ``~``
    is expanded. Cameras naming the same file share one loaded producer."""
    features: dict[str, FeatureValue] = Field(default_factory=dict)
    """GenICam features written to the camera, in the order given, when it is opened (before the
    rig's own settings), for what the rig file has no key for: a frame grabber's link or tap
    configuration, or pylon's emulated camera's ``ImageFilename``. ``pylon`` and ``gentl`` backends only."""

    @field_validator("pixel_format")
    @classmethod
    def _colour_format(cls, value: str) -> str:
        # Mono8 is accepted here for a rig used to calibrate (a board is black and white);
        # load_rig, which every tracking command uses, refuses it with the reason.
        if value in MONO_PIXEL_FORMATS and value != CALIBRATION_ONLY_FORMAT:
            raise ValueError(
                f"{value} is monochrome and cannot tell the pointer's red end from its blue end;"
                f" use one of {', '.join(COLOUR_PIXEL_FORMATS)} ({CALIBRATION_ONLY_FORMAT} for calibration only)"
            )
        if value not in (*COLOUR_PIXEL_FORMATS, CALIBRATION_ONLY_FORMAT):
            raise ValueError(
                f"'{value}' is not supported; use one of {', '.join(COLOUR_PIXEL_FORMATS)}"
                f" ({CALIBRATION_ONLY_FORMAT} for calibration only)"
            )
        return value

    @model_validator(mode="after")
    def _backend_lookup(self) -> CameraConfig:
        if self.backend != "aravis" and self.address is not None:
            raise ValueError(
                f"address is for GigE Vision cameras reached through Aravis; a camera with backend ="
                f" '{self.backend}' is found by serial or device_id (as `trackerd cameras` lists it)"
            )
        if self.backend == "aravis" and self.features:
            raise ValueError("features are written by the pylon and gentl backends only (backend = 'pylon' or 'gentl')")
        if self.backend == "gentl" and not self.producer:
            raise ValueError(
                "backend = 'gentl' needs producer = the path of the GenTL producer (.cti file) that reaches the camera"
            )
        if self.backend != "gentl" and self.producer is not None:
            raise ValueError(f"producer is for backend = 'gentl' (this camera's backend is '{self.backend}')")
        return self

    @model_validator(mode="after")
    def _principal_point_inside(self) -> CameraConfig:
        intr = self.intrinsics
        if isinstance(intr, OpenCVIntrinsics) and not (
            0 <= intr.cx_px < self.width_px and 0 <= intr.cy_px < self.height_px
        ):
            raise ValueError(
                f"principal point ({intr.cx_px}, {intr.cy_px}) lies outside the {self.width_px}x{self.height_px} image"
            )
        return self
