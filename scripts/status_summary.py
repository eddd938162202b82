#!/usr/bin/env python3
"""Summarise one daemon run from its status messages: pair rate, frame rates, skew, latency.

    trackerd listen --endpoint E --topic status --json --timeout 15 > status.jsonl   # while `trackerd run` runs
    python3 scripts/status_summary.py status.jsonl

Rates are counted between the first and last ``running`` status (counters over the
elapsed uptime); skew and latency percentiles are the median, over those statuses,
of the windows each status reports. Used for the backend comparison in
docs/acquisition.md.
"""

from __future__ import annotations

import json
import statistics
import sys


def summary(lines: list[str]) -> str:
    rows = [json.loads(line) for line in lines if line.strip()]
    running = [r for r in rows if r.get("topic") == "status" and r["state"] == "running"]
    if len(running) < 2:
        raise ValueError("fewer than two 'running' statuses: was the daemon running and tracking?")
    first, last = running[0], running[-1]
    elapsed_s = last["uptime_s"] - first["uptime_s"]

    def rate(a: float, b: float) -> float:
        return (b - a) / elapsed_s

    def median(section: str, key: str) -> float | None:
        values = [r[section][key] for r in running if r[section].get(key) is not None]
        return statistics.median(values) if values else None

    frames = [round(rate(a["frames"], b["frames"]), 1) for a, b in zip(first["cameras"], last["cameras"], strict=True)]
    hits = rate(first["messages"].get("hit", 0), last["messages"].get("hit", 0))
    skew = [median("pairing", "skew_p50_us"), median("pairing", "skew_p99_us")]
    latency = [median("latency", k) for k in ("p50_ms", "p90_ms", "p99_ms")]
    losses = [c["losses"] for c in last["cameras"]]
    return "\n".join(
        [
            f"{len(running)} running statuses over {elapsed_s:.1f} s",
            f"pairs/s {rate(first['pairing']['pairs'], last['pairing']['pairs']):.2f}  frames/s per camera {frames}"
            f"  hits/s {hits:.2f}  camera losses {losses}",
            f"frames not paired {last['pairing']['dropped_frames']}  pairs dropped {last['pairing']['dropped_pairs']}",
            "skew p50 / p99 " + " / ".join("n/a" if v is None else f"{v / 1000:.2f}" for v in skew) + " ms",
            "latency p50 / p90 / p99 " + " / ".join("n/a" if v is None else f"{v:.1f}" for v in latency) + " ms",
        ]
    )


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("usage: status_summary.py STATUS.jsonl", file=sys.stderr)
        return 2
    try:
        with open(argv[1], encoding="utf-8") as handle:
            print(summary(handle.readlines()))
    except (OSError, ValueError, KeyError) as err:
        print(f"status_summary.py: {argv[1]}: {err}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
