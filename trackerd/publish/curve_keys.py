"""CURVE key files: the publisher's key pair and the public keys subscribers need (``trackerd keys``).

Apart from the publisher, so that a subscriber (``trackerd listen``) can read keys
without importing the rig's configuration models.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

import zmq.auth

from trackerd.errors import ConfigError


def _read_certificate(path: Path, missing: str) -> tuple[bytes, bytes | None]:
    """(public, secret or None) from a ZeroMQ certificate file; ConfigError, ending in ``missing``
    when there is no such file, for anything unusable."""
    try:
        path.stat()  # load_certificate says only "Invalid certificate file" for a missing one
        return zmq.auth.load_certificate(os.fspath(path))
    except FileNotFoundError as err:
        raise ConfigError(f"{path}: no such CURVE key file{missing}") from err
    except OSError as err:
        raise ConfigError(f"{path}: cannot read CURVE key file: {err.strerror}") from err
    except ValueError as err:
        raise ConfigError(f"{path}: not a CURVE key file ({err})") from err


def load_curve_key_pair(path: Path) -> tuple[bytes, bytes]:
    """(public, secret) Z85 keys from a ``.key_secret`` file; ConfigError when unusable or exposed."""
    public, secret = _read_certificate(path, " (make one with `trackerd keys server`)")
    if not secret:
        raise ConfigError(f"{path}: holds a public key only; give the .key_secret file")
    mode = path.stat().st_mode
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise ConfigError(
            f"{path}: secret key is accessible to other users (mode {stat.S_IMODE(mode):04o}); chmod 600 it"
        )
    return public, secret


def load_curve_public_key(path: Path) -> bytes:
    """The public key from a ``.key`` (or ``.key_secret``) file; ConfigError when unusable."""
    return _read_certificate(path, "")[0]
