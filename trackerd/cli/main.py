"""Entry point of the `trackerd` command: argument parsing and error reporting.

Subcommands live in sibling modules (config.py, locate.py, bench.py, ...); each
defines ``register(subparsers)`` and is discovered here, so adding a command
never touches this file; only the module of the command given is imported.
Signal handling belongs to the commands that run long (``run``, ``simrig``,
``record``), never to the library.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import pkgutil
import sys
from collections.abc import Sequence

import trackerd
import trackerd.cli
from trackerd import logs
from trackerd.errors import TrackerdError


def _command_modules() -> list[str]:
    """The modules that define commands; a module ``cpu_latency`` defines ``cpu-latency``."""
    names = (m.name for m in pkgutil.iter_modules(trackerd.cli.__path__))
    return sorted(n for n in names if not n.startswith("_") and n != "main")


def _chosen_command(argv: Sequence[str], commands: set[str]) -> str | None:
    """The command word in ``argv`` (after the global options), or None: none given, a typo, or
    the main parser's own ``--help`` or ``--version`` before it (whose output lists every command)."""
    words = iter(argv)
    for word in words:
        if word in ("-h", "--help", "--version"):
            return None
        if word == "--log-level":
            next(words, None)
        elif not word.startswith("-"):
            return word if word in commands else None
    return None


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The whole parser, or, when ``argv`` names a command, one where only that command's module is
    imported: the others' imports (OpenCV, the pydantic models) would double the start-up time of a
    command such as ``trackerd keys`` or ``trackerd listen``. The rest are registered by name only."""
    parser = argparse.ArgumentParser(
        prog="trackerd",
        description="Track a red/blue pointer with two cameras and report where on the wall it points.",
        # No abbreviations of the global options: `--he run` would be the help of a parser in
        # which only `run` was loaded.
        allow_abbrev=False,
    )
    parser.add_argument("--version", action="version", version=f"trackerd {trackerd.__version__}")
    parser.add_argument(
        "--log-level",
        default="warning",
        choices=["debug", "info", "warning", "error"],
        help="how much to log on stderr (default: warning)",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    modules = {name.replace("_", "-"): name for name in _command_modules()}
    chosen = None if argv is None else _chosen_command(argv, set(modules))
    for command, name in modules.items():
        if chosen is not None and command != chosen:
            subparsers.add_parser(command)
            continue
        register = getattr(importlib.import_module(f"trackerd.cli.{name}"), "register", None)
        if register is not None:
            register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    args = build_parser(argv).parse_args(argv)
    # Timestamped lines on a terminal; priority-prefixed ones when stderr is journald's (logs.py).
    logs.configure(getattr(logging, args.log_level.upper()))
    try:
        return int(args.handler(args) or 0)
    except TrackerdError as err:
        print(f"{logs.error_prefix()}trackerd {args.command}: {err}", file=sys.stderr)
        return err.exit_code
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # Output piped into `head` and closed early: not an error worth a traceback.
        return 0


if __name__ == "__main__":
    sys.exit(main())
