"""Any vendor's GenTL producer through harvesters: loading it, finding a camera, one configured connection.

The third acquisition backend (``backend = "gentl"`` with ``producer = "/path/to/vendor.cti"`` in a
camera's entry of the rig file). A frame grabber's vendor (CameraLink, CoaXPress: Teledyne DALSA's
Sapera, Euresys, Matrox, Silicon Software, ...) ships a GenTL producer, a ``.cti`` library; the
`harvesters <https://pypi.org/project/harvesters/>`_ consumer loads it and reaches the cameras behind
the grabber as GenICam devices. pylon, the other GenTL-capable backend, loads Basler's producers only
(docs/acquisition.md). harvesters is the optional extra ``trackerd[gentl]``; without it, asking for
this backend raises CameraError naming the extra.

One producer is loaded once per process and shared by every camera that names it
(:mod:`trackerd.acquisition.gentl_producer`, whose names this module re-exports). harvesters'
device list can only be refreshed while none of the producer's cameras is open (its ``update()``
closes them all), so a camera that appears after another camera of the same producer has opened is
found only when that one closes; for a grabber, whose cameras are cabled before the daemon starts,
that is the normal case.

A :class:`GentlSession` is one connection: harvesters' ``ImageAcquirer``, configured from the rig file
and acquiring with ``buffer_count`` announced buffers. The worker pops one buffer at a time
(``try_fetch``, on the worker's own thread: harvesters' background thread is not used) and queues it
back before anything else happens to the frame.

Clocks: harvesters gives no host time of a buffer's completion, so a frame's host time is when
:meth:`GentlSession.pop` returned it, as with pylon. Device timestamps are GenTL's
``BUFFER_INFO_TIMESTAMP_NS`` (or the tick timestamp over ``GevTimestampTickFrequency``) when the
producer has them, else 0 (the test producer ``viky.cti`` has none).
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from trackerd.acquisition.arv import CameraConfigError, describe_lookup, require_a_way_to_find
from trackerd.acquisition.gentl_producer import (
    GENTL_EXTRA,
    GentlDevice,
    Producer,
    genicam_errors,
    harvesters_missing_reason,
    list_gentl_devices,
    load_harvesters,
    producer,
    producer_path,
)
from trackerd.acquisition.session import Grab
from trackerd.config.acquisition import RigAcquisition
from trackerd.config.models import CameraConfig
from trackerd.errors import CameraError

if TYPE_CHECKING:
    from trackerd.acquisition.discovery import CameraDetails, DeviceEntry

__all__ = [
    "GENTL_EXTRA",
    "PADDED_FORMATS",
    "GentlDevice",
    "GentlSession",
    "Producer",
    "describe_gentl_camera",
    "harvesters_missing_reason",
    "list_gentl_devices",
    "load_harvesters",
    "open_session",
    "producer",
    "producer_path",
    "resolve_device_id",
]

log = logging.getLogger(__name__)

PADDED_FORMATS = {"RGB8": "RGBa8", "BGR8": "BGRa8"}
"""A producer that offers only the 4-byte form of a colour format (viky.cti's RGBa8) is read as the
3-byte one the rig asks for, its padding byte dropped in the one copy every frame gets anyway."""


def resolve_device_id(cam: CameraConfig) -> str:
    """The producer's id of the camera: ``device_id`` as given, else found by serial."""
    path = producer_path(cam)
    require_a_way_to_find(cam)
    if cam.device_id:
        return cam.device_id
    for device in producer(path).devices():
        if device.serial == cam.serial:
            return device.device_id
    raise CameraError(
        f"camera '{cam.id}' (gentl, serial {cam.serial}) not offered by {path};"
        f" `trackerd cameras --producer {path}` lists what it offers"
    )


@dataclass
class GentlSession:
    """One open, configured, acquiring connection to a camera through a GenTL producer."""

    camera_id: str
    camera: Any
    """harvesters' ``ImageAcquirer``."""
    owner: Producer
    pixel_format: str = ""
    """The PFNC name trackerd reports (the rig's), which may be the padded form's 3-byte reading."""
    padded: bool = False
    """The producer delivers the 4-byte form of ``pixel_format``; the padding byte is dropped."""
    tick_ns: float = 0.0
    """Nanoseconds per tick of the buffer's tick timestamp, 0 when only the ns timestamp is used."""
    address: str | None = None
    control_lost: threading.Event = field(default_factory=threading.Event)
    notes: list[str] = field(default_factory=list)
    ptp_feature: str | None = None
    buffers: list[Any] = field(default_factory=list)
    """Always empty: harvesters owns the announced buffers (``outstanding`` counts the ones trackerd holds)."""
    outstanding: int = 0
    closed: bool = False

    def pop(self, timeout_us: int) -> tuple[Any, int] | None:
        """The next filled buffer with its host arrival time, or None after ``timeout_us``."""
        try:
            buffer = self.camera.try_fetch(timeout=max(timeout_us, 1000) / 1e6)
        except genicam_errors() as err:
            self.notes.append(f"fetch failed: {err}")
            self.control_lost.set()
            return None
        if buffer is None:
            return None
        self.outstanding += 1
        return buffer, time.monotonic_ns()

    def push(self, buffer: tuple[Any, int]) -> None:
        """Queue the buffer back to the producer."""
        buffer[0].queue()
        self.outstanding -= 1

    def read(self, buffer: tuple[Any, int]) -> Grab:
        buf, host_ns = buffer
        module = buf.module
        frame_id = int(module.frame_id)
        if not module.is_complete():
            return Grab("incomplete", frame_id, "", 0, 0, 0, host_ns, lambda _nbytes: b"")
        component = buf.payload.components[0]
        data = component.data

        def pixels(_nbytes: int) -> Any:
            if self.padded:
                return data.reshape(-1, 4)[:, :3].copy()
            return data.copy()

        delivered = str(component.data_format)
        fmt = self.pixel_format if (self.padded or delivered == self.pixel_format) else delivered
        return Grab(
            failure=None,
            frame_id=frame_id,
            pixel_format=fmt,
            width_px=int(component.width),
            height_px=int(component.height),
            device_timestamp_ns=self._device_ns(module),
            host_timestamp_ns=host_ns,
            pixels=pixels,
        )

    def _device_ns(self, module: Any) -> int:
        if self.tick_ns == -1.0:
            return 0
        try:
            if self.tick_ns > 0:
                return round(int(module.timestamp) * self.tick_ns)
            return int(module.timestamp_ns)
        except genicam_errors():
            # The producer has no timestamps (viky.cti): stop asking; capture time is the host time.
            self.tick_ns = -1.0
            return 0

    def fire(self) -> int:
        """Execute TriggerSoftware; CameraError if the camera refuses it."""
        try:
            sent_ns = time.monotonic_ns()
            self.camera.remote_device.node_map.TriggerSoftware.execute()
        except genicam_errors() as err:
            raise CameraError(f"camera '{self.camera_id}': software trigger failed: {_message(err)}") from err
        return sent_ns

    def counters(self) -> dict[str, int]:
        """None: GenTL standardizes no stream statistics, and harvesters counts only on its own thread."""
        return {}

    def ptp_state(self) -> str | None:
        return None

    def close(self) -> int:
        """Stop acquiring and close the device; harvesters revokes its buffers (returns 0: none are trackerd's)."""
        if self.closed:
            return 0
        self.closed = True
        try:
            self.camera.stop()
        except genicam_errors() as err:
            self.notes.append(f"close: {err}")
        finally:
            self.owner.release(self.camera)
        return 0

    def leave_control(self) -> None:
        """Nothing to hand back: closing the device releases it."""

    def abandon(self) -> None:
        try:
            self.close()
        except Exception:  # best effort on a device that is gone
            log.debug("camera %s: dropping the GenTL device failed", self.camera_id, exc_info=True)

    def buffers_released(self) -> bool:
        return self.outstanding == 0


def _message(err: Exception) -> str:
    """A GenICam exception's text without the node, call and source file it carries."""
    return str(err).split(" : ")[0].strip()


def open_session(cam: CameraConfig, rig: RigAcquisition, device_id: str) -> GentlSession:
    """Open ``device_id`` on the camera's producer, configure it from the rig file and start acquiring."""
    owner = producer(producer_path(cam))
    where = f"camera '{cam.id}' ({describe_lookup(cam)})"
    try:
        acquirer = owner.create(device_id)
    except genicam_errors() as err:
        raise CameraError(
            f"{where}: {owner.path} does not offer {device_id!r} ({err});"
            f" `trackerd cameras --producer {owner.path}` lists what it offers"
        ) from err
    session = GentlSession(cam.id, acquirer, owner)
    try:
        _configure(session, cam, rig)
        acquirer.num_buffers = max(cam.acquisition.buffer_count, acquirer.min_num_buffers)
        acquirer.start()
    except genicam_errors() as err:
        session.abandon()
        raise CameraError(f"{where}: {_message(err)}") from err
    except CameraError:
        session.abandon()
        raise
    return session


def _node(session: GentlSession, name: str) -> Any | None:
    from genicam import genapi

    nodemap = session.camera.remote_device.node_map
    if not nodemap.has_node(name):
        return None
    node = getattr(nodemap, name)  # the typed node (an IEnumeration has symbolics, an IInteger min/max)
    return node if genapi.is_available(node) else None


def _allowed(node: Any, unit: str = "") -> str | None:
    try:
        if hasattr(node, "symbolics"):
            return "one of " + ", ".join(node.symbolics)
        if hasattr(node, "min"):
            return f"{node.min:g} to {node.max:g}{' ' + unit if unit else ''}"
    except genicam_errors():
        return None
    return None


def _write(cam: CameraConfig, session: GentlSession, setting: str, feature: str, value: object, unit: str = "") -> None:
    """Write one feature; a value or feature the camera refuses raises CameraConfigError saying what it allows."""
    where = f"camera '{cam.id}' ({describe_lookup(cam)})"
    shown = f"{value:g}" if isinstance(value, float) else repr(value) if isinstance(value, str) else value
    node = _node(session, feature)
    if node is None:
        raise CameraConfigError(f"{where}: {setting} = {shown}: the camera has no feature {feature}")
    try:
        if isinstance(value, str):
            node.from_string(value)
        else:
            node.value = value
    except genicam_errors() as err:
        limits = _allowed(node, unit)
        which = f", which allows {limits}" if limits else ""
        raise CameraConfigError(
            f"{where}: {setting} = {shown} is refused by the camera{which} ({_message(err)})"
        ) from err


def _configure(session: GentlSession, cam: CameraConfig, rig: RigAcquisition) -> None:
    acq = cam.acquisition
    where = f"camera '{cam.id}' ({describe_lookup(cam)})"
    for feature, value in cam.features.items():
        _write(cam, session, f"features.{feature}", feature, value)
    pixel_node = _node(session, "PixelFormat")
    offered = list(pixel_node.symbolics) if pixel_node is not None else []
    name = cam.pixel_format
    if name not in offered and PADDED_FORMATS.get(name) in offered:
        name = PADDED_FORMATS[name]
        session.padded = True
    if name not in offered:
        raise CameraConfigError(
            f"{where}: pixel_format = {cam.pixel_format!r} is not offered by the camera, which offers"
            f" {', '.join(offered) or 'none'}"
        )
    _write(cam, session, "pixel_format", "PixelFormat", name)
    session.pixel_format = cam.pixel_format
    region = "region (acquisition.offset_x_px, acquisition.offset_y_px, width_px, height_px)"
    for feature in ("OffsetX", "OffsetY"):
        if _node(session, feature) is not None:
            _write(cam, session, region, feature, 0, "px")
    _write(cam, session, "width_px", "Width", cam.width_px, "px")
    _write(cam, session, "height_px", "Height", cam.height_px, "px")
    if acq.offset_x_px or acq.offset_y_px:
        _write(cam, session, "acquisition.offset_x_px", "OffsetX", acq.offset_x_px, "px")
        _write(cam, session, "acquisition.offset_y_px", "OffsetY", acq.offset_y_px, "px")
    if acq.exposure_us is not None:
        if _node(session, "ExposureAuto") is not None:
            _write(cam, session, "acquisition.exposure_us: ExposureAuto", "ExposureAuto", "Off")
        _write(cam, session, "acquisition.exposure_us", "ExposureTime", float(acq.exposure_us), "us")
    if acq.gain_db is not None:
        if _node(session, "GainAuto") is not None:
            _write(cam, session, "acquisition.gain_db: GainAuto", "GainAuto", "Off")
        _write(cam, session, "acquisition.gain_db", "Gain", float(acq.gain_db), "dB")
    _configure_trigger(session, cam, rig)
    tick_hz = _node(session, "GevTimestampTickFrequency")
    if tick_hz is not None and tick_hz.value > 0:
        session.tick_ns = 1e9 / tick_hz.value
    if rig.ptp:
        session.notes.append("PTP is not driven through the gentl backend; pairing uses host time")


def _configure_trigger(session: GentlSession, cam: CameraConfig, rig: RigAcquisition) -> None:
    selector = _node(session, "TriggerSelector")
    if rig.trigger == "free_running":
        if selector is not None and _node(session, "TriggerMode") is not None:
            for entry in selector.symbolics:
                selector.from_string(entry)
                _write(cam, session, "trigger = 'free_running': TriggerMode", "TriggerMode", "Off")
        if _node(session, "AcquisitionFrameRate") is None:
            session.notes.append("frame rate is not settable; the camera runs at its own rate")
            return
        if _node(session, "AcquisitionFrameRateEnable") is not None:
            _write(cam, session, "frame_rate_hz: AcquisitionFrameRateEnable", "AcquisitionFrameRateEnable", True)
        _write(cam, session, "frame_rate_hz", "AcquisitionFrameRate", float(rig.frame_rate_hz), "Hz")
        return
    source = "Software" if rig.trigger == "software" else rig.hardware_trigger_line
    if _node(session, "TriggerMode") is None:
        raise CameraConfigError(
            f"camera '{cam.id}' ({describe_lookup(cam)}): trigger = {rig.trigger!r} is refused by the camera,"
            " which has no TriggerMode feature and allows only trigger = 'free_running'"
        )
    _write(cam, session, "trigger_selector", "TriggerSelector", rig.trigger_selector)
    _write(cam, session, f"trigger = {rig.trigger!r}: TriggerMode", "TriggerMode", "On")
    setting = "hardware_trigger_line" if rig.trigger == "hardware" else "trigger = 'software': TriggerSource"
    _write(cam, session, setting, "TriggerSource", source)
    if rig.trigger == "hardware":
        if _node(session, "TriggerActivation") is not None:
            _write(cam, session, "hardware_trigger_activation", "TriggerActivation", rig.hardware_trigger_activation)
        else:
            session.notes.append("no TriggerActivation feature; the camera's default edge applies")


def describe_gentl_camera(device: DeviceEntry) -> CameraDetails:
    """What a device a producer offers allows (a :class:`~trackerd.acquisition.discovery.CameraDetails`)."""
    from trackerd.acquisition.discovery import details_from_features

    owner = producer(Path(device.producer))
    try:
        acquirer = owner.create(device.device_id)
    except genicam_errors() as err:
        raise CameraError(f"cannot open {device.device_id} on {owner.path}: {err}") from err
    session = GentlSession(device.device_id, acquirer, owner)
    try:
        return details_from_features(device, _GentlFeatures(session))
    finally:
        session.close()


@dataclass(frozen=True)
class _GentlFeatures:
    """An open session's features through harvesters' typed nodes (discovery.FeatureReader)."""

    session: GentlSession

    def has(self, name: str) -> bool:
        return _node(self.session, name) is not None

    def value(self, name: str, default: Any = None) -> Any:
        node = _node(self.session, name)
        return node.value if node is not None else default

    def span(self, name: str) -> tuple[float, float] | None:
        node = _node(self.session, name)
        return (float(node.min), float(node.max)) if node is not None else None

    def entries(self, name: str) -> tuple[str, ...]:
        node = _node(self.session, name)
        return tuple(node.symbolics) if node is not None else ()

    def size(self, name: str) -> tuple[int, int, int]:
        node = _node(self.session, name)
        return (int(node.min), int(node.max), int(node.inc)) if node is not None else (0, 0, 1)
