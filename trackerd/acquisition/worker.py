"""One thread per camera: pop a buffer, turn it into a frame, push the buffer back; notice loss; reconnect.

The loop is kept lean: every blocking call has a timeout of at most
``POLL_S`` and the loop checks the stop event on every turn, so stopping
takes one turn. Per frame it does one copy (the payload into the frame's own
array), a few Aravis getters and a hand-off to the pairing stage.

A camera is *lost* when Aravis reports ``control-lost`` (heartbeat failure),
when no frame arrives within ``loss_timeout_ms``, or when a software trigger
cannot be delivered. Its connection is then handed to the *releaser* to be
dropped (Aravis may block there for seconds on a dead camera) and the thread
probes the camera's last known address with one GVCP discovery packet per
attempt, backing off from ``reconnect_min_backoff_ms`` to
``reconnect_max_backoff_ms``. When the camera answers, a fresh Aravis camera
object is opened and configured; the frames it delivers start a new epoch.

A camera that is not there at start (with the source's ``wait_for_cameras``)
is tried on the same backoff as after a loss. The states, the back-off and
which of these events are logged are :class:`~trackerd.acquisition.connection.ConnectionTracker`'s;
turning a buffer into an image is :func:`~trackerd.acquisition.decode.decode_grab`'s;
the counters the status shows are :class:`~trackerd.acquisition.figures.CameraFigures`'.
This module wires them to the camera's session, its trigger thread and the sink.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any, Protocol

from trackerd.acquisition.arv import CameraConfigError, describe_lookup
from trackerd.acquisition.clock import FrameIdUnwrapper
from trackerd.acquisition.connection import ConnectionTracker, Notice
from trackerd.acquisition.decode import decode_grab
from trackerd.acquisition.figures import CameraFigures
from trackerd.acquisition.firing import TriggerThread
from trackerd.acquisition.frame import Frame
from trackerd.acquisition.gvcp import probe
from trackerd.acquisition.pairing import Arrival
from trackerd.acquisition.session import Session, open_session, resolve_device_id
from trackerd.acquisition.status import CameraStatus
from trackerd.acquisition.trigger import TickSchedule, TriggerGate
from trackerd.config.acquisition import RigAcquisition
from trackerd.config.models import CameraConfig
from trackerd.errors import CameraError

log = logging.getLogger(__name__)

POLL_S = 0.1
"""Longest single wait inside the loop (buffer pop, stop check, probe)."""


class FrameSink(Protocol):
    """Where a worker sends its frames and news of its camera (the pair source)."""

    def deliver(self, arrival: Arrival) -> None: ...
    def camera_lost(self, camera_index: int) -> None: ...
    def camera_back(self, camera_index: int) -> None: ...
    def abandon(self, session: Session) -> threading.Thread:
        """Release a connection on another thread; the thread ends when it is released."""
        ...

    def observe_clock(self, camera_index: int, device_ns: int, host_ns: int) -> int:
        """Record a frame's timestamps; returns its estimated capture time on the host clock."""
        ...

    def worker_failed(self, camera_index: int) -> None: ...


OpenHook = Callable[[str, Any], None]
"""Called as ``hook(camera_id, aravis_camera)`` after a camera is opened and configured."""


class EarlierConnections:
    """What of a camera's earlier connections may still talk to it: release and trigger threads.

    Aravis retries a GVCP command to a camera that stopped answering for about 2.5 s; a camera
    that comes back within that time would otherwise receive the old connection's last commands
    (a trigger, a release of control) after the new connection has configured it.
    """

    def __init__(self) -> None:
        self._releases: list[threading.Thread] = []
        self._triggers: list[TriggerThread] = []

    @property
    def triggers(self) -> list[TriggerThread]:
        return list(self._triggers)

    def releasing(self, thread: threading.Thread) -> None:
        self._releases.append(thread)

    def retire(self, trigger: TriggerThread | None) -> None:
        """Stop a connection's trigger thread; keep it to be joined (it may be hung)."""
        if trigger is not None:
            trigger.stop()
            self._triggers.append(trigger)
        self._triggers = [t for t in self._triggers if t.alive]

    def quiet(self) -> bool:
        """Nothing of an earlier connection can still talk to the camera."""
        self._releases = [t for t in self._releases if t.is_alive()]
        self._triggers = [t for t in self._triggers if t.alive]
        return not self._releases and not self._triggers


class CameraWorker:
    """Acquisition for one camera of the rig, on its own thread: wires its session, trigger thread,
    connection tracker and figures to the sink."""

    def __init__(
        self,
        index: int,
        cam: CameraConfig,
        rig: RigAcquisition,
        sink: FrameSink,
        schedule: TickSchedule | None,
        gate: TriggerGate | None = None,
        on_open: OpenHook | None = None,
    ) -> None:
        self.index = index
        self.cam = cam
        self.rig = rig
        self.sink = sink
        self.on_open = on_open
        self.schedule = schedule
        self.gate = gate
        self.crash: str | None = None
        """Set when the acquisition thread died of an unexpected exception (a bug)."""
        self.last_pool: list[Any] = []
        """The buffer pool of the last connection closed gracefully (for checking none is held)."""
        self.last_session: Session | None = None
        """The last connection closed gracefully (``buffers_released()`` says whether every buffer came back)."""
        self.connection = ConnectionTracker(
            cam.id,
            loss_timeout_ms=rig.loss_timeout_ms,
            min_backoff_ms=rig.reconnect_min_backoff_ms,
            max_backoff_ms=rig.reconnect_max_backoff_ms,
            clock_ns=time.monotonic_ns,
        )
        self.figures = CameraFigures(rig.ptp_poll_interval_ms)
        self._earlier = EarlierConnections()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._session: Session | None = None
        self._trigger: TriggerThread | None = None
        self._device_id: str | None = None
        self._epoch = -1
        self._unwrap = FrameIdUnwrapper()

    # ------------------------------------------------------------------ lifecycle

    def open(self, wait: bool = False) -> bool:
        """The first connection attempt, on the calling thread (start-up errors surface here).

        Returns True when the camera is open. A camera that is not there (not found, not
        answering, not opening) raises CameraError; with ``wait`` it returns False instead, and
        the thread, once started, keeps trying on the reconnection backoff. A configuration the
        camera refuses raises CameraConfigError either way: trying again cannot fix it.
        """
        self.connection.begin()
        if not wait:
            self._device_id = resolve_device_id(self.cam)
            self._connect(self._device_id)
            return True
        return self._try_connect(config_errors_raise=True)

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name=f"camera-{self.cam.id}", daemon=True)
        self._thread.start()
        if self._trigger is not None:
            self._trigger.start()

    def request_stop(self) -> None:
        self._stop.set()

    def join(self, timeout_s: float) -> bool:
        """Join this camera's threads; True if all ended within ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        done = True
        if self._thread is not None:
            self._thread.join(max(timeout_s, 0.0))
            done = not self._thread.is_alive()
        for trigger in [*self._earlier.triggers, *([self._trigger] if self._trigger else [])]:
            done = trigger.join(deadline - time.monotonic()) and done
        return done

    @property
    def alive(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    @property
    def holds_camera(self) -> bool:
        """A connection is open: stopping must wait for its release."""
        return self._session is not None

    def close(self) -> None:
        """Release the camera of a worker whose thread never started (start-up failed elsewhere)."""
        self._shutdown()

    def status(self, clock_offset_ns: int | None = None) -> CameraStatus:
        lookup = self._device_id or describe_lookup(self.cam)
        return self.figures.status(self.cam.id, lookup, self.connection.figures(), clock_offset_ns)

    # ------------------------------------------------------------------ the thread

    def _run(self) -> None:
        try:
            self._loop()
        except Exception as err:  # a bug: never silent; the source raises it to its consumer
            log.exception("camera %s: acquisition thread failed", self.cam.id)
            self.crash = f"camera '{self.cam.id}': acquisition thread failed: {err!r}"
            self.connection.failed(self.crash)
        finally:
            self._shutdown()
            if self.crash is not None:
                self.sink.worker_failed(self.index)

    def _loop(self) -> None:
        while not self._stop.is_set():
            if self._session is None:
                if not self._try_connect():
                    self._stop.wait(self.connection.next_backoff_s())
                continue
            self._turn(self._session)

    def _turn(self, session: Session) -> None:
        """One pass: wait for a buffer, handle it, check the camera's health."""
        buffer = session.pop(int(POLL_S * 1e6))
        if buffer is not None:
            try:
                self._handle(session, buffer)
            finally:
                session.push(buffer)
        if session.control_lost.is_set():
            self._lose("Aravis reported control lost (no heartbeat answer)")
        elif self._trigger is not None and self._trigger.failure is not None:
            self._lose(self._trigger.failure)
        elif self.connection.overdue():
            self._lose(f"no frame for {self.rig.loss_timeout_ms:g} ms")
        else:
            self.figures.poll(session, time.monotonic_ns())

    def _handle(self, session: Session, buffer: Any) -> None:
        grab = session.read(buffer)
        frame_id = self._unwrap(grab.frame_id) if grab.frame_id is not None else None
        trigger = self._trigger
        tick = trigger.ticks.frame(frame_id) if (trigger is not None and frame_id is not None) else None
        image = decode_grab(grab, self.cam.pixel_format, self.cam.width_px, self.cam.height_px)
        if isinstance(image, str):
            self.figures.failure(image)
            return
        if trigger is not None and tick is None:
            self.figures.failure("no-trigger")
            return
        device_ns = grab.device_timestamp_ns
        host_ns = grab.host_timestamp_ns
        frame = Frame(self.cam.id, int(frame_id or 0), device_ns, host_ns, grab.pixel_format, image)
        capture_ns = self.sink.observe_clock(self.index, device_ns, host_ns)
        if device_ns == 0 and tick is not None and trigger is not None:
            # No camera clock (pylon's emulated cameras): the trigger's send time is a better capture
            # time than the arrival, which adds each camera's own delivery delay and jitter.
            capture_ns = trigger.sent_ns(tick) or capture_ns
        self._tell(self.connection.frame())
        self.figures.frame(time.monotonic_ns())
        self.sink.deliver(Arrival(self.index, frame, capture_ns, self._epoch, tick))

    # ------------------------------------------------------------------ connection changes

    def _connect(self, device_id: str) -> None:
        session = open_session(self.cam, self.rig, device_id)
        if self.on_open is not None:
            self.on_open(self.cam.id, session.camera)
        self._adopt(session)

    def _adopt(self, session: Session) -> None:
        now = time.monotonic_ns()
        self._session = session
        self._epoch += 1
        self._unwrap = FrameIdUnwrapper()
        if self.schedule is not None and self.gate is not None:
            # The first trigger waits five periods (at least 0.1 s) after acquisition starts.
            settle_ns = max(5 * self.schedule.period_ns, 100_000_000)
            self._trigger = TriggerThread(
                self.index,
                self.cam.id,
                self.schedule,
                self.gate,
                session.fire,
                self.rig.max_outstanding_triggers,
                settle_ns,
            )
            if self._thread is not None:  # reconnecting; at start-up, start() starts it
                self._trigger.start()
        self.figures.opened(session, now)
        self.connection.connected()
        self.sink.camera_back(self.index)

    def _lose(self, reason: str) -> None:
        session = self._session
        self._session = None
        trigger = self._trigger
        self._earlier.retire(trigger)
        self._trigger = None
        detail = f" (triggers unanswered: {trigger.ticks.outstanding})" if trigger is not None else ""
        self._tell(self.connection.lost(reason, detail))
        self.figures.closed()
        self.sink.camera_lost(self.index)
        if session is not None:
            self._earlier.releasing(self.sink.abandon(session))

    def _try_connect(self, config_errors_raise: bool = False) -> bool:
        """One attempt: probe the camera, and open it if it answers. True when open.

        The first connection (start-up) and reconnections after a loss differ only in the
        state shown meanwhile (``connecting`` / ``lost``) and in what is counted. A refused
        configuration is logged as an error and tried again (the camera may be replaced), or
        raised with ``config_errors_raise`` (start-up, where the daemon exits with status 2).
        """
        first = self.connection.never_connected
        known = self.figures.address or (self.cam.address if first else None)
        address = known.split(":")[0] if known else None
        if address is not None:
            answer = probe(address, POLL_S * 2)
            if answer is None:
                # After a loss, silence is the loss going on: last_error keeps the loss's reason.
                return self._unavailable(f"no answer from {address} (GVCP discovery)", record=first)
            if self.cam.serial and answer.serial and answer.serial != self.cam.serial:
                return self._unavailable(f"{address} answers as serial {answer.serial}, not {self.cam.serial}")
        if not self._earlier.quiet():
            return False
        self.connection.attempting()
        try:
            if address is None and self._device_id is None:
                self._device_id = resolve_device_id(self.cam)  # by serial: Aravis's discovery, about a second
            self._connect(address or self._device_id)  # type: ignore[arg-type]
        except CameraConfigError as err:
            if config_errors_raise:
                raise
            return self._unavailable(str(err), level=logging.ERROR)
        except CameraError as err:
            return self._unavailable(str(err))
        return True

    def _unavailable(self, reason: str, level: int = logging.INFO, record: bool = True) -> bool:
        """A failed attempt (see ConnectionTracker.unavailable). Returns False (the attempt's outcome)."""
        self._tell(self.connection.unavailable(reason, level, record))
        return False

    def _shutdown(self) -> None:
        session = self._session
        self._session = None
        self._earlier.retire(self._trigger)
        self._trigger = None
        if session is not None:
            recent = self.connection.ns_since_frame() < 3 * 1e9 / self.rig.frame_rate_hz + 1e8
            address = session.address.split(":")[0] if session.address else None
            if recent or address is None or probe(address, 0.05) is not None:
                self.figures.closed(session.counters())
                session.close()
                self.last_pool = session.buffers
                self.last_session = session
            else:
                self.sink.abandon(session)
        self.connection.stopped()

    @staticmethod
    def _tell(notice: Notice | None) -> None:
        if notice is not None:
            log.log(notice.level, notice.message)
