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

A camera's state follows its connection: ``connecting`` until it is first
opened, ``connected`` from then until its first complete frame, ``streaming``
from that frame on, ``lost`` and ``reconnecting`` while it is away, then
``connected`` again. A camera that is not there at start (with the source's
``wait_for_cameras``) is tried on the same backoff as after a loss. Failed
attempts are logged at info when their reason changes and every
``REMINDER_S`` otherwise, so a long wait leaves a trail without flooding the
journal; the first frame after a loss is logged with how long the camera was away.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np

from trackerd.acquisition.arv import CameraConfigError, describe_lookup
from trackerd.acquisition.clock import FrameIdUnwrapper
from trackerd.acquisition.firing import TriggerThread
from trackerd.acquisition.frame import Frame
from trackerd.acquisition.gvcp import probe
from trackerd.acquisition.meters import RateMeter
from trackerd.acquisition.pairing import Arrival
from trackerd.acquisition.session import Session, open_session, resolve_device_id
from trackerd.acquisition.status import CameraState, CameraStatus
from trackerd.acquisition.trigger import TickMap, TickSchedule, TriggerGate
from trackerd.config.acquisition import RigAcquisition
from trackerd.config.models import CameraConfig
from trackerd.errors import CameraError
from trackerd.pixelformat import frame_shape

log = logging.getLogger(__name__)

POLL_S = 0.1
"""Longest single wait inside the loop (buffer pop, stop check, probe)."""
FIRST_FRAME_GRACE_NS = 1_000_000_000
"""Extra time a camera gets for its first frame after (re)connecting: some cameras (Aravis's
simulated one among them) take a frame period or a tenth of a second to start streaming."""
COUNTER_PERIOD_NS = 1_000_000_000
REMINDER_S = 30.0
"""While a camera stays unavailable for the same reason, how often that is logged again."""


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


class CameraWorker:
    """Acquisition for one camera of the rig, on its own thread."""

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
        self._stop = threading.Event()
        self.schedule = schedule
        self.gate = gate
        self._trigger: TriggerThread | None = None
        self._old_triggers: list[TriggerThread] = []
        self._releases: list[threading.Thread] = []
        self.crash: str | None = None
        """Set when the acquisition thread died of an unexpected exception (a bug)."""
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self._session: Session | None = None
        self._device_id: str | None = None
        self._address: str | None = None
        self._epoch = -1
        self._state: CameraState = "connecting"
        self._frames = 0
        self._failed: Counter[str] = Counter()
        self._stream_totals: Counter[str] = Counter()
        self._stream_current: dict[str, int] = {}
        self._losses = 0
        self._reconnects = 0
        self._lost_since: int | None = None
        self._connections = 0
        self._awaiting_first_frame = False
        self._outage_ns: int | None = None
        """Since when the camera has not been streaming (start-up or loss), for the log."""
        self._attempts = 0
        """Failed connection attempts in the current outage."""
        self._logged_reason: str | None = None
        self._next_reminder_ns = 0
        self._last_error: str | None = None
        self._ptp_state: str | None = None
        self._notes: tuple[str, ...] = ()
        self._rate = RateMeter()
        self.last_pool: list[Any] = []
        """The buffer pool of the last connection closed gracefully (for checking none is held)."""
        self.last_session: Session | None = None
        """The last connection closed gracefully (``buffers_released()`` says whether every buffer came back)."""
        self._unwrap = FrameIdUnwrapper()
        self._ticks: TickMap | None = None
        self._last_frame_ns = 0
        self._grace_ns = 0
        self._next_housekeeping_ns = 0
        self._next_ptp_ns = 0

    # ------------------------------------------------------------------ lifecycle

    def open(self, wait: bool = False) -> bool:
        """The first connection attempt, on the calling thread (start-up errors surface here).

        Returns True when the camera is open. A camera that is not there (not found, not
        answering, not opening) raises CameraError; with ``wait`` it returns False instead, and
        the thread, once started, keeps trying on the reconnection backoff. A configuration the
        camera refuses raises CameraConfigError either way: trying again cannot fix it.
        """
        self._outage_ns = time.monotonic_ns()
        if not wait:
            self._device_id = _resolve(self.cam)
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
        for trigger in self._all_triggers():
            done = trigger.join(deadline - time.monotonic()) and done
        return done

    def _all_triggers(self) -> list[TriggerThread]:
        return [*self._old_triggers, *([self._trigger] if self._trigger else [])]

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

    # ------------------------------------------------------------------ status

    def status(self, clock_offset_ns: int | None = None) -> CameraStatus:
        now = time.monotonic_ns()
        with self._lock:
            stream = Counter(self._stream_totals)
            stream.update(self._stream_current)
            return CameraStatus(
                camera_id=self.cam.id,
                state=self._state,
                device=self._address or self._device_id or describe_lookup(self.cam),
                frames=self._frames,
                frame_rate_hz=round(self._rate.rate_hz(now), 3),
                failed_buffers=dict(self._failed),
                stream=dict(stream),
                losses=self._losses,
                reconnects=self._reconnects,
                lost_since_ns=self._lost_since,
                last_error=self._last_error,
                ptp_state=self._ptp_state,
                clock_offset_ns=clock_offset_ns,
                notes=self._notes,
            )

    @property
    def ptp_state(self) -> str | None:
        return self._ptp_state

    # ------------------------------------------------------------------ the thread

    def _run(self) -> None:
        try:
            self._loop()
        except Exception as err:  # a bug: never silent; the source raises it to its consumer
            log.exception("camera %s: acquisition thread failed", self.cam.id)
            self.crash = f"camera '{self.cam.id}': acquisition thread failed: {err!r}"
            with self._lock:
                self._last_error = self.crash
        finally:
            self._shutdown()
            if self.crash is not None:
                self.sink.worker_failed(self.index)

    def _loop(self) -> None:
        backoff_s = self.rig.reconnect_min_backoff_ms / 1000.0
        while not self._stop.is_set():
            if self._session is None:
                if self._try_connect():
                    backoff_s = self.rig.reconnect_min_backoff_ms / 1000.0
                else:
                    self._stop.wait(backoff_s)
                    backoff_s = min(backoff_s * 2.0, self.rig.reconnect_max_backoff_ms / 1000.0)
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
        now = time.monotonic_ns()
        if session.control_lost.is_set():
            self._lose("Aravis reported control lost (no heartbeat answer)")
        elif self._trigger is not None and self._trigger.failure is not None:
            self._lose(self._trigger.failure)
        elif now - self._last_frame_ns > self.rig.loss_timeout_ms * 1e6 + self._grace_ns:
            self._lose(f"no frame for {self.rig.loss_timeout_ms:g} ms")
        elif now >= self._next_housekeeping_ns:
            self._housekeeping(session, now)

    def _handle(self, session: Session, buffer: Any) -> None:
        grab = session.read(buffer)
        frame_id = self._unwrap(grab.frame_id) if grab.frame_id is not None else None
        tick = self._ticks.frame(frame_id) if (self._ticks is not None and frame_id is not None) else None
        if grab.failure is not None:
            self._count_failure(grab.failure)
            return
        pixel_format = grab.pixel_format
        if pixel_format != self.cam.pixel_format:
            self._count_failure("wrong-format")
            return
        width, height = grab.width_px, grab.height_px
        shape = frame_shape(pixel_format, width, height)
        nbytes = int(np.prod(shape))
        if (width, height) != (self.cam.width_px, self.cam.height_px):
            self._count_failure("wrong-size")
            return
        data = grab.pixels(nbytes)  # the one copy per frame
        if memoryview(data).nbytes < nbytes:
            self._count_failure("wrong-size")
            return
        if self._ticks is not None and tick is None:
            self._count_failure("no-trigger")
            return
        image = np.frombuffer(data, dtype=np.uint8, count=nbytes).reshape(shape)
        image.flags.writeable = False
        device_ns = grab.device_timestamp_ns
        host_ns = grab.host_timestamp_ns
        frame = Frame(self.cam.id, int(frame_id or 0), device_ns, host_ns, pixel_format, image)
        capture_ns = self.sink.observe_clock(self.index, device_ns, host_ns)
        if device_ns == 0 and tick is not None and self._trigger is not None:
            # No camera clock (pylon's emulated cameras): the trigger's send time is a better capture
            # time than the arrival, which adds each camera's own delivery delay and jitter.
            capture_ns = self._trigger.sent_ns(tick) or capture_ns
        now = time.monotonic_ns()
        self._last_frame_ns = now
        self._grace_ns = 0
        if self._awaiting_first_frame:
            self._first_frame(now)
        with self._lock:
            self._frames += 1
            self._rate.tick(now)
        self.sink.deliver(Arrival(self.index, frame, capture_ns, self._epoch, tick))

    def _first_frame(self, now: int) -> None:
        """The connection's first complete frame: the camera streams (again)."""
        self._awaiting_first_frame = False
        away_s = (now - self._outage_ns) / 1e9 if self._outage_ns is not None else 0.0
        with self._lock:
            self._state = "streaming"
            self._lost_since = None
            reconnects = self._reconnects
        if reconnects:
            log.warning("camera %s streaming again after %.1f s (reconnect %d)", self.cam.id, away_s, reconnects)
        elif self._attempts:
            # At warning, as the wait was: the operator who saw one sees the other.
            log.warning("camera %s streaming, after waiting %.1f s for it (%d attempts)", self.cam.id, away_s,
                        self._attempts + 1)
        else:
            log.info("camera %s streaming", self.cam.id)
        self._outage_ns = None
        self._attempts = 0
        self._logged_reason = None

    def _housekeeping(self, session: Session, now: int) -> None:
        self._next_housekeeping_ns = now + COUNTER_PERIOD_NS
        counters = session.counters()
        ptp = None
        if session.ptp_feature is not None and now >= self._next_ptp_ns:
            self._next_ptp_ns = now + int(self.rig.ptp_poll_interval_ms * 1e6)
            ptp = session.ptp_state()
        with self._lock:
            self._stream_current = counters
            if ptp is not None:
                self._ptp_state = ptp

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
            self._ticks = self._trigger.ticks
            if self._thread is not None:  # reconnecting; at start-up, start() starts it
                self._trigger.start()
        self._last_frame_ns = now
        self._grace_ns = FIRST_FRAME_GRACE_NS
        self._next_housekeeping_ns = now
        self._next_ptp_ns = now
        self._awaiting_first_frame = True
        self._connections += 1
        with self._lock:
            self._address = session.address or self._address
            self._notes = tuple(session.notes)
            # Not streaming yet: that waits for a complete frame (a hardware-triggered camera
            # with no pulses, or one whose packets do not get through, never gets there).
            self._state = "connected"
            self._stream_current = {}
        self.sink.camera_back(self.index)

    def _lose(self, reason: str) -> None:
        session = self._session
        self._session = None
        self._retire_trigger()
        ticks = self._ticks
        detail = f" (triggers unanswered: {ticks.outstanding})" if ticks is not None else ""
        now = time.monotonic_ns()
        # A connection lost before its first frame continues the outage it was to end. Its loss
        # is logged like a failed attempt, not again every cycle: a hardware-triggered camera
        # with nothing on its line would otherwise log a warning every two seconds.
        continuing = self._outage_ns is not None
        if not continuing or reason != self._logged_reason or now >= self._next_reminder_ns:
            since = " (no frame since it was opened)" if continuing else ""
            log.warning("camera %s lost: %s%s%s", self.cam.id, reason, detail, since)
            self._logged_reason = reason
            self._next_reminder_ns = now + int(REMINDER_S * 1e9)
        if not continuing:
            self._outage_ns = now
        self._awaiting_first_frame = False
        with self._lock:
            self._state = "lost"
            self._losses += 1
            if self._lost_since is None:
                self._lost_since = now
            self._last_error = reason
            self._stream_totals.update(self._stream_current)
            self._stream_current = {}
        self.sink.camera_lost(self.index)
        if session is not None:
            self._releases.append(self.sink.abandon(session))

    def _previous_connection_quiet(self) -> bool:
        """Whether nothing of an earlier connection can still talk to the camera.

        Aravis retries a GVCP command to a camera that stopped answering for about
        2.5 s; a camera that comes back within that time would otherwise receive
        the old connection's last commands (a trigger, a release of control)
        after the new connection has configured it.
        """
        self._releases = [t for t in self._releases if t.is_alive()]
        self._old_triggers = [t for t in self._old_triggers if t.alive]
        return not self._releases and not self._old_triggers

    def _try_connect(self, config_errors_raise: bool = False) -> bool:
        """One attempt: probe the camera, and open it if it answers. True when open.

        The first connection (start-up) and reconnections after a loss differ only in the
        state shown meanwhile (``connecting`` / ``lost``) and in what is counted. A refused
        configuration is logged as an error and tried again (the camera may be replaced), or
        raised with ``config_errors_raise`` (start-up, where the daemon exits with status 2).
        """
        first = self._connections == 0
        known = self._address or (self.cam.address if first else None)
        address = known.split(":")[0] if known else None
        if address is not None:
            answer = probe(address, POLL_S * 2)
            if answer is None:
                # After a loss, silence is the loss going on: last_error keeps the loss's reason.
                return self._unavailable(f"no answer from {address} (GVCP discovery)", record=first)
            if self.cam.serial and answer.serial and answer.serial != self.cam.serial:
                return self._unavailable(f"{address} answers as serial {answer.serial}, not {self.cam.serial}")
        if not self._previous_connection_quiet():
            return False
        with self._lock:
            self._state = "connecting" if first else "reconnecting"
        try:
            if address is None and self._device_id is None:
                self._device_id = _resolve(self.cam)  # by serial: Aravis's discovery, about a second
            self._connect(address or self._device_id)  # type: ignore[arg-type]
        except CameraConfigError as err:
            if config_errors_raise:
                raise
            return self._unavailable(str(err), level=logging.ERROR)
        except CameraError as err:
            return self._unavailable(str(err))
        if not first:
            with self._lock:
                self._reconnects += 1
        return True

    def _unavailable(self, reason: str, level: int = logging.INFO, record: bool = True) -> bool:
        """Count a failed attempt; log why if the reason is new or a reminder is due; ``record`` it as
        the status's last_error. Returns False (the attempt's outcome)."""
        now = time.monotonic_ns()
        self._attempts += 1
        with self._lock:
            if record:
                self._last_error = reason
            self._state = "connecting" if self._connections == 0 else "lost"
        if reason != self._logged_reason or now >= self._next_reminder_ns:
            self._logged_reason = reason
            self._next_reminder_ns = now + int(REMINDER_S * 1e9)
            waited_s = (now - self._outage_ns) / 1e9 if self._outage_ns is not None else 0.0
            what = "not available yet" if self._connections == 0 else "still lost"
            if self._connections == 0:
                # Nothing is tracked until it comes: say so at the default log level (the loss of a
                # camera that streamed is a warning already; its retries are details).
                level = max(level, logging.WARNING)
            log.log(level, "camera %s %s (attempt %d, %.0f s): %s; retrying", self.cam.id, what, self._attempts,
                    waited_s, reason)
        return False

    def _shutdown(self) -> None:
        session = self._session
        self._session = None
        self._retire_trigger()
        if session is not None:
            recent = time.monotonic_ns() - self._last_frame_ns < 3 * 1e9 / self.rig.frame_rate_hz + 1e8
            address = session.address.split(":")[0] if session.address else None
            if recent or address is None or probe(address, 0.05) is not None:
                with self._lock:
                    self._stream_totals.update(session.counters())
                    self._stream_current = {}
                session.close()
                self.last_pool = session.buffers
                self.last_session = session
            else:
                self.sink.abandon(session)
        with self._lock:
            self._state = "stopped"

    def _retire_trigger(self) -> None:
        """Stop the current connection's trigger thread; keep it to be joined (it may be hung)."""
        if self._trigger is not None:
            self._trigger.stop()
            self._old_triggers.append(self._trigger)
            self._trigger = None
        self._old_triggers = [t for t in self._old_triggers if t.alive]

    def _count_failure(self, cause: str) -> None:
        with self._lock:
            self._failed[cause] += 1


def _resolve(cam: CameraConfig) -> str:
    return resolve_device_id(cam)
