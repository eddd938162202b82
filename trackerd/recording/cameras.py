"""The cameras `trackerd record` and `trackerd snap` read: the rig's, or the virtual rig's for trying things out.

Both open an :class:`~trackerd.acquisition.live.AravisPairSource` directly (no
pipeline), and note each camera's vendor, model and serial as it opens, for the
recording's metadata.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from typing import Any

from trackerd.config.models import RigConfig

log = logging.getLogger(__name__)


@dataclass
class CameraSource:
    """An open pair source, the rig it was opened with and what each camera said about itself."""

    source: Any
    rig: RigConfig
    info: dict[str, dict[str, str | None]] = field(default_factory=dict)
    virtual: Any = None


def describe_camera(camera: Any) -> dict[str, str | None]:
    """Vendor, model, serial and device id of an Aravis camera (None for what it does not say)."""
    out: dict[str, str | None] = {}
    for key, getter in (("vendor", "get_vendor_name"), ("model", "get_model_name"),
                        ("serial", "get_device_serial_number"), ("device", "get_device_id")):
        try:
            value = getattr(camera, getter)()
        except Exception:  # noqa: BLE001 - a camera that cannot say is still recorded
            value = None
        out[key] = str(value) if value else None
    return out


@contextmanager
def open_cameras(
    rig: RigConfig, *, virtual_motion: str | None = None, label: str = "trackerd"
) -> Iterator[CameraSource]:
    """Start the rig's cameras (or, with ``virtual_motion``, simulated cameras serving that motion)."""
    from trackerd.acquisition.live import AravisPairSource

    with ExitStack() as stack:
        virtual = None
        if virtual_motion is not None:
            from trackerd.sim import netns
            from trackerd.sim.rig import VirtualRig

            network = "netns" if netns.netns_missing_reason() is None else "loopback"
            if network == "loopback" and rig.acquisition.trigger == "software":
                acquisition = rig.acquisition.model_copy(update={"trigger": "free_running"})
                rig = rig.model_copy(update={"acquisition": acquisition})
            print(f"{label}: starting simulated cameras serving the '{virtual_motion}' motion (rendered once, then"
                  " cached)...", file=sys.stderr, flush=True)
            virtual = stack.enter_context(VirtualRig(rig, motion=virtual_motion, network=network))
            rig = virtual.daemon_rig
        opened = CameraSource(None, rig, virtual=virtual)

        def on_open(camera_id: str, camera: Any) -> None:
            if virtual is not None:
                virtual.on_open(camera_id, camera)
            opened.info[camera_id] = describe_camera(camera)

        opened.source = stack.enter_context(AravisPairSource(rig, on_open=on_open))
        yield opened
