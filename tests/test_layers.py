"""The layer contract: a trackerd module imports its own layer and the layers below it, never one above.

LAYERS below is the one statement of the layers; docs/architecture.md ("Layers") draws it and
cites this file, and a test here holds the drawing to the table. Every ``import`` and
``from ... import`` in a module counts, wherever it stands: at the top, inside a function (the
lazy imports that keep a command quick to start) and under ``if TYPE_CHECKING:`` (a type is a
dependency too). Imports by a computed name (``importlib.import_module(f"...")``) are not seen.

A second rule keeps private things private: a name starting with ``_`` is imported by no other
module, and a module starting with ``_`` (``trackerd/cli/_args.py``) only from its own package.
"""

from __future__ import annotations

import ast
import functools
import re
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
ARCHITECTURE_DOC = REPO / "docs" / "architecture.md"

LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    # Lowest first. A module is in the layer of the longest prefix that names it (trackerd.pipeline.tap
    # is in "stages", the rest of trackerd.pipeline in "daemon").
    (
        "foundation",
        (
            "trackerd",
            "trackerd.errors",
            "trackerd.pixelformat",
            "trackerd.files",
            "trackerd.logs",
            "trackerd.sdnotify",
            "trackerd.cpu_latency",
        ),
    ),
    # Pure math on NumPy arrays; knows nothing of the rig file.
    ("geometry", ("trackerd.geometry",)),
    # The rig file: models, loader, and the adapter that builds the geometry from it (rig_geometry.py).
    ("config", ("trackerd.config",)),
    # Images and the detector, which take the rig's camera and detector settings.
    ("detection", ("trackerd.detect", "trackerd.images", "trackerd.image_pairs")),
    # One image per camera in, one fix out.
    ("locator", ("trackerd.locator", "trackerd.ends", "trackerd.tracked_ends", "trackerd.joint", "trackerd.refine")),
    # What the daemon is built from: sources, calibration and its health, the wire messages and the
    # publisher, and the pipeline's own parts (queues, figures, the extension interface, the tap).
    (
        "stages",
        (
            "trackerd.acquisition",
            "trackerd.calibration",
            "trackerd.publish",
            "trackerd.pipeline.queues",
            "trackerd.pipeline.stats",
            "trackerd.pipeline.threadtime",
            "trackerd.pipeline.extensions",
            "trackerd.pipeline.events",
            "trackerd.pipeline.tap",
        ),
    ),
    # Beside the pipeline, attached through its extension interface or its tap.
    ("beside the pipeline", ("trackerd.recording", "trackerd.interaction", "trackerd.console")),
    # The daemon: the threads that wire the stages together.
    ("daemon", ("trackerd.pipeline",)),
    # The simulator and the benchmarks, which drive everything below.
    ("tools", ("trackerd.sim", "trackerd.bench")),
    # The command line: arguments, printing, signals, exit codes.
    ("commands", ("trackerd.cli", "trackerd.__main__")),
)

KNOWN_EXCEPTIONS: dict[tuple[str, str], str] = {
    # (importing module, imported module or private name): why it stays for now. The list only
    # shrinks: an exception whose import has gone fails test_known_exceptions_are_still_needed.
    (
        "trackerd.detect.margin",
        "trackerd.detect.colour._plane",
    ): "the detector's hot path, rewritten by the robustness issue; not touched by the layers change",
    (
        "trackerd.detect.search",
        "trackerd.detect.colour._plane",
    ): "the detector's hot path, rewritten by the robustness issue; not touched by the layers change",
}


@dataclass(frozen=True)
class Import:
    """One module imported by another, at a line, with the names taken from it (``from m import a``)."""

    importer: str
    imported: str
    names: tuple[str, ...]
    path: Path
    line: int

    def __str__(self) -> str:
        return f"{self.path.relative_to(REPO)}:{self.line}: {self.importer} imports {self.imported}"


def module_name(path: Path, root: Path = REPO) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def is_module(name: str, root: Path = REPO) -> bool:
    base = root.joinpath(*name.split("."))
    return base.with_suffix(".py").is_file() or (base / "__init__.py").is_file()


def imports_in(source: str, importer: str, path: Path, *, is_package: bool = False, root: Path = REPO) -> list[Import]:
    """Every trackerd module that ``source`` imports, wherever the statement stands.

    ``from A import b`` imports the module A.b when there is one, else the name b of A.
    """
    package = importer if is_package else importer.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [Import(importer, alias.name, (), path, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            origin = node.module or ""
            if node.level:
                parts = package.split(".")
                origin = ".".join(parts[: len(parts) - node.level + 1] + ([origin] if origin else []))
            names = []
            for alias in node.names:
                if is_module(f"{origin}.{alias.name}", root):
                    found.append(Import(importer, f"{origin}.{alias.name}", (), path, node.lineno))
                else:
                    names.append(alias.name)
            if names:
                found.append(Import(importer, origin, tuple(names), path, node.lineno))
    return [imp for imp in found if imp.imported == "trackerd" or imp.imported.startswith("trackerd.")]


@functools.cache
def all_imports(root: Path = REPO) -> list[Import]:
    """Every import in trackerd/ (read once per test session)."""
    out = []
    for path in sorted((root / "trackerd").rglob("*.py")):
        out += imports_in(
            path.read_text(encoding="utf-8"),
            module_name(path, root),
            path,
            is_package=path.name == "__init__.py",
            root=root,
        )
    return out


def layer_of(module: str) -> int | None:
    """Index in LAYERS of the longest prefix naming ``module`` (None if no layer names it)."""
    best: tuple[int, int] | None = None
    for index, (_, prefixes) in enumerate(LAYERS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and (best is None or len(prefix) > best[0]):
                best = (len(prefix), index)
    return None if best is None else best[1]


def upward(imports: list[Import]) -> list[str]:
    """One line for each import of a higher layer, naming both layers."""
    out = []
    for imp in imports:
        low, high = layer_of(imp.importer), layer_of(imp.imported)
        if low is None or high is None or high <= low or (imp.importer, imp.imported) in KNOWN_EXCEPTIONS:
            continue
        out.append(f"{imp}: layer '{LAYERS[low][0]}' may not import layer '{LAYERS[high][0]}'")
    return out


def private_reached(imports: list[Import]) -> list[str]:
    """One line for each private name taken from another module, or private module from another package."""
    out = []
    for imp in imports:
        for name in imp.names:
            key = (imp.importer, f"{imp.imported}.{name}")
            if name.startswith("_") and not name.startswith("__") and key not in KNOWN_EXCEPTIONS:
                out.append(f"{imp}: the private name {name}")
        parts = imp.imported.split(".")
        for depth, part in enumerate(parts):
            owner = ".".join(parts[:depth])
            inside = imp.importer == owner or imp.importer.startswith(owner + ".")
            if part.startswith("_") and not part.startswith("__") and not inside:
                out.append(f"{imp}: a private module of {owner}")
    return out


def test_every_module_has_a_layer() -> None:
    modules = [module_name(p) for p in sorted((REPO / "trackerd").rglob("*.py"))]
    unplaced = [m for m in modules if layer_of(m) is None]
    assert unplaced == [], "give these modules a layer in LAYERS (tests/test_layers.py)"


def test_no_layer_imports_a_higher_one() -> None:
    violations = upward(all_imports())
    assert violations == [], "\n".join(
        [
            "imports pointing up (LAYERS in tests/test_layers.py, docs/architecture.md 'Layers'): move the code to"
            " the layer that may import it, or hand the lower layer what it needs (arrays, a callable)",
            *violations,
        ]
    )


def test_private_names_and_modules_stay_private() -> None:
    violations = private_reached(all_imports())
    assert violations == [], "\n".join(
        ["private names used elsewhere (make them public or keep them home):", *violations]
    )


def test_known_exceptions_are_still_needed() -> None:
    """An exception whose import has gone is struck from the list, so the list only shrinks."""
    seen = set()
    for imp in all_imports():
        seen.add((imp.importer, imp.imported))
        seen.update((imp.importer, f"{imp.imported}.{name}") for name in imp.names)
    assert [pair for pair in KNOWN_EXCEPTIONS if pair not in seen] == []


def test_the_architecture_doc_draws_these_layers() -> None:
    """docs/architecture.md's drawing names the layers of LAYERS, top (commands) to bottom."""
    text = ARCHITECTURE_DOC.read_text(encoding="utf-8")
    section = text.split("\n## Layers\n", 1)[1].split("\n## ", 1)[0]
    drawing = section.split("```", 2)[1]
    names = {name for name, _ in LAYERS}
    drawn = [
        match
        for line in drawing.splitlines()
        if (match := re.match(r"\s*(\w[\w ]*?)\s{2,}", line)) and match.group(1) in names
    ]
    assert [m.group(1) for m in drawn] == [name for name, _ in reversed(LAYERS)]
    assert "tests/test_layers.py" in section


# ----------------------------------------------------------------- the checker itself


def test_an_upward_import_inside_a_function_is_caught() -> None:
    """A lazy import of a higher layer, as the benchmarks once imported replay_rig from the CLI."""
    source = "def handler():\n    from trackerd.cli.replay import replay_rig\n    from trackerd import errors\n"
    found = imports_in(source, "trackerd.bench.replay", REPO / "trackerd/bench/replay.py")
    assert [(i.imported, i.names, i.line) for i in found] == [
        ("trackerd.cli.replay", ("replay_rig",), 2),
        ("trackerd.errors", (), 3),
    ]
    [line] = upward(found)
    assert line.startswith("trackerd/bench/replay.py:2: ") and "'tools' may not import layer 'commands'" in line


def test_type_checking_and_relative_imports_count() -> None:
    source = (
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from . import camera\n"
        "    from ..config.models import WallConfig\n"
    )
    found = imports_in(source, "trackerd.geometry.wall", REPO / "trackerd/geometry/wall.py")
    assert [i.imported for i in found] == ["trackerd.geometry.camera", "trackerd.config.models"]
    [line] = upward(found)
    assert "layer 'geometry' may not import layer 'config'" in line


def test_private_names_from_another_module_are_caught() -> None:
    source = "from trackerd.sim.render import SceneRenderer, _quantise\nfrom trackerd.cli._args import positive_int\n"
    found = imports_in(source, "trackerd.sim.board", REPO / "trackerd/sim/board.py")
    assert [line.split(": ", 1)[1] for line in private_reached(found)] == [
        "trackerd.sim.board imports trackerd.sim.render: the private name _quantise",
        "trackerd.sim.board imports trackerd.cli._args: a private module of trackerd.cli",
    ]
    own = imports_in(
        "from trackerd.cli._args import positive_int\n",
        "trackerd.cli.calibrate",
        REPO / "trackerd/cli/calibrate/__init__.py",
        is_package=True,
    )
    assert private_reached(own) == []


@pytest.mark.parametrize(
    ("module", "layer"),
    [
        ("trackerd.pipeline.daemon", "daemon"),
        ("trackerd.pipeline.tap", "stages"),
        ("trackerd.config.rig_geometry", "config"),
        ("trackerd", "foundation"),
        ("trackerd.cli.calibrate.wall", "commands"),
    ],
)
def test_the_longest_prefix_decides(module: str, layer: str) -> None:
    index = layer_of(module)
    assert index is not None and LAYERS[index][0] == layer
