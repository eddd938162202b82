"""What each camera says about itself as it opens (vendor, model, serial), for a recording's metadata.

The daemon, `trackerd record` and `trackerd snap` hand :meth:`CameraInfo.on_open`
to their source; opening the cameras for the two commands is
trackerd/cli/_cameras.py's.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

log = logging.getLogger(__name__)


class CameraInfo(dict[str, dict[str, str | None]]):
    """What each camera says about itself (vendor, model, serial, device), by camera id, noted as
    it opens: give :meth:`on_open` to ``LivePairSource(on_open=...)`` and the mapping itself to
    ``Recorder(camera_info=...)``, which reads it when the first pair arrives (every camera of a
    pair has opened by then). ``before`` is another open hook, called first (the virtual rig's)."""

    def __init__(self, before: Callable[[str, Any], None] | None = None) -> None:
        super().__init__()
        self._before = before

    def on_open(self, camera_id: str, camera: Any) -> None:
        """The source's open hook; runs on the camera's thread after each (re)connection."""
        if self._before is not None:
            self._before(camera_id, camera)
        self[camera_id] = describe_camera(camera)


def describe_camera(camera: Any) -> dict[str, str | None]:
    """Vendor, model, serial and device id of an Aravis camera (None for what it does not say)."""
    out: dict[str, str | None] = {}
    for key, getter in (
        ("vendor", "get_vendor_name"),
        ("model", "get_model_name"),
        ("serial", "get_device_serial_number"),
        ("device", "get_device_id"),
    ):
        try:
            value = getattr(camera, getter)()
        except Exception:  # noqa: BLE001 - a camera that cannot say is still recorded
            value = None
        out[key] = str(value) if value else None
    return out
