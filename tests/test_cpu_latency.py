"""The PM QoS CPU latency request (trackerd/cpu_latency.py, `trackerd cpu-latency`) against the real
kernel interface: the request is in force while held, gone once released, and refused with one line
to a process that may not make it."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.cpu_holder import run_holder
from trackerd.cpu_latency import DEVICE, CpuLatencyError, available, current_us, held

needs_device = pytest.mark.skipif(
    not available(), reason=f"{DEVICE} is not writable here (needs root and a kernel with PM QoS)"
)


def _looser_than(us: int) -> int:
    """What is in force now, skipping the test if it is already as strict as ``us`` (someone on this
    host holds a request, trackerd-cpu-latency for one): then ours could not be seen."""
    before = current_us()
    assert before is not None
    if before <= us:
        pytest.skip(f"a request of {before} µs is already in force here")
    return before


@needs_device
def test_a_request_is_in_force_while_held_and_gone_after():
    before = _looser_than(7)
    with held(7):
        assert current_us() == 7
    assert current_us() == before


@needs_device
def test_the_request_ends_when_the_block_raises():
    before = _looser_than(9)
    with pytest.raises(RuntimeError), held(9):
        assert current_us() == 9
        raise RuntimeError("the block fails")
    assert current_us() == before


def test_a_missing_device_is_one_line(tmp_path: Path):
    with pytest.raises(CpuLatencyError) as err, held(0, tmp_path / "no-such-device"):
        pass
    assert "no such device" in str(err.value)
    assert "\n" not in str(err.value)


def test_an_out_of_range_request_is_refused():
    with pytest.raises(CpuLatencyError, match="0 to"), held(-1):
        pass


@needs_device
def test_the_command_holds_the_request_tells_systemd_and_stops_on_sigterm(tmp_path: Path):
    """As the trackerd-cpu-latency unit runs it: root with no capabilities and no new privileges."""
    if shutil.which("setpriv") is None:
        pytest.skip("setpriv (util-linux) is not installed")
    before = _looser_than(11)
    run = run_holder(
        [
            "setpriv",
            "--bounding-set=-all",
            "--inh-caps=-all",
            "--no-new-privs",
            sys.executable,
            "-m",
            "trackerd",
            "cpu-latency",
            "--max-us",
            "11",
        ],
        tmp_path,
    )
    assert "READY=1" in run.ready.splitlines()
    assert "STATUS=CPU wake-up latency held at 11 µs" in run.ready
    assert run.in_force_us == 11
    assert run.returncode == 0, run.stderr
    assert run.stop_s < 1.0
    assert "held at 11 µs" in run.stdout
    assert run.stderr == ""
    assert current_us() == before


def test_the_command_as_an_unprivileged_user_says_why_in_one_line():
    if os.geteuid() != 0 or shutil.which("setpriv") is None or not DEVICE.exists():
        pytest.skip(f"needs root (to become another user), setpriv and {DEVICE}")
    nobody = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"]
    result = subprocess.run(
        [*nobody, sys.executable, "-m", "trackerd", "cpu-latency"], capture_output=True, text=True, timeout=30
    )
    assert result.returncode == CpuLatencyError.exit_code == 3  # the unit's RestartPreventExitStatus
    assert result.stderr.count("\n") == 1, result.stderr
    assert "permission denied" in result.stderr
    assert "Traceback" not in result.stderr
