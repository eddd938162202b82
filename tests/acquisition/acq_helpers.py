"""Shared helpers of the acquisition tests (imported by name: tests/acquisition is on sys.path)."""

from __future__ import annotations

import gc
import os
import threading
import time
from collections.abc import Callable

import pytest

from trackerd.acquisition.arv import aravis_missing_reason
from trackerd.config.models import RigConfig
from trackerd.sim.netns import netns_missing_reason

TEST_PREFIX = "trkdt"
"""Namespace prefix of the tests' virtual rigs, distinct from `trackerd simrig`'s default."""
TEST_SUBNET = "10.213.200.0/24"

ARAVIS_MISSING = aravis_missing_reason()
NETNS_MISSING = netns_missing_reason()

needs_aravis = pytest.mark.skipif(ARAVIS_MISSING is not None, reason=f"needs Aravis: {ARAVIS_MISSING}")
needs_netns = pytest.mark.skipif(
    NETNS_MISSING is not None, reason=f"needs network namespaces for two simulated cameras: {NETNS_MISSING}"
)


def quick_rig(rig: RigConfig, **acquisition: object) -> RigConfig:
    """The rig with quicker loss detection and reconnection, plus any acquisition overrides."""
    settings: dict[str, object] = {
        "loss_timeout_ms": 300.0,
        "reconnect_min_backoff_ms": 50.0,
        "reconnect_max_backoff_ms": 200.0,
    }
    settings.update(acquisition)
    return rig.model_copy(update={"acquisition": rig.acquisition.model_copy(update=settings)})


def wait_until(condition: Callable[[], bool], timeout_s: float, step_s: float = 0.02) -> bool:
    """Poll ``condition`` until it holds or ``timeout_s`` passes; whether it held."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(step_s)
    return condition()


def resources() -> tuple[int, int]:
    """(threads, open file descriptors) of this process, as the kernel counts them."""
    return len(os.listdir("/proc/self/task")), len(os.listdir("/proc/self/fd"))


def settled_resources(timeout_s: float = 15.0, steady_s: float = 0.6) -> tuple[int, int]:
    """``resources()`` once nothing is left to collect and the counts have not changed for ``steady_s``.

    Earlier tests in the same process leave cameras' objects (pylon's, GenTL's, Aravis's) in reference
    cycles that hold threads and descriptors until the garbage collector runs, whenever that is; and
    Aravis ends some of its threads asynchronously. So the collector is run before every reading, and
    the counts must hold still (under load a thread's exit shows late).
    """
    deadline = time.monotonic() + timeout_s
    gc.collect()
    last = resources()
    steady_since = time.monotonic()
    while time.monotonic() < deadline:
        time.sleep(0.1)
        gc.collect()
        now = resources()
        if now != last:
            last, steady_since = now, time.monotonic()
        elif time.monotonic() - steady_since >= steady_s:
            return now
    return last


def acquisition_threads() -> list[str]:
    """Names of live threads started by the acquisition package."""
    prefixes = ("camera-", "trigger-")
    return [t.name for t in threading.enumerate() if t.name.startswith(prefixes)]
