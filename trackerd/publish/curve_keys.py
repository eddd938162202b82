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


def load_curve_key_pair(path: Path) -> tuple[bytes, bytes]:
    """(public, secret) Z85 keys from a ``.key_secret`` file; ConfigError when unusable or exposed."""
    try:
        mode = path.stat().st_mode
        public, secret = zmq.auth.load_certificate(os.fspath(path))
    except FileNotFoundError as err:
        raise ConfigError(f"{path}: no such CURVE key file (make one with `trackerd keys server`)") from err
    except OSError as err:
        raise ConfigError(f"{path}: cannot read CURVE key file: {err.strerror}") from err
    except ValueError as err:
        raise ConfigError(f"{path}: not a CURVE key file ({err})") from err
    if not secret:
        raise ConfigError(f"{path}: holds a public key only; give the .key_secret file")
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise ConfigError(
            f"{path}: secret key is accessible to other users (mode {stat.S_IMODE(mode):04o}); chmod 600 it"
        )
    return public, secret


def load_curve_public_key(path: Path) -> bytes:
    """The public key from a ``.key`` (or ``.key_secret``) file; ConfigError when unusable."""
    try:
        public, _ = zmq.auth.load_certificate(os.fspath(path))
    except FileNotFoundError as err:
        raise ConfigError(f"{path}: no such CURVE key file") from err
    except OSError as err:
        raise ConfigError(f"{path}: cannot read CURVE key file: {err.strerror}") from err
    except ValueError as err:
        raise ConfigError(f"{path}: not a CURVE key file ({err})") from err
    return public
