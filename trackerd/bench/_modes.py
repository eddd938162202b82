"""`trackerd bench replay --modes`: the recording modes side by side on one raw recording, in one run.

The raw recording is rewritten as compressed and as windowed, pair by pair
through :class:`~trackerd.recording.writer.RecordingWriter` as the recorder's
writer thread does; the CPU time of each ``write`` (on the calling thread,
``time.thread_time``: zstd, the windowed mode's two locates, the checksums)
gives the recorder's CPU share at the recorded rate. The raw row writes the
same pairs as `trackerd record` would (``writev`` and checksums). Then each
recording is replayed at max speed through the pipeline exactly as
`trackerd replay --speed max` runs it (today's raw replay with checksums, as
the baseline, and without), each also located in the pipeline's own process
(``one process``, as `--one-process` and as before the worker locating ahead,
trackerd.recording.ahead) beside the default, and the hits of every replay are
compared with the raw replay's, field for field. The CPU figures count the
worker too, its start (about a second of imports) included.
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path
from typing import Any

from trackerd.bench.progress import BenchProgress
from trackerd.recording.format import Mode

MODES: tuple[Mode, ...] = ("raw", "compressed", "windowed")


def write_modes(raw_path: Path, workdir: Path, keyframe_interval_s: float) -> dict[str, dict[str, Any]]:
    """Each mode written from the raw recording's pairs: bytes per pair and writer CPU per pair."""
    from trackerd.recording.reader import Recording
    from trackerd.recording.writer import RecordingWriter

    out: dict[str, dict[str, Any]] = {}
    with Recording.open(raw_path) as source:
        n = len(source)
        span_s = source.duration_s
        rate = (n - 1) / span_s if span_s > 0 else 60.0
        progress = BenchProgress("replay", len(MODES) * n, "pairs written")
        for mode in MODES:
            path = workdir / f"{mode}.trec"
            if path.exists():
                shutil.rmtree(path)
            writer = RecordingWriter(
                path,
                source.metadata.model_copy(update={"end": None}),
                mode=mode,
                keyframe_interval_s=keyframe_interval_s,
            )
            cpu = 0.0
            for index in range(n):
                pair = source.pair(index, verify=False)
                start = time.thread_time()
                writer.write(pair)
                cpu += time.thread_time() - start
                progress.step()
            writer.close("bench")
            planner = getattr(writer, "_planner", None)
            out[mode] = {
                "path": path,
                "pairs": writer.pairs,
                "bytes_per_pair": round(writer.data_bytes / writer.pairs),
                "keyframes": writer.keyframes if mode != "raw" else writer.pairs,
                "keyframe_reasons": dict(planner.keyframes) if planner is not None else {},
                "writer_cpu_ms_per_pair": round(1e3 * cpu / writer.pairs, 2),
                "cpu_share_at_rate": round(cpu / writer.pairs * rate, 3),
                "rate_hz": round(rate, 1),
            }
        progress.done()
    raw_bytes = out["raw"]["bytes_per_pair"]
    for figures in out.values():
        figures["ratio_to_raw"] = round(raw_bytes / figures["bytes_per_pair"], 1)
    return out


def replay_modes(
    written: dict[str, dict[str, Any]], rig_path: str | None, truth: list[dict] | None
) -> dict[str, dict[str, Any]]:
    """Each recording replayed at max speed through the pipeline; hits compared with the raw replay's."""
    from trackerd.bench.replay import replay_once
    from trackerd.recording.reader import Recording
    from trackerd.recording.replay_rig import replay_rig

    # "one process": located in the pipeline, as before the worker locating ahead
    # (trackerd.recording.ahead) and as `trackerd replay --speed max --one-process` (old vs new, one run).
    runs = [
        ("raw, one process", "raw", True, False),
        ("raw", "raw", True, True),
        ("raw --no-verify, one process", "raw", False, False),
        ("raw --no-verify", "raw", False, True),
        ("compressed, one process", "compressed", True, False),
        ("compressed", "compressed", True, True),
        ("windowed, one process", "windowed", True, False),
        ("windowed", "windowed", True, True),
    ]
    out: dict[str, dict[str, Any]] = {}
    reference: dict[int, dict] | None = None
    progress = BenchProgress("replay", len(runs), "replays")
    for name, mode, verify, ahead in runs:
        with Recording.open(written[mode]["path"]) as recording:
            rig, _ = replay_rig(recording, rig_path, ["tcp://127.0.0.1:*"])
            figures = replay_once(
                recording, rig, None, verify, len(recording), truth, keep_hits=True, locate_ahead=ahead
            )
        hits = {h["sequence"]: {k: v for k, v in h.items() if k != "publish_ns"} for h in figures.pop("hit_messages")}
        if reference is None:
            reference = hits
        # Every hit published is the raw replay's of that pair; a pair the pipeline's publishing queue
        # dropped (a loaded machine; dropped_before_publishing) has none to compare.
        figures["hits_identical_to_raw"] = all(reference.get(seq) == hit for seq, hit in hits.items())
        figures["hits_missing"] = len(set(reference) - set(hits))
        figures["mode"] = mode
        out[name] = figures
        progress.step()
    progress.done()
    return out


def format_modes(written: dict[str, dict[str, Any]], replays: dict[str, dict[str, Any]]) -> str:
    lines = [
        "mode        bytes/pair  ratio to raw  keyframes  writer CPU/pair  CPU share at"
        f" {written['raw']['rate_hz']:g} pairs/s"
    ]
    for mode, f in written.items():
        reasons = ", ".join(f"{k} {v}" for k, v in f["keyframe_reasons"].items())
        lines.append(
            f"{mode:<11} {f['bytes_per_pair']:>10}  {f['ratio_to_raw']:>11}x  {f['keyframes']:>9}"
            f"  {f['writer_cpu_ms_per_pair']:>12} ms  {100 * f['cpu_share_at_rate']:>5.1f} % of a core"
            + (f"  ({reasons})" if reasons else "")
        )
    from trackerd.recording.checksum import CRC32_IMPLEMENTATION

    # The checksums' library sets what checking them costs (raw rows, the writer's CPU): say which ran.
    lines.append(f"replay, max speed, through the pipeline (frame checksums by {CRC32_IMPLEMENTATION}):")
    for name, f in replays.items():
        same = "identical to raw's" if f["hits_identical_to_raw"] else "DIFFER from raw's"
        dropped = f["dropped_before_publishing"]
        note = f"; {dropped} pairs dropped before publishing (load)" if dropped else ""
        lines.append(
            f"  {name:<30} {f['pair_rate_hz']:>7} pairs/s, {f['cpu_ms_per_pair']:>5} ms CPU/pair over"
            f" {f['pairs']} pairs, {f['hits']} hits ({same}{note})"
        )
    return "\n".join(lines)
