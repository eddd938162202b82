"""Basler pylon, through pypylon: loading it, finding a camera, and one configured connection to it.

The second acquisition backend beside Aravis (``backend = "pylon"`` in a camera's
entry of the rig file). pylon reaches cameras through its transport layers: its
camera emulation (``PYLON_CAMEMU=<n>`` makes it offer *n* emulated cameras), Basler
GigE and USB cameras, and frame grabbers through its GenTL consumer (Basler's
CoaXPress producer; pylon loads no other vendor's producer without a licence
from Basler, see docs/acquisition.md). pypylon is the optional extra
``trackerd[gentl]``; without it, asking for this backend raises CameraError
saying which extra to install.

A :class:`PylonSession` is one connection: the ``InstantCamera``, opened,
configured from the rig file and grabbing with ``buffer_count`` buffers that
pylon allocates and recycles. The worker pops one grab result at a time and
pushes it back (releases it) before anything else happens to the frame, so the
grab engine always has its buffers.

Clocks: pylon gives no host time of a buffer's completion, so a frame's host
time is when :meth:`PylonSession.pop` returned it (the GIL is released while
pylon waits, so the delay is the acquisition thread's own). Device timestamps are
the camera's ``TimeStamp`` in ticks of ``GevTimestampTickFrequency`` where the
camera has it, else nanoseconds; pylon's emulated cameras send 0, which makes
every frame's capture time its host time (no clock mapping, no warm-up).

Errors: as with Aravis, a camera that is not there or cannot be opened raises
:class:`~trackerd.errors.CameraError`; a value the camera refuses (out of its
range, not one of its entries, not writable, a feature it lacks) raises
:class:`~trackerd.acquisition.arv.CameraConfigError` naming the setting and what
the camera allows.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from trackerd.acquisition.arv import CameraConfigError, describe_lookup, require_a_way_to_find
from trackerd.acquisition.session import Grab
from trackerd.config.acquisition import RigAcquisition
from trackerd.config.models import CameraConfig
from trackerd.errors import CameraError
from trackerd.pixelformat import PFNC_NAMES

if TYPE_CHECKING:
    from trackerd.acquisition.discovery import CameraDetails, DeviceEntry

log = logging.getLogger(__name__)

PYLON_EXTRA = "trackerd[gentl]"
"""The optional extra that installs pypylon."""

STREAM_COUNTERS = {
    "Statistic_Total_Buffer_Count": "n_completed_buffers",
    "Statistic_Failed_Buffer_Count": "n_failures",
    "Statistic_Buffer_Underrun_Count": "n_underruns",
    "Statistic_Total_Packet_Count": "n_received_packets",
    "Statistic_Failed_Packet_Count": "n_error_packets",
    "Statistic_Resend_Request_Count": "n_resend_requests",
    "Statistic_Resend_Packet_Count": "n_resent_packets",
}
"""pylon stream grabber statistics read into the status, under the names Aravis's counters have there."""

LEGACY_FORMAT_NAMES = {"RGB8": "RGB8Packed", "BGR8": "BGR8Packed"}
"""Older Basler cameras (and pylon's emulation) name the PFNC formats RGB8 and BGR8 this way."""

_NO_BLOCK_ID = 1 << 63
"""pylon reports a block id of all ones when the transport has none."""


def load_pylon() -> tuple[Any, Any]:
    """``(pylon, genicam)`` from pypylon; CameraError naming the extra to install if it is missing."""
    try:
        from pypylon import genicam, pylon
    except ImportError as err:
        raise CameraError(
            f"backend = 'pylon' needs pypylon, which is not installed ({err}); install the optional extra:"
            f" pip install '{PYLON_EXTRA}'"
        ) from err
    return pylon, genicam


def pylon_missing_reason() -> str | None:
    """Why pylon cannot be used here, or None if it can (for skipping tests and commands)."""
    try:
        load_pylon()
    except CameraError as err:
        return str(err)
    return None


@dataclass(frozen=True)
class PylonDevice:
    """One camera pylon enumerates."""

    full_name: str
    """pylon's unique name of the device: its ``device_id`` in the rig file."""
    serial: str
    vendor: str
    model: str
    device_class: str
    """pylon's transport layer: ``BaslerCamEmu``, ``BaslerGigE``, ``BaslerUsb``, ``BaslerGTC/...``."""
    address: str | None


def list_pylon_devices() -> list[PylonDevice]:
    """Every camera pylon's transport layers find now (CameraError if pypylon is missing)."""
    pylon, _ = load_pylon()
    devices = []
    for info in pylon.TlFactory.GetInstance().EnumerateDevices():
        address = info.GetIpAddress() if info.IsIpAddressAvailable() else None
        devices.append(
            PylonDevice(
                full_name=info.GetFullName(),
                serial=info.GetSerialNumber(),
                vendor=info.GetVendorName(),
                model=info.GetModelName(),
                device_class=info.GetDeviceClass(),
                address=address or None,
            )
        )
    return devices


def resolve_device_id(cam: CameraConfig) -> str:
    """pylon's full name of the camera: ``device_id`` as given, else found by serial."""
    require_a_way_to_find(cam)
    if cam.device_id:
        return cam.device_id
    for device in list_pylon_devices():
        if device.serial == cam.serial:
            return device.full_name
    raise CameraError(
        f"camera '{cam.id}' (pylon, serial {cam.serial}) not found; `trackerd cameras` lists the cameras pylon sees"
    )


@dataclass
class PylonSession:
    """One open, configured, grabbing connection to a camera through pylon."""

    camera_id: str
    camera: Any
    """The pylon ``InstantCamera``."""
    software_trigger: bool
    tick_ns: float = 1.0
    """Nanoseconds per tick of the camera's timestamps."""
    address: str | None = None
    control_lost: threading.Event = field(default_factory=threading.Event)
    notes: list[str] = field(default_factory=list)
    ptp_feature: str | None = None
    buffers: list[Any] = field(default_factory=list)
    """Always empty: pylon owns its buffers (``outstanding`` counts the ones trackerd holds)."""
    outstanding: int = 0
    """Grab results popped and not yet pushed back."""
    ready_timeout_ms: int = 1000
    """How long a software trigger waits for the camera to be ready for it (the rig's loss_timeout_ms):
    a camera that cannot take a trigger that long is lost, as one that sends no frame."""

    def pop(self, timeout_us: int) -> tuple[Any, int] | None:
        """The next grab result with its host arrival time, or None after ``timeout_us``."""
        pylon, genicam = load_pylon()
        try:
            result = self.camera.RetrieveResult(max(int(timeout_us) // 1000, 1), pylon.TimeoutHandling_Return)
        except genicam.GenericException as err:
            # Grabbing ended under us: the device was removed, or its transport failed.
            self.notes.append(f"grab stopped: {err}")
            self.control_lost.set()
            return None
        host_ns = time.monotonic_ns()
        if result is None or not result.IsValid():
            if self.camera.IsCameraDeviceRemoved():
                self.control_lost.set()
            return None
        self.outstanding += 1
        return result, host_ns

    def push(self, buffer: tuple[Any, int]) -> None:
        """Hand the grab result's buffer back to pylon's grab engine."""
        buffer[0].Release()
        self.outstanding -= 1

    def read(self, buffer: tuple[Any, int]) -> Grab:
        result, host_ns = buffer
        if not result.GrabSucceeded():
            return Grab(
                f"error-0x{result.GetErrorCode() & 0xFFFFFFFF:08x}",
                _block_id(result),
                "",
                0,
                0,
                0,
                host_ns,
                lambda _nbytes: b"",
            )
        code = int(result.GetPixelType())
        # pylon's pixel types are PFNC codes.
        return Grab(
            failure=None,
            frame_id=_block_id(result),
            pixel_format=PFNC_NAMES.get(code, f"0x{code:08x}"),
            width_px=int(result.GetWidth()),
            height_px=int(result.GetHeight()),
            device_timestamp_ns=round(int(result.GetTimeStamp()) * self.tick_ns),
            host_timestamp_ns=host_ns,
            pixels=lambda _nbytes: result.GetBuffer(),
        )

    def fire(self) -> int:
        """Execute TriggerSoftware once the camera waits for a frame trigger; CameraError if it does not.
        Returns when the trigger was sent (host monotonic ns), after the wait.

        A camera ignores a trigger that comes while it is still busy with the previous frame (outside
        its FrameTriggerWait state), and a trigger lost that way would leave trackerd waiting for a frame
        that never comes. pylon's WaitForFrameTriggerReady reads the camera's acquisition status
        (pylon's emulated cameras, on a loaded machine, come back to it a few milliseconds after their
        frame is delivered).
        """
        pylon, genicam = load_pylon()
        try:
            if not self.camera.WaitForFrameTriggerReady(self.ready_timeout_ms, pylon.TimeoutHandling_Return):
                raise CameraError(
                    f"camera '{self.camera_id}': not ready for a software trigger within {self.ready_timeout_ms} ms"
                )
            sent_ns = time.monotonic_ns()
            self.camera.ExecuteSoftwareTrigger()
        except genicam.GenericException as err:
            raise CameraError(f"camera '{self.camera_id}': software trigger failed: {_message(err)}") from err
        return sent_ns

    def counters(self) -> dict[str, int]:
        """pylon's stream grabber statistics that this transport keeps."""
        _, genicam = load_pylon()
        values: dict[str, int] = {}
        try:
            nodemap = self.camera.GetStreamGrabberNodeMap()
            for name, key in STREAM_COUNTERS.items():
                node = nodemap.GetNode(name)
                if node is not None and genicam.IsAvailable(node) and genicam.IsReadable(node):
                    values[key] = int(node.GetValue())
        except genicam.GenericException:
            pass  # a connection going away: the counters are a report, not a reason to fail
        return values

    def ptp_state(self) -> str | None:
        return None

    def close(self) -> int:
        """Stop grabbing and close the camera; pylon frees its buffers (returns 0: none are trackerd's)."""
        _, genicam = load_pylon()
        try:
            self.camera.StopGrabbing()
            self.camera.Close()
        except genicam.GenericException as err:
            self.notes.append(f"close: {err}")
        self.camera.DestroyDevice()
        return 0

    def leave_control(self) -> None:
        """Nothing to hand back: closing the camera releases it."""

    def abandon(self) -> None:
        """Drop a connection that stopped delivering."""
        try:
            self.close()
        except Exception:  # best effort on a device that is gone
            log.debug("camera %s: dropping the pylon device failed", self.camera_id, exc_info=True)

    def buffers_released(self) -> bool:
        return self.outstanding == 0


def _block_id(result: Any) -> int | None:
    block = int(result.GetBlockID())
    return None if block >= _NO_BLOCK_ID else block


def open_session(cam: CameraConfig, rig: RigAcquisition, device_id: str) -> PylonSession:
    """Open ``device_id`` (pylon's full name), configure it from the rig file and start grabbing."""
    pylon, genicam = load_pylon()
    where = f"camera '{cam.id}' ({describe_lookup(cam)})"
    factory = pylon.TlFactory.GetInstance()
    info = next((i for i in factory.EnumerateDevices() if i.GetFullName() == device_id), None)
    if info is None:
        raise CameraError(f"{where}: pylon does not see {device_id!r}; `trackerd cameras` lists what it sees")
    try:
        camera = pylon.InstantCamera(factory.CreateDevice(info))
        camera.Open()
    except genicam.GenericException as err:
        raise CameraError(f"{where}: cannot open: {_message(err)}") from err
    session = PylonSession(cam.id, camera, rig.trigger == "software", ready_timeout_ms=round(rig.loss_timeout_ms))
    try:
        _configure(session, cam, rig)
        camera.MaxNumBuffer.Value = cam.acquisition.buffer_count
        camera.StartGrabbing(pylon.GrabStrategy_OneByOne)
    except genicam.GenericException as err:
        session.abandon()
        raise CameraError(f"{where}: {_message(err)}") from err
    except CameraError:
        session.abandon()
        raise
    return session


def _message(err: Exception) -> str:
    """A GenICam exception's text without the source file and line it carries."""
    return str(err).split(" : ")[0].strip()


def _node(camera: Any, name: str) -> Any | None:
    _, genicam = load_pylon()
    node = camera.GetNodeMap().GetNode(name)
    return node if node is not None and genicam.IsAvailable(node) else None


def _allowed(node: Any, unit: str = "") -> str | None:
    """What a feature allows, as text (its range, or its entries)."""
    _, genicam = load_pylon()
    try:
        if hasattr(node, "Symbolics"):
            return "one of " + ", ".join(node.Symbolics)
        if hasattr(node, "GetMin"):
            return f"{node.GetMin():g} to {node.GetMax():g}{' ' + unit if unit else ''}"
    except genicam.GenericException:
        return None  # the camera does not say; the error's own text still does
    return None


def _write(cam: CameraConfig, setting: str, camera: Any, feature: str, value: object, unit: str = "") -> None:
    """Write one feature; a value or feature the camera refuses raises CameraConfigError saying what it allows."""
    _, genicam = load_pylon()
    where = f"camera '{cam.id}' ({describe_lookup(cam)})"
    shown = f"{value:g}" if isinstance(value, float) else repr(value) if isinstance(value, str) else value
    node = _node(camera, feature)
    if node is None:
        raise CameraConfigError(f"{where}: {setting} = {shown}: the camera has no feature {feature}")
    try:
        if isinstance(value, str):
            node.FromString(value)
        else:
            node.SetValue(value)
    except (
        genicam.OutOfRangeException,
        genicam.InvalidArgumentException,
        genicam.AccessException,
        genicam.LogicalErrorException,
    ) as err:
        limits = _allowed(node, unit)
        which = f", which allows {limits}" if limits else ""
        raise CameraConfigError(
            f"{where}: {setting} = {shown} is refused by the camera{which} ({_message(err)})"
        ) from err


def _first(camera: Any, *names: str) -> str | None:
    return next((n for n in names if _node(camera, n) is not None), None)


def _configure(session: PylonSession, cam: CameraConfig, rig: RigAcquisition) -> None:
    camera = session.camera
    acq = cam.acquisition
    where = f"camera '{cam.id}' ({describe_lookup(cam)})"
    # The rig's own features first: a grabber's link or tap configuration can change what else is allowed.
    for feature, value in cam.features.items():
        _write(cam, f"features.{feature}", camera, feature, value)
    pixel_node = _node(camera, "PixelFormat")
    offered = list(pixel_node.Symbolics) if pixel_node is not None else []
    name = cam.pixel_format
    if name not in offered and LEGACY_FORMAT_NAMES.get(name) in offered:
        name = LEGACY_FORMAT_NAMES[name]
    if name not in offered:
        raise CameraConfigError(
            f"{where}: pixel_format = {cam.pixel_format!r} is not offered by the camera, which offers"
            f" {', '.join(offered) or 'none'}"
        )
    _write(cam, "pixel_format", camera, "PixelFormat", name)
    region = "region (acquisition.offset_x_px, acquisition.offset_y_px, width_px, height_px)"
    # Offsets to 0 first, so the size fits whatever region the camera had.
    for feature in ("OffsetX", "OffsetY"):
        if _node(camera, feature) is not None:
            _write(cam, region, camera, feature, 0, "px")
    _write(cam, "width_px", camera, "Width", cam.width_px, "px")
    _write(cam, "height_px", camera, "Height", cam.height_px, "px")
    if acq.offset_x_px or acq.offset_y_px:
        _write(cam, "acquisition.offset_x_px", camera, "OffsetX", acq.offset_x_px, "px")
        _write(cam, "acquisition.offset_y_px", camera, "OffsetY", acq.offset_y_px, "px")
    if acq.exposure_us is not None:
        if _node(camera, "ExposureAuto") is not None:
            _write(cam, "acquisition.exposure_us: ExposureAuto", camera, "ExposureAuto", "Off")
        feature = _first(camera, "ExposureTime", "ExposureTimeAbs") or "ExposureTime"
        _write(cam, "acquisition.exposure_us", camera, feature, float(acq.exposure_us), "us")
    if acq.gain_db is not None:
        if _node(camera, "GainAuto") is not None:
            _write(cam, "acquisition.gain_db: GainAuto", camera, "GainAuto", "Off")
        if _node(camera, "Gain") is not None:
            _write(cam, "acquisition.gain_db", camera, "Gain", float(acq.gain_db), "dB")
        else:
            _write(cam, "acquisition.gain_db (GainRaw, raw counts)", camera, "GainRaw", round(acq.gain_db))
    _configure_trigger(session, cam, rig)
    tick_hz = _node(camera, "GevTimestampTickFrequency")
    if tick_hz is not None and tick_hz.GetValue() > 0:
        session.tick_ns = 1e9 / tick_hz.GetValue()
    if rig.ptp:
        session.notes.append("PTP is not driven through the pylon backend; pairing uses host time")


def _configure_trigger(session: PylonSession, cam: CameraConfig, rig: RigAcquisition) -> None:
    camera = session.camera
    selector = _node(camera, "TriggerSelector")
    if rig.trigger == "free_running":
        if selector is not None:
            # Every trigger off, as Aravis's clear_triggers does: a frame-start trigger left on by a
            # previous user would otherwise hold the camera.
            for entry in selector.Symbolics:
                selector.FromString(entry)
                if _node(camera, "TriggerMode") is not None:
                    _write(cam, "trigger = 'free_running': TriggerMode", camera, "TriggerMode", "Off")
        rate = _first(camera, "AcquisitionFrameRate", "AcquisitionFrameRateAbs")
        if rate is None:
            session.notes.append("frame rate is not settable; the camera runs at its own rate")
            return
        if _node(camera, "AcquisitionFrameRateEnable") is not None:
            _write(cam, "frame_rate_hz: AcquisitionFrameRateEnable", camera, "AcquisitionFrameRateEnable", True)
        _write(cam, "frame_rate_hz", camera, rate, float(rig.frame_rate_hz), "Hz")
        return
    source = "Software" if rig.trigger == "software" else rig.hardware_trigger_line
    _write(cam, "trigger_selector", camera, "TriggerSelector", rig.trigger_selector)
    _write(cam, f"trigger = {rig.trigger!r}: TriggerMode", camera, "TriggerMode", "On")
    setting = "hardware_trigger_line" if rig.trigger == "hardware" else "trigger = 'software': TriggerSource"
    _write(cam, setting, camera, "TriggerSource", source)
    if rig.trigger == "hardware":
        if _node(camera, "TriggerActivation") is not None:
            _write(cam, "hardware_trigger_activation", camera, "TriggerActivation", rig.hardware_trigger_activation)
        else:
            session.notes.append("no TriggerActivation feature; the camera's default edge applies")


def describe_pylon_camera(device: DeviceEntry) -> CameraDetails:
    """What a camera pylon lists offers (a :class:`~trackerd.acquisition.discovery.CameraDetails`)."""
    from trackerd.acquisition.discovery import details_from_features

    pylon, genicam = load_pylon()
    factory = pylon.TlFactory.GetInstance()
    info = next((i for i in factory.EnumerateDevices() if i.GetFullName() == device.device_id), None)
    if info is None:
        raise CameraError(f"pylon no longer sees {device.device_id}")
    try:
        camera = pylon.InstantCamera(factory.CreateDevice(info))
        camera.Open()
    except genicam.GenericException as err:
        raise CameraError(f"cannot open {device.device_id}: {_message(err)}") from err
    try:
        return details_from_features(device, _PylonFeatures(camera, genicam))
    finally:
        camera.Close()
        camera.DestroyDevice()


SPAN_FALLBACKS = {
    "AcquisitionFrameRate": ("AcquisitionFrameRateAbs",),
    "ExposureTime": ("ExposureTimeAbs",),
    "Gain": ("GainRaw",),
}
"""Older Basler GigE cameras' names for the standard number features (pre-SFNC 2.0)."""


@dataclass(frozen=True)
class _PylonFeatures:
    """An open InstantCamera's features (discovery.FeatureReader); a standard number feature the
    camera lacks is read under its older Basler name."""

    camera: Any
    genicam: Any

    def has(self, name: str) -> bool:
        return _node(self.camera, name) is not None

    def value(self, name: str, default: Any = None) -> Any:
        node = _node(self.camera, name)
        return node.GetValue() if node is not None and self.genicam.IsReadable(node) else default

    def span(self, name: str) -> tuple[float, float] | None:
        found = _first(self.camera, name, *SPAN_FALLBACKS.get(name, ()))
        node = _node(self.camera, found) if found is not None else None
        return (float(node.GetMin()), float(node.GetMax())) if node is not None else None

    def entries(self, name: str) -> tuple[str, ...]:
        node = _node(self.camera, name)
        return tuple(node.Symbolics) if node is not None else ()

    def size(self, name: str) -> tuple[int, int, int]:
        node = _node(self.camera, name)
        return (int(node.GetMin()), int(node.GetMax()), int(node.GetInc())) if node is not None else (0, 0, 1)
