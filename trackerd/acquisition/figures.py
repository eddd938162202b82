"""A camera's figures for its status: frames, failed buffers, stream counters, PTP state, across connections.

The worker's thread counts and polls; any thread reads :meth:`CameraFigures.status`. A connection's
stream counters (Aravis's, or pylon's stream grabber statistics under the same names) are kept
apart while it is open and join the totals when it ends, so a reconnection does not reset them.
"""

from __future__ import annotations

import threading
import time
from collections import Counter

from trackerd.acquisition.connection import ConnectionFigures
from trackerd.acquisition.meters import RateMeter
from trackerd.acquisition.session import Session
from trackerd.acquisition.status import CameraStatus

COUNTER_PERIOD_NS = 1_000_000_000
"""How often the open connection's stream counters are read."""


class CameraFigures:
    """What a camera delivered and what its connections report, across connections (any thread reads).

    The open connection's stream counters are read every ``COUNTER_PERIOD_NS``, its PTP state every
    ``ptp_poll_interval_ms`` (:meth:`poll`, on the worker's thread).
    """

    def __init__(self, ptp_poll_interval_ms: float) -> None:
        self._ptp_poll_interval_ns = int(ptp_poll_interval_ms * 1e6)
        self._next_counters_ns = 0
        self._next_ptp_ns = 0
        self._lock = threading.Lock()
        self._frames = 0
        self._rate = RateMeter()
        self._failed: Counter[str] = Counter()
        self._stream_totals: Counter[str] = Counter()
        """Stream counters of the connections that ended."""
        self._stream_current: dict[str, int] = {}
        """The open connection's stream counters, as last read."""
        self._ptp_state: str | None = None
        self._address: str | None = None
        self._notes: tuple[str, ...] = ()

    @property
    def ptp_state(self) -> str | None:
        return self._ptp_state

    @property
    def address(self) -> str | None:
        """The camera's address as its last connection gave it (None before one did)."""
        return self._address

    def frame(self, now_ns: int) -> None:
        with self._lock:
            self._frames += 1
            self._rate.tick(now_ns)

    def failure(self, cause: str) -> None:
        """A buffer that did not become a frame, counted by ``cause``."""
        with self._lock:
            self._failed[cause] += 1

    def opened(self, session: Session, now_ns: int) -> None:
        """A connection opened: read its counters (and PTP state) on the next poll."""
        self._next_counters_ns = now_ns
        self._next_ptp_ns = now_ns
        with self._lock:
            self._address = session.address or self._address
            self._notes = tuple(session.notes)

    def poll(self, session: Session, now_ns: int) -> None:
        """Read the open connection's stream counters and PTP state if due."""
        if now_ns < self._next_counters_ns:
            return
        self._next_counters_ns = now_ns + COUNTER_PERIOD_NS
        stream = session.counters()
        ptp_state = None
        if session.ptp_feature is not None and now_ns >= self._next_ptp_ns:
            self._next_ptp_ns = now_ns + self._ptp_poll_interval_ns
            ptp_state = session.ptp_state()
        with self._lock:
            self._stream_current = stream
            if ptp_state is not None:
                self._ptp_state = ptp_state

    def closed(self, final: dict[str, int] | None = None) -> None:
        """The connection ended: its counters (``final``, or as last read) join the totals."""
        with self._lock:
            self._stream_totals.update(self._stream_current if final is None else final)
            self._stream_current = {}

    def status(
        self, camera_id: str, lookup: str, connection: ConnectionFigures, clock_offset_ns: int | None
    ) -> CameraStatus:
        """The camera's status; ``lookup`` names the camera until a connection gives its address."""
        now = time.monotonic_ns()
        with self._lock:
            stream = Counter(self._stream_totals)
            stream.update(self._stream_current)
            return CameraStatus(
                camera_id=camera_id,
                state=connection.state,
                device=self._address or lookup,
                frames=self._frames,
                frame_rate_hz=round(self._rate.rate_hz(now), 3),
                failed_buffers=dict(self._failed),
                stream=dict(stream),
                losses=connection.losses,
                reconnects=connection.reconnects,
                lost_since_ns=connection.lost_since_ns,
                last_error=connection.last_error,
                ptp_state=self._ptp_state,
                clock_offset_ns=clock_offset_ns,
                notes=self._notes,
            )
