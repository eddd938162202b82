"""Telling systemd how the daemon is doing (sd_notify), with the standard library only.

systemd passes a datagram socket in ``NOTIFY_SOCKET`` (a path, or an abstract
socket name written with a leading ``@``); each notification is one datagram
of ``KEY=VALUE`` lines. Without ``NOTIFY_SOCKET`` (not started by systemd, or
by a unit that is not ``Type=notify``) every call does nothing.

The pipeline decides when to call what (docs/deployment.md, "What the daemon
tells systemd"): ``ready()`` once every camera streams, ``progress()`` after
each processed pair (so the watchdog is fed by real work, never by a timer),
``status()`` on every change, ``reloading()`` on SIGHUP, ``stopping()`` on SIGTERM.
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import time

log = logging.getLogger(__name__)


class SdNotify:
    """A connection to systemd's notification socket; every method is a no-op without one.

    Thread-safe: each call sends one datagram.
    """

    def __init__(self, environ: dict[str, str] | None = None) -> None:
        env = os.environ if environ is None else environ
        self._address = _socket_address(env.get("NOTIFY_SOCKET", ""))
        self._watchdog_s = _watchdog_interval_s(env)
        self._socket: socket.socket | None = None
        self._lock = threading.Lock()
        self._last_watchdog = -float("inf")
        self._warned = False
        self._stopping = False
        if self._address is not None:
            self._socket = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)

    @property
    def enabled(self) -> bool:
        """Whether a notification socket was given."""
        return self._socket is not None

    def watchdog_interval_s(self) -> float | None:
        """systemd's watchdog timeout (WatchdogSec) for this process, or None when it has none.

        The watchdog must be fed well within it; :meth:`progress` feeds it every quarter.
        """
        return self._watchdog_s

    def notify(self, **fields: str | int) -> bool:
        """Send ``KEY=value`` lines (``notify(READY=1, STATUS="...")``); False when not sent."""
        if self._socket is None or self._address is None:
            return False
        lines = []
        for key, value in fields.items():
            text = str(value)
            if "\n" in text:
                raise ValueError(f"sd_notify {key} must be one line")
            lines.append(f"{key}={text}")
        try:
            self._socket.sendto("\n".join(lines).encode("utf-8"), self._address)
        except OSError as err:
            # systemd gone (or the unit not Type=notify): the daemon must carry on regardless.
            if not self._warned:
                log.warning("cannot notify systemd at %s: %s", os.environ.get("NOTIFY_SOCKET"), err)
                self._warned = True
            return False
        return True

    def ready(self, status: str | None = None) -> bool:
        """The daemon is up (every camera streams): systemd's start job completes."""
        return self.notify(READY=1, **({"STATUS": status} if status else {}))

    def status(self, text: str) -> bool:
        """One line shown by ``systemctl status``; not sent once :meth:`stopping` was.

        The publishing thread may still report the pair in hand ("running: ...") after the
        signal handler said the daemon stops; systemd would show that line for the rest of
        the stop, so it is dropped.
        """
        with self._lock:
            if self._stopping:
                return False
        return self.notify(STATUS=text)

    def watchdog(self) -> bool:
        """Feed the watchdog now."""
        with self._lock:
            self._last_watchdog = time.monotonic()
        return self.notify(WATCHDOG=1)

    def progress(self) -> bool:
        """Call after every processed pair: feeds the watchdog at most every quarter of its timeout."""
        if self._watchdog_s is None or self._socket is None:
            return False
        now = time.monotonic()
        with self._lock:
            if now - self._last_watchdog < self._watchdog_s / 4.0:
                return False
            self._last_watchdog = now
        return self.notify(WATCHDOG=1)

    def reloading(self) -> bool:
        """Configuration reload begins; call ready() when it is done.

        MONOTONIC_USEC lets systemd 253+ (Type=notify-reload) match the reload to
        the request; older systemd ignores it.
        """
        return self.notify(RELOADING=1, MONOTONIC_USEC=time.clock_gettime_ns(time.CLOCK_MONOTONIC) // 1000)

    def stopping(self, status: str | None = None) -> bool:
        """The daemon is shutting down; later :meth:`status` lines are not sent."""
        with self._lock:
            self._stopping = True
        return self.notify(STOPPING=1, **({"STATUS": status} if status else {}))

    def close(self) -> None:
        if self._socket is not None:
            self._socket.close()
            self._socket = None

    def __enter__(self) -> SdNotify:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _socket_address(value: str) -> str | bytes | None:
    if not value:
        return None
    if value.startswith("@"):
        # Abstract namespace: a leading NUL byte instead of '@', no file behind it.
        return b"\0" + value[1:].encode()
    if value.startswith("/"):
        return value
    log.warning("ignoring NOTIFY_SOCKET=%r: not a path or an abstract socket name", value)
    return None


def _watchdog_interval_s(env: dict[str, str] | os._Environ[str]) -> float | None:
    """WATCHDOG_USEC in seconds, when it is meant for this process (WATCHDOG_PID absent or ours)."""
    usec = env.get("WATCHDOG_USEC")
    if not usec:
        return None
    pid = env.get("WATCHDOG_PID")
    if pid and pid != str(os.getpid()):
        return None
    try:
        value = int(usec)
    except ValueError:
        log.warning("ignoring WATCHDOG_USEC=%r: not a number", usec)
        return None
    return value / 1e6 if value > 0 else None
