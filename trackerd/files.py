"""Reading the small files trackerd is given (rig and calibration TOML, a recording's JSON) safely.

A path given by an operator, or by whoever can write where it points, can name
something that is not a file: a FIFO blocks a reader until someone writes to it
(the daemon's main loop, reloading on SIGHUP, then ignores SIGTERM), a device
never ends. A file can also be crafted to hurt the parser: a megabyte of
nested arrays exhausts Python's recursion limit in ``tomllib`` and ``json``.
So these files are opened without blocking, must be regular files of bounded
size, and their data is refused when nested deeper than any real one is.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterable
from pathlib import Path
from typing import Any

MAX_DEPTH = 32
"""Nesting levels (tables, arrays, objects) a configuration or a recording's metadata may have; the
deepest real ones have about 6."""


class NotRegularFile(OSError):
    """The path names a FIFO, a socket or a device, not a file."""


class TooLarge(OSError):
    """The file is larger than the kind of file it should be can be."""


def read_bounded(path: Path, limit_bytes: int) -> bytes:
    """The bytes of the regular file at ``path``, refusing anything else and anything over ``limit_bytes``.

    Raises NotRegularFile or TooLarge (OSErrors), or the OSError of opening or reading it
    (FileNotFoundError, IsADirectoryError, PermissionError, ...). Never blocks on a FIFO.
    """
    info = os.stat(path)
    if stat.S_ISDIR(info.st_mode):
        raise IsADirectoryError(21, "Is a directory", str(path))
    if not stat.S_ISREG(info.st_mode):
        raise NotRegularFile(f"{path}: not a regular file ({_kind(info.st_mode)})")
    if info.st_size > limit_bytes:
        raise TooLarge(f"{path}: {info.st_size} bytes, larger than such a file can be ({limit_bytes})")
    # O_NONBLOCK: should the path have been swapped for a FIFO since the stat, opening it does not wait.
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    with os.fdopen(fd, "rb") as handle:
        if not stat.S_ISREG(os.fstat(handle.fileno()).st_mode):
            raise NotRegularFile(f"{path}: not a regular file")
        data = handle.read(limit_bytes + 1)
    if len(data) > limit_bytes:
        raise TooLarge(f"{path}: larger than such a file can be ({limit_bytes} bytes)")
    return data


def open_regular(path: Path) -> int:
    """A read-only descriptor of the regular file at ``path`` (for a file too large to read whole, to map).

    Raises IsADirectoryError, NotRegularFile (a FIFO, a socket, a device) or the OSError of opening
    it. O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer, for ever.
    """
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    try:
        mode = os.fstat(fd).st_mode
        if stat.S_ISDIR(mode):
            raise IsADirectoryError(21, "Is a directory", str(path))
        if not stat.S_ISREG(mode):
            raise NotRegularFile(f"{path}: not a regular file ({_kind(mode)})")
    except BaseException:
        os.close(fd)
        raise
    return fd


def nesting_depth(value: Any, limit: int = MAX_DEPTH) -> int:
    """How deeply ``value`` (parsed TOML or JSON) nests dicts and lists, counted without recursion;
    counting stops once past ``limit``."""
    deepest = 0
    stack = [(value, 0)]
    while stack:
        item, depth = stack.pop()
        children: Iterable[Any]
        if isinstance(item, dict):
            children = item.values()
        elif isinstance(item, list | tuple):
            children = item
        else:
            continue
        depth += 1
        deepest = max(deepest, depth)
        if deepest > limit:
            return deepest
        stack.extend((child, depth) for child in children)
    return deepest


def _kind(mode: int) -> str:
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    return "not a file"
