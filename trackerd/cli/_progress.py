"""The live progress line of `trackerd record` and `trackerd replay`, on stderr.

On a terminal one line is rewritten in place (``\\r``) a few times a second;
otherwise (a log file, journald) a full line is written every few seconds, so
logs stay readable.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

from trackerd.recording.recorder import RecorderStatus

TTY_INTERVAL_S = 0.5
LOG_INTERVAL_S = 5.0


class ProgressLine:
    """Prints progress at most every ``interval_s`` (default: 0.5 s on a terminal, 5 s otherwise)."""

    def __init__(self, stream: TextIO | None = None, interval_s: float | None = None) -> None:
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.interval_s = interval_s if interval_s is not None else (TTY_INTERVAL_S if self.tty else LOG_INTERVAL_S)
        self._next = 0.0
        self._width = 0
        self._pending = False

    def due(self) -> bool:
        return time.monotonic() >= self._next

    def show(self, text: str, *, force: bool = False) -> None:
        now = time.monotonic()
        if not force and now < self._next:
            return
        self._next = now + self.interval_s
        if self.tty:
            pad = max(0, self._width - len(text))
            self.stream.write("\r" + text + " " * pad)
            self._width = len(text)
            self._pending = True
        else:
            self.stream.write(text + "\n")
        self.stream.flush()

    def done(self) -> None:
        """End the rewritten line (call before printing anything else)."""
        if self._pending:
            self.stream.write("\n")
            self.stream.flush()
            self._pending = False


def describe(status: RecorderStatus, source_dropped: int = 0) -> str:
    """One line: pairs written, rate, MB/s, drops (the recorder's and the source's), disk space left."""
    free = "?" if status.free_space_mb is None else f"{status.free_space_mb / 1000:.1f} GB"
    line = (
        f"{status.path}: {status.pairs} pairs, {status.pair_rate_hz:.1f} pairs/s, {status.write_rate_mb_s:.0f} MB/s,"
        f" dropped {status.dropped_pairs} (writer) + {source_dropped} (cameras), {free} free"
    )
    if status.state != "recording":
        line += f" [{status.state}{': ' + status.detail if status.detail else ''}]"
    return line
