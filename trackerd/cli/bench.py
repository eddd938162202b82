"""`trackerd bench NAME`: benchmarks that print figures (never pass/fail timing asserts).

Each benchmark is a module trackerd/bench/NAME.py defining ``add_arguments(parser)``
and ``run(args) -> int``; it is found here automatically.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil

import trackerd.bench


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("bench", help="run a benchmark and print its figures")
    bench_sub = parser.add_subparsers(dest="bench_name", metavar="NAME", required=True)
    for module_info in sorted(pkgutil.iter_modules(trackerd.bench.__path__), key=lambda m: m.name):
        if module_info.name.startswith("_"):
            continue
        module = importlib.import_module(f"trackerd.bench.{module_info.name}")
        if not hasattr(module, "run"):
            continue
        summary = (module.__doc__ or module_info.name).strip().splitlines()[0]
        sub = bench_sub.add_parser(module_info.name, help=summary, description=module.__doc__,
                                   formatter_class=argparse.RawDescriptionHelpFormatter)
        sub.add_argument("--json", action="store_true", help="print the figures as one JSON object")
        module.add_arguments(sub)
        sub.set_defaults(handler=module.run)
