"""TUIO 1.1 cursor output: the pointer as a ``/tuio/2Dcur`` cursor over OSC/UDP.

TUIO (Kaltenbrunner et al., 2005; TUIO 1.1 specification) is what multi-touch
tables and large-display software listen to. trackerd sends one OSC bundle per
camera pair while the pointer is entered on the display::

    /tuio/2Dcur source trackerd@HOST
    /tuio/2Dcur alive S
    /tuio/2Dcur set S x y X Y m
    /tuio/2Dcur fseq F

``S`` is the session id (trackerd's ``cursor_id``: a new one per ``enter``),
``x, y`` the position normalised to the display, origin top-left, y down, in
[0, 1]; ``X, Y`` the velocity in the same units per second; ``m`` the motion
acceleration (normalised units per second squared); ``F`` counts bundles. When the
pointer leaves, a bundle with an empty ``alive`` removes the cursor, and one is
repeated every second while nothing points (TUIO clients expect to hear the
source is alive). :meth:`TuioSender.end` (a reset or a rebuild of the stage) and
:meth:`TuioSender.close` (the daemon stops) send one too, so a client never keeps
a cursor nobody moves; a rebuilt sender carries on the frame count, because
clients drop a bundle whose ``fseq`` is just below the last one as late. The
bundles are encoded by python-osc and sent from a non-blocking UDP socket: a
missing listener or a full buffer costs a counted error, never a wait.
"""

from __future__ import annotations

import math
import socket
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
from pythonosc.osc_message_builder import OscMessageBuilder

from trackerd.config.interaction import TuioConfig
from trackerd.errors import ConfigError

ADDRESS = "/tuio/2Dcur"
IDLE_PERIOD_NS = 1_000_000_000


@dataclass(frozen=True)
class Cursor:
    """One TUIO cursor, normalised to the display (origin top-left)."""

    session_id: int
    x: float
    y: float
    velocity_x_per_s: float
    velocity_y_per_s: float
    acceleration_per_s2: float


def _message(*args: str | int | float) -> OscMessageBuilder:
    builder = OscMessageBuilder(address=ADDRESS)
    for arg in args:
        if isinstance(arg, str):
            builder.add_arg(arg, OscMessageBuilder.ARG_TYPE_STRING)
        elif isinstance(arg, int):
            builder.add_arg(arg, OscMessageBuilder.ARG_TYPE_INT)
        else:
            builder.add_arg(float(arg), OscMessageBuilder.ARG_TYPE_FLOAT)
    return builder


def encode_frame(source: str, cursors: list[Cursor], frame: int) -> bytes:
    """One TUIO 1.1 ``/tuio/2Dcur`` bundle (source, alive, set per cursor, fseq) as a datagram."""
    bundle = OscBundleBuilder(IMMEDIATELY)
    bundle.add_content(_message("source", source).build())
    bundle.add_content(_message("alive", *[c.session_id for c in cursors]).build())
    for c in cursors:
        bundle.add_content(
            _message(
                "set", c.session_id, c.x, c.y, c.velocity_x_per_s, c.velocity_y_per_s, c.acceleration_per_s2
            ).build()
        )
    bundle.add_content(_message("fseq", frame).build())
    return bundle.build().dgram


def resolve(config: TuioConfig) -> tuple[int, int, int, tuple]:
    """(family, type, protocol, address) of the TUIO client; ConfigError when the host does not resolve."""
    try:
        infos = socket.getaddrinfo(config.host, config.port, type=socket.SOCK_DGRAM)
    except socket.gaierror as err:
        raise ConfigError(f"interaction.tuio.host: cannot resolve '{config.host}': {err.strerror}") from err
    family, kind, proto, _, address = infos[0]
    return family, kind, proto, address


class TuioSender:
    """Sends the pointer's cursor to one TUIO client; call :meth:`frame` once per pair."""

    def __init__(self, config: TuioConfig) -> None:
        self.config = config
        self.source = f"{config.source}@{socket.gethostname()}"
        family, kind, proto, self.address = resolve(config)
        self._socket = socket.socket(family, kind, proto)
        self._socket.setblocking(False)
        self._closed = False
        self._ended = False
        """The last bundle was end()'s empty alive: saying it again adds nothing."""
        self.packets = 0
        self.errors = 0
        self._frame = 0
        self._last_sent_ns: int | None = None
        self._had_cursor = False
        self._last_velocity: tuple[float, float, int] | None = None

    def frame(self, time_ns: int, cursor: tuple[int, float, float, float, float] | None) -> None:
        """The cursor for this pair: (session id, x, y, X, Y) normalised, or None when nothing points."""
        self._ended = False
        if cursor is None:
            self._last_velocity = None
            # A time before the last send (a looped replay starting over) is due as well.
            idle_due = self._last_sent_ns is None or not 0 <= time_ns - self._last_sent_ns < IDLE_PERIOD_NS
            if not self._had_cursor and not idle_due:
                return
            self._had_cursor = False
            self._send(time_ns, [])
            return
        session, x, y, vx, vy = cursor
        acceleration = 0.0
        if self._last_velocity is not None:
            pvx, pvy, pt = self._last_velocity
            dt_s = (time_ns - pt) / 1e9
            if dt_s > 0:
                acceleration = math.hypot(vx - pvx, vy - pvy) / dt_s
        self._last_velocity = (vx, vy, time_ns)
        self._had_cursor = True
        self._send(time_ns, [Cursor(session, x, y, vx, vy, acceleration)])

    @property
    def frame_count(self) -> int:
        """The last ``fseq`` sent."""
        return self._frame

    def continue_after(self, frame: int) -> None:
        """Number the next bundle after ``frame`` (the last ``fseq`` of the sender this one replaces)."""
        self._frame = max(self._frame, frame)

    def end(self) -> None:
        """No cursor any more, whatever came before: an empty ``alive`` now, and motion forgotten."""
        if self._closed or self._ended:
            return
        self._last_velocity = None
        self._had_cursor = False
        self._send(self._last_sent_ns or 0, [])
        self._ended = True

    def _send(self, time_ns: int, cursors: list[Cursor]) -> None:
        self._frame += 1
        datagram = encode_frame(self.source, cursors, self._frame)
        self._last_sent_ns = time_ns
        try:
            self._socket.sendto(datagram, self.address)
            self.packets += 1
        except OSError:
            # Nobody listening (ICMP refused), a full socket buffer, no route: TUIO is fire-and-forget.
            self.errors += 1

    def close(self) -> None:
        """Send a last empty ``alive`` (the client removes the cursor) and close the socket; idempotent."""
        if self._closed:
            return
        self.end()
        self._closed = True
        self._socket.close()


class WallCursor:
    """The pointer's TUIO cursor, one frame per pair: its smoothed hit normalised to the wall
    (x right, y down, 0 to 1), with the filter's velocity."""

    def __init__(self, sender: TuioSender, width_m: float, height_m: float) -> None:
        self.sender = sender
        self.width_m = width_m
        self.height_m = height_m
        self._last_m: NDArray[np.float64] | None = None

    def frame(
        self,
        time_ns: int,
        smoothed_m: NDArray[np.float64] | None,
        inside: bool,
        velocity_m_s: NDArray[np.float64],
        cursor_id: int,
    ) -> None:
        """Send this pair's bundle: the cursor while the pointer is entered, else none."""
        if smoothed_m is not None:
            self._last_m = smoothed_m
        if not inside or self._last_m is None:
            self._last_m = None
            self.sender.frame(time_ns, None)
            return
        # A pair without a hit while entered keeps the cursor where it was (no remove and re-add).
        w, h = self.width_m, self.height_m
        x = min(max(float(self._last_m[0]) / w, 0.0), 1.0)
        y = min(max(1.0 - float(self._last_m[1]) / h, 0.0), 1.0)
        vx, vy = float(velocity_m_s[0]) / w, -float(velocity_m_s[1]) / h
        self.sender.frame(time_ns, (cursor_id, x, y, vx, vy))

    def forget(self) -> None:
        """No cursor any more (a reset): an empty ``alive`` now, and the last position forgotten."""
        self._last_m = None
        self.sender.end()
