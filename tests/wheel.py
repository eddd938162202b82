"""trackerd's wheel, built from a copy of the checkout without the network, for the install tests."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
NOT_SOURCE = shutil.ignore_patterns(
    ".git",
    ".venv",
    ".cache",
    "build",
    "*.egg-info",
    "__pycache__",
    ".pytest_cache",
    ".ruff_cache",
    ".mypy_cache",
    ".hypothesis",
    "simrig-out",
    "tests",
)
"""What a build does not need from the checkout: VCS, caches, earlier builds' leftovers, the tests."""


def build_wheel(work: Path) -> Path:
    """Build ``trackerd-*.whl`` into ``work/wheels`` and return it.

    From a copy (a build writes build/ into its source, and must not pack a stale build/lib), with the
    test environment's own build backend (setuptools>=77 is in the [test] extra) and no index: tests
    reach nothing beyond loopback, and a build needs nothing from it.
    """
    source = work / "source"
    shutil.copytree(REPO, source, symlinks=True, ignore=NOT_SOURCE)
    built = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "--disable-pip-version-check",
            "-q",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "--no-index",
            "-w",
            str(work / "wheels"),
            str(source),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert built.returncode == 0, built.stderr
    (wheel,) = (work / "wheels").glob("trackerd-*.whl")
    return wheel
