"""A small TOML writer for trackerd's own files (calibration files, rig files it generates).

Python's standard library reads TOML (tomllib) but does not write it. The
files need only tables, strings, integers, booleans, floats and
(nested) arrays of those, so this emitter covers exactly that:

* floats are written with ``repr``, the shortest text that reads back to the
  same double, so a value survives a write and a read bit for bit; NaN and
  infinity are refused (no calibration value can take them);
* a table's plain values come first, then its sub-tables as ``[a.b]`` headers,
  then its arrays of tables as ``[[a.b]]`` (a rig file's cameras);
* keys that are not bare (letters, digits, ``_`` and ``-``) are quoted.
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def dumps(data: Mapping[str, Any], header: str = "") -> str:
    """The TOML text of a mapping; ``header`` lines are written first as comments."""
    lines: list[str] = [f"# {line}".rstrip() for line in header.splitlines()]
    if lines:
        lines.append("")
    _table(data, [], lines)
    while lines and lines[-1] == "":
        lines.pop()
    return "\n".join(lines) + "\n"


def _table(data: Mapping[str, Any], path: list[str], lines: list[str], element: bool = False) -> None:
    """Write a table: its plain values under its header, then its sub-tables and arrays of tables.

    ``element``: the table is one element of an array of tables (``[[path]]``), whose
    header must be written even when it holds only sub-tables.
    """

    def is_table_array(v: Any) -> bool:
        return (
            isinstance(v, Sequence)
            and not isinstance(v, str)
            and bool(v)
            and all(isinstance(item, Mapping) for item in v)
        )

    values = [(k, v) for k, v in data.items() if not isinstance(v, Mapping) and not is_table_array(v)]
    tables = [(k, v) for k, v in data.items() if isinstance(v, Mapping)]
    arrays = [(k, v) for k, v in data.items() if is_table_array(v)]
    header = ".".join(_key(p) for p in path)
    if element:
        lines.append(f"[[{header}]]")
    elif path and (values or not (tables or arrays)):
        lines.append(f"[{header}]")
    for key, value in values:
        if value is None:
            continue
        lines.append(f"{_key(key)} = {_value(value, [*path, key])}")
    if values or element or (path and not (tables or arrays)):
        lines.append("")
    for key, value in tables:
        _table(value, [*path, key], lines)
    for key, items in arrays:
        for item in items:
            _table(item, [*path, key], lines, element=True)


def _key(key: str) -> str:
    if not isinstance(key, str):
        raise TypeError(f"TOML keys are strings, got {key!r}")
    return key if _BARE_KEY.fullmatch(key) else _string(key)


def _value(value: Any, path: list[str]) -> str:
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        value = float(value)  # NumPy's float64 repr is 'np.float64(...)'
        if not math.isfinite(value):
            raise ValueError(f"{'.'.join(path)}: {value} cannot be written (no calibration value is NaN or infinite)")
        text = repr(value)
        return text if any(c in text for c in ".eE") else text + ".0"
    if isinstance(value, str):
        return _string(value)
    if isinstance(value, Sequence) or hasattr(value, "tolist"):
        value = value.tolist() if hasattr(value, "tolist") else value
        return "[" + ", ".join(_value(v, path) for v in value if v is not None) + "]"
    raise TypeError(f"{'.'.join(path)}: cannot write {type(value).__name__} to TOML")


def _string(text: str) -> str:
    out = []
    for char in text:
        if char == '"':
            out.append('\\"')
        elif char == "\\":
            out.append("\\\\")
        elif char == "\n":
            out.append("\\n")
        elif char == "\t":
            out.append("\\t")
        elif char == "\r":
            out.append("\\r")
        elif ord(char) < 0x20 or ord(char) == 0x7F:
            out.append(f"\\u{ord(char):04x}")
        else:
            out.append(char)
    return '"' + "".join(out) + '"'
