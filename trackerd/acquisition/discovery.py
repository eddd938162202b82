"""What the backends can see: the cameras Aravis (GigE Vision, USB3 Vision), pylon and GenTL producers offer,
and what one offers."""

from __future__ import annotations

import ipaddress
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Protocol

from trackerd.acquisition import gvcp
from trackerd.acquisition.arv import aravis_missing_reason, load_aravis
from trackerd.errors import CameraError

ADDRESS_PROBE_TRIES = 3
ADDRESS_PROBE_TIMEOUT_S = 0.5
"""Per try: a GVCP discovery answer comes back in milliseconds; three tries cover a lost packet."""

TRIGGER_FEATURES = ("TriggerSelector", "TriggerMode", "TriggerSource", "TriggerActivation")
PTP_FEATURES = ("PtpEnable", "GevIEEE1588")


@dataclass(frozen=True)
class DeviceEntry:
    """One camera that a backend lists."""

    device_id: str
    vendor: str
    model: str
    serial: str
    address: str
    protocol: str
    physical_id: str
    backend: str = "aravis"
    """The rig file's ``backend`` that reaches the camera this way."""
    producer: str = ""
    """The GenTL producer (``.cti``) that offers the camera, for ``backend = "gentl"``; empty otherwise."""


@dataclass(frozen=True)
class CameraDetails:
    """What one camera offers, as trackerd would configure it."""

    device_id: str
    vendor: str
    model: str
    serial: str
    protocol: str
    sensor_px: tuple[int, int]
    width_px: tuple[int, int, int]
    """(min, max, increment)."""
    height_px: tuple[int, int, int]
    pixel_format: str
    pixel_formats: tuple[str, ...]
    frame_rate_hz: tuple[float, float] | None
    exposure_us: tuple[float, float] | None
    gain: tuple[float, float] | None
    triggers: tuple[str, ...]
    """Trigger selectors (FrameStart, ...)."""
    trigger_sources: tuple[str, ...]
    trigger_activations: tuple[str, ...]
    software_trigger: bool
    ptp: str | None
    """The PTP feature the camera has (PtpEnable or GevIEEE1588), None without PTP."""
    packet_size_bytes: int | None
    packet_delay: bool

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


class FeatureReader(Protocol):
    """A camera's GenICam features as a backend without Aravis's camera API reads them (pylon, GenTL)."""

    def has(self, name: str) -> bool:
        """Whether the camera has the feature and it is available now."""
        ...

    def value(self, name: str, default: Any = None) -> Any:
        """The feature's value, ``default`` without it."""
        ...

    def span(self, name: str) -> tuple[float, float] | None:
        """A number feature's (min, max), None without it."""
        ...

    def entries(self, name: str) -> tuple[str, ...]:
        """An enumeration's entries, () without it."""
        ...

    def size(self, name: str) -> tuple[int, int, int]:
        """An integer feature's (min, max, increment), (0, 0, 1) without it."""
        ...


def details_from_features(device: DeviceEntry, features: FeatureReader) -> CameraDetails:
    """What a camera offers, read feature by feature by name (the standard features' names, SFNC)."""
    sources = features.entries("TriggerSource")
    return CameraDetails(
        device_id=device.device_id,
        vendor=device.vendor,
        model=device.model,
        serial=device.serial,
        protocol=device.protocol,
        sensor_px=(int(features.value("SensorWidth", 0)), int(features.value("SensorHeight", 0))),
        width_px=features.size("Width"),
        height_px=features.size("Height"),
        pixel_format=str(features.value("PixelFormat", "")),
        pixel_formats=features.entries("PixelFormat"),
        frame_rate_hz=features.span("AcquisitionFrameRate"),
        exposure_us=features.span("ExposureTime"),
        gain=features.span("Gain"),
        triggers=features.entries("TriggerSelector"),
        trigger_sources=sources,
        trigger_activations=features.entries("TriggerActivation"),
        software_trigger="Software" in sources,
        ptp=next((f for f in PTP_FEATURES if features.has(f)), None),
        packet_size_bytes=features.value("GevSCPSPacketSize"),
        packet_delay=features.has("GevSCPD"),
    )


def list_devices(include_fake: bool = False, producers: list[str] | None = None) -> list[DeviceEntry]:
    """Every camera Aravis discovers, then every camera pylon finds when pypylon is installed, then the
    devices of each GenTL producer in ``producers`` (``.cti`` paths; harvesters needed).

    Aravis's GigE Vision discovery takes about a second. A Basler camera that both
    reach is listed once for each backend. CameraError if no library is there.
    """
    from trackerd.acquisition.pylon import pylon_missing_reason

    aravis_missing = aravis_missing_reason()
    pylon_missing = pylon_missing_reason()
    if aravis_missing is not None and pylon_missing is not None and not producers:
        raise CameraError(aravis_missing)
    devices = [] if aravis_missing is not None else list_aravis_devices(include_fake)
    if pylon_missing is None:
        devices.extend(list_pylon_entries())
    if producers:
        devices.extend(list_gentl_entries(producers))
    return devices


def list_gentl_entries(producers: list[str]) -> list[DeviceEntry]:
    """The devices each GenTL producer offers, as entries of the listing (``backend = "gentl"``)."""
    from trackerd.acquisition.gentl import list_gentl_devices

    entries: list[DeviceEntry] = []
    for path in producers:
        resolved = str(Path(path).expanduser().resolve())
        entries.extend(
            DeviceEntry(
                device_id=d.device_id,
                vendor=d.vendor,
                model=d.model,
                serial=d.serial,
                address="",
                protocol=d.tl_type,
                physical_id="",
                backend="gentl",
                producer=resolved,
            )
            for d in list_gentl_devices(path)
        )
    return entries


def list_pylon_entries() -> list[DeviceEntry]:
    """The cameras pylon finds, as entries of the listing (``backend = "pylon"``)."""
    from trackerd.acquisition.pylon import list_pylon_devices

    return [
        DeviceEntry(
            device_id=d.full_name,
            vendor=d.vendor,
            model=d.model,
            serial=d.serial,
            address=d.address or "",
            protocol=d.device_class,
            physical_id="",
            backend="pylon",
        )
        for d in list_pylon_devices()
    ]


def list_aravis_devices(include_fake: bool = False) -> list[DeviceEntry]:
    """Every camera Aravis discovers (takes about a second for GigE Vision discovery)."""
    aravis, _ = load_aravis()
    if include_fake:
        aravis.enable_interface("Fake")
    aravis.update_device_list()
    return [
        DeviceEntry(
            device_id=aravis.get_device_id(i) or "",
            vendor=aravis.get_device_vendor(i) or "",
            model=aravis.get_device_model(i) or "",
            serial=aravis.get_device_serial_nbr(i) or "",
            address=aravis.get_device_address(i) or "",
            protocol=aravis.get_device_protocol(i) or "",
            physical_id=aravis.get_device_physical_id(i) or "",
        )
        for i in range(aravis.get_n_devices())
    ]


def find_device(devices: list[DeviceEntry], wanted: str) -> DeviceEntry | None:
    """The device whose id, serial or address is ``wanted``."""
    for device in devices:
        if wanted in (device.device_id, device.serial, device.address, device.physical_id) and wanted:
            return device
    return None


def is_ipv4_address(text: str) -> bool:
    """Whether ``text`` is a literal IPv4 address (as a GigE Vision camera is named by address)."""
    try:
        ipaddress.IPv4Address(text)
    except ValueError:
        return False
    return True


def device_at(address: str) -> DeviceEntry | None:
    """The GigE Vision camera at ``address``, asked directly; None if nothing answers.

    Aravis's device list comes from broadcast discovery, which reaches only the
    subnets of this host's interfaces: a camera behind a router, or on a subnet
    the host is not on but has a route to, is not in it, although Aravis opens it
    by its address. A GVCP discovery sent to the address itself (unicast) reaches
    any camera the host can route to, and its answer names the camera. The entry's
    device id is the address, which is what Aravis (and a rig file) opens it by.
    """
    for _ in range(ADDRESS_PROBE_TRIES):
        found = gvcp.probe(address, ADDRESS_PROBE_TIMEOUT_S)
        if found is not None:
            return DeviceEntry(
                device_id=address,
                vendor=found.manufacturer,
                model=found.model,
                serial=found.serial,
                address=found.address,
                protocol="GigEVision",
                physical_id=found.mac,
            )
    return None


def describe_camera(device: DeviceEntry) -> CameraDetails:
    """Open the camera and read what it offers; CameraError if it cannot be opened."""
    if device.backend == "pylon":
        from trackerd.acquisition.pylon import describe_pylon_camera

        return describe_pylon_camera(device)
    if device.backend == "gentl":
        from trackerd.acquisition.gentl import describe_gentl_camera

        return describe_gentl_camera(device)
    aravis, glib = load_aravis()
    try:
        camera = aravis.Camera.new(device.device_id)
    except glib.Error as err:
        raise CameraError(f"cannot open {device.device_id}: {err.message}") from err
    try:
        return _details(camera, device, glib)
    except glib.Error as err:
        raise CameraError(f"{device.device_id}: {err.message}") from err


def _bounds(camera: Any, available: str, getter: str, glib: Any) -> tuple[float, float] | None:
    try:
        if not getattr(camera, available)():
            return None
        low, high = getattr(camera, getter)()
        return float(low), float(high)
    except glib.Error:
        return None


def _enumeration(camera: Any, feature: str, glib: Any) -> tuple[str, ...]:
    try:
        if not camera.is_feature_available(feature):
            return ()
        return tuple(camera.dup_available_enumerations_as_strings(feature) or ())
    except glib.Error:
        return ()


def _details(camera: Any, device: DeviceEntry, glib: Any) -> CameraDetails:
    width_min, width_max = camera.get_width_bounds()
    height_min, height_max = camera.get_height_bounds()
    sensor_width, sensor_height = camera.get_sensor_size()
    ptp = next((f for f in PTP_FEATURES if camera.is_feature_available(f)), None)
    packet_size = None
    if camera.is_gv_device():
        try:
            packet_size = int(camera.gv_get_packet_size())
        except glib.Error:
            packet_size = None
    return CameraDetails(
        device_id=device.device_id,
        vendor=camera.get_vendor_name() or device.vendor,
        model=camera.get_model_name() or device.model,
        serial=camera.get_device_serial_number() or device.serial,
        protocol=device.protocol,
        sensor_px=(sensor_width, sensor_height),
        width_px=(int(width_min), int(width_max), int(camera.get_width_increment())),
        height_px=(int(height_min), int(height_max), int(camera.get_height_increment())),
        pixel_format=camera.get_pixel_format_as_string() or "",
        pixel_formats=tuple(camera.dup_available_pixel_formats_as_strings() or ()),
        frame_rate_hz=_bounds(camera, "is_frame_rate_available", "get_frame_rate_bounds", glib),
        exposure_us=_bounds(camera, "is_exposure_time_available", "get_exposure_time_bounds", glib),
        gain=_bounds(camera, "is_gain_available", "get_gain_bounds", glib),
        triggers=tuple(camera.dup_available_triggers() or ()),
        trigger_sources=tuple(camera.dup_available_trigger_sources() or ()),
        trigger_activations=_enumeration(camera, "TriggerActivation", glib),
        software_trigger=bool(camera.is_software_trigger_supported()),
        ptp=ptp,
        packet_size_bytes=packet_size,
        packet_delay=camera.is_gv_device() and camera.is_feature_available("GevSCPD"),
    )
