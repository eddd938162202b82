"""The GenTL test producer that EMVA's genicam wheel (harvesters' dependency) ships, and a rig on it."""

from __future__ import annotations

from pathlib import Path

import pytest

from trackerd.acquisition.gentl import harvesters_missing_reason
from trackerd.config.models import RigConfig

VIKY_DEVICES = ("VikyTL_DEV_red", "VikyTL_DEV_green")
WIDTH, HEIGHT = 320, 240


def viky_cti() -> Path | None:
    """genicam's ``viky.cti`` as installed, found in the installed package; None without it."""
    try:
        import genicam
    except ImportError:
        return None
    path = Path(genicam.__file__).parent / "viky.cti"
    return path if path.is_file() else None


def viky_missing_reason() -> str | None:
    reason = harvesters_missing_reason()
    if reason is not None:
        return reason
    if viky_cti() is None:
        return "genicam is installed without its test producer viky.cti"
    return None


VIKY_MISSING = viky_missing_reason()
needs_viky = pytest.mark.skipif(
    VIKY_MISSING is not None,
    reason=f"needs harvesters and genicam's test producer viky.cti (pip install 'trackerd[gentl]'): {VIKY_MISSING}",
)


def viky_rig(rig: RigConfig, **acquisition: object) -> RigConfig:
    """``rig`` with its two cameras on two of viky.cti's virtual devices, 320x240 RGB8 (viky's RGBa8),
    uncalibrated (nothing tracks on viky's test pattern), plus any acquisition overrides."""
    data = rig.model_dump()
    data["acquisition"].update({"trigger": "free_running", "frame_rate_hz": 30.0, **acquisition})
    for cam, device in zip(data["cameras"], VIKY_DEVICES, strict=True):
        cam.update(
            backend="gentl",
            producer=str(viky_cti()),
            device_id=device,
            serial=None,
            address=None,
            width_px=WIDTH,
            height_px=HEIGHT,
            pixel_format="RGB8",
            intrinsics=None,
            extrinsics=None,
            features={},
        )
        cam["acquisition"].update(exposure_us=None, gain_db=None)
    return RigConfig.model_validate(data)


def viky_daemon_rig(rig: RigConfig, endpoint: str) -> RigConfig:
    """The simulated rig on two viky devices at a third of its resolution (640x360, the lenses scaled to
    match, so the daemon's pipeline runs), free running at 30 fps, publishing on ``endpoint``."""
    small = viky_rig(rig)
    cameras = []
    for cam, full in zip(small.cameras, rig.cameras, strict=True):
        k = full.intrinsics
        intrinsics = k.model_copy(
            update={"fx_px": k.fx_px / 3, "fy_px": k.fy_px / 3, "cx_px": k.cx_px / 3, "cy_px": k.cy_px / 3}
        )
        cameras.append(
            cam.model_copy(
                update={
                    "width_px": full.width_px // 3,
                    "height_px": full.height_px // 3,
                    "intrinsics": intrinsics,
                    "extrinsics": full.extrinsics,
                }
            )
        )
    zmq_cfg = rig.outputs.zmq.model_copy(update={"endpoints": (endpoint,), "status_interval_ms": 250.0})
    data = small.model_dump()
    data["cameras"] = [c.model_dump() for c in cameras]
    data["outputs"] = rig.outputs.model_copy(update={"zmq": zmq_cfg}).model_dump()
    return RigConfig.model_validate(data)
