"""What a camera offers, read through its GenICam features (the pylon and GenTL backends' path)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from trackerd.acquisition.discovery import DeviceEntry, details_from_features

DEVICE = DeviceEntry("dev-1", "Vendor", "Model 7", "S123", "", "CoaXPress", "", backend="gentl", producer="/x.cti")


@dataclass
class Features:
    """A node map as plain data: values, (min, max) spans, enumerations, (min, max, inc) sizes."""

    values: dict[str, Any] = field(default_factory=dict)
    spans: dict[str, tuple[float, float]] = field(default_factory=dict)
    enums: dict[str, tuple[str, ...]] = field(default_factory=dict)
    sizes: dict[str, tuple[int, int, int]] = field(default_factory=dict)

    def has(self, name: str) -> bool:
        return any(name in table for table in (self.values, self.spans, self.enums, self.sizes))

    def value(self, name: str, default: Any = None) -> Any:
        return self.values.get(name, default)

    def span(self, name: str) -> tuple[float, float] | None:
        return self.spans.get(name)

    def entries(self, name: str) -> tuple[str, ...]:
        return self.enums.get(name, ())

    def size(self, name: str) -> tuple[int, int, int]:
        return self.sizes.get(name, (0, 0, 1))


def test_a_full_node_map_reads_into_every_field() -> None:
    features = Features(
        values={
            "SensorWidth": 1936,
            "SensorHeight": 1216,
            "PixelFormat": "BayerRG8",
            "GevSCPSPacketSize": 8192,
            "GevIEEE1588": False,
            "GevSCPD": 0,
        },
        spans={"AcquisitionFrameRate": (1.0, 120.0), "ExposureTime": (20.0, 1e6), "Gain": (0.0, 24.0)},
        enums={
            "PixelFormat": ("Mono8", "BayerRG8"),
            "TriggerSelector": ("FrameStart",),
            "TriggerSource": ("Line1", "Software"),
            "TriggerActivation": ("RisingEdge", "FallingEdge"),
        },
        sizes={"Width": (16, 1936, 4), "Height": (16, 1216, 2)},
    )
    details = details_from_features(DEVICE, features)
    assert (details.device_id, details.vendor, details.model, details.serial, details.protocol) == (
        "dev-1",
        "Vendor",
        "Model 7",
        "S123",
        "CoaXPress",
    )
    assert details.sensor_px == (1936, 1216)
    assert (details.width_px, details.height_px) == ((16, 1936, 4), (16, 1216, 2))
    assert details.pixel_format == "BayerRG8" and details.pixel_formats == ("Mono8", "BayerRG8")
    assert (details.frame_rate_hz, details.exposure_us, details.gain) == ((1.0, 120.0), (20.0, 1e6), (0.0, 24.0))
    assert details.triggers == ("FrameStart",) and details.trigger_activations == ("RisingEdge", "FallingEdge")
    assert details.software_trigger is True
    assert details.ptp == "GevIEEE1588"  # the older name, as this camera has it
    assert details.packet_size_bytes == 8192 and details.packet_delay is True


def test_a_bare_node_map_says_what_is_missing() -> None:
    details = details_from_features(DEVICE, Features(enums={"TriggerSource": ("Line1",)}))
    assert details.sensor_px == (0, 0) and details.width_px == (0, 0, 1) and details.pixel_format == ""
    assert details.frame_rate_hz is None and details.exposure_us is None and details.gain is None
    assert details.software_trigger is False and details.ptp is None
    assert details.packet_size_bytes is None and details.packet_delay is False


def test_ptp_enable_is_preferred_when_a_camera_has_both() -> None:
    details = details_from_features(DEVICE, Features(values={"PtpEnable": False, "GevIEEE1588": False}))
    assert details.ptp == "PtpEnable"
