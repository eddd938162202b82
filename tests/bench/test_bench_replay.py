"""`trackerd bench replay`: a short run records, replays and compares against the baselines."""

from __future__ import annotations

import json
import subprocess
import sys


def _bench_replay(tmp_path, *arguments: str) -> dict:
    """`trackerd bench replay ARGUMENTS --dir TMP --json`, its figures (it must exit 0)."""
    run = subprocess.run(
        [sys.executable, "-m", "trackerd", "bench", "replay", *arguments, "--dir", str(tmp_path), "--json"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stderr
    return json.loads(run.stdout)


def test_a_short_run_completes_with_every_row(tmp_path) -> None:
    """It crashed once, unnoticed, when the locator's detection changed under its baseline locator."""
    figures = _bench_replay(tmp_path, "--record-seconds", "1", "--pairs", "30", "--reference-pairs", "10")
    rows = figures["replay"]
    assert {"trackerd", "trackerd, checksums off", "report's method (eq. 10-12, whole image)"} <= set(rows)
    assert any(name.startswith("opencv") for name in rows)
    for row in rows.values():
        assert row["pairs"] > 0 and row["pair_rate_hz"] > 0
    # trackerd hits every pair of the rendered motion, within the accuracy budget.
    assert rows["trackerd"]["hits"] == rows["trackerd"]["pairs"] and rows["trackerd"]["hit_error_mm"]["p50"] < 2.0
    assert figures["ratio_trackerd_to_opencv"] > 0


def test_the_modes_run_puts_each_replay_beside_its_one_process_row_with_the_raw_hits(tmp_path) -> None:
    """`--modes` prints the baseline ("one process": located in the pipeline, not in the worker ahead
    of it) beside today's replay of each mode, and every replay's hits are the raw one's."""
    figures = _bench_replay(tmp_path, "--record-seconds", "0.5", "--modes", "--keyframe-interval", "0.2")
    rows = figures["mode_replays"]
    for mode in ("raw", "raw --no-verify", "compressed", "windowed"):
        assert {mode, f"{mode}, one process"} <= set(rows), sorted(rows)
    for name, row in rows.items():
        assert row["pairs"] > 0 and row["hits"] > 0, name
        assert row["hits_identical_to_raw"], name
