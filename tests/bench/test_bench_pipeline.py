"""`trackerd bench pipeline`: its figures, and how it takes the latency apart.

The figures themselves (60 s at 60 pairs/s) are the benchmark's to print; here a
one-second run must produce all of them, consistently, and the pure functions
that split the time must split it right.
"""

from __future__ import annotations

import json
import subprocess
import sys

from trackerd import cpu_latency
from trackerd.bench.pairtrace import HELD_UP_NS, PairTrace, latency_by_steal, latency_by_wakeup, off_cpu_figures
from trackerd.bench.pipeline import _format
from trackerd.pipeline.threadtime import OffCpu

MS = 1_000_000


def _trace(
    received_ms: float, latency_ms: float, off_ms: float = 0.0, runqueue_ms: float = 0.0, slept: bool = False
) -> PairTrace:
    processing = OffCpu(
        wall_ns=int(2 * MS + off_ms * MS), off_cpu_ns=int(off_ms * MS), runqueue_ns=int(runqueue_ms * MS), slept=slept
    )
    publishing = OffCpu(wall_ns=int(0.2 * MS), off_cpu_ns=0, runqueue_ns=0, slept=False)
    return PairTrace(
        received_ns=int(received_ms * MS),
        latency_ns=int(latency_ms * MS),
        waiting_ns=int(0.1 * MS),
        processing=processing,
        handoff_ns=int(0.1 * MS),
        publishing=publishing,
    )


def test_off_cpu_time_is_split_by_where_it_went():
    trace = [
        _trace(0, 2.5),
        _trace(16, 2.6, off_ms=0.1),
        _trace(33, 6.0, off_ms=3.0, runqueue_ms=1.0),  # 1 ms on the run queue, 2 ms unseen
        _trace(50, 5.0, off_ms=1.0, slept=True),  # asleep
    ]
    figures = off_cpu_figures(trace)
    assert figures["pairs"] == 4
    # Held up: 3 ms and 1 ms off the CPU, each with 0.2 ms of waits.
    assert figures["pairs_held_up_1_ms_or_more"] == 2
    # 4.1 ms off the CPU in all: 1 ms on the run queue, 1 ms asleep, 2.1 ms unseen (0.1 + 2).
    assert figures["off_cpu_split_percent"] == {"run_queue": 24.4, "asleep": 24.4, "hypervisor_or_interrupts": 51.2}
    # The pairs nothing held up are the first two: their latency, not the others'.
    assert figures["latency_not_held_up_ms"]["max_ms"] == 2.6
    assert figures["held_ms_per_pair"]["max_ms"] == 3.2
    assert figures["latency_all_ms"]["max_ms"] == 6.0
    # Work is wall time less time off the CPU, both threads: 2.2 ms for every pair here.
    assert figures["work_ms_per_pair"]["p50_ms"] == figures["work_ms_per_pair"]["max_ms"] == 2.2
    assert off_cpu_figures([]) == {"pairs": 0}
    assert HELD_UP_NS == 1 * MS


def test_pairs_are_told_apart_by_whether_the_hypervisor_stole_cpu_while_they_were_handled():
    def ticks(steal: int, total: int) -> dict[str, int]:
        return {"steal": steal, "total": total}

    # Four periods of 200 ms; CPU is stolen only in the second.
    machine = [
        (0, ticks(5, 100)),
        (200 * MS, ticks(5, 140)),
        (400 * MS, ticks(7, 180)),
        (600 * MS, ticks(7, 220)),
        (800 * MS, ticks(7, 260)),
        (900 * MS, None),
    ]
    trace = [
        _trace(50, 2.0),
        _trace(250, 9.0),
        _trace(390, 8.0),
        _trace(450, 2.5),
        _trace(750, 3.0),
        _trace(198, 4.0),  # arrived in a quiet period, published in the stolen one
        _trace(850, 99.0),
    ]  # arrived after the last sample: in no period
    figures = latency_by_steal(trace, machine)
    assert figures["periods"] == 4 and figures["periods_with_steal"] == 1
    assert figures["quiet"]["pairs"] == 3 and figures["quiet"]["max_ms"] == 3.0
    assert figures["stolen"]["pairs"] == 3 and figures["stolen"]["max_ms"] == 9.0
    assert latency_by_steal([], machine) == {}
    assert latency_by_steal(trace, [(0, None)]) == {}


def test_pairs_and_stolen_cpu_are_told_apart_by_whether_the_cpus_were_held_awake():
    def ticks(steal: int, total: int) -> dict[str, int]:
        return {"steal": steal, "total": total}

    # Not held from 0, held from 400 ms, not held again from 800 ms; as in the bench, each switch is
    # recorded just after the /proc/stat sample taken at that moment.
    turns = [(0, False), (401 * MS, True), (801 * MS, False)]
    machine = [
        (0, ticks(0, 100)),
        (200 * MS, ticks(6, 200)),
        (400 * MS, ticks(8, 300)),
        (600 * MS, ticks(8, 400)),
        (800 * MS, ticks(9, 500)),
        (1000 * MS, ticks(13, 600)),
    ]
    trace = [
        _trace(50, 9.0),
        _trace(390, 7.0),  # not held (the second published after the turn: its arrival counts)
        _trace(450, 2.5),
        _trace(790, 3.0),  # held
        _trace(850, 8.0),
    ]  # not held
    figures = latency_by_wakeup(trace, turns, machine)
    assert figures["held"]["pairs"] == 2 and figures["held"]["max_ms"] == 3.0
    assert figures["not_held"]["pairs"] == 3 and figures["not_held"]["max_ms"] == 9.0
    assert figures["held"]["waiting_ms"]["max_ms"] == 0.1
    # Stolen: 6 + 2 + 4 ticks of 300 not held, 0 + 1 of 200 held.
    assert figures["not_held"]["steal_percent"] == 4.0
    assert figures["held"]["steal_percent"] == 0.5
    # A run that never held them has one condition only.
    assert list(latency_by_wakeup(trace, [(0, False)], machine)) == ["not_held"]
    assert latency_by_wakeup(trace, [], machine) == {}


def test_a_short_run_reports_every_figure_consistently():
    request_before = cpu_latency.current_us()
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "trackerd",
            "bench",
            "pipeline",
            "--seconds",
            "1",
            "--json",
            "--endpoint",
            "tcp://127.0.0.1:5598",
            "--turn-seconds",
            "0.4",
            "--paced-pairs",
            "20",
            "--console",
            "viewer",
        ],
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert run.returncode == 0, run.stderr
    figures = json.loads(run.stdout)
    assert figures["failure"] is None
    assert figures["pairs_processed"] >= 30  # 60 pairs/s for a second, whatever the machine did
    outlines = figures["outlines_measured_again"]
    # Counted over the run's pairs only: at most each of the two cameras' two ends on every pair.
    assert 0 <= outlines["between_pairs"] + outlines["in_pairs"] <= 4 * figures["pairs_processed"]
    assert min(outlines.values()) >= 0
    off = figures["off_cpu"]
    # Every pair processed in the run is traced (give or take the one in flight at either end).
    assert abs(off["pairs"] - figures["pairs_processed"]) <= 2
    assert off["latency_not_held_up_ms"]["p50_ms"] <= off["latency_all_ms"]["max_ms"]
    assert off["pairs_held_up_1_ms_or_more"] <= off["pairs"]
    split = off["off_cpu_split_percent"]
    assert abs(sum(split.values()) - 100.0) < 0.5 or off["off_cpu_ms_per_pair"]["max_ms"] == 0
    by_steal = figures["latency_by_steal"]
    if by_steal:  # /proc/stat is readable here
        assert by_steal["quiet"]["pairs"] + by_steal["stolen"]["pairs"] <= off["pairs"]
        assert 3 <= by_steal["periods"] <= 7
    paced = figures["paced_detection_ms"]
    assert paced["together"]["p50_ms"] > 0 and paced["one_at_a_time"]["p50_ms"] > 0
    wakeup = figures["cpu_wakeup"]
    if cpu_latency.available():
        # As root the CPUs are held awake in turns: both conditions have pairs, and every pair has one.
        assert wakeup["mode"] == "alternate"
        assert wakeup["held"]["pairs"] > 0 and wakeup["not_held"]["pairs"] > 0
        assert wakeup["held"]["pairs"] + wakeup["not_held"]["pairs"] == off["pairs"]
        assert cpu_latency.current_us() == request_before  # released when the run ended
    else:
        assert wakeup["mode"] == "off" and list(wakeup) == ["mode", "turn_s", "other_request_us", "not_held"]
    received = figures["messages_received"]
    assert received.get("pointer", 0) >= figures["pairs_processed"] - 5
    # The text the command prints by default says every figure in words, no raw Python values.
    text = _format(figures)
    assert "None" not in text and "{" not in text, text
    assert f"pointer {received['pointer']}" in text and "target p99 <= 4 ms" in text
    # The console's viewer (a page's WebSocket in a process of its own) took images all along.
    console = figures["console"]
    assert console["mode"] == "viewer" and console["images"] >= 2 and console["texts"] >= 1
    assert f"console: one page connected, {console['images']} camera images" in text


def test_a_turn_of_no_length_is_refused_in_one_line():
    run = subprocess.run(
        [sys.executable, "-m", "trackerd", "bench", "pipeline", "--turn-seconds", "0"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert run.returncode == 2
    assert run.stderr.count("\n") == 1 and "--turn-seconds" in run.stderr, run.stderr
