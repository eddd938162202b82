"""The observer the pipeline benchmark installs: what it keeps of each pair (no pipeline, no cameras)."""

from __future__ import annotations

import threading

from trackerd.bench.pairtrace import TraceObserver
from trackerd.pipeline.observer import PairTimes
from trackerd.pipeline.threadtime import ThreadTimes

MS = 1_000_000


def _times() -> PairTimes:
    return PairTimes(
        received_ns=100 * MS, taken_ns=101 * MS, queued_ns=104 * MS, sending_ns=104 * MS + MS // 2, sent_ns=105 * MS
    )


def test_a_pair_is_taken_apart_from_its_moments_and_marks():
    observer = TraceObserver()
    observer.thread_started()
    try:
        # The processing thread's marks: 3 ms of wall time, 2 ms of it running, 0.5 ms on the run queue.
        taken = ThreadTimes(wall_ns=101 * MS, cpu_ns=10 * MS, runqueue_ns=0, voluntary_switches=7)
        handed_over = ThreadTimes(wall_ns=104 * MS, cpu_ns=12 * MS, runqueue_ns=MS // 2, voluntary_switches=7)
        observer.published(_times(), (taken, handed_over), observer.mark())  # before start: not kept
        assert observer.trace() == []
        observer.start()
        observer.published(_times(), (taken, handed_over), observer.mark())
    finally:
        observer.thread_stopped()
    [trace] = observer.trace()
    assert (trace.received_ns, trace.latency_ns, trace.waiting_ns, trace.handoff_ns) == (100 * MS, 5 * MS, MS, MS // 2)
    assert (trace.processing.wall_ns, trace.processing.off_cpu_ns, trace.processing.runqueue_ns) == (
        3 * MS,
        MS,
        MS // 2,
    )
    assert not trace.processing.slept
    # The publishing thread's interval is real: from the mark to the end of published().
    assert 0 <= trace.publishing.off_cpu_ns <= trace.publishing.wall_ns


def test_each_thread_marks_its_own_clocks():
    observer = TraceObserver()
    marks: dict[str, ThreadTimes] = {}

    def spin_then_mark(name: str, cpu_ns: int) -> None:
        observer.thread_started()
        try:
            start = observer.mark()
            while observer.mark().cpu_ns - start.cpu_ns < cpu_ns:
                pass
            marks[name] = observer.mark()
        finally:
            observer.thread_stopped()

    busy = threading.Thread(target=spin_then_mark, args=("busy", 50 * MS))
    busy.start()
    busy.join()
    idle = threading.Thread(target=spin_then_mark, args=("idle", 0))
    idle.start()
    idle.join()
    # A thread's CPU time is its own: the idle thread did not inherit the busy one's 50 ms.
    assert marks["busy"].cpu_ns >= 50 * MS
    assert marks["idle"].cpu_ns < 50 * MS
