"""Keeping the CPUs from sleeping deeply: a PM QoS CPU latency request (``/dev/cpu_dma_latency``).

An idle CPU halts, and the deeper it sleeps the longer it takes to wake when a
frame arrives. In a virtual machine a halted virtual CPU is handed back to the
hypervisor, which may take milliseconds to run it again. On the development VM
that wake-up is the largest part of the daemon's latency tail (docs/deployment.md,
"Wake-up latency"): while a request for 0 µs is held, the processing thread's
wait to be woken for a pair has a p99 of 0.4-1.3 ms instead of 1.7-4.4 ms.

The kernel's interface (Documentation/power/pm_qos_interface.rst): whoever
holds ``/dev/cpu_dma_latency`` open with a 32-bit value written to it asks that
no CPU sleep in a state slower than that many microseconds to leave; the
request ends when the file is closed, so it cannot outlive its process. Reading
the file gives the strictest request in force. The price is power: an idle CPU
polls instead of halting. It is for a host that is there to run the wall.
"""

from __future__ import annotations

import contextlib
import errno
import os
import struct
from collections.abc import Iterator
from pathlib import Path

from trackerd.errors import TrackerdError

DEVICE = Path("/dev/cpu_dma_latency")

NO_REQUEST_US = 2_000_000_000
"""What the device reads with no request in force (the kernel's default, PM_QOS_CPU_LATENCY_DEFAULT_VALUE)."""

MAX_REQUEST_US = 1_000_000
"""Largest request accepted here: anything longer than a second asks for nothing."""


class CpuLatencyError(TrackerdError):
    """The CPU latency request cannot be made (no such device, no permission)."""

    exit_code = 3
    """Its own exit status, so that trackerd-cpu-latency.service does not restart on it
    (RestartPreventExitStatus=3): a restart cannot make the device appear or be writable."""


@contextlib.contextmanager
def held(max_wakeup_us: int, device: Path = DEVICE) -> Iterator[None]:
    """Ask that no CPU take longer than ``max_wakeup_us`` to wake, for the ``with`` block.

    Raises :class:`CpuLatencyError` with one line saying why when the request
    cannot be made; the request ends with the block however it ends.
    """
    if not 0 <= max_wakeup_us <= MAX_REQUEST_US:
        raise CpuLatencyError(f"a CPU wake-up latency of {max_wakeup_us} µs: give 0 to {MAX_REQUEST_US} µs")
    try:
        fd = os.open(device, os.O_WRONLY | os.O_CLOEXEC)
    except OSError as err:
        raise CpuLatencyError(_why(device, err)) from None
    try:
        try:
            os.write(fd, struct.pack("=i", max_wakeup_us))
        except OSError as err:
            raise CpuLatencyError(f"{device}: the request of {max_wakeup_us} µs was refused: {err.strerror}") from None
        yield
    finally:
        os.close(fd)


def current_us(device: Path = DEVICE) -> int | None:
    """The strictest CPU wake-up latency requested by anyone now, in µs; None if it cannot be read
    (:data:`NO_REQUEST_US` when nobody asks)."""
    try:
        fd = os.open(device, os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        data = os.read(fd, 4)
    except OSError:
        return None
    finally:
        os.close(fd)
    return struct.unpack("=i", data)[0] if len(data) == 4 else None


def available(device: Path = DEVICE) -> bool:
    """Whether this process may make a request (the device exists and is writable)."""
    return os.access(device, os.W_OK)


def _why(device: Path, err: OSError) -> str:
    if err.errno == errno.ENOENT:
        return f"{device}: no such device (a kernel without PM QoS, or a container without it)"
    if err.errno in (errno.EACCES, errno.EPERM):
        return (
            f"{device}: permission denied (only root may hold the CPUs awake: run `trackerd cpu-latency`"
            " as root, or the trackerd-cpu-latency service; docs/deployment.md)"
        )
    return f"{device}: {err.strerror}"
