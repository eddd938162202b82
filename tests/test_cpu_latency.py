"""The PM QoS CPU latency request (trackerd/cpu_latency.py, `trackerd cpu-latency`) against the real
kernel interface: the request is in force while held, gone once released, and refused with one line
to a process that may not make it."""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from trackerd.cpu_latency import DEVICE, CpuLatencyError, available, current_us, held

needs_device = pytest.mark.skipif(
    not available(), reason=f"{DEVICE} is not writable here (needs root and a kernel with PM QoS)"
)


@needs_device
def test_a_request_is_in_force_while_held_and_gone_after():
    before = current_us()
    assert before is not None
    # 7 µs: stricter than the kernel's default (no request), looser than anything else a test holds.
    with held(7):
        assert current_us() <= 7
    assert current_us() == before


@needs_device
def test_the_request_ends_when_the_block_raises():
    before = current_us()
    with pytest.raises(RuntimeError), held(9):
        assert current_us() <= 9
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
    notify_path = tmp_path / "notify"
    notify = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    notify.bind(str(notify_path))
    notify.settimeout(20.0)
    before = current_us()
    command = ["setpriv", "--bounding-set=-all", "--inh-caps=-all", "--no-new-privs",
               sys.executable, "-m", "trackerd", "cpu-latency", "--max-us", "11"]
    env = dict(os.environ, NOTIFY_SOCKET=str(notify_path))
    holder = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        ready = notify.recv(4096).decode()
        assert "READY=1" in ready.splitlines()
        assert "STATUS=CPU wake-up latency held at 11 µs" in ready
        assert current_us() <= 11
        holder.send_signal(signal.SIGTERM)
        sent = time.monotonic()
        out, err = holder.communicate(timeout=5.0)
        took = time.monotonic() - sent
    finally:
        if holder.poll() is None:
            holder.kill()
            holder.wait()
        notify.close()
    assert holder.returncode == 0, err
    assert took < 1.0
    assert "held at 11 µs" in out
    assert err == ""
    assert current_us() == before


def test_the_command_as_an_unprivileged_user_says_why_in_one_line():
    if os.geteuid() != 0 or shutil.which("setpriv") is None:
        pytest.skip("needs root (to become another user) and setpriv")
    nobody = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"]
    result = subprocess.run([*nobody, sys.executable, "-m", "trackerd", "cpu-latency"],
                            capture_output=True, text=True, timeout=30)
    assert result.returncode == 1
    assert result.stderr.count("\n") == 1, result.stderr
    assert "permission denied" in result.stderr
    assert "Traceback" not in result.stderr
