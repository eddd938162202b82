"""`trackerd bench NAME`: benchmarks that print figures (never pass/fail timing asserts).

Each benchmark is a module trackerd/bench/NAME.py defining ``add_arguments(parser)``
and ``run(args) -> int``; it is found here automatically. Only the benchmark asked
for is imported: together they pull in the simulator, calibration and recording
code, which every other command would otherwise load too (about half a second).
"""

from __future__ import annotations

import argparse
import ast
import importlib
import pkgutil
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import trackerd.bench


class _BenchParser(argparse.ArgumentParser):
    """A benchmark's parser, filled from its module only when that benchmark is chosen."""

    module_name: str | None = None

    def parse_known_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> tuple[argparse.Namespace, list[str]]:
        if self.module_name is not None:
            module = importlib.import_module(self.module_name)
            self.module_name = None
            self.description = module.__doc__
            module.add_arguments(self)
            self.set_defaults(handler=module.run)
        return super().parse_known_args(args, namespace)


def _module_doc(path: Path) -> tuple[str | None, bool]:
    """A benchmark module's docstring, and whether it defines run(), read without importing it."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    has_run = any(isinstance(node, ast.FunctionDef) and node.name == "run" for node in tree.body)
    return ast.get_docstring(tree), has_run


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser("bench", help="run a benchmark and print its figures")
    bench_sub = parser.add_subparsers(dest="bench_name", metavar="NAME", required=True, parser_class=_BenchParser)
    folder = Path(trackerd.bench.__path__[0])
    for module_info in sorted(pkgutil.iter_modules(trackerd.bench.__path__), key=lambda m: m.name):
        if module_info.name.startswith("_"):
            continue
        doc, has_run = _module_doc(folder / f"{module_info.name}.py")
        if not has_run:
            continue
        summary = (doc or module_info.name).strip().splitlines()[0]
        sub = bench_sub.add_parser(
            module_info.name, help=summary, description=doc, formatter_class=argparse.RawDescriptionHelpFormatter
        )
        sub.module_name = f"trackerd.bench.{module_info.name}"
        sub.add_argument("--json", action="store_true", help="print the figures as one JSON object")
