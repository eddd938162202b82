"""Where a thread's wall time went while it handled a pair: running, or not, and why not.

A pair's latency is the work of two threads plus the time they were not
running. On a shared machine that time decides the tail, and there are three
places it can go, which call for different remedies:

* the run queue: the thread was ready, and the guest's scheduler ran something
  else (another thread of the daemon, another process): a priority question;
* asleep: the thread blocked on a lock or the GIL (a voluntary context switch):
  a question of the daemon's own threads;
* neither: the guest counts the time as neither the thread's nor anyone's
  wait. That is time the hypervisor took from the virtual CPU (steal) or the
  CPU spent on interrupts, both of which the kernel keeps out of a thread's CPU
  time: a question of the machine.

The kernel's figures: the thread's CPU time (``CLOCK_THREAD_CPUTIME_ID``), its
run-queue delay (``/proc/thread-self/schedstat``, where the kernel keeps
scheduler statistics) and its voluntary context switches (``getrusage``). A
sample costs a few microseconds; the pipeline takes them only when asked (the
pipeline benchmark).
"""

from __future__ import annotations

import os
import resource
import time
from dataclasses import dataclass

SCHEDSTAT = "/proc/thread-self/schedstat"


@dataclass(frozen=True)
class ThreadTimes:
    """One thread's clocks at one instant."""

    wall_ns: int
    """CLOCK_MONOTONIC."""
    cpu_ns: int
    """CPU time the thread has used."""
    runqueue_ns: int | None
    """Time the thread has spent ready to run but waiting for a CPU; None where the kernel keeps no
    scheduler statistics (then all time off the CPU that is not sleep counts as unseen)."""
    voluntary_switches: int
    """Times the thread has gone to sleep of its own accord (waiting on a lock, the GIL, I/O)."""


@dataclass(frozen=True)
class OffCpu:
    """The part of an interval a thread was not running, and where it went."""

    wall_ns: int
    off_cpu_ns: int
    """Wall time minus CPU time."""
    runqueue_ns: int
    """Ready to run, waiting for a CPU of the guest (0 where unknown)."""
    slept: bool
    """The thread went to sleep at least once (a lock, the GIL)."""

    @property
    def unseen_ns(self) -> int:
        """Not running, not on the run queue, not asleep: taken by the hypervisor or by interrupts
        (which kernels with steal and interrupt time accounting keep out of a thread's CPU time).

        0 when the thread slept: its sleep and any steal cannot then be told apart, so this is a
        lower bound of the time taken, and :attr:`asleep_ns` an upper bound of the sleep."""
        return 0 if self.slept else max(0, self.off_cpu_ns - self.runqueue_ns)

    @property
    def asleep_ns(self) -> int:
        """Off the CPU beyond the run queue in an interval in which the thread slept."""
        return max(0, self.off_cpu_ns - self.runqueue_ns) if self.slept else 0


def off_cpu(before: ThreadTimes, after: ThreadTimes) -> OffCpu:
    """What happened to a thread between two of its samples (pure)."""
    wall = after.wall_ns - before.wall_ns
    off = max(0, wall - (after.cpu_ns - before.cpu_ns))
    runqueue = 0
    if before.runqueue_ns is not None and after.runqueue_ns is not None:
        # The run-queue figure is updated when the thread is switched in, so it may lag the
        # clocks by a little: never more than the time off the CPU.
        runqueue = min(off, max(0, after.runqueue_ns - before.runqueue_ns))
    return OffCpu(wall, off, runqueue, after.voluntary_switches > before.voluntary_switches)


class ThreadClock:
    """Samples the clocks of the thread that created it (create it in the thread it measures)."""

    def __init__(self) -> None:
        try:
            self._schedstat: int | None = os.open(SCHEDSTAT, os.O_RDONLY)
        except OSError:
            self._schedstat = None
        else:
            # A kernel built with the file but keeping no statistics reports "0 0 0": the thread
            # has run (Python started it), so a CPU time of 0 means unknown, not none.
            if int(os.pread(self._schedstat, 128, 0).split()[0]) == 0:
                os.close(self._schedstat)
                self._schedstat = None

    def now(self) -> ThreadTimes:
        runqueue = None
        if self._schedstat is not None:
            # "<cpu time ns> <run-queue delay ns> <timeslices>"; pread at 0 reads the current values.
            runqueue = int(os.pread(self._schedstat, 128, 0).split()[1])
        switches = resource.getrusage(resource.RUSAGE_THREAD).ru_nvcsw
        return ThreadTimes(time.monotonic_ns(), time.thread_time_ns(), runqueue, switches)

    def close(self) -> None:
        if self._schedstat is not None:
            os.close(self._schedstat)
            self._schedstat = None

    def __enter__(self) -> ThreadClock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
