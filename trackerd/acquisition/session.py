"""What a camera worker needs of one open connection, whichever library made it.

An acquisition backend (Aravis in :mod:`trackerd.acquisition.arv`, pylon in
:mod:`trackerd.acquisition.pylon`, any vendor's GenTL producer in :mod:`trackerd.acquisition.gentl`)
opens a camera into a :class:`Session`: a
configured, acquiring connection whose finished buffers the worker pops, reads
into a :class:`Grab` and pushes back, always in that order. Everything above the
session (loss, reconnection, triggers, clocks, pairing, status) is shared, so the
pipeline cannot tell which backend fed it. :func:`open_session` and
:func:`resolve_device_id` pick the backend named by the camera's ``backend``.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from trackerd.config.acquisition import RigAcquisition
from trackerd.config.models import CameraConfig


@dataclass(frozen=True)
class Grab:
    """One finished buffer as the backend read it; the pixels are copied only on demand."""

    failure: str | None
    """Why the buffer is not a complete frame (counted by this cause), None when it is."""
    frame_id: int | None
    """The camera's frame (block) counter as sent, None when the camera sends none."""
    pixel_format: str
    """PFNC name of the buffer's pixel format (``0x...`` when trackerd does not know it)."""
    width_px: int
    height_px: int
    device_timestamp_ns: int
    """Capture time on the camera's clock, 0 when the camera sends none."""
    host_timestamp_ns: int
    """When the buffer was complete, on the host's monotonic clock."""
    pixels: Callable[[int], Any]
    """``pixels(nbytes)``: a copy of the image's first ``nbytes`` (bytes or a NumPy array)."""


class Session(Protocol):
    """One open, configured, acquiring connection to a camera."""

    camera_id: str
    camera: Any
    """The backend's camera object (an ``ArvCamera``, a pylon ``InstantCamera``), for on_open hooks."""
    buffers: list[Any]
    address: str | None
    """IPv4 address to probe before reopening (GigE Vision through Aravis), None otherwise."""
    control_lost: threading.Event
    notes: list[str]
    ptp_feature: str | None

    def pop(self, timeout_us: int) -> Any | None: ...
    def push(self, buffer: Any) -> None: ...
    def read(self, buffer: Any) -> Grab: ...
    def fire(self) -> int | None: ...
    def counters(self) -> dict[str, int]: ...
    def ptp_state(self) -> str | None: ...
    def close(self) -> int: ...
    def abandon(self) -> None: ...
    def leave_control(self) -> None: ...
    def buffers_released(self) -> bool: ...


def open_session(cam: CameraConfig, rig: RigAcquisition, device_id: str) -> Session:
    """Open ``device_id`` through the camera's backend, configured from the rig file and acquiring."""
    if cam.backend == "pylon":
        from trackerd.acquisition import pylon

        return pylon.open_session(cam, rig, device_id)
    if cam.backend == "gentl":
        from trackerd.acquisition import gentl

        return gentl.open_session(cam, rig, device_id)
    from trackerd.acquisition import arv

    return arv.open_session(cam, rig, device_id)


def resolve_device_id(cam: CameraConfig) -> str:
    """The id the camera's backend opens it by (CameraError if it is not found)."""
    if cam.backend == "pylon":
        from trackerd.acquisition import pylon

        return pylon.resolve_device_id(cam)
    if cam.backend == "gentl":
        from trackerd.acquisition import gentl

        return gentl.resolve_device_id(cam)
    from trackerd.acquisition import arv

    return arv.resolve_device_id(cam)


def load_backends(rig_cameras: tuple[CameraConfig, ...] | list[CameraConfig]) -> None:
    """Load every library the rig's cameras need; CameraError saying what to install if one is missing.

    CameraConfigError, before any camera is opened or waited for, if the rig file gives one of
    them no way to be found: waiting cannot supply the key."""
    from trackerd.acquisition.arv import require_a_way_to_find

    for cam in rig_cameras:
        require_a_way_to_find(cam)
    backends = {cam.backend for cam in rig_cameras}
    if "aravis" in backends:
        from trackerd.acquisition.arv import load_aravis

        load_aravis()
    if "pylon" in backends:
        from trackerd.acquisition.pylon import load_pylon

        load_pylon()
    if "gentl" in backends:
        from trackerd.acquisition.gentl import load_harvesters, producer_path

        load_harvesters()
        # A producer file that is not there will not appear by waiting: a configuration error now.
        for cam in rig_cameras:
            if cam.backend == "gentl":
                producer_path(cam)
