"""Stopping while a camera is still being looked for: no wait for Aravis's discovery (real Aravis, no cameras)."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from acq_helpers import needs_aravis

pytestmark = [needs_aravis, pytest.mark.serial]  # serial: times how soon the daemon stops

RIG = Path(__file__).resolve().parents[2] / "config" / "simulated.toml"


def test_stopping_does_not_wait_for_the_search_for_a_missing_camera(simulated_rig) -> None:
    from trackerd.cli.run import aravis_source

    # config/simulated.toml's cameras (serials SIM-LEFT, SIM-RIGHT) are not there: each thread runs
    # Aravis's discovery, a second long and not interruptible, again and again.
    source = aravis_source(simulated_rig)
    source.start()
    try:
        time.sleep(1.5)
        assert [c.state for c in source.status().cameras] == ["connecting", "connecting"]
    finally:
        start = time.monotonic()
        source.stop()
        took = time.monotonic() - start
    # It holds nothing, so it is not waited for (a camera with a connection is: tests/acquisition/
    # test_start_stop.py).
    assert took < 0.5, f"stop took {took:.2f} s"


def test_the_daemon_says_which_cameras_it_waits_for_and_stops_at_once_without_them() -> None:
    run = subprocess.Popen([sys.executable, "-m", "trackerd", "run", "--config", str(RIG)], stderr=subprocess.PIPE)
    assert run.stderr is not None
    # Up when it says where it publishes (after the pipeline and the console started) and what it waits
    # for: a fixed wait sent SIGTERM before a loaded machine had even imported the daemon (exit -15),
    # and a stop sent before it was up timed the rest of its start too. Read unbuffered: the lines may
    # come in one read.
    said = b""
    deadline = time.monotonic() + 60.0

    def up() -> bool:
        return b"publishing on" in said and said.count(b"not available yet") >= 2

    try:
        while not up() and time.monotonic() < deadline:
            if select.select([run.stderr], [], [], 1.0)[0]:
                chunk = os.read(run.stderr.fileno(), 65536)
                if not chunk:
                    break  # it exited
                said += chunk
    finally:
        start = time.monotonic()
        run.send_signal(signal.SIGTERM)
        code = run.wait(10)
        took = time.monotonic() - start
    stderr = (said + run.stderr.read()).decode()
    assert code == 0, stderr
    assert took < 1.0, f"exit took {took:.2f} s after SIGTERM"
    # At the default log level, one line per camera says what is missing.
    waiting = [line for line in stderr.splitlines() if "not available yet" in line]
    assert len(waiting) == 2 and all("WARNING" in line for line in waiting), stderr
    assert "camera 'left' (serial SIM-LEFT) not found" in waiting[0]
    assert "Traceback" not in stderr and "did not stop in time" not in stderr
