"""A real install (issue 15): the wheel's commands find their example rigs from any directory.

The wheel is built from a copy of the checkout and installed into a fresh virtual
environment that borrows only the project environment's dependencies (a .pth file
naming its site-packages; the editable install there is not loaded, so a module
missing from the wheel cannot be served from a checkout). Its ``trackerd`` script then
runs from a folder that is not the checkout. Before the example rigs were package data,
`trackerd demo` looked for ``site-packages/config/simulated.toml`` and every bench
for ``./config/simulated.toml``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

from tests.wheel import build_wheel
from trackerd.acquisition.arv import aravis_missing_reason

REPO = Path(__file__).resolve().parent.parent
ARAVIS_MISSING = aravis_missing_reason()
PREFIX = "trkdw"
"""Namespace prefix of the demo's virtual rig here, distinct from the other tests' and `trackerd demo`'s."""
SUBNET = "10.213.230.0/24"
ENDPOINT = "tcp://127.0.0.1:5583"
"""Away from the rig's own 5560, which other tests use. Fixed, because the endpoint is part of the rig
the simulated cameras' rendered loop is cached under: a new one each run would render it again (~20 s)."""

pytestmark = [pytest.mark.slow, pytest.mark.serial]  # serial: runs the installed demo on a virtual rig


def _run(*command: str | Path, timeout_s: float, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """``command`` without the test session's PYTHONPATH (which puts the checkout first), caches shared."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["TRACKERD_SIMRIG_CACHE"] = str(REPO / ".cache" / "simrig")
    return subprocess.run(
        [str(c) for c in command], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout_s
    )


@pytest.fixture(scope="module")
def venv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh virtual environment with trackerd installed from a freshly built wheel."""
    work = tmp_path_factory.mktemp("install")
    wheel = build_wheel(work)
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    # --system-site-packages for Debian's PyGObject and Aravis, as docs/deployment.md makes it.
    venv = work / "venv"
    made = _run(sys.executable, "-m", "venv", "--without-pip", "--system-site-packages", venv, timeout_s=60)
    assert made.returncode == 0, made.stderr
    (site_packages,) = venv.glob("lib/python*/site-packages")
    (site_packages / "project-dependencies.pth").write_text(sysconfig.get_path("purelib") + "\n")
    setup = _run(*pip, "--python", venv / "bin" / "python", "install", "--no-deps", "--no-index", wheel, timeout_s=120)
    assert setup.returncode == 0, setup.stderr
    return venv


@pytest.fixture
def elsewhere(tmp_path: Path) -> Path:
    """A working directory with no config/ in it."""
    folder = tmp_path / "elsewhere"
    folder.mkdir()
    return folder


def test_the_installed_package_is_the_one_that_runs(venv: Path, elsewhere: Path) -> None:
    where = _run(
        venv / "bin" / "python", "-c", "import trackerd; print(trackerd.__file__)", cwd=elsewhere, timeout_s=30
    )
    assert Path(where.stdout.strip()).is_relative_to(venv / "lib"), where.stderr


def test_the_console_page_is_installed(venv: Path, elsewhere: Path) -> None:
    # The console serves its page from package data: a wheel without it answers every browser with 404.
    code = (
        "from importlib import resources; s = resources.files('trackerd.console') / 'static';"
        " print(sorted(p.name for p in s.iterdir()))"
    )
    listed = _run(venv / "bin" / "python", "-c", code, cwd=elsewhere, timeout_s=30)
    assert listed.returncode == 0, listed.stderr
    for name in ("index.html", "console.js", "console.css"):
        assert name in listed.stdout, listed.stdout


def test_bench_accuracy_runs_from_another_directory(venv: Path, elsewhere: Path) -> None:
    # One group of the three keeps it short; the default --config is the same for all.
    run = _run(
        venv / "bin" / "trackerd",
        "bench",
        "accuracy",
        "--poses",
        "5",
        "--groups",
        "placements",
        cwd=elsewhere,
        timeout_s=120,
    )
    assert run.returncode == 0, run.stderr
    assert "trackerd median" in run.stdout


@pytest.mark.aravis
@pytest.mark.skipif(ARAVIS_MISSING is not None, reason=f"needs Aravis: {ARAVIS_MISSING}")
def test_demo_runs_from_another_directory(venv: Path, elsewhere: Path) -> None:
    run = _run(
        venv / "bin" / "trackerd",
        "demo",
        "--seconds",
        "5",
        "--prefix",
        PREFIX,
        "--subnet",
        SUBNET,
        "--endpoint",
        ENDPOINT,
        cwd=elsewhere,
        timeout_s=180,
    )
    assert run.returncode == 0, run.stderr
    assert "hit " in run.stdout, run.stderr
