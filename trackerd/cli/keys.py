"""`trackerd keys server|client`: make a CURVE key pair for the ZeroMQ publisher or a subscriber.

Writes NAME.key (the public key, to hand out) and NAME.key_secret (the key pair,
mode 0600, to keep) in ZeroMQ's certificate format, which pyzmq's
``zmq.auth.load_certificate`` and czmq's ``zcert_load`` read. docs/protocol.md,
"Security", walks through the whole setup.
"""

from __future__ import annotations

import argparse
import os
import re
from datetime import UTC, datetime
from pathlib import Path

import zmq

from trackerd.errors import ConfigError, TrackerdError

_NAME = re.compile(r"^[A-Za-z0-9_.-]{1,64}$")


class KeyFileError(TrackerdError):
    """A key file that cannot be written (exists, no permission, no such directory)."""


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "keys",
        help="make a CURVE key pair for the publisher (server) or a subscriber (client)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "role",
        choices=["server", "client"],
        help="server: the daemon's pair (outputs.zmq.curve_secret_key_file);"
        " client: a subscriber's pair (its .key goes into curve_authorized_keys_dir)",
    )
    parser.add_argument("--dir", default=".", help="directory to write into (default: the current one)")
    parser.add_argument("--name", help="file name stem (default: the role); e.g. the subscriber's host or app")
    parser.add_argument("--force", action="store_true", help="overwrite existing files")
    parser.set_defaults(handler=keys_command)


def keys_command(args: argparse.Namespace) -> int:
    name = args.name or args.role
    if not _NAME.match(name):
        raise ConfigError(f"--name '{name}': use letters, digits, '.', '_' or '-' (at most 64)")
    directory = Path(args.dir)
    if not directory.is_dir():
        raise KeyFileError(f"{directory}: no such directory")
    public_path, secret_path = write_key_pair(directory, name, args.role, force=args.force)
    print(f"public key: {public_path}")
    print(f"secret key: {secret_path} (mode 0600; keep it private)")
    if args.role == "server":
        print(
            "next: set outputs.zmq.curve_secret_key_file to the secret key's absolute path, make it"
            " readable by the trackerd user only, and give the public key to subscribers"
        )
    else:
        print(
            "next: copy the public key into the daemon's curve_authorized_keys_dir (if it has one) and"
            " run subscribers with --client-key on the secret key"
        )
    return 0


def write_key_pair(directory: Path, name: str, role: str, *, force: bool = False) -> tuple[Path, Path]:
    """Create NAME.key and NAME.key_secret in ``directory``; the secret is never readable by others."""
    public_path = directory / f"{name}.key"
    secret_path = directory / f"{name}.key_secret"
    if not force:
        existing = [str(p) for p in (public_path, secret_path) if p.exists()]
        if existing:
            verb = "exists" if len(existing) == 1 else "exist"
            raise KeyFileError(f"{' and '.join(existing)} already {verb}; use --force to replace")
    public, secret = zmq.curve_keypair()
    stamp = datetime.now(UTC).strftime("%Y-%m-%d %H:%M:%S UTC")
    _write(public_path, _certificate(public, None, role, stamp), 0o644)
    _write(secret_path, _certificate(public, secret, role, stamp), 0o600)
    return public_path, secret_path


def _certificate(public: bytes, secret: bytes | None, role: str, stamp: str) -> str:
    kind = "Secret" if secret else "Public"
    lines = [
        f"#   ZeroMQ CURVE {kind} Certificate: trackerd {role}, made {stamp} by `trackerd keys`",
        "#   Keep this file private (mode 0600)." if secret else "#   Hand this file to the other side.",
        "",
        "metadata",
        f'    role = "{role}"',
        "curve",
        f'    public-key = "{public.decode("ascii")}"',
    ]
    if secret:
        lines.append(f'    secret-key = "{secret.decode("ascii")}"')
    return "\n".join(lines) + "\n"


def _write(path: Path, text: str, mode: int) -> None:
    """Write a new file created with ``mode`` from the start (never briefly readable by others)."""
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, mode)
        with os.fdopen(fd, "w", encoding="ascii") as handle:
            handle.write(text)
        os.chmod(tmp, mode)  # the umask may have taken bits away from a public key
        os.replace(tmp, path)
    except OSError as err:
        tmp.unlink(missing_ok=True)
        raise KeyFileError(f"{path}: cannot write: {err.strerror}") from err
