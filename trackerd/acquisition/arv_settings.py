"""Writing a rig file's settings to an Aravis camera, and telling a refused value from a silent camera.

A value the camera refuses (out of its range, not one of its entries, a feature it lacks) raises
:class:`~trackerd.acquisition.arv.CameraConfigError` naming the camera, the setting and what the
camera allows; any other Aravis error (a timeout, a transfer error, another controller) passes
through, for the caller to treat as a camera that does not answer. Settings trackerd can do
without (packet size negotiation, packet delay, PTP) become the session's notes.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from trackerd.acquisition.arv import CameraConfigError, describe_lookup, load_aravis
from trackerd.config.acquisition import RigAcquisition
from trackerd.config.models import CameraConfig

if TYPE_CHECKING:
    from trackerd.acquisition.arv import CameraSession

_REFUSED = {
    # GenICam: the value is outside the feature's range, not one of its entries, or not writable.
    "arv-gc-error-quark": {"out-of-range", "enum-entry-not-found", "read-only", "invalid-length"},
    # The device: no such feature, or the camera itself rejected the written value.
    "arv-device-error-quark": {
        "feature-not-found",
        "wrong-feature",
        "invalid-parameter",
        "protocol-error-invalid-parameter",
        "protocol-error-write-protect",
    },
}
"""Aravis errors that mean "the camera refuses this value", as opposed to "the camera did not
answer" (timeouts, transfer errors, another controller), which reopening may cure."""


def configure(session: CameraSession, cam: CameraConfig, rig: RigAcquisition, aravis: Any, glib: Any) -> None:
    camera = session.camera
    acq = cam.acquisition
    offered = list(camera.dup_available_pixel_formats_as_strings() or [])
    if offered and cam.pixel_format not in offered:
        raise CameraConfigError(
            f"camera '{cam.id}' ({describe_lookup(cam)}): pixel_format = {cam.pixel_format!r} is not offered"
            f" by the camera, which offers {', '.join(offered)}"
        )
    _setting(cam, "pixel_format", cam.pixel_format, lambda: camera.set_pixel_format_from_string(cam.pixel_format))
    wanted = (acq.offset_x_px, acq.offset_y_px, cam.width_px, cam.height_px)
    _setting(
        cam,
        "region (acquisition.offset_x_px, acquisition.offset_y_px, width_px, height_px)",
        wanted,
        lambda: camera.set_region(*wanted),
        lambda: _region_limits(camera),
    )
    region = camera.get_region()
    got = (region.x, region.y, region.width, region.height)
    if got != wanted:
        raise CameraConfigError(
            f"camera '{cam.id}' ({describe_lookup(cam)}) took region x={got[0]} y={got[1]} {got[2]}x{got[3]}"
            f" instead of x={wanted[0]} y={wanted[1]} {wanted[2]}x{wanted[3]}: it allows {_region_limits(camera)}"
        )
    if acq.exposure_us is not None:
        _setting(
            cam,
            "acquisition.exposure_us",
            acq.exposure_us,
            lambda: camera.set_exposure_time(acq.exposure_us),
            lambda: _limits(camera.get_exposure_time_bounds(), "us"),
        )
    if acq.gain_db is not None:
        _setting(
            cam,
            "acquisition.gain_db",
            acq.gain_db,
            lambda: camera.set_gain(acq.gain_db),
            lambda: _limits(camera.get_gain_bounds(), "dB"),
        )
    _configure_trigger(session, cam, rig, camera)
    if camera.is_gv_device():
        _configure_gige(session, cam, aravis, glib)
    if rig.ptp:
        _enable_ptp(session, camera, glib)


def _configure_trigger(session: CameraSession, cam: CameraConfig, rig: RigAcquisition, camera: Any) -> None:
    camera.clear_triggers()
    if rig.trigger == "free_running":
        if camera.is_frame_rate_available():
            _setting(
                cam,
                "frame_rate_hz",
                rig.frame_rate_hz,
                lambda: camera.set_frame_rate(rig.frame_rate_hz),
                lambda: _limits(camera.get_frame_rate_bounds(), "Hz"),
            )
        else:
            session.notes.append("frame rate is not settable; the camera runs at its own rate")
        return
    if rig.trigger == "software" and not camera.is_software_trigger_supported():
        raise CameraConfigError(
            f"camera '{cam.id}' ({describe_lookup(cam)}): trigger = 'software' is not supported by the camera"
        )
    source = "Software" if rig.trigger == "software" else rig.hardware_trigger_line
    sources = list(camera.dup_available_trigger_sources() or [])
    if sources and source not in sources:
        raise CameraConfigError(
            f"camera '{cam.id}' ({describe_lookup(cam)}) has no trigger source {source} (it has {', '.join(sources)})"
        )

    def options(feature: str) -> Callable[[], str]:
        return lambda: "one of " + ", ".join(camera.dup_available_enumerations_as_strings(feature) or ["none"])

    _setting(
        cam,
        "trigger_selector",
        rig.trigger_selector,
        lambda: camera.set_string("TriggerSelector", rig.trigger_selector),
        options("TriggerSelector"),
    )
    _setting(cam, f"trigger = {rig.trigger!r}: TriggerMode", "On", lambda: camera.set_string("TriggerMode", "On"))
    _setting(
        cam,
        "hardware_trigger_line" if rig.trigger == "hardware" else "trigger = 'software': TriggerSource",
        source,
        lambda: camera.set_string("TriggerSource", source),
        options("TriggerSource"),
    )
    if rig.trigger == "hardware":
        if camera.is_feature_available("TriggerActivation"):
            _setting(
                cam,
                "hardware_trigger_activation",
                rig.hardware_trigger_activation,
                lambda: camera.set_string("TriggerActivation", rig.hardware_trigger_activation),
                options("TriggerActivation"),
            )
        else:
            session.notes.append("no TriggerActivation feature; the camera's default edge applies")


def _configure_gige(session: CameraSession, cam: CameraConfig, aravis: Any, glib: Any) -> None:
    camera = session.camera
    acq = cam.acquisition
    address = camera.get_device().get_device_address()
    session.address = address.to_string() if address is not None else None
    if not acq.packet_socket:
        camera.gv_set_stream_options(aravis.GvStreamOption.PACKET_SOCKET_DISABLED)
    try:
        if acq.packet_size_bytes is not None:
            camera.gv_set_packet_size(acq.packet_size_bytes)
        else:
            camera.gv_auto_packet_size()
    except glib.Error as err:
        session.notes.append(f"packet size not set ({err.message}); using the camera's")
    if camera.is_feature_available("GevSCPD"):
        _setting(
            cam,
            "acquisition.packet_delay_ns",
            acq.packet_delay_ns,
            lambda: camera.gv_set_packet_delay(acq.packet_delay_ns),
        )
    elif acq.packet_delay_ns:
        session.notes.append("no packet delay feature (GevSCPD); packet_delay_ns ignored")


def refused(err: Any) -> bool:
    """Whether an Aravis error (a ``GLib.Error``) says the camera refuses a value or lacks a feature."""
    load_aravis()
    nicks = _REFUSED.get(str(err.domain))
    if not nicks:
        return False
    from gi.repository import Aravis

    enum = Aravis.GcError if err.domain == "arv-gc-error-quark" else Aravis.DeviceError
    value = enum.__enum_values__.get(err.code)
    return value is not None and value.value_nick in nicks


def _setting(
    cam: CameraConfig, name: str, value: object, apply: Callable[[], None], allowed: Callable[[], str] | None = None
) -> None:
    """Write one setting of the rig file; a value the camera refuses raises CameraConfigError naming the
    camera, the setting and, where the camera tells, what it allows. Other Aravis errors pass through."""
    _, glib = load_aravis()
    try:
        apply()
    except glib.Error as err:
        if not refused(err):
            raise
        limits = None
        if allowed is not None:
            try:
                limits = allowed()
            except glib.Error:
                limits = None  # the camera does not say; the Aravis message below still does
        which = f", which allows {limits}" if limits else ""
        shown = f"{value:g}" if isinstance(value, float) else repr(value) if isinstance(value, str) else value
        raise CameraConfigError(
            f"camera '{cam.id}' ({describe_lookup(cam)}): {name} = {shown} is refused by the camera{which}"
            f" ({err.message})"
        ) from err


def _limits(bounds: Any, unit: str) -> str:
    """``(min, max)`` from Aravis (a tuple or a struct with min and max) as text."""
    low, high = (bounds.min, bounds.max) if hasattr(bounds, "min") else bounds
    return f"{low:g} to {high:g} {unit}"


def _region_limits(camera: Any) -> str:
    """What region the camera allows, as text: sizes with their steps, then offsets."""

    def span(bounds: Any) -> str:
        low, high = (bounds.min, bounds.max) if hasattr(bounds, "min") else bounds
        return f"{low:g}-{high:g}"

    return (
        f"width {span(camera.get_width_bounds())} (steps of {camera.get_width_increment()}),"
        f" height {span(camera.get_height_bounds())} (steps of {camera.get_height_increment()}),"
        f" offset x {span(camera.get_x_offset_bounds())}, offset y {span(camera.get_y_offset_bounds())} px"
    )


def _enable_ptp(session: CameraSession, camera: Any, glib: Any) -> None:
    for feature in ("PtpEnable", "GevIEEE1588"):
        if camera.is_feature_available(feature):
            try:
                camera.set_boolean(feature, True)
            except glib.Error as err:
                session.notes.append(f"PTP not enabled ({feature}: {err.message})")
                return
            session.ptp_feature = feature
            return
    session.notes.append("no PTP support (PtpEnable / GevIEEE1588); pairing uses host time")
