"""Argument types the commands share (a module starting with ``_`` defines no command)."""

from __future__ import annotations

import argparse
import math


def _finite(text: str) -> float:
    """The number in ``text``, NaN when it is none or not finite (nan and inf crashed where they were taken)."""
    try:
        value = float(text)
    except ValueError:
        return math.nan
    return value if math.isfinite(value) else math.nan


def _whole(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None


def positive_seconds(text: str) -> float:
    """``--seconds``: a finite number above zero (0 or -1 used to run for a moment and exit 0)."""
    if not _finite(text) > 0:
        raise argparse.ArgumentTypeError(f"must be a positive number of seconds, not {text!r}")
    return float(text)


def delay_seconds(text: str) -> float:
    """``--delay``: a finite number of seconds, 0 or more."""
    if not _finite(text) >= 0:
        raise argparse.ArgumentTypeError(f"must be a number of seconds, 0 or more, not {text!r}")
    return float(text)


def pair_number(text: str) -> int:
    """A pair's number in a recording, from 0 (a negative one was taken as 0 in silence)."""
    value = _whole(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"pairs are numbered from 0, not {value}")
    return value


def positive_int(text: str) -> int:
    """A count of at least 1."""
    value = _whole(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, not {value}")
    return value


def console_address(text: str) -> str:
    """``--console HOST:PORT`` of a running daemon's console (a malformed one was a traceback)."""
    from trackerd.config.console import split_listen

    try:
        split_listen(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    return text


def add_console_option(parser: argparse.ArgumentParser) -> None:
    """``--console ADDR``: where the operator's console listens (the rig's ``[console]`` otherwise)."""
    parser.add_argument(
        "--console",
        metavar="ADDR",
        help="serve the operator's console on HOST:PORT instead of the rig's [console] listen"
        " (default 127.0.0.1:8560), or 'off'",
    )
