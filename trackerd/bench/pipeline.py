"""The daemon's real-time figures: latency, CPU per pair and drops at 1920x1080, 60 pairs/s, two cameras.

The pipeline runs exactly as under `trackerd run` (processing and publishing
threads, ZeroMQ publisher, and a subscriber in a process of its own reading
every message), fed by one of two sources:

* memory (default): a rendered 1920x1080 motion loop served through the
  PairSource interface at 60 pairs per second, paced like free-running cameras.
  The virtual GigE rig cannot serve 60 fps while the daemon runs on the same two
  cores (its simulated cameras take most of a core each), so this is how the
  daemon itself is measured at full rate;
* virtual: the virtual GigE Vision rig (as root), to see the whole chain
  including Aravis, at the rate this machine sustains.

Figures: processing latency (last frame of a pair received to its messages
handed to ZeroMQ) median and 99th percentile, per-stage timings, CPU time of
the whole process per pair, pairs dropped and why, and how many tracked ends'
outlines were measured again between pairs and how many in a pair's latency
(trackerd.locator.Locator.measure_ahead). Targets on a 2-core machine:
p99 at most 4 ms, no drops caused by processing, under one core of CPU.

And what the machine adds, so a slow tail can be told from slow code: the
processing thread's CPU time per pair beside its wall time (the difference is
time spent not running), the same work done back to back with warm caches
(memory source; on the development VM, a pair after 14 ms idle costs nearly
twice one right after another), and the CPU time the hypervisor stole during
the run (/proc/stat). Each pair's time off the CPU, in both threads, is taken
apart (an observer installed in the pipeline, trackerd.bench.pairtrace): waiting
on the guest's run queue, asleep on a lock or the GIL, or neither (the
hypervisor or interrupts); and the latency of the pairs that nothing held up is shown beside that of all, as is
that of the pairs during which /proc/stat shows no CPU stolen.

And side by side in the same run, as root: the latency while the CPUs are held
awake (a PM QoS request for 0 µs, as the trackerd-cpu-latency service holds it;
trackerd.cpu_latency) and while they are not, the two alternating every few
seconds (``--cpu-wakeup``). On the development VM, a CPU that halts between
frames is what most of the tail is made of.

And what the operator's console costs (``--console``): off (no console), idle
(served, nobody connected: the pipeline only checks its flags) or viewer (one
page connected for the whole run, a WebSocket client in a process of its own
taking every camera image, fix and status, as a browser does).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import multiprocessing
import os
import queue
import time
from typing import Any

import numpy as np
import zmq

from trackerd import cpu_latency
from trackerd.acquisition.source import PairSource
from trackerd.bench.pairtrace import TraceObserver, latency_by_steal, latency_by_wakeup, off_cpu_figures
from trackerd.bench.progress import BenchProgress
from trackerd.config.examples import example_rig
from trackerd.config.loader import load_rig
from trackerd.config.models import RigConfig
from trackerd.errors import ConfigError
from trackerd.pipeline.stats import percentiles_ms

WAKEUP_MODES = ("auto", "alternate", "held", "off")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--config", default=str(example_rig("simulated")), help="rig (default: the bundled config/simulated.toml)"
    )
    parser.add_argument("--seconds", type=float, default=60.0, help="length of the run (default 60)")
    parser.add_argument("--rate", type=float, default=60.0, help="pairs per second served (memory source)")
    parser.add_argument("--motion", default="figure8", help="rendered motion (default figure8)")
    parser.add_argument("--source", choices=["memory", "virtual"], default="memory", help="see above")
    parser.add_argument("--endpoint", default="tcp://127.0.0.1:5599", help="publisher endpoint for the run")
    parser.add_argument(
        "--cpu-wakeup",
        choices=WAKEUP_MODES,
        default="auto",
        help="hold the CPUs awake (PM QoS 0 µs, as root): alternate (held and not, in turns), held (the whole"
        " run), off (never); auto (default): alternate where this process may, else off",
    )
    parser.add_argument(
        "--turn-seconds", type=float, default=5.0, help="length of each turn with --cpu-wakeup alternate (default 5)"
    )
    parser.add_argument(
        "--console",
        choices=["off", "idle", "viewer"],
        default="off",
        help="the operator's console: off (default), idle (served, nobody connected) or viewer"
        " (one page connected for the whole run)",
    )
    parser.add_argument(
        "--paced-pairs",
        type=int,
        default=240,
        help="pairs detected after a pause before the run, half with both cameras together and"
        " half one at a time, in turns (memory source; default 240)",
    )


def run(args: argparse.Namespace) -> int:
    from trackerd.pipeline.daemon import Pipeline
    from trackerd.publish import Publisher

    if not (args.seconds > 0 and args.turn_seconds > 0 and args.rate > 0 and args.paced_pairs >= 0):
        raise ConfigError("--seconds, --turn-seconds and --rate must be above 0, --paced-pairs at least 0")
    rig = load_rig(args.config).config
    wakeup = args.cpu_wakeup
    if wakeup == "auto":
        wakeup = "alternate" if cpu_latency.available() else "off"
    elif wakeup != "off" and not cpu_latency.available():
        # Said now, in one line, rather than after the warm-up.
        with cpu_latency.held(0):
            pass
    # Someone else's request (trackerd-cpu-latency, tuned) would hold the CPUs in the turns said free.
    in_force_us = cpu_latency.current_us()
    other_request = in_force_us if in_force_us is not None and in_force_us < cpu_latency.NO_REQUEST_US else None
    zmq_cfg = rig.outputs.zmq.model_copy(update={"endpoints": (args.endpoint,)})
    rig = rig.model_copy(update={"outputs": rig.outputs.model_copy(update={"zmq": zmq_cfg})})
    virtual = None
    progress = BenchProgress("pipeline")
    if args.source == "memory":
        from trackerd.acquisition.memory import MemoryPairSource
        from trackerd.sim.rig import render_loop

        progress.phase(f"the '{args.motion}' loop (rendered once, then cached) and detection back to back")
        loop = render_loop(rig, args.motion)
        frames = [np.load(path) for path in loop.frame_paths]
        image_sets = [[cam[i] for cam in frames] for i in range(loop.n_frames)]

        def factory(r: RigConfig) -> PairSource:
            return MemoryPairSource(r, image_sets, rate_hz=args.rate)

        source_note = f"rendered '{args.motion}' loop ({loop.n_frames} scenes) from memory at {args.rate:g} pairs/s"
        back_to_back: dict[str, Any] | None = _back_to_back_ms(rig, image_sets)
        paced_detection: dict[str, Any] | None = _paced_detection_ms(rig, image_sets, args.paced_pairs)
    else:
        from trackerd.acquisition.live import AravisPairSource
        from trackerd.sim.rig import VirtualRig

        progress.phase(f"starting the virtual GigE Vision rig ('{args.motion}')")
        virtual = VirtualRig(rig, motion=args.motion)
        virtual.start()
        rig = virtual.daemon_rig

        def factory(r: RigConfig) -> PairSource:
            return AravisPairSource(r, on_open=virtual.on_open)

        source_note = f"virtual GigE Vision rig, '{args.motion}', {rig.acquisition.trigger}"
        back_to_back = paced_detection = None
    # The subscriber is another process, as every real one is: in this one it would take the
    # GIL from the pipeline for every message and count its own cost as the daemon's.
    context = multiprocessing.get_context("fork")
    stop = context.Event()
    results = context.Queue()
    subscriber = context.Process(target=_subscribe, args=(args.endpoint, stop, results), daemon=True)
    subscriber.start()
    tap = console = viewer = None
    viewer_results = context.Queue()
    if args.console != "off":
        from trackerd.pipeline.tap import ConsoleTap

        tap = ConsoleTap()
        listen = f"127.0.0.1:{_free_port()}"
        if args.console == "viewer":
            # Forked before any thread of the pipeline's starts; it connects once the console answers.
            viewer = context.Process(target=_view, args=(f"http://{listen}/ws", stop, viewer_results), daemon=True)
            viewer.start()
    observer = TraceObserver()
    pipeline = Pipeline(rig, factory, lambda r: Publisher(r.outputs.zmq), tap=tap, observer=observer)
    wakeup_request = contextlib.ExitStack()
    turns: list[tuple[int, bool]] = []
    try:
        if wakeup == "held":
            wakeup_request.enter_context(cpu_latency.held(0))
        pipeline.start()
        if tap is not None:
            from trackerd.console.server import ConsoleServer

            console = ConsoleServer(pipeline, tap, listen=listen)
            console.start()
        progress.phase(f"measuring {args.seconds:g} s after 2 s of warm-up")
        time.sleep(2.0)  # warm up: tracking windows found, caches filled
        cpu0, wall0, machine0, machine0_ns = os.times(), time.monotonic(), _cpu_ticks(), time.monotonic_ns()
        pairs0 = pipeline.pairs_processed
        outlines0 = (pipeline.locator.measured_between_pairs, pipeline.locator.measured_in_pairs)
        source = pipeline.source
        if source is None:
            raise RuntimeError("the pipeline started without a source")
        status0 = source.status()
        kept = pipeline.figures
        windows = {"processing": kept.processing, **kept.stages, "processing_cpu": kept.processing_cpu}
        for window in windows.values():
            window.record()
        observer.start()
        end = time.monotonic() + args.seconds
        machine = [(machine0_ns, machine0)]
        # The first turn from the start: the pair in flight when tracing began was received before it.
        turns.append((0, wakeup == "held"))
        next_turn = time.monotonic() + args.turn_seconds
        while time.monotonic() < end and pipeline.failure is None:
            time.sleep(0.2)
            machine.append((time.monotonic_ns(), _cpu_ticks()))
            if wakeup == "alternate" and time.monotonic() >= next_turn:
                next_turn += args.turn_seconds
                if turns[-1][1]:
                    wakeup_request.close()
                else:
                    wakeup_request.enter_context(cpu_latency.held(0))
                turns.append((time.monotonic_ns(), not turns[-1][1]))
        samples = {name: window.recorded() for name, window in windows.items()}
        trace = observer.trace()
        cpu1, wall1, machine1 = os.times(), time.monotonic(), _cpu_ticks()
        pairs = pipeline.pairs_processed - pairs0
        outlines = {
            "between_pairs": pipeline.locator.measured_between_pairs - outlines0[0],
            "in_pairs": pipeline.locator.measured_in_pairs - outlines0[1],
        }
        status1 = source.status()
        queue_drops = pipeline.pairs_dropped_before_publishing
    finally:
        wakeup_request.close()
        if console is not None:
            console.stop()
        pipeline.stop()
        stop.set()
        if virtual is not None:
            virtual.stop()
    try:
        counts = results.get(timeout=5.0)
    except queue.Empty:
        counts = {}
    subscriber.join(2.0)
    viewed: dict[str, Any] = {"mode": args.console}
    if viewer is not None:
        try:
            viewed.update(viewer_results.get(timeout=5.0))
        except queue.Empty:
            viewed["error"] = "the viewer reported nothing"
        viewer.join(2.0)
    cpu_s = (cpu1.user + cpu1.system) - (cpu0.user + cpu0.system)
    elapsed = wall1 - wall0
    figures: dict[str, Any] = {
        "source": source_note,
        "seconds": round(elapsed, 1),
        "pairs_processed": pairs,
        "pair_rate_hz": round(pairs / elapsed, 2),
        "processing_latency_ms": percentiles_ms(samples["processing"]),
        "stages_ms": {k: percentiles_ms(v) for k, v in samples.items() if k not in ("processing", "processing_cpu")},
        "processing_thread_cpu_ms": percentiles_ms(samples["processing_cpu"]),
        "outlines_measured_again": outlines,
        "back_to_back_cpu_ms": back_to_back,
        "paced_detection_ms": paced_detection,
        "machine_steal_percent": _share_percent(machine0, machine1, "steal"),
        "machine_interrupt_percent": _share_percent(machine0, machine1, "interrupts"),
        "off_cpu": off_cpu_figures(trace),
        "latency_by_steal": latency_by_steal(trace, machine),
        "cpu_wakeup": {
            "mode": wakeup,
            "turn_s": args.turn_seconds if wakeup == "alternate" else None,
            "other_request_us": other_request,
            **latency_by_wakeup(trace, turns, machine),
        },
        "cpu_cores": round(cpu_s / elapsed, 3),
        "cpu_ms_per_pair": round(cpu_s / max(pairs, 1) * 1000, 3),
        "dropped_pairs_source": status1.dropped_pairs - status0.dropped_pairs,
        "dropped_pairs_queue": queue_drops,
        "messages_received": dict(counts),
        "failure": pipeline.failure,
        "console": viewed,
    }
    progress.done()
    if args.json:
        print(json.dumps(figures, indent=2))
    else:
        print(_format(figures))
    return 0 if pipeline.failure is None else 1


def _back_to_back_ms(rig: Any, image_sets: list[list[np.ndarray]]) -> dict[str, float | None]:
    """The processing thread's work for each pair (locate, messages), done back to back: what a
    pair costs with warm caches, thread CPU time in ms (two passes over the loop, the first
    to warm up)."""
    from trackerd.locator import Locator
    from trackerd.publish import messages_from_fix

    locator = Locator(rig)
    costs = []
    for index in range(2 * len(image_sets)):
        start = time.thread_time_ns()
        fix = locator.locate(image_sets[index % len(image_sets)])
        messages_from_fix(fix, locator, sequence=index, capture_ns=time.time_ns())
        if fix.status == "not_found":
            locator.reset()
        if index >= len(image_sets):
            costs.append(time.thread_time_ns() - start)
    return percentiles_ms(np.asarray(costs, dtype=np.int64))


PAUSE_S = 0.014
"""The pause before each pair in :func:`_paced_detection_ms`: what 60 pairs/s leaves idle."""


def _paced_detection_ms(rig: Any, image_sets: list[list[np.ndarray]], pairs: int) -> dict[str, Any] | None:
    """Detection of a pair after a pause, as the daemon does it (both cameras' windows measured
    together, trackerd.detect.detect_all_cameras) and one camera at a time, in turns pair by pair
    (each way with its own detectors, so each tracks as it would alone): wall time per pair, ms."""
    from trackerd.detect import ColourEndDetector, detect_all_cameras

    if pairs < 2 or len(rig.cameras) < 2:
        return None

    def detectors() -> list[ColourEndDetector]:
        return [
            ColourEndDetector(rig.detector, c.pixel_format, c.width_px, c.height_px, rig.pointer) for c in rig.cameras
        ]

    ways = {"together": detectors(), "one_at_a_time": detectors()}
    times: dict[str, list[int]] = {name: [] for name in ways}
    for index in range(pairs + 2 * len(ways)):
        name = "together" if index % 2 else "one_at_a_time"
        images = image_sets[(index // 2) % len(image_sets)]
        time.sleep(PAUSE_S)
        start = time.perf_counter_ns()
        if name == "together":
            detect_all_cameras(ways[name], images)
        else:
            for detector, image in zip(ways[name], images, strict=True):
                detector.detect(image)
        if index >= 2 * len(ways):  # the first pair of each way searches in full
            times[name].append(time.perf_counter_ns() - start)
    return {name: percentiles_ms(np.asarray(values, dtype=np.int64)) for name, values in times.items()}


_STAT_FIELDS = ("user", "nice", "system", "idle", "iowait", "irq", "softirq", "steal")


def _cpu_ticks() -> dict[str, int] | None:
    """The machine's CPU ticks so far by kind, from /proc/stat; None where unreadable."""
    try:
        with open("/proc/stat", encoding="ascii") as stat:
            fields = [int(v) for v in stat.readline().split()[1:]]
    except (OSError, ValueError):
        return None
    # user nice system idle iowait irq softirq steal [guest guest_nice, already in user and nice]
    ticks = dict(zip(_STAT_FIELDS, fields + [0] * (len(_STAT_FIELDS) - len(fields)), strict=False))
    ticks["interrupts"] = ticks["irq"] + ticks["softirq"]
    ticks["total"] = sum(ticks[name] for name in _STAT_FIELDS)
    return ticks


def _share_percent(before: dict[str, int] | None, after: dict[str, int] | None, kind: str) -> float | None:
    if before is None or after is None or after["total"] <= before["total"]:
        return None
    return round(100.0 * (after[kind] - before[kind]) / (after["total"] - before["total"]), 2)


def _subscribe(endpoint: str, stop: Any, results: Any) -> None:
    """The subscriber process: reads every message until ``stop``, then puts the counts by topic."""
    counts: dict[str, int] = {}
    ctx = zmq.Context()
    sub = ctx.socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"")
    sub.connect(endpoint)
    try:
        while not stop.is_set():
            if sub.poll(100):
                topic = sub.recv_multipart()[0].decode()
                counts[topic] = counts.get(topic, 0) + 1
    finally:
        sub.close(0)
        ctx.term()
        results.put(counts)


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def _view(url: str, stop: Any, results: Any) -> None:
    """The viewer process: a page's WebSocket, every message read until ``stop``; puts the counts."""
    import asyncio

    import aiohttp

    async def view() -> dict[str, Any]:
        counts = {"images": 0, "image_bytes": 0, "texts": 0}
        async with aiohttp.ClientSession() as session:
            while not stop.is_set():
                try:
                    ws = await session.ws_connect(url)
                    break
                except aiohttp.ClientError:
                    await asyncio.sleep(0.1)
            else:
                return counts
            async with ws:
                while not stop.is_set():
                    try:
                        message = await ws.receive(timeout=0.2)
                    except TimeoutError:
                        continue
                    if message.type == aiohttp.WSMsgType.BINARY:
                        counts["images"] += 1
                        counts["image_bytes"] += len(message.data)
                    elif message.type == aiohttp.WSMsgType.TEXT:
                        counts["texts"] += 1
                    else:
                        break
        return counts

    results.put(asyncio.run(view()))


def _spread(figures: dict[str, Any]) -> str:
    if figures.get("p50_ms") is None:
        return "none"
    return f"median {figures['p50_ms']} ms, p99 {figures['p99_ms']} ms"


def _format(f: dict[str, Any]) -> str:
    lat = f["processing_latency_ms"]
    lines = [
        f"source: {f['source']}",
        f"{f['pairs_processed']} pairs in {f['seconds']} s ({f['pair_rate_hz']} pairs/s)",
        f"processing latency (last frame received -> published): median {lat['p50_ms']} ms,"
        f" p99 {lat['p99_ms']} ms, max {lat['max_ms']} ms   (target p99 <= 4 ms)",
    ]
    for name, s in f["stages_ms"].items():
        lines.append(f"  {name:<12} median {s['p50_ms']} ms  p99 {s['p99_ms']} ms")
    outlines = f["outlines_measured_again"]
    lines.append(
        f"tracked ends' outlines measured again: {outlines['between_pairs']} between pairs,"
        f" {outlines['in_pairs']} in a pair's latency"
    )
    lines.append(f"CPU: {f['cpu_cores']} cores, {f['cpu_ms_per_pair']} ms per pair   (target < 1 core)")
    own = f["processing_thread_cpu_ms"]
    lines.append(
        f"machine: processing thread CPU per pair median {own['p50_ms']} ms, p99 {own['p99_ms']} ms"
        " (wall beyond it: time off the CPU)"
    )
    warm = f["back_to_back_cpu_ms"]
    if warm is not None:
        lines.append(f"  the same work back to back (warm caches): median {warm['p50_ms']} ms, p99 {warm['p99_ms']} ms")
    paced = f["paced_detection_ms"]
    if paced is not None:
        lines.append(
            f"  detection of a pair after {PAUSE_S * 1000:g} ms idle: both cameras together (as the daemon)"
            f" median {paced['together']['p50_ms']} ms, one camera at a time {paced['one_at_a_time']['p50_ms']} ms"
        )
    if f["machine_steal_percent"] is not None:
        lines.append(
            f"  CPU time stolen by the hypervisor during the run: {f['machine_steal_percent']} %"
            f" (interrupts: {f['machine_interrupt_percent']} %)"
        )
    off = f["off_cpu"]
    if off["pairs"]:
        split, clear, every = off["off_cpu_split_percent"], off["latency_not_held_up_ms"], off["latency_all_ms"]
        lines += [
            f"  time off the CPU (both threads, per pair): median {off['off_cpu_ms_per_pair']['p50_ms']} ms,"
            f" p99 {off['off_cpu_ms_per_pair']['p99_ms']} ms",
            f"    of that time: {split['run_queue']} % waiting for a CPU of this machine, {split['asleep']} %"
            f" asleep (a lock, the GIL), {split['hypervisor_or_interrupts']} % taken by the hypervisor or"
            " interrupts",
            f"  waits: to be taken median {off['waiting_ms']['p50_ms']} ms, p99 {off['waiting_ms']['p99_ms']} ms;"
            f" hand-over median {off['handoff_ms']['p50_ms']} ms, p99 {off['handoff_ms']['p99_ms']} ms",
            f"  {off['pairs_held_up_1_ms_or_more']} of {off['pairs']} pairs were held up 1 ms or more (waits and"
            f" time off the CPU); the others' latency: {_spread(clear)}"
            f" (all pairs: {every['p50_ms']} / {every['p99_ms']} ms)",
        ]
    by_steal = f["latency_by_steal"]
    if by_steal:
        quiet, loud = by_steal["quiet"], by_steal["stolen"]
        lines.append(
            f"  by /proc/stat, in {by_steal['periods']} periods of 0.2 s, {by_steal['periods_with_steal']} with CPU"
            f" stolen: latency of the {quiet['pairs']} pairs that overlap none of them {_spread(quiet)};"
            f" of the {loud['pairs']} others {_spread(loud)}"
        )
    wakeup = f["cpu_wakeup"]
    names = {"held": "held awake (PM QoS 0 µs)", "not_held": "free to halt"}
    if wakeup["mode"] == "alternate" and "held" in wakeup:
        lines.append(f"CPUs held awake and free to halt in turns of {wakeup['turn_s']:g} s, side by side:")
    elif wakeup["mode"] == "alternate":
        lines.append(f"CPUs free to halt (the run was shorter than one turn of {wakeup['turn_s']:g} s):")
    else:
        whole_run = "held awake (PM QoS 0 µs) for the whole run" if wakeup["mode"] == "held" else "free to halt"
        lines.append(f"CPUs {whole_run} (--cpu-wakeup to compare):")
    for name in ("held", "not_held"):
        if name in wakeup:
            turn = wakeup[name]
            steal = "unknown" if turn["steal_percent"] is None else f"{turn['steal_percent']} %"
            latency = (
                f"latency {_spread(turn)}, max {turn['max_ms']} ms; wait to be taken"
                f" p99 {turn['waiting_ms']['p99_ms']} ms"
                if turn["pairs"]
                else "no latency"
            )
            lines.append(f"  {names[name]}: {turn['pairs']} pairs, {latency}; CPU stolen {steal}")
    if wakeup["other_request_us"] is not None:
        lines.append(
            f"  NOTE: another process holds a CPU wake-up latency request of {wakeup['other_request_us']} µs"
            " (trackerd-cpu-latency, tuned?): the CPUs were never free to halt"
        )
    lines.append(
        f"drops: {f['dropped_pairs_source']} pairs not taken in time by processing,"
        f" {f['dropped_pairs_queue']} at the publisher queue   (target 0 caused by processing)"
    )
    received = ", ".join(f"{topic} {count}" for topic, count in sorted(f["messages_received"].items()))
    lines.append(f"received by a subscriber (the warm-up included): {received or 'nothing'}")
    console = f.get("console") or {"mode": "off"}
    if console["mode"] == "viewer":
        lines.append(
            f"console: one page connected, {console.get('images', 0)} camera images"
            f" ({console.get('image_bytes', 0) / 1e6:.1f} MB) and {console.get('texts', 0)} other messages"
        )
    else:
        lines.append(f"console: {console['mode']}")
    if f["failure"]:
        lines.append(f"FAILED: {f['failure']}")
    return "\n".join(lines)
