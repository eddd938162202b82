"""Every pair's latency taken apart, for the pipeline benchmark: the observer it installs, and the figures.

The bench installs a :class:`TraceObserver` in the pipeline (trackerd.pipeline.observer);
from :meth:`TraceObserver.start` on, it keeps one :class:`PairTrace` per pair
published: how long the pair waited to be taken, each thread's time off the CPU
while on it, taken apart with the kernel's figures (trackerd.pipeline.threadtime),
and the hand-over between the threads. The functions below turn a trace into
figures (pure).
"""

from __future__ import annotations

import itertools
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np

from trackerd.pipeline.observer import PairTimes
from trackerd.pipeline.stats import percentiles_ms
from trackerd.pipeline.threadtime import OffCpu, ThreadClock, ThreadTimes, off_cpu

HELD_UP_NS = 1_000_000
"""A pair was held up when, in all, it waited this long or longer: to be taken by the processing
thread, in the hand-over to the publishing thread, and with either thread off the CPU while on it
(about 0.3 ms for a pair nothing happened to, on the development VM)."""


@dataclass(frozen=True)
class PairTrace:
    """One pair's latency taken apart."""

    received_ns: int
    """Monotonic time the last frame of the pair arrived."""
    latency_ns: int
    """Last frame received to messages handed to ZeroMQ, as in the pipeline's ``processing`` figures."""
    waiting_ns: int
    """Last frame received to the processing thread taking the pair."""
    processing: OffCpu
    """The processing thread, from taking the pair to handing over its messages."""
    handoff_ns: int
    """Messages handed over to the publishing thread starting on them."""
    publishing: OffCpu
    """The publishing thread, sending the pair's messages."""


class TraceObserver:
    """A :class:`trackerd.pipeline.observer.PairObserver` that keeps a :class:`PairTrace` of every pair
    published after :meth:`start` (each thread's clocks are sampled from its start, a few
    microseconds a pair; the trace grows by one small record a pair)."""

    def __init__(self) -> None:
        self._clocks = threading.local()
        self._trace: list[PairTrace] | None = None

    def start(self) -> None:
        """Keep the pairs published from now on (the warm-up before is left out)."""
        self._trace = []

    def trace(self) -> list[PairTrace]:
        """The pairs traced since :meth:`start`."""
        return list(self._trace or [])

    def thread_started(self) -> None:
        # A thread's clock reads that thread's figures: made in the thread it measures.
        self._clocks.clock = ThreadClock()

    def thread_stopped(self) -> None:
        self._clocks.clock.close()

    def mark(self) -> ThreadTimes:
        clock: ThreadClock = self._clocks.clock
        return clock.now()

    def published(self, times: PairTimes, processing: tuple[object, object], sending: object) -> None:
        trace = self._trace
        if trace is None:
            return
        taken, handed_over = processing
        assert isinstance(taken, ThreadTimes) and isinstance(handed_over, ThreadTimes)
        assert isinstance(sending, ThreadTimes)
        trace.append(
            PairTrace(
                received_ns=times.received_ns,
                latency_ns=times.sent_ns - times.received_ns,
                waiting_ns=times.taken_ns - times.received_ns,
                processing=off_cpu(taken, handed_over),
                handoff_ns=times.sending_ns - times.queued_ns,
                publishing=off_cpu(sending, self.mark()),
            )
        )


def off_cpu_figures(trace: list[PairTrace]) -> dict[str, Any]:
    """Where the pairs' time off the CPU went, from a pipeline's :class:`PairTrace` list (pure).

    Per pair, the processing and publishing threads' time off the CPU is summed,
    and split in all: on the guest's run queue, asleep (a lock, the GIL), or
    neither (taken by the hypervisor or by interrupts). A pair was held up
    (:data:`HELD_UP_NS`) by that time plus its waits to be taken and handed over.
    """
    if not trace:
        return {"pairs": 0}
    latency = np.array([t.latency_ns for t in trace], dtype=np.int64)
    off = np.array([t.processing.off_cpu_ns + t.publishing.off_cpu_ns for t in trace], dtype=np.int64)
    work = np.array([t.processing.wall_ns + t.publishing.wall_ns for t in trace], dtype=np.int64) - off
    runqueue = sum(t.processing.runqueue_ns + t.publishing.runqueue_ns for t in trace)
    asleep = sum(t.processing.asleep_ns + t.publishing.asleep_ns for t in trace)
    unseen = sum(t.processing.unseen_ns + t.publishing.unseen_ns for t in trace)
    total = max(int(off.sum()), 1)
    waiting = np.array([t.waiting_ns for t in trace], dtype=np.int64)
    handoff = np.array([t.handoff_ns for t in trace], dtype=np.int64)
    held = off + waiting + handoff
    clear = held < HELD_UP_NS
    return {
        "pairs": len(trace),
        "pairs_held_up_1_ms_or_more": int((~clear).sum()),
        "held_ms_per_pair": percentiles_ms(held),
        "off_cpu_ms_per_pair": percentiles_ms(off),
        "off_cpu_split_percent": {
            "run_queue": round(100.0 * runqueue / total, 1),
            "asleep": round(100.0 * asleep / total, 1),
            "hypervisor_or_interrupts": round(100.0 * unseen / total, 1),
        },
        "work_ms_per_pair": percentiles_ms(work),
        "waiting_ms": percentiles_ms(waiting),
        "handoff_ms": percentiles_ms(handoff),
        "latency_all_ms": percentiles_ms(latency),
        "latency_not_held_up_ms": percentiles_ms(latency[clear]),
    }


def latency_by_steal(trace: list[PairTrace], machine: list[tuple[int, dict[str, int] | None]]) -> dict[str, Any]:
    """The latency of pairs during which the hypervisor stole no CPU time, beside the rest (pure).

    ``machine`` is the run's /proc/stat samples, (monotonic ns, ticks), about 0.2 s apart: a
    pair counts as quiet when no tick was stolen in any period between two samples that its
    latency (arrival to published) overlaps. Side by side in one run, this tells the code's
    tail from the machine's."""
    samples = [(at, ticks) for at, ticks in machine if ticks is not None]
    if len(samples) < 2 or not trace:
        return {}
    starts = np.array([at for at, _ in samples], dtype=np.int64)
    stolen = np.diff([ticks["steal"] for _, ticks in samples]) > 0
    received = np.array([t.received_ns for t in trace], dtype=np.int64)
    latency = np.array([t.latency_ns for t in trace], dtype=np.int64)
    first = np.searchsorted(starts, received, side="right") - 1
    last = np.searchsorted(starts, received + latency, side="right") - 1
    inside = (first >= 0) & (last < stolen.size)
    # Periods with CPU stolen among first..last, from the running count.
    running = np.concatenate([[0], np.cumsum(stolen)])
    touched = running[np.clip(last, 0, stolen.size - 1) + 1] - running[np.clip(first, 0, stolen.size - 1)]
    quiet = inside & (touched == 0)
    loud = inside & ~quiet
    return {
        "periods": int(stolen.size),
        "periods_with_steal": int(stolen.sum()),
        "quiet": {"pairs": int(quiet.sum()), **percentiles_ms(latency[quiet])},
        "stolen": {"pairs": int(loud.sum()), **percentiles_ms(latency[loud])},
    }


def latency_by_wakeup(
    trace: list[PairTrace], turns: list[tuple[int, bool]], machine: list[tuple[int, dict[str, int] | None]]
) -> dict[str, Any]:
    """The latency, the wait to be taken and the CPU stolen while the CPUs were held awake, and while
    they were not (pure).

    ``turns`` are (monotonic ns, held) from the run's start, each in force until
    the next; a pair belongs to the turn it arrived in, a /proc/stat period of
    ``machine`` to the turn its middle lies in. Only the conditions the run had are given.
    """
    if not turns:
        return {}
    starts = np.array([at for at, _ in turns], dtype=np.int64)
    held = np.array([h for _, h in turns], dtype=bool)
    received = np.array([t.received_ns for t in trace], dtype=np.int64)
    latency = np.array([t.latency_ns for t in trace], dtype=np.int64)
    waiting = np.array([t.waiting_ns for t in trace], dtype=np.int64)
    turn_of_pair = np.searchsorted(starts, received, side="right") - 1
    pair_held = np.where(turn_of_pair >= 0, held[np.clip(turn_of_pair, 0, None)], False)
    pair_known = turn_of_pair >= 0
    stolen = {True: 0, False: 0}
    total = {True: 0, False: 0}
    samples = [(at, ticks) for at, ticks in machine if ticks is not None]
    for (at, before), (end, after) in itertools.pairwise(samples):
        # By the period's middle: the bench switches right after taking a sample, so a period that
        # begins at a switch lies in the turn that the switch begins.
        turn = int(np.searchsorted(starts, (at + end) // 2, side="right")) - 1
        if turn >= 0:
            stolen[bool(held[turn])] += after["steal"] - before["steal"]
            total[bool(held[turn])] += after["total"] - before["total"]
    out: dict[str, Any] = {}
    for name, condition in (("held", True), ("not_held", False)):
        if not np.any(held == condition):
            continue
        chosen = pair_known & (pair_held == condition)
        steal = round(100.0 * stolen[condition] / total[condition], 2) if total[condition] > 0 else None
        out[name] = {
            "pairs": int(chosen.sum()),
            **percentiles_ms(latency[chosen]),
            "waiting_ms": percentiles_ms(waiting[chosen]),
            "steal_percent": steal,
        }
    return out
