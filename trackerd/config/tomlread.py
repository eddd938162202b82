"""Reading a rig or calibration file's TOML, bounded, with one-line errors."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from trackerd.errors import ConfigError
from trackerd.files import MAX_DEPTH, NotRegularFile, TooLarge, nesting_depth, read_bounded

MAX_TOML_BYTES = 4 * 1024 * 1024
"""A rig or calibration file is a few kilobytes; one of megabytes is not one (and would be parsed on
the daemon's main thread at a SIGHUP)."""


def read_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file, turning I/O and syntax problems into one-line ConfigErrors.

    Only a regular file of at most :data:`MAX_TOML_BYTES`, nested at most ``MAX_DEPTH`` levels, is
    read (trackerd.files): never a FIFO, which would block the reader until someone writes to it.
    """
    try:
        # utf-8-sig: a byte-order mark in front (Windows editors write one) is not the file's content.
        text = read_bounded(path, MAX_TOML_BYTES).decode("utf-8-sig")
        data = tomllib.loads(text)
    except FileNotFoundError as err:
        raise ConfigError(f"{path}: no such file") from err
    except IsADirectoryError as err:
        raise ConfigError(f"{path}: is a directory, expected a TOML file") from err
    except PermissionError as err:
        raise ConfigError(f"{path}: permission denied") from err
    except (NotRegularFile, TooLarge) as err:
        raise ConfigError(f"{err}; expected a TOML file") from err
    except OSError as err:
        raise ConfigError(f"{path}: cannot read: {err.strerror or err}") from err
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"{path}: not valid TOML: {err}") from err
    except UnicodeDecodeError as err:
        raise ConfigError(f"{path}: not a text file (UTF-8 expected)") from err
    except RecursionError as err:
        raise ConfigError(f"{path}: nested too deeply to be a rig or calibration file") from err
    except ValueError as err:
        # Not a TOMLDecodeError: tomllib reads an integer with int(), which refuses one of more than
        # sys.get_int_max_str_digits() digits (4300) with a plain ValueError.
        raise ConfigError(f"{path}: not valid TOML: {str(err).split(';')[0]}") from err
    if nesting_depth(data) > MAX_DEPTH:
        raise ConfigError(f"{path}: nested more than {MAX_DEPTH} levels deep; not a rig or calibration file")
    return data
