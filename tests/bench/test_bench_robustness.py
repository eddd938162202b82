"""`trackerd bench robustness`: a small run completes and reports every figure the docs name."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from trackerd.bench import robustness
from trackerd.bench.robustness import FACTORS, figures, floor_hit, format_summary, summarise


def test_a_small_run_reports_trackerd_and_the_naive_method_per_factor(tmp_path) -> None:
    records = tmp_path / "frames.jsonl"
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "trackerd",
            "bench",
            "robustness",
            "--rigs",
            "1",
            "--poses",
            "3",
            "--workers",
            "1",
            "--seed",
            "3",
            "--json",
            "--records",
            str(records),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stderr
    assert "robustness: 1/1 installations" in run.stderr  # progress on stderr
    summary = json.loads(run.stdout)
    overall = summary["overall"]
    assert overall["frames"] == 3
    for key in (
        "found_percent",
        "median_mm",
        "p95_mm",
        "worst_mm",
        "over_3_sigma_percent",
        "over_5_sigma_percent",
        "within_1_sigma_percent",
        "within_2_sigma_percent",
    ):
        assert key in overall["trackerd"]
    assert set(overall["naive"]) == {"found_percent", "median_mm", "p95_mm", "worst_mm"}
    assert set(overall["floor"]) == {"median_mm", "p95_mm"}
    assert set(summary["factors"]) == set(FACTORS)
    lines = [json.loads(line) for line in records.read_text().splitlines()]
    assert [(r["rig"], r["frame"]) for r in lines] == [(0, 0), (0, 1), (0, 2)]
    assert "placement" in format_summary(summary)


def test_figures_count_confident_wrong_answers_and_sigma_coverage() -> None:
    def record(error, sigma, eligible=True):
        return {
            "eligible": eligible,
            "error_m": error,
            "sigma_m": sigma,
            "naive_error_m": None,
            "factors": dict.fromkeys(FACTORS, "x"),
            "reason": None,
            "seconds": 0.01,
        }

    records = [
        record(0.001, 0.002),
        record(0.003, 0.002),
        record(0.05, 0.002),
        record(None, None),
        record(0.04, 0.001, eligible=False),
        record(0.001, 0.002, eligible=False),
    ]
    f = figures(records)
    assert f["eligible"] == 4 and f["trackerd"]["found_percent"] == 75.0
    assert f["trackerd"]["within_1_sigma_percent"] == round(100 / 3, 1)
    assert f["trackerd"]["within_2_sigma_percent"] == round(200 / 3, 1)
    assert f["trackerd"]["over_5_sigma_percent"] == round(100 / 3, 1)
    assert f["hidden"] == {"frames": 2, "hits": 2, "confidently_wrong": 1}
    assert summarise(records)["misses"] == {"(no reason)": 1}


def test_a_miss_is_counted_by_the_detectors_reason_and_the_searchs() -> None:
    """A pair the detector's ends made impossible and the search did not find says both (trackerd/refine.py);
    the count keeps both, without the figures, and without the cameras' own reasons."""
    reasons = [
        "ends are 1854 mm apart, the pointer is 454 +- 50 mm; searched: no blue ball seen consistently",
        "ends are 2027 mm apart, the pointer is 435 +- 50 mm; searched: no blue ball seen consistently",
        "no red ball seen consistently by two cameras; cam0: 2 red blobs, none ball-shaped",
    ]
    records = [
        {
            "eligible": True,
            "error_m": None,
            "sigma_m": None,
            "naive_error_m": None,
            "reason": r,
            "factors": dict.fromkeys(FACTORS, "x"),
            "seconds": 0.1,
        }
        for r in reasons
    ]
    misses = summarise(records)["misses"]
    assert len(misses) == 2 and sorted(misses.values()) == [1, 2]
    assert any("(searched: no blue ball seen consistently)" in k for k in misses)
    assert "no red ball seen consistently by two cameras" in misses


@pytest.mark.parametrize("placement", ["side-on", "behind high", "ceiling"])
def test_the_geometric_floor_is_the_true_hit_when_the_ends_are_measured_exactly(monkeypatch, placement) -> None:
    """The floor runs the pointer fit on the true ends' images: with no noise it must land on the true hit
    (its figures are only worth printing if its own geometry is right), and with the bench's noise near it."""
    from trackerd.config.rig_geometry import wall_frame
    from trackerd.sim.randomized import random_rig, random_shot
    from trackerd.sim.scene import true_wall_hit

    rng = np.random.default_rng(5)
    drawn = random_rig(rng, placement=placement)
    wall = wall_frame(drawn.rig.wall)
    shot = random_shot(drawn, rng, wall)
    truth = true_wall_hit(shot.pose, wall).wall_xy_m
    seeing = [True] * len(drawn.cameras)
    monkeypatch.setattr(robustness, "FLOOR_SIGMA_PX", 1e-6)
    exact = floor_hit(drawn.cameras, seeing, shot.pose, drawn.rig, wall, np.random.default_rng(0))
    assert exact is not None and np.linalg.norm(exact - truth) < 1e-5
    monkeypatch.setattr(robustness, "FLOOR_SIGMA_PX", 0.1)
    noisy = [floor_hit(drawn.cameras, seeing, shot.pose, drawn.rig, wall, np.random.default_rng(k)) for k in range(5)]
    spread = [float(np.linalg.norm(hit - truth)) for hit in noisy if hit is not None]
    # A tenth of a pixel moves a typical hit by about a millimetre (the robust fit may, rarely and rightly, leave
    # out a measurement that noise put 3 sigma off, and then land centimetres away: hence the median).
    assert len(spread) == 5 and 0 < float(np.median(spread)) < 0.005
