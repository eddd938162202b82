"""Argument types the commands share (a module starting with ``_`` defines no command)."""

from __future__ import annotations

import argparse
import math


def positive_seconds(text: str) -> float:
    """``--seconds``: a finite number above zero (0 or -1 used to run for a moment and exit 0)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a positive number of seconds, not {text!r}")
    return value


def positive_int(text: str) -> int:
    """A count of at least 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, not {value}")
    return value
