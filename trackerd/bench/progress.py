"""What a long benchmark is doing, on stderr: one line per step (rewritten in place on a terminal).

Benchmarks run for minutes; one that prints nothing until it ends looks hung. The figures themselves go
to stdout (``--json`` included), so the progress never mixes with them.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

LOG_INTERVAL_S = 5.0
"""Off a terminal (a log file, CI), a step's line at most this often: the last step's always."""


class BenchProgress:
    """``name: step k/total units, elapsed s`` after each step, and a phase line for steps of their own."""

    def __init__(self, name: str, total: int = 0, unit: str = "", stream: TextIO | None = None) -> None:
        self.name = name
        self.total = total
        self.unit = unit
        self.finished = 0
        self.stream = stream or sys.stderr
        self.start = time.monotonic()
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._open = False
        self._next_log = 0.0

    def step(self, count: int = 1) -> None:
        """``count`` more of the ``total`` are done."""
        self.finished += count
        now = time.monotonic()
        if not self.tty and self.finished < self.total and now < self._next_log:
            return
        self._next_log = now + LOG_INTERVAL_S
        self._show(f"{self.name}: {self.finished}/{self.total} {self.unit}, {self._elapsed()}")

    def phase(self, text: str) -> None:
        """A step that is not one of the ``total`` (calibrating, rendering, ...) has begun."""
        self._show(f"{self.name}: {text}, {self._elapsed()}")

    def done(self) -> None:
        """End a line rewritten in place (call before the figures are printed)."""
        if self._open:
            print(file=self.stream, flush=True)
            self._open = False

    def _elapsed(self) -> str:
        return f"{time.monotonic() - self.start:.0f} s"

    def _show(self, text: str) -> None:
        if self.tty:
            print(f"\r\033[K{text}", end="", file=self.stream, flush=True)
            self._open = True
        else:
            print(text, file=self.stream, flush=True)
