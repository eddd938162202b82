"""`trackerd bench robustness`: a small run completes and reports every figure the docs name."""

from __future__ import annotations

import json
import subprocess
import sys

from trackerd.bench.robustness import FACTORS, figures, format_summary, summarise


def test_a_small_run_reports_trackerd_and_the_naive_method_per_factor(tmp_path) -> None:
    records = tmp_path / "frames.jsonl"
    run = subprocess.run(
        [sys.executable, "-m", "trackerd", "bench", "robustness", "--rigs", "1", "--poses", "3", "--workers", "1",
         "--seed", "3", "--json", "--records", str(records)],
        capture_output=True, text=True, timeout=600,
    )
    assert run.returncode == 0, run.stderr
    assert "robustness: 1/1 installations" in run.stderr  # progress on stderr
    summary = json.loads(run.stdout)
    overall = summary["overall"]
    assert overall["frames"] == 3
    for key in ("found_percent", "median_mm", "p95_mm", "worst_mm", "over_3_sigma_percent", "over_5_sigma_percent",
                "within_1_sigma_percent", "within_2_sigma_percent"):
        assert key in overall["trackerd"]
    assert set(overall["naive"]) == {"found_percent", "median_mm", "p95_mm", "worst_mm"}
    assert set(summary["factors"]) == set(FACTORS)
    lines = [json.loads(line) for line in records.read_text().splitlines()]
    assert [(r["rig"], r["frame"]) for r in lines] == [(0, 0), (0, 1), (0, 2)]
    assert "placement" in format_summary(summary)


def test_figures_count_confident_wrong_answers_and_sigma_coverage() -> None:
    def record(error, sigma, eligible=True):
        return {"eligible": eligible, "error_m": error, "sigma_m": sigma, "naive_error_m": None,
                "factors": dict.fromkeys(FACTORS, "x"), "reason": None, "seconds": 0.01}

    records = [record(0.001, 0.002), record(0.003, 0.002), record(0.05, 0.002), record(None, None),
               record(0.04, 0.001, eligible=False), record(0.001, 0.002, eligible=False)]
    f = figures(records)
    assert f["eligible"] == 4 and f["trackerd"]["found_percent"] == 75.0
    assert f["trackerd"]["within_1_sigma_percent"] == round(100 / 3, 1)
    assert f["trackerd"]["within_2_sigma_percent"] == round(200 / 3, 1)
    assert f["trackerd"]["over_5_sigma_percent"] == round(100 / 3, 1)
    assert f["hidden"] == {"frames": 2, "hits": 2, "confidently_wrong": 1}
    assert summarise(records)["misses"] == {"(no reason)": 1}
