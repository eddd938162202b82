"""`trackerd cpu-latency` as a test's subprocess, a datagram socket of the test's own standing in for
systemd's notification socket: started, waited for until READY, looked at, stopped with SIGTERM."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

from trackerd.cpu_latency import current_us


@dataclass
class HolderRun:
    ready: str
    """The notification the command sent first."""
    in_force_us: int | None
    """The strictest request in force while it ran (read after READY)."""
    returncode: int
    stdout: str
    stderr: str
    stop_s: float
    """From SIGTERM to its exit."""


def run_holder(command: list[str], tmp_path: Path, stdin_text: str | None = None) -> HolderRun:
    """Run ``command`` (ending in ``trackerd cpu-latency ...``) until READY, then SIGTERM it."""
    notify_path = tmp_path / "notify"
    notify = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    notify.bind(str(notify_path))
    notify.settimeout(30.0)
    env = dict(os.environ, NOTIFY_SOCKET=str(notify_path))
    holder = subprocess.Popen(
        command,
        env=env,
        stdin=subprocess.PIPE if stdin_text is not None else None,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        if stdin_text is not None:
            assert holder.stdin is not None
            holder.stdin.write(stdin_text)
            holder.stdin.close()
            holder.stdin = None  # written and closed: communicate() has nothing more to send
        try:
            ready = notify.recv(4096).decode()
        except TimeoutError:
            holder.kill()
            raise AssertionError(f"no READY=1 within 30 s: {holder.communicate()[1][-3000:]}") from None
        in_force = current_us()
        holder.send_signal(signal.SIGTERM)
        sent = time.monotonic()
        out, err = holder.communicate(timeout=5.0)
        took = time.monotonic() - sent
    finally:
        if holder.poll() is None:
            holder.kill()
            holder.wait()
        notify.close()
    return HolderRun(ready, in_force, holder.returncode, out, err, took)
