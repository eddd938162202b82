"""Recording and replay: MB/s and drops recording two 1080p cameras at 60 fps; replay throughput against baselines.

1. record: a rendered 1920x1080 BayerRG8 motion loop is served from memory at
   60 pairs per second (paced like free-running cameras) for --record-seconds,
   either through the daemon's pipeline with recording on demand enabled
   (``daemon``, the default: tracking and recording at once, as `trackerd run`
   does) or straight into the recorder (``recorder``, what `trackerd record`
   does with the cameras). Figures: pairs written, pairs dropped (by the
   writer's queue, and by the source because the consumer was late), the
   average write rate in MB/s and its lowest two-second value.
2. replay: the recording replayed at max speed through the pipeline exactly as
   `trackerd replay --speed max` runs it (publisher, extensions), in pairs per
   second, with trackerd's detector (frame checksums on, then off), with its
   eq. 12 bounding-box centre, and, side by side in the same run on the same
   pairs, with the report's method (eq. 10-12 over the whole image) and the
   OpenCV reference detector (demosaic, HSV, inRange, moments) in its place.
   Each line also gives the median and 95th percentile hit error against the
   rendered ground truth. Targets (issue): at least 400 pairs per second on two
   cores, and at least 8x the OpenCV reference.

The recording goes to a temporary folder under --dir (deleted afterwards
unless --keep); --recording replays an existing recording instead (no truth).
"""

from __future__ import annotations

import argparse
import json
import resource
import shutil
import tempfile
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from trackerd.bench.progress import BenchProgress
from trackerd.config.examples import example_rig
from trackerd.config.loader import load_rig
from trackerd.config.models import RigConfig
from trackerd.config.recording import RecordingConfig
from trackerd.detect.result import ImageDetections
from trackerd.locator import Locator
from trackerd.publish import Publisher
from trackerd.publish.messages import Message

REFERENCE_PAIRS = 300
"""The baselines take tens of milliseconds a pair: they replay this many pairs by default."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--config", default=str(example_rig("simulated")), help="rig (default: the bundled config/simulated.toml)"
    )
    parser.add_argument("--motion", default="figure8", help="rendered motion to record (default figure8)")
    parser.add_argument("--record-seconds", type=float, default=30.0, help="length of the recording (default 30)")
    parser.add_argument("--rate", type=float, default=60.0, help="pairs per second recorded (default 60)")
    parser.add_argument("--record-via", choices=("daemon", "recorder"), default="daemon", help="see above")
    parser.add_argument("--dir", help="where to write the recording (default: the system's temporary folder)")
    parser.add_argument("--keep", action="store_true", help="keep the recording")
    parser.add_argument("--recording", help="replay this recording instead of recording one")
    parser.add_argument("--pairs", type=int, help="pairs replayed by trackerd's detector (default: all)")
    parser.add_argument(
        "--reference-pairs",
        type=int,
        default=REFERENCE_PAIRS,
        help=f"pairs replayed by the baselines (default {REFERENCE_PAIRS})",
    )
    parser.add_argument(
        "--modes",
        action="store_true",
        help="instead of the baselines: the recording rewritten compressed and windowed, each"
        " mode's size, writer CPU and replay rate side by side (trackerd/bench/_modes.py)",
    )
    parser.add_argument(
        "--keyframe-interval",
        type=float,
        default=1.0,
        metavar="S",
        help="with --modes: keyframe interval of the compressed and windowed modes (default 1)",
    )
    parser.add_argument(
        "--cold",
        action="store_true",
        help="drop the page cache before each replay (root): read from the disk, not memory",
    )


def run(args: argparse.Namespace) -> int:
    from trackerd.recording.reader import Recording

    rig = load_rig(args.config).config
    figures: dict[str, Any] = {}
    workdir = None
    truth = None
    try:
        if args.recording:
            path = Path(args.recording)
        else:
            if args.dir:
                Path(args.dir).mkdir(parents=True, exist_ok=True)
            workdir = Path(tempfile.mkdtemp(prefix="trackerd-bench-replay-", dir=args.dir))
            path, figures["record"], truth = _record(rig, args, workdir)
        if args.modes:
            from trackerd.bench._modes import format_modes, replay_modes, write_modes

            mode_dir = Path(tempfile.mkdtemp(prefix="trackerd-bench-modes-", dir=args.dir))
            try:
                figures["modes"] = write_modes(path, mode_dir, args.keyframe_interval)
                figures["mode_replays"] = replay_modes(
                    figures["modes"], args.config if not args.recording else None, truth
                )
            finally:
                if not args.keep:
                    shutil.rmtree(mode_dir, ignore_errors=True)
            for f in figures["modes"].values():
                f["path"] = str(f["path"])
            print(
                json.dumps(figures, indent=2, default=str)
                if args.json
                else format_modes(figures["modes"], figures["mode_replays"])
            )
            return 0
        with Recording.open(path) as recording:
            figures["recording"] = {
                "path": str(path),
                "pairs": len(recording),
                "mb": round(recording.data_size / 1e6, 1),
                "cameras": [f"{c.id} {c.pixel_format} {c.width_px}x{c.height_px}" for c in recording.cameras],
            }
            figures["replay"] = _replays(recording, args, truth)
    finally:
        if workdir is not None and not args.keep:
            shutil.rmtree(workdir, ignore_errors=True)
    ours = figures["replay"]["trackerd, same pairs as the baselines"]["pair_rate_hz"]
    opencv = figures["replay"]["opencv reference"]["pair_rate_hz"]
    figures["ratio_trackerd_to_opencv"] = round(ours / opencv, 1) if opencv else None
    print(json.dumps(figures, indent=2) if args.json else _format(figures))
    return 0


# --------------------------------------------------------------------------- recording


def _bench_rig(rig: RigConfig, endpoint: str, recording: RecordingConfig | None = None) -> RigConfig:
    zmq_cfg = rig.outputs.zmq.model_copy(update={"endpoints": (endpoint,)})
    update: dict[str, Any] = {"outputs": rig.outputs.model_copy(update={"zmq": zmq_cfg})}
    if recording is not None:
        update["recording"] = recording
    return rig.model_copy(update=update)


def _record(rig: RigConfig, args: argparse.Namespace, workdir: Path) -> tuple[Path, dict[str, Any], list[dict]]:
    from trackerd.acquisition.memory import MemoryPairSource
    from trackerd.sim.rig import render_loop

    BenchProgress("replay").phase(f"recording {args.record_seconds:g} s of the '{args.motion}' loop")
    loop = render_loop(rig, args.motion)
    frames = [np.load(p) for p in loop.frame_paths]
    image_sets = [[cam[i] for cam in frames] for i in range(loop.n_frames)]
    count = int(args.record_seconds * args.rate)
    source = MemoryPairSource(rig, image_sets, rate_hz=args.rate, count=count)
    samples: list[tuple[float, float]] = []
    if args.record_via == "daemon":
        from trackerd.interaction.extension import create as interaction_extension
        from trackerd.pipeline.daemon import Pipeline
        from trackerd.publish import Publisher
        from trackerd.recording.extension import create as recording_extension

        directory = workdir / "daemon"
        bench_rig = _bench_rig(rig, "tcp://127.0.0.1:*", RecordingConfig(directory=directory, enabled=True))
        # As `trackerd run` builds them (trackerd/cli/run.py).
        extension = recording_extension(bench_rig)
        assert extension is not None  # the bench rig gives it a directory
        interaction = interaction_extension(bench_rig)
        pipeline = Pipeline(
            bench_rig,
            lambda r: source,
            lambda r: Publisher(r.outputs.zmq),
            extensions=[extension, *([interaction] if interaction is not None else [])],
        )
        pipeline.start()
        try:
            while source.status().running and pipeline.failure is None:
                time.sleep(0.5)
                status = extension.status() or {}
                samples.append((time.monotonic(), float(status.get("write_rate_mb_s") or 0.0)))
            processing_drops = pipeline.source.status().dropped_pairs if pipeline.source else 0
        finally:
            pipeline.stop(timeout_s=5.0)
        if pipeline.failure is not None:
            raise RuntimeError(f"the pipeline crashed while recording:\n{pipeline.failure}")
        (path,) = directory.glob("*.trec")
    else:
        from trackerd.recording.recorder import Recorder

        path = workdir / "recorder.trec"
        recorder = Recorder(path, rig, producer="trackerd bench replay", config=RecordingConfig()).start()
        source.start()
        last = time.monotonic()
        while (pair := source.next_pair(0.5)) is not None:
            recorder.put(pair)
            if time.monotonic() - last >= 0.5:
                last = time.monotonic()
                samples.append((last, recorder.status().write_rate_mb_s))
        recorder.stop(60.0)
        processing_drops = source.status().dropped_pairs
    return path, _record_figures(path, args, processing_drops, samples), loop.truth()


def _record_figures(
    path: Path, args: argparse.Namespace, late: int, samples: list[tuple[float, float]]
) -> dict[str, Any]:
    from trackerd.recording.reader import Recording

    with Recording.open(path) as recording:
        end = recording.metadata.end
        span = recording.duration_s
        rates = [r for _, r in samples[4:] if r > 0]  # after the first two seconds
        return {
            "via": args.record_via,
            "offered_pairs": int(args.record_seconds * args.rate),
            "rate_hz": args.rate,
            "pairs_written": len(recording),
            "dropped_by_writer": end.dropped_pairs if end else None,
            "dropped_late_consumer": late,
            "mb_written": round(recording.data_size / 1e6, 1),
            "write_mb_s": round(recording.data_size / 1e6 / span, 1) if span else None,
            "lowest_2s_write_mb_s": round(min(rates), 1) if rates else None,
            "problems": recording.problems,
        }


# --------------------------------------------------------------------------- replay


class _Baseline:
    """One of detect.reference's functions behind the detector interface the locator uses."""

    def __init__(self, function: Any, pixel_format: str, rig: RigConfig) -> None:
        self.function, self.pixel_format, self.cfg = function, pixel_format, rig.detector

    def detect(self, image: np.ndarray) -> Any:
        return self.function(image, self.pixel_format, self.cfg)

    def reset(self) -> None:
        pass


class _BaselineLocator(Locator):
    """The locator with a baseline detector in place of trackerd's: all else is the pipeline's."""

    def __init__(self, rig: RigConfig, function: Any) -> None:
        # The baseline's centroids go through the interpretation planes, as the pipeline's did before the
        # refined path: the pointer fit needs trackerd's own detections and outlines.
        rig = rig.model_copy(update={"locator": rig.locator.model_copy(update={"refine": "never"})})
        super().__init__(rig)
        self._baselines = [_Baseline(function, fmt, rig) for fmt in self.pixel_formats]
        self._detect_all = _each_alone

    @property
    def detectors(self) -> list:
        return self._baselines


def _each_alone(detectors: Sequence[Any], frames: Sequence[np.ndarray]) -> list[ImageDetections]:
    """Each baseline detector on its own frame (they have no joint measurement)."""
    return [detector.detect(frame) for detector, frame in zip(detectors, frames, strict=True)]


class _KeepingPublisher(Publisher):
    """A real Publisher that also keeps the hits it publishes (for their error against the truth)."""

    def __init__(self, rig: RigConfig) -> None:
        super().__init__(rig.outputs.zmq)
        self.hits: list[dict[str, Any]] = []

    def publish(self, message: Message) -> bool:
        if message.topic == "hit":
            self.hits.append(message.model_dump())
        return super().publish(message)


def _replays(recording: Any, args: argparse.Namespace, truth: list[dict] | None) -> dict[str, dict[str, Any]]:
    from trackerd.detect.reference import opencv_reference, report_baseline
    from trackerd.recording.replay_rig import replay_rig

    rig, _ = replay_rig(recording, args.config if not args.recording else None, ["tcp://127.0.0.1:*"])
    bbox_rig = rig.model_copy(update={"detector": rig.detector.model_copy(update={"centroid": "bbox"})})
    n = len(recording) if args.pairs is None else min(args.pairs, len(recording))
    n_ref = min(args.reference_pairs, len(recording))
    runs = [
        ("trackerd", rig, None, True, n),
        ("trackerd, checksums off", rig, None, False, n),
        ("trackerd, same pairs as the baselines", rig, None, True, n_ref),
        ("trackerd, bbox centre (eq. 12 on its blob)", bbox_rig, None, True, n_ref),
        ("report's method (eq. 10-12, whole image)", rig, report_baseline, True, n_ref),
        ("opencv reference", rig, opencv_reference, True, n_ref),
    ]
    out = {}
    progress = BenchProgress("replay", len(runs), "replays")
    for name, run_rig, baseline, verify, count in runs:
        if args.cold:
            _drop_page_cache()
        out[name] = replay_once(recording, run_rig, baseline, verify, count, truth)
        progress.step()
    progress.done()
    return out


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def replay_once(
    recording: Any,
    rig: RigConfig,
    baseline: Any,
    verify: bool,
    count: int,
    truth: list[dict] | None,
    *,
    keep_hits: bool = False,
    batch: bool = True,
    threaded_decode: bool = True,
    locate_ahead: bool = True,
) -> dict[str, Any]:
    """One replay at max speed through the pipeline, as `trackerd replay --speed max` runs it
    (``batch``, ``threaded_decode`` and ``locate_ahead`` False: as before those, for the
    side-by-side rows; a baseline always locates in the pipeline)."""
    from trackerd.interaction.extension import create as interaction_extension
    from trackerd.pipeline.daemon import Pipeline
    from trackerd.pipeline.extensions import ExtensionContext, PipelineExtension
    from trackerd.recording.extension import create as recording_extension
    from trackerd.recording.replay import ReplayPairSource

    source = ReplayPairSource(
        recording,
        speed=None,
        verify=verify,
        count=count,
        batch=batch,
        threaded_decode=threaded_decode,
        locate_with=rig if locate_ahead and baseline is None else None,
    )
    publishers: list[_KeepingPublisher] = []

    def publisher_factory(r: RigConfig) -> _KeepingPublisher:
        publishers.append(_KeepingPublisher(r))
        return publishers[-1]

    # As `trackerd replay` builds them (trackerd/cli/run.py).
    context = ExtensionContext(replay=True)
    extensions: list[PipelineExtension] = [
        e for e in (recording_extension(rig, context), interaction_extension(rig, context)) if e is not None
    ]
    pipeline = Pipeline(
        rig,
        lambda r: source,
        publisher_factory,
        extensions=extensions,
        clock_offset_ns=source.pipeline_clock_offset_ns(),
    )
    if baseline is not None:
        pipeline.locator = _BaselineLocator(rig, baseline)
    done = threading.Event()
    cpu_start = time.process_time()
    children_start = _children_cpu_s()
    pipeline.start()
    try:
        while not done.is_set() and pipeline.failure is None:
            if source.finished and pipeline.pairs_processed >= source.delivered and pipeline.backlog <= 0:
                done.set()
            time.sleep(0.01)
    finally:
        pipeline.stop()
    if pipeline.failure is not None:
        raise RuntimeError(f"the pipeline crashed during a replay:\n{pipeline.failure}")
    if source.failure is not None:
        raise RuntimeError(f"the replay stopped early: {source.failure}")
    # The worker locating ahead is a child process, waited for once the source stops.
    cpu_s = time.process_time() - cpu_start + _children_cpu_s() - children_start
    first_ns, last_ns = source.first_delivery_ns, source.last_delivery_ns
    elapsed = (last_ns - first_ns) / 1e9 if first_ns is not None and last_ns is not None else 0.0
    hits = [h for p in publishers for h in p.hits]
    figures: dict[str, Any] = {
        "pairs": source.delivered,
        "pair_rate_hz": round((source.delivered - 1) / elapsed, 1) if elapsed > 0 else None,
        "hits": len(hits),
        # CPU of the whole process (every thread) and of the worker locating ahead (its start, about
        # a second of imports, included) per pair: what a replay costs, whatever else the machine
        # runs (pairs/s above depends on that).
        "cpu_ms_per_pair": round(1e3 * cpu_s / max(source.delivered, 1), 2),
    }
    status = pipeline.build_status(source.status())
    figures["fixes"] = dict(status.fixes)
    # Processed but never handed to the publisher: its drop-oldest queue dropped them (a loaded machine).
    figures["dropped_before_publishing"] = pipeline.pairs_processed - pipeline.pairs_published
    if keep_hits:
        figures["hit_messages"] = hits
    figures["dropped_pairs"] = status.pairing.dropped_pairs
    if truth:
        frame_ids = {e.sequence: recording.header(i).frames[0].frame_id for i, e in enumerate(recording.entries)}
        errors = []
        for hit in hits:
            true_xy = truth[frame_ids[hit["sequence"]] % len(truth)].get("wall_xy_m")
            x = hit.get("raw_wall_x_m") if hit.get("raw_wall_x_m") is not None else hit["wall_x_m"]
            y = hit.get("raw_wall_y_m") if hit.get("raw_wall_y_m") is not None else hit["wall_y_m"]
            if true_xy is not None:
                errors.append(1000 * float(np.hypot(x - true_xy[0], y - true_xy[1])))
        if errors:
            figures["hit_error_mm"] = {
                "p50": round(float(np.median(errors)), 2),
                "p95": round(float(np.percentile(errors, 95)), 2),
            }
    return figures


def _drop_page_cache() -> None:
    import os

    os.sync()
    try:
        Path("/proc/sys/vm/drop_caches").write_text("3\n")
    except OSError as err:
        raise SystemExit(f"--cold needs root to drop the page cache ({err.strerror})") from err


def _format(f: dict[str, Any]) -> str:
    lines = []
    rec = f.get("record")
    if rec:
        lines.append(
            f"record ({rec['via']}): {rec['pairs_written']} of {rec['offered_pairs']} pairs offered at"
            f" {rec['rate_hz']:g} pairs/s written, {rec['mb_written']} MB; average {rec['write_mb_s']} MB/s,"
            f" lowest 2 s window {rec['lowest_2s_write_mb_s']} MB/s; dropped {rec['dropped_by_writer']} by the"
            f" writer, {rec['dropped_late_consumer']} because the consumer was late"
        )
    r = f["recording"]
    lines.append(f"replayed: {r['path']} ({r['pairs']} pairs, {r['mb']} MB, {', '.join(r['cameras'])}), max speed:")
    for name, fig in f["replay"].items():
        error = fig.get("hit_error_mm")
        err = f"  hit error p50 {error['p50']} mm, p95 {error['p95']} mm" if error else ""
        rate = f"{fig['pair_rate_hz']:>7} pairs/s over {fig['pairs']} pairs"
        lines.append(f"  {name:<44} {rate}, {fig['hits']} hits{err}")
        if fig["hits"] < fig["pairs"]:
            lines.append(f"  {'':<44} outcomes: {fig['fixes']}")
    lines.append(f"trackerd / opencv reference: {f['ratio_trackerd_to_opencv']}x   (targets: >= 400 pairs/s, >= 8x)")
    return "\n".join(lines)
