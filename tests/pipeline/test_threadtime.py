"""A thread's time off the CPU, taken apart with the kernel's own figures (no mocks: real threads, a real rival)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time

import pytest

from trackerd.pipeline.threadtime import SCHEDSTAT, OffCpu, ThreadClock, ThreadTimes, off_cpu


def _spin(seconds: float) -> None:
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        pass


def test_off_cpu_takes_an_interval_apart():
    before = ThreadTimes(wall_ns=0, cpu_ns=0, runqueue_ns=100, voluntary_switches=3)
    stolen = off_cpu(before, ThreadTimes(10_000_000, 6_000_000, 1_100_100, 3))
    assert (stolen.wall_ns, stolen.off_cpu_ns, stolen.runqueue_ns) == (10_000_000, 4_000_000, 1_100_000)
    assert not stolen.slept
    assert (stolen.unseen_ns, stolen.asleep_ns) == (2_900_000, 0)

    slept = off_cpu(before, ThreadTimes(10_000_000, 6_000_000, 100, 4))
    assert slept.slept and (slept.unseen_ns, slept.asleep_ns) == (0, 4_000_000)

    # A run-queue figure that got ahead of the clocks is never more than the time off the CPU.
    ahead = off_cpu(before, ThreadTimes(10_000_000, 9_000_000, 5_000_100, 3))
    assert ahead.runqueue_ns == ahead.off_cpu_ns == 1_000_000 and ahead.unseen_ns == 0

    unknown = off_cpu(ThreadTimes(0, 0, None, 0), ThreadTimes(10_000_000, 6_000_000, None, 0))
    assert unknown.runqueue_ns == 0 and unknown.unseen_ns == 4_000_000


# Measured in a child process with one thread: in the test process another thread (pytest-xdist's
# channel, a test's leftover daemon thread) can want the GIL while the spinning thread holds it, and a
# thread that waits for the GIL back has gone to sleep of its own accord (a voluntary switch): right
# for the daemon's threads, but not what a lone spinning thread is meant to show.
_MEASURE = """
import json, os, sys, time
from dataclasses import asdict
from trackerd.pipeline.threadtime import ThreadClock, off_cpu

def spin_wall(seconds):
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        pass

def spin_cpu(seconds):
    # Until this thread has run for `seconds` of CPU time, not of wall time: on a loaded machine the
    # two differ by whatever the rivals took.
    end = time.thread_time_ns() + round(seconds * 1e9)
    while time.thread_time_ns() < end:
        pass

def measure(act, seconds):
    with ThreadClock() as clock:
        before = clock.now()
        act(seconds)
        return asdict(off_cpu(before, clock.now()))

cpu = sys.argv[1]
if cpu != "any":
    os.sched_setaffinity(0, {int(cpu)})
print(json.dumps({
    "asleep": measure(time.sleep, 0.05),
    "running": measure(spin_cpu, 0.05),
    "shared": measure(spin_wall, 0.4),
}))
"""


def _measured_alone(cpu: int | None = None) -> dict[str, OffCpu]:
    """A sleep of 50 ms, a spin of 50 ms of CPU and a spin of 0.4 s of wall time, each measured by a
    ThreadClock in a child process with one thread (pinned to ``cpu`` if given)."""
    child = subprocess.run(
        [sys.executable, "-c", _MEASURE, "any" if cpu is None else str(cpu)],
        capture_output=True,
        text=True,
        check=True,
    )
    return {name: OffCpu(**fields) for name, fields in json.loads(child.stdout).items()}


def test_a_sleeping_thread_is_asleep_and_a_spinning_one_is_running():
    measured = _measured_alone()
    asleep, running = measured["asleep"], measured["running"]
    assert asleep.slept and asleep.asleep_ns >= 45_000_000 and asleep.unseen_ns == 0
    assert not running.slept
    # The clock sees the 50 ms of CPU the spinning thread used, however busy the machine was (how much
    # of the interval that is depends on the rivals, so it is not asserted); whatever else of the
    # interval passed was off the CPU without sleeping: run queue or unseen, never asleep.
    assert running.wall_ns - running.off_cpu_ns >= 45_000_000
    assert running.asleep_ns == 0 and running.runqueue_ns + running.unseen_ns == running.off_cpu_ns


def test_a_clock_measures_the_thread_that_made_it():
    """Another thread's work does not count as this one's, nor its sleep as this one's sleep."""
    with ThreadClock() as clock:
        before = clock.now()
        worker = threading.Thread(target=lambda: (_spin(0.03), time.sleep(0.02)))
        worker.start()
        worker.join()
        after = clock.now()
    interval = off_cpu(before, after)
    assert after.cpu_ns - before.cpu_ns < 15_000_000  # the worker spun 30 ms
    assert interval.slept  # this thread waited in join()


@pytest.mark.skipif(not os.path.exists(SCHEDSTAT), reason="this kernel keeps no scheduler statistics")
def test_a_rival_on_the_same_cpu_shows_as_run_queue_time():
    cpu = min(os.sched_getaffinity(0))
    rival = subprocess.Popen(
        [sys.executable, "-c", f"import os; os.sched_setaffinity(0, {{{cpu}}})\nwhile True: pass"],
    )
    try:
        time.sleep(0.3)  # the rival is spinning
        shared = _measured_alone(cpu)["shared"]
    finally:
        rival.kill()
        rival.wait()
    # Two runnable tasks on one CPU share it: this one waits on the run queue for much of the time,
    # and the guest's scheduler accounts for that wait (it is not the hypervisor's).
    assert not shared.slept
    assert shared.runqueue_ns > 0.2 * shared.wall_ns
    assert shared.runqueue_ns >= 0.5 * shared.off_cpu_ns
