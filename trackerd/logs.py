"""Log lines for a terminal or for journald.

Under systemd, standard error is a stream into journald, and every line of it is
stored at the unit's default priority (info) with a timestamp of journald's own.
So `journalctl -p warning` would never show a warning, and each line carried two
timestamps. systemd says which stream it connected in ``JOURNAL_STREAM``
("DEV:INODE", systemd.exec(5)); when that is the stream we write to, each line
starts with an sd-daemon(3) priority prefix (``<4>`` for a warning) and carries no
timestamp. A stream that merely inherited the variable (``trackerd ... 2>file`` run
from a unit's shell) is not journald's, and keeps the plain format.
"""

from __future__ import annotations

import logging
import os
import sys
from collections.abc import Mapping
from typing import TextIO

PLAIN_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"
JOURNAL_FORMAT = "%(levelname)s %(name)s: %(message)s"
"""The level name stays, for `journalctl -o cat | grep WARNING` and for reading without colours."""


def journal_priority(levelno: int) -> int:
    """The syslog priority of a logging level: 2 critical, 3 error, 4 warning, 5 notice (a level
    between info and warning), 6 info, 7 debug (sd-daemon(3))."""
    if levelno >= logging.CRITICAL:
        return 2
    if levelno >= logging.ERROR:
        return 3
    if levelno >= logging.WARNING:
        return 4
    if levelno > logging.INFO:
        return 5
    if levelno >= logging.INFO:
        return 6
    return 7


def is_journal_stream(stream: TextIO, environ: Mapping[str, str] = os.environ) -> bool:
    """Whether ``stream`` is the one systemd connected to journald: ``JOURNAL_STREAM`` names its
    device and inode. The variable alone is not enough, since children inherit it after
    redirecting their standard error elsewhere."""
    value = environ.get("JOURNAL_STREAM", "")
    device, _, inode = value.partition(":")
    if not (device.isdigit() and inode.isdigit()):
        return False
    try:
        status = os.fstat(stream.fileno())
    except (OSError, ValueError, AttributeError):
        # Closed, or a stream without a descriptor (pytest's capture, io.StringIO).
        return False
    return (status.st_dev, status.st_ino) == (int(device), int(inode))


class JournalFormatter(logging.Formatter):
    """Every line of a record prefixed with its priority: journald makes each line an entry of
    its own, so a traceback's later lines would otherwise drop back to info."""

    def __init__(self) -> None:
        super().__init__(JOURNAL_FORMAT)

    def format(self, record: logging.LogRecord) -> str:
        prefix = f"<{journal_priority(record.levelno)}>"
        return "\n".join(prefix + line for line in super().format(record).split("\n"))


def stderr_handler(stream: TextIO | None = None) -> logging.Handler:
    """A handler writing to ``stream`` (standard error by default), in journald's form when that
    stream is journald's and in the plain, timestamped form otherwise."""
    stream = sys.stderr if stream is None else stream
    handler = logging.StreamHandler(stream)
    handler.setFormatter(JournalFormatter() if is_journal_stream(stream) else logging.Formatter(PLAIN_FORMAT))
    return handler


def configure(level: int) -> None:
    """The root logger for a command: ``level`` and one handler on standard error. Like
    ``logging.basicConfig``, nothing changes when the root logger has handlers already."""
    root = logging.getLogger()
    if root.handlers:
        return
    root.addHandler(stderr_handler())
    root.setLevel(level)


def error_prefix(stream: TextIO | None = None) -> str:
    """``<3>`` when ``stream`` (standard error by default) is journald's, else nothing: for the
    one-line errors the CLI prints itself, so that a configuration error, the journal's last line
    before the unit fails, is found by `journalctl -p err`."""
    return "<3>" if is_journal_stream(sys.stderr if stream is None else stream) else ""
