"""Aravis, through PyGObject: loading it, finding a camera, and one configured connection to it.

A :class:`CameraSession` is one connection: the ``ArvCamera``, its stream and a
pool of buffers allocated once and recycled for every frame. It is built by
:func:`open_session` and closed exactly once, either gracefully
(:meth:`CameraSession.close`, acquisition stopped, buffers drained back) or, for
a camera that stopped answering, by dropping it (:meth:`CameraSession.abandon`),
which can block for several seconds inside Aravis (its GVCP retries) and is
therefore done off the acquisition thread.

Aravis emits ``control-lost`` from its own heartbeat thread; the handler here
only sets an event that the acquisition thread polls.

Errors: a camera that is not there, does not answer or cannot be opened raises
:class:`~trackerd.errors.CameraError` (reopening it later may work); a value of
the rig file that the camera refuses (out of its range, not one of its options,
a feature it lacks) raises :class:`CameraConfigError`, which is also a
:class:`~trackerd.errors.ConfigError` (exit status 2): reopening cannot fix it. Writing the rig
file's settings, and telling the two kinds of error apart, is :mod:`trackerd.acquisition.arv_settings`.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import logging
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from trackerd.acquisition.clock import realtime_to_monotonic_ns
from trackerd.acquisition.session import Grab
from trackerd.config.acquisition import RigAcquisition
from trackerd.config.models import CameraConfig
from trackerd.errors import CameraError, ConfigError
from trackerd.pixelformat import PFNC_NAMES

log = logging.getLogger(__name__)

ARAVIS_VERSION = "0.8"

STREAM_COUNTERS = (
    "n_completed_buffers",
    "n_failures",
    "n_underruns",
    "n_timeouts",
    "n_aborted",
    "n_missing_frames",
    "n_size_mismatch_errors",
    "n_received_packets",
    "n_missing_packets",
    "n_error_packets",
    "n_ignored_packets",
    "n_resend_requests",
    "n_resent_packets",
    "n_duplicated_packets",
)
"""Aravis stream statistics read into the status, where the stream has them."""

PTP_LOCKED_STATES = ("Master", "Slave")
_PTP_REARM_STATES = ("Faulty", "Disabled")


class CameraConfigError(CameraError, ConfigError):
    """A camera's configuration that reopening the camera cannot fix: a value it refuses, an
    option it lacks, or no way to find it in the rig file. Exit status 2, like any ConfigError."""


def load_aravis() -> tuple[Any, Any]:
    """``(Aravis, GLib)`` from PyGObject, pinned to Aravis 0.8; CameraError saying what to install."""
    try:
        import gi

        gi.require_version("Aravis", ARAVIS_VERSION)
        from gi.repository import Aravis, GLib
    except (ImportError, ValueError) as err:
        raise CameraError(
            f"Aravis {ARAVIS_VERSION} is not available through PyGObject ({err}); on Debian install"
            " python3-gi and gir1.2-aravis-0.8"
        ) from err
    return Aravis, GLib


@functools.cache
def _libaravis() -> ctypes.CDLL:
    lib = ctypes.CDLL(ctypes.util.find_library(f"aravis-{ARAVIS_VERSION}") or "libaravis-0.8.so.0")
    lib.arv_buffer_get_data.restype = ctypes.c_void_p
    lib.arv_buffer_get_data.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_size_t)]
    return lib


def image_bytes(buffer: Any, nbytes: int, allocated: int) -> bytes:
    """A copy of the first ``nbytes`` of a finished buffer's image.

    Aravis's in-process Fake stream never records how much it wrote, so its
    buffers report no image data; for them the payload is read directly, within
    the ``allocated`` size of the buffer.
    """
    data: bytes = buffer.get_image_data()  # PyGObject's bytes (GBytes' data), untyped for mypy
    if data or nbytes > allocated:
        return data
    pointer = _libaravis().arv_buffer_get_data(hash(buffer), None)  # hash(): the C pointer
    return ctypes.string_at(pointer, nbytes) if pointer else b""


def aravis_missing_reason() -> str | None:
    """Why Aravis cannot be used here, or None if it can (for skipping tests and commands)."""
    try:
        load_aravis()
    except CameraError as err:
        return str(err)
    return None


def describe_lookup(cam: CameraConfig) -> str:
    """How the rig file says to find a camera, for messages: ``address 10.0.0.2``."""
    if cam.backend != "aravis":
        return f"{cam.backend} {_lookup(cam)}"
    return _lookup(cam)


def _lookup(cam: CameraConfig) -> str:
    if cam.device_id:
        return f"device id {cam.device_id}"
    if cam.address:
        return f"address {cam.address}"
    if cam.serial:
        return f"serial {cam.serial}"
    return "no serial, address or device_id"


def require_a_way_to_find(cam: CameraConfig) -> None:
    """CameraConfigError if the rig file gives no key to find the camera by (its backend's keys).

    A rig without them is valid for replay and simulation, which open no camera; every backend's
    lookup starts here, and a live source checks every camera before it opens any (waiting for
    the cameras cannot supply a missing key)."""
    keys = ("serial", "address", "device_id") if cam.backend == "aravis" else ("serial", "device_id")
    if any(getattr(cam, key) for key in keys):
        return
    backend = "" if cam.backend == "aravis" else f" (backend {cam.backend})"
    raise CameraConfigError(f"camera '{cam.id}'{backend} has no {', '.join(keys[:-1])} or {keys[-1]} in the rig file")


def resolve_device_id(cam: CameraConfig) -> str:
    """The id Aravis opens the camera by: device id or address as given, else found by serial.

    Looking up a serial runs Aravis's discovery (about a second).
    """
    require_a_way_to_find(cam)
    if cam.device_id:
        return cam.device_id
    if cam.address:
        return cam.address
    aravis, _ = load_aravis()
    aravis.update_device_list()
    for index in range(aravis.get_n_devices()):
        if aravis.get_device_serial_nbr(index) == cam.serial:
            device_id: str = aravis.get_device_id(index)  # a str from PyGObject, untyped for mypy
            return device_id
    raise CameraError(
        f"camera '{cam.id}' (serial {cam.serial}) not found; `trackerd cameras` lists the cameras Aravis sees"
    )


@dataclass
class CameraSession:
    """One open, configured, acquiring connection to a camera."""

    camera_id: str
    camera: Any
    stream: Any
    buffers: list[Any]
    """The buffer pool: every Aravis buffer this session allocated, whether queued or not."""
    address: str | None
    """IPv4 address of a GigE Vision camera (for reconnect probes), None otherwise."""
    software_trigger: bool
    control_lost: threading.Event = field(default_factory=threading.Event)
    notes: list[str] = field(default_factory=list)
    ptp_feature: str | None = None
    """``PtpEnable`` or ``GevIEEE1588`` when PTP was enabled on this camera."""
    payload_bytes: int = 0
    """Size of each buffer of the pool."""
    _handler: int | None = None

    def pop(self, timeout_us: int) -> Any | None:
        """The next finished buffer, or None after ``timeout_us`` (the GIL is released meanwhile)."""
        return self.stream.timeout_pop_buffer(max(int(timeout_us), 1))

    def push(self, buffer: Any) -> None:
        """Give a buffer back to the stream to be filled again."""
        self.stream.push_buffer(buffer)

    def read(self, buffer: Any) -> Grab:
        """What a popped buffer holds (its image is copied only when asked for)."""
        aravis, _ = load_aravis()
        status = buffer.get_status()
        raw_id = buffer.get_frame_id()
        failure = None if status == aravis.BufferStatus.SUCCESS else str(status.value_nick)
        code = buffer.get_image_pixel_format() if failure is None else 0
        system_ns = int(buffer.get_system_timestamp()) if failure is None else 0
        # Aravis's completion time, taken on its stream thread (a busy interpreter does not delay it).
        host_ns = realtime_to_monotonic_ns(system_ns) if system_ns else time.monotonic_ns()
        payload = self.payload_bytes
        return Grab(
            failure=failure,
            frame_id=int(raw_id) if raw_id else None,
            pixel_format=PFNC_NAMES.get(code, f"0x{code:08x}"),
            width_px=buffer.get_image_width() if failure is None else 0,
            height_px=buffer.get_image_height() if failure is None else 0,
            device_timestamp_ns=int(buffer.get_timestamp()) if failure is None else 0,
            host_timestamp_ns=host_ns,
            pixels=lambda nbytes: image_bytes(buffer, nbytes, payload),
        )

    def fire(self) -> None:
        """Execute TriggerSoftware (one GVCP command); CameraError if the camera does not answer."""
        _, glib = load_aravis()
        try:
            self.camera.software_trigger()
        except glib.Error as err:
            raise CameraError(f"camera '{self.camera_id}': software trigger failed: {err.message}") from err

    def counters(self) -> dict[str, int]:
        """The Aravis stream statistics this stream offers."""
        values: dict[str, int] = {}
        names = {self.stream.get_info_name(i) for i in range(self.stream.get_n_infos())}
        for name in STREAM_COUNTERS:
            if name in names:
                values[name] = int(self.stream.get_info_uint64_by_name(name))
        return values

    def ptp_state(self) -> str | None:
        """The camera's IEEE 1588 state (re-armed if Faulty or Disabled), None without PTP."""
        if self.ptp_feature is None:
            return None
        _, glib = load_aravis()
        device = self.camera.get_device()
        try:
            if self.ptp_feature == "PtpEnable":
                if device.is_feature_available("PtpDataSetLatch"):
                    device.execute_command("PtpDataSetLatch")
                state = device.get_string_feature_value("PtpStatus")
            else:
                state = device.get_string_feature_value("GevIEEE1588Status")
            if state in _PTP_REARM_STATES:
                device.set_boolean_feature_value(self.ptp_feature, False)
                device.set_boolean_feature_value(self.ptp_feature, True)
            return str(state)
        except glib.Error as err:
            return f"unreadable ({err.message})"

    def close(self) -> int:
        """Stop acquisition and drain the stream; returns how many buffers came back from it.

        The stream and camera are released afterwards; every buffer is then held by
        ``buffers`` alone (each one's GObject reference count is 1).
        """
        _, glib = load_aravis()
        self._disconnect()
        try:
            self.camera.stop_acquisition()
        except glib.Error as err:
            self.notes.append(f"stop_acquisition: {err.message}")
        returned = 0
        while self.stream.try_pop_buffer() is not None:
            returned += 1
        self.stream = None
        self.camera = None
        return returned

    def leave_control(self) -> None:
        """Give up control of a GigE Vision camera that still answers (no-op for other kinds)."""
        if self.camera is None:
            return
        device = self.camera.get_device()
        leave = getattr(device, "leave_control", None)
        if leave is not None:
            try:
                leave()
            except Exception:  # best effort: the heartbeat expiring does the same, later
                log.debug("camera %s: leave_control failed", self.camera_id, exc_info=True)

    def abandon(self) -> None:
        """Drop a camera that stopped answering. Blocks while Aravis gives up on it (seconds)."""
        self._disconnect()
        self.stream = None
        self.camera = None

    def buffers_released(self) -> bool:
        """True once nothing but this pool references any of its buffers."""
        return all(buffer.__grefcount__ == 1 for buffer in self.buffers)

    def _disconnect(self) -> None:
        if self._handler is not None and self.camera is not None:
            self.camera.get_device().disconnect(self._handler)
            self._handler = None


def held_hint(message: str) -> str:
    """What to check when a camera that answered refuses to be written: a GigE Vision camera takes one
    controller, and another's writes time out or are denied (a second daemon on the same rig logged only
    Aravis's "write_register timeout" at every retry)."""
    lowered = message.lower()
    if "write_register timeout" in lowered or any(f"access{c}denied" in lowered for c in " _-"):
        return " (a camera takes one controller: is another program, a trackerd daemon or a viewer, holding it?)"
    return ""


def open_session(cam: CameraConfig, rig: RigAcquisition, device_id: str) -> CameraSession:
    """Open ``device_id``, configure it from the rig file, allocate its buffers and start it.

    Settings the camera lacks but trackerd can do without (packet size
    negotiation, packet delay, PTP) become notes; a setting that matters
    (pixel format, region, trigger, exposure or gain asked for) raises
    CameraError naming the camera and the value.
    """
    aravis, glib = load_aravis()
    try:
        camera = aravis.Camera.new(device_id)
    except glib.Error as err:
        raise CameraError(f"camera '{cam.id}' ({describe_lookup(cam)}): cannot open: {err.message}") from err
    session = CameraSession(cam.id, camera, None, [], None, rig.trigger == "software")
    # Refuse out-of-range values (a region beyond the sensor, say) instead of writing them.
    camera.set_range_check_policy(aravis.RangeCheckPolicy.ENABLE)
    # Here, not at the top: arv_settings imports this module.
    from trackerd.acquisition.arv_settings import configure

    try:
        configure(session, cam, rig, aravis, glib)
        _create_stream(session, cam, aravis, glib)
        session._handler = camera.get_device().connect("control-lost", _on_control_lost, session.control_lost)
        camera.start_acquisition()
    except glib.Error as err:
        session.abandon()
        raise CameraError(f"camera '{cam.id}' ({describe_lookup(cam)}): {err.message}{held_hint(err.message)}") from err
    except CameraError:
        # The camera answered and refused a setting: hand its control back now. Dropping our
        # reference is not enough while the exception's traceback keeps the camera object alive,
        # and until the heartbeat expires (seconds) the camera would refuse the next controller
        # (a reload that reopens the cameras with the previous settings).
        session.leave_control()
        session.abandon()
        raise
    return session


def _on_control_lost(_device: Any, event: threading.Event) -> None:
    # Runs on Aravis's heartbeat thread: record the fact, nothing else.
    event.set()


def _create_stream(session: CameraSession, cam: CameraConfig, aravis: Any, glib: Any) -> None:
    camera = session.camera
    acq = cam.acquisition
    stream = camera.create_stream(None, None)
    if stream is None:
        raise CameraError(f"camera '{cam.id}': Aravis could not create a stream")
    session.stream = stream
    if isinstance(stream, aravis.GvStream):
        stream.set_property(
            "packet-resend",
            aravis.GvStreamPacketResend.ALWAYS if acq.packet_resend else aravis.GvStreamPacketResend.NEVER,
        )
        stream.set_property("packet-timeout", acq.packet_timeout_us)
        stream.set_property("initial-packet-timeout", acq.initial_packet_timeout_us)
        stream.set_property("frame-retention", acq.frame_retention_us)
        stream.set_property("packet-request-ratio", acq.packet_request_ratio)
        if acq.socket_buffer_bytes is None:
            stream.set_property("socket-buffer", aravis.GvStreamSocketBuffer.AUTO)
        else:
            stream.set_property("socket-buffer", aravis.GvStreamSocketBuffer.FIXED)
            stream.set_property("socket-buffer-size", acq.socket_buffer_bytes)
    payload = camera.get_payload()
    session.payload_bytes = payload
    session.buffers = [aravis.Buffer.new_allocate(payload) for _ in range(acq.buffer_count)]
    for buffer in session.buffers:
        stream.push_buffer(buffer)
