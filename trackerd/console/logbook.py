"""The console's log of recent warnings: a logging handler keeping the last few, numbered."""

from __future__ import annotations

import datetime as dt
import logging
import threading
from collections import deque
from typing import Any

KEPT = 200
"""Warnings and errors kept for the page."""


class Logbook(logging.Handler):
    """Keeps the last :data:`KEPT` records of level WARNING and above, each with a serial number,
    so a page asks for what it has not seen yet."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self._entries: deque[dict[str, Any]] = deque(maxlen=KEPT)
        self._serial = 0
        self._entries_lock = threading.Lock()

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = record.getMessage()
        except Exception:  # noqa: BLE001 - a bad format string must not break the daemon's logging
            text = str(record.msg)
        with self._entries_lock:
            self._serial += 1
            self._entries.append(
                {
                    "serial": self._serial,
                    "time_utc": dt.datetime.fromtimestamp(record.created, dt.UTC).isoformat(timespec="milliseconds"),
                    "level": record.levelname.lower(),
                    "logger": record.name,
                    "message": text.splitlines()[0] if text else "",
                }
            )

    def since(self, serial: int) -> list[dict[str, Any]]:
        """The entries after ``serial`` (0: all kept), oldest first."""
        with self._entries_lock:
            return [e for e in self._entries if e["serial"] > serial]

    @property
    def serial(self) -> int:
        with self._entries_lock:
            return self._serial
