"""Fixtures shared across the test suite: the example rigs and the scene renderer.

Rendered backgrounds are cached under the repository's .cache/ (ignored by git),
so only the first test session on a machine pays for rendering each camera's room.
"""

from __future__ import annotations

import copy
import os
from pathlib import Path

# One OpenBLAS thread per process, set before NumPy loads OpenBLAS (which reads it once) and inherited
# by the xdist workers and every trackerd the tests start. The suite runs two workers on two cores, or
# daemons beside the test: OpenBLAS's own threads then wait for cores, spinning, and the renderer's
# (N, 3) @ (3, 3) ray rotations took 10-20 times longer (91 ms against 1.8 s for 2 million rays, measured
# on this 2-core machine under load). Results are the same bit for bit (tests/sim/test_rendered_bits.py).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# OpenBLAS picks its matrix kernels by CPU model unless told, and kernels differ in the last bit of a
# product; the renderer's ray rotations are matrix products, so tests/sim/test_rendered_bits.py's hashes
# hold for one kernel only (an Intel CPU's "SkylakeX" kernels recorded them first; this machine's
# environment asks for "Haswell", under which all 8 of its tests failed on unchanged code). The hashes are
# now those of the Haswell kernels, which every x86 CPU with AVX2 runs, set here whatever the environment says.
if Path("/proc/cpuinfo").exists() and " avx2" in Path("/proc/cpuinfo").read_text(encoding="ascii", errors="replace"):
    os.environ["OPENBLAS_CORETYPE"] = "Haswell"

import numpy as np
import pytest
from hypothesis import settings

from trackerd.config.loader import load_rig
from trackerd.config.models import RigConfig

# Property tests check results, not speed: on a loaded machine one example may take longer than
# hypothesis's default 200 ms deadline, which would fail a correct test.
settings.register_profile("trackerd", deadline=None)
# HYPOTHESIS_PROFILE=thorough: many more examples, to look for bugs on purpose.
settings.register_profile("thorough", deadline=None, max_examples=2000)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "trackerd"))


def _same_draws_whatever_was_imported() -> None:
    """Hypothesis (6.131 on) mixes constants found in the source of every local module loaded so far
    into what it draws, so a derandomized test drew other cases depending on which tests had run
    before it in the same process, which pytest-xdist decides: the publisher fuzz of test_fuzz.py
    sent 93 messages after tests/cli/test_command_loading.py had loaded every command, 179
    otherwise, and failed its check of how much it sent. The fuzz tests promise the same cases on
    every run (``derandomize``): the constants stay those of before any test (none)."""
    try:
        from hypothesis.internal.conjecture import providers
    except ImportError:  # a Hypothesis without it draws no local constants
        return
    if not hasattr(providers, "_get_local_constants") or not hasattr(providers, "_local_constants"):
        return
    before_any_test = copy.deepcopy(providers._local_constants)
    providers._get_local_constants = lambda: before_any_test


_same_draws_whatever_was_imported()

REPO = Path(__file__).resolve().parent.parent
CONFIG_DIR = REPO / "config"
DATA_DIR = Path(__file__).resolve().parent / "data"
RENDER_CACHE = REPO / ".cache" / "backgrounds"


@pytest.fixture(scope="session")
def simulated_rig() -> RigConfig:
    """config/simulated.toml, as loaded by trackerd."""
    return load_rig(CONFIG_DIR / "simulated.toml").config


@pytest.fixture(scope="session")
def renderer(simulated_rig: RigConfig):
    """A SceneRenderer for the simulated rig, shared by the whole session (its backgrounds are cached)."""
    from trackerd.sim.render import SceneRenderer

    return SceneRenderer(simulated_rig, cache_dir=RENDER_CACHE)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


@pytest.fixture
def searches(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """One entry per run of the refined path's search over every camera's candidates during the test
    (RefinedPath._locate_searched, the real one, called through): its length is how many ran."""
    from trackerd.refine import RefinedPath

    runs: list[int] = []
    search = RefinedPath._locate_searched

    def counted(self: RefinedPath, *args: object) -> object:
        runs.append(1)
        return search(self, *args)

    monkeypatch.setattr(RefinedPath, "_locate_searched", counted)
    return runs


def pytest_configure(config: pytest.Config) -> None:
    # Benchmarks and the CLI share the cache with tests when run from the repo.
    os.environ.setdefault("TRACKERD_RENDER_CACHE", str(RENDER_CACHE))


SERIAL_MARKERS = frozenset({"root", "aravis", "pylon", "gentl", "hardware", "serial"})
"""Modules holding a test with one of these markers run in scripts/test's second pass, alone and
one test after another: they run cameras (virtual GigE Vision rigs in network namespaces, whose
prefixes, locks and ports a module's tests share, pylon's emulation, a GenTL producer), daemons
or a browser, or measure how long something takes (`serial`: stopping within a second, events
within a few seconds). The first pass runs the rest on two pytest-xdist workers."""


@pytest.hookimpl(tryfirst=True)  # before pytest's -m selection reads the markers
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    # Whole modules: a module's other tests share its rigs' ports and files (a refusal test binds
    # the endpoint its module's daemons use).
    serial = {item.path for item in items if SERIAL_MARKERS & {mark.name for mark in item.iter_markers()}}
    for item in items:
        if item.path in serial:
            item.add_marker(pytest.mark.serial)
