"""One camera's connection as the worker sees it: its state, its outages, the back-off, what to log.

A camera's state follows its connection: ``connecting`` until it is first
opened, ``connected`` from then until its first complete frame, ``streaming``
from that frame on, ``lost`` and ``reconnecting`` while it is away, then
``connected`` again. A connection lost before its first frame continues the
outage it was to end: ``lost_since_ns`` keeps the outage's start and the loss
is logged like a failed attempt.

Failed attempts are retried after a back-off that doubles from the rig's
``reconnect_min_backoff_ms`` to ``reconnect_max_backoff_ms`` and starts again at
the minimum once a connection opens. A camera is overdue (to be declared lost)
when no frame came for ``loss_timeout_ms``, plus ``FIRST_FRAME_GRACE_NS`` for a
connection's first frame.

Logging: a failed attempt is logged when its reason changes and every
``REMINDER_S`` otherwise, so a long wait leaves a trail without flooding the
journal; the first frame after an outage is logged with how long the camera was
away. :class:`ConnectionTracker` decides and words these lines (:class:`Notice`);
the worker writes them. It reads time only from the clock it is given, so its
tests drive it without cameras and without sleeping.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass

from trackerd.acquisition.status import CameraState

FIRST_FRAME_GRACE_NS = 1_000_000_000
"""Extra time a camera gets for its first frame after (re)connecting: some cameras (Aravis's
simulated one among them) take a frame period or a tenth of a second to start streaming."""
REMINDER_S = 30.0
"""While a camera stays unavailable for the same reason, how often that is logged again."""


@dataclass(frozen=True, slots=True)
class Notice:
    """A log line the worker should write: its level and its text."""

    level: int
    message: str


@dataclass(frozen=True, slots=True)
class ConnectionFigures:
    """The connection's part of a camera's status (see :class:`~trackerd.acquisition.status.CameraStatus`)."""

    state: CameraState
    losses: int
    reconnects: int
    lost_since_ns: int | None
    last_error: str | None


class ConnectionTracker:
    """The connection state machine of one camera, on an injected monotonic clock (ns).

    The worker's thread reports what happens (:meth:`attempting`, :meth:`unavailable`,
    :meth:`connected`, :meth:`frame`, :meth:`lost`, ...); any thread may read :meth:`figures`.
    Methods that may warrant a log line return a :class:`Notice`, or None.
    """

    def __init__(
        self,
        camera_id: str,
        *,
        loss_timeout_ms: float,
        min_backoff_ms: float,
        max_backoff_ms: float,
        clock_ns: Callable[[], int],
    ) -> None:
        self.camera_id = camera_id
        self._clock_ns = clock_ns
        self._loss_timeout_ns = loss_timeout_ms * 1e6
        self._min_backoff_s = min_backoff_ms / 1000.0
        self._max_backoff_s = max_backoff_ms / 1000.0
        self._backoff_s = self._min_backoff_s
        self._lock = threading.Lock()
        # What the status shows (under the lock).
        self._state: CameraState = "connecting"
        self._losses = 0
        self._reconnects = 0
        self._lost_since_ns: int | None = None
        self._last_error: str | None = None
        # The worker thread's own.
        self._connections = 0
        self._awaiting_first_frame = False
        self._last_frame_ns = 0
        self._grace_ns = 0
        self._outage_ns: int | None = None
        """Since when the camera has not been streaming (start-up or loss), for the log."""
        self._attempts = 0
        """Failed connection attempts in the current outage."""
        self._logged_reason: str | None = None
        self._next_reminder_ns = 0

    # ------------------------------------------------------------------ reading

    @property
    def never_connected(self) -> bool:
        """No connection has opened yet (start-up): the camera is awaited, not lost."""
        return self._connections == 0

    def figures(self) -> ConnectionFigures:
        with self._lock:
            return ConnectionFigures(self._state, self._losses, self._reconnects, self._lost_since_ns, self._last_error)

    def overdue(self) -> bool:
        """No frame within the loss timeout (and the first-frame grace, before a connection's first frame)."""
        return self._clock_ns() - self._last_frame_ns > self._loss_timeout_ns + self._grace_ns

    def ns_since_frame(self) -> int:
        """Time since the last frame (or since the connection opened, before its first)."""
        return self._clock_ns() - self._last_frame_ns

    def next_backoff_s(self) -> float:
        """How long to wait before the next attempt, after a failed one; doubles up to the maximum."""
        backoff_s = self._backoff_s
        self._backoff_s = min(backoff_s * 2.0, self._max_backoff_s)
        return backoff_s

    # ------------------------------------------------------------------ attempts

    def begin(self) -> None:
        """The first attempt starts: the wait for the camera is timed from now."""
        self._outage_ns = self._clock_ns()

    def attempting(self) -> None:
        """The camera answers and is being opened."""
        with self._lock:
            self._state = "connecting" if self.never_connected else "reconnecting"

    def unavailable(self, reason: str, level: int = logging.INFO, record: bool = True) -> Notice | None:
        """An attempt failed for ``reason``; ``record`` it as the status's last_error.

        Logged when the reason is new or a reminder is due; while the camera was never connected,
        at warning at least (nothing is tracked until it comes; the loss of a camera that streamed
        is a warning already, its retries are details).
        """
        now = self._clock_ns()
        self._attempts += 1
        with self._lock:
            if record:
                self._last_error = reason
            self._state = "connecting" if self.never_connected else "lost"
        if reason == self._logged_reason and now < self._next_reminder_ns:
            return None
        self._remind_from(reason, now)
        waited_s = (now - self._outage_ns) / 1e9 if self._outage_ns is not None else 0.0
        what = "not available yet" if self.never_connected else "still lost"
        if self.never_connected:
            level = max(level, logging.WARNING)
        return Notice(
            level, f"camera {self.camera_id} {what} (attempt {self._attempts}, {waited_s:.0f} s): {reason}; retrying"
        )

    def connected(self) -> None:
        """A connection opened and is configured: not streaming until its first complete frame (a
        hardware-triggered camera with no pulses, or one whose packets do not get through, never is)."""
        now = self._clock_ns()
        reconnect = not self.never_connected
        self._connections += 1
        self._backoff_s = self._min_backoff_s
        self._last_frame_ns = now
        self._grace_ns = FIRST_FRAME_GRACE_NS
        self._awaiting_first_frame = True
        with self._lock:
            self._state = "connected"
            if reconnect:
                self._reconnects += 1

    # ------------------------------------------------------------------ the connection

    def frame(self) -> Notice | None:
        """A complete frame arrived; the connection's first ends the outage (and says so)."""
        self._last_frame_ns = self._clock_ns()
        self._grace_ns = 0
        if not self._awaiting_first_frame:
            return None
        return self._first_frame(self._last_frame_ns)

    def _first_frame(self, now: int) -> Notice:
        self._awaiting_first_frame = False
        away_s = (now - self._outage_ns) / 1e9 if self._outage_ns is not None else 0.0
        with self._lock:
            self._state = "streaming"
            self._lost_since_ns = None
            reconnects = self._reconnects
        if reconnects:
            notice = Notice(
                logging.WARNING,
                f"camera {self.camera_id} streaming again after {away_s:.1f} s (reconnect {reconnects})",
            )
        elif self._attempts:
            # At warning, as the wait was: the operator who saw one sees the other.
            notice = Notice(
                logging.WARNING,
                f"camera {self.camera_id} streaming, after waiting {away_s:.1f} s "
                f"for it ({self._attempts + 1} attempts)",
            )
        else:
            notice = Notice(logging.INFO, f"camera {self.camera_id} streaming")
        self._outage_ns = None
        self._attempts = 0
        self._logged_reason = None
        return notice

    def lost(self, reason: str, detail: str = "") -> Notice | None:
        """The connection is lost for ``reason`` (``detail`` is added to the log line only).

        A connection lost before its first frame continues the outage it was to end: its loss is
        logged like a failed attempt, not again every cycle (a hardware-triggered camera with
        nothing on its line would otherwise log a warning every two seconds).
        """
        now = self._clock_ns()
        continuing = self._outage_ns is not None
        notice = None
        if not continuing or reason != self._logged_reason or now >= self._next_reminder_ns:
            since = " (no frame since it was opened)" if continuing else ""
            notice = Notice(logging.WARNING, f"camera {self.camera_id} lost: {reason}{detail}{since}")
            self._remind_from(reason, now)
        if not continuing:
            self._outage_ns = now
        self._awaiting_first_frame = False
        with self._lock:
            self._state = "lost"
            self._losses += 1
            if self._lost_since_ns is None:
                self._lost_since_ns = now
            self._last_error = reason
        return notice

    def stopped(self) -> None:
        with self._lock:
            self._state = "stopped"

    def failed(self, error: str) -> None:
        """The worker's thread died of ``error`` (a bug): the status's last_error says so."""
        with self._lock:
            self._last_error = error

    def _remind_from(self, reason: str, now: int) -> None:
        self._logged_reason = reason
        self._next_reminder_ns = now + int(REMINDER_S * 1e9)
