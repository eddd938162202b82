"""Every `trackerd bench NAME` runs in the suite with its smallest arguments, so none can rot unseen
(`bench replay` once crashed on main for weeks): each completes, and its JSON holds the figures the docs
quote. (detector: tests/detect/test_detect_bench.py; pipeline, replay, robustness: their own files here.)"""

from __future__ import annotations

import json
import subprocess
import sys


def _bench(*args: str) -> dict:
    run = subprocess.run(
        [sys.executable, "-m", "trackerd", "bench", *args, "--json"], capture_output=True, text=True, timeout=600
    )
    assert run.returncode == 0, run.stderr
    assert "Traceback" not in run.stderr
    return json.loads(run.stdout)


def test_bench_accuracy_with_five_poses() -> None:
    figures = _bench("accuracy", "--poses", "5", "--workers", "1")
    assert set(figures["groups"]) == {"placements", "rotations", "lengths"}
    for group in figures["groups"].values():
        assert group["poses"] == 5
        assert {"trackerd", "two_points", "report"} <= set(group["methods"])
        trackerd = group["methods"]["trackerd"]
        # Five poses say nothing of the targets (the bench's default 250 do): a sanity bound only.
        assert 0 < trackerd["median_mm"] < 5.0 and trackerd["median_mm"] <= trackerd["p95_mm"], trackerd


def test_bench_calibration_with_the_fewest_views() -> None:
    figures = _bench("calibration", "--views", "10", "--pairs", "6", "--pointing", "2", "--poses", "5")
    assert {"cameras", "stereo", "wall"} <= set(figures["parameters"])
    errors = figures["wall_hit_error"]
    assert errors["true"]["poses"] == errors["recovered"]["poses"] == 5
    assert errors["recovered"]["failures"] == 0 and errors["recovered"]["median_mm"] < 5.0, errors


def test_bench_interaction_with_a_few_of_each() -> None:
    figures = _bench(
        "interaction", "--rendered-pairs", "4", "--sessions", "1", "--pointing-minutes", "0.1", "--hands", "2"
    )
    assert {"smoothing", "gestures", "hands", "cost"} <= set(figures)
    assert figures["smoothing"]["scripted"] and figures["hands"]["hands"] == 2
    assert figures["cost"]["engine_per_pair_us"] and figures["cost"]["hand_look_ms"] is not None
