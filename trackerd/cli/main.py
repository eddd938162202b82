"""Entry point of the `trackerd` command: argument parsing and error reporting.

Subcommands live in sibling modules (config.py, locate.py, bench.py, ...); each
defines ``register(subparsers)`` and is discovered here, so adding a command
never touches this file. Signal handling belongs to the commands that run
long (``run``, ``simrig``, ``record``), never to the library.
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
from trackerd.errors import TrackerdError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="trackerd",
        description="Track a red/blue pointer with two cameras and report where on the wall it points.",
    )
    parser.add_argument("--version", action="version", version=f"trackerd {trackerd.__version__}")
    parser.add_argument(
        "--log-level",
        default="warning",
        choices=["debug", "info", "warning", "error"],
        help="how much to log on stderr (default: warning)",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for module_info in sorted(pkgutil.iter_modules(trackerd.cli.__path__), key=lambda m: m.name):
        if module_info.name.startswith("_") or module_info.name == "main":
            continue
        module = importlib.import_module(f"trackerd.cli.{module_info.name}")
        register = getattr(module, "register", None)
        if register is not None:
            register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=getattr(logging, args.log_level.upper()),
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
    )
    try:
        return int(args.handler(args) or 0)
    except TrackerdError as err:
        print(f"trackerd {args.command}: {err}", file=sys.stderr)
        return err.exit_code
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # Output piped into `head` and closed early: not an error worth a traceback.
        return 0


if __name__ == "__main__":
    sys.exit(main())
