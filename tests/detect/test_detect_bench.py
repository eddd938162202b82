"""`trackerd bench detector` runs end to end and reports what the issue asks for."""

from __future__ import annotations

import json

import pytest

from trackerd.cli.main import main

pytestmark = pytest.mark.slow


def test_bench_detector_json(capsys) -> None:
    args = ["bench", "detector", "--frames", "3", "--poses", "1", "--repeats", "1", "--json"]
    args.append("--own-samples")
    assert main([*args, "--min-excess", "75", "65"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert set(report["median_ms"]) == {
        "full",
        "tracked",
        "opencv",
        "floor",
        "full_own",
        "tracked_own",
    }
    assert all(v > 0 for v in report["median_ms"].values())
    assert {"opencv_over_full", "full_over_floor", "tracked_over_floor"} <= set(report["ratios"])
    assert report["min_excess"] == {"red": 75, "blue": 65}
    assert report["load_average"] >= 0  # the machine is shared: each run says how busy it was
    accuracy = report["accuracy_px"]
    assert {"coverage (default)", "tracked", "opencv", "bbox (eq. 12, chosen blob)"} <= set(accuracy)
    assert "own samples only" in accuracy
    assert accuracy["coverage (default)"]["across_std"] >= 0
    assert accuracy["coverage (default)"]["ends"] == 2 * 2 * (3 + 1)
    assert accuracy["coverage (default)"]["missed"] == 0


def test_bench_detector_table_and_bad_option(capsys) -> None:
    assert main(["bench", "detector", "--frames", "2", "--poses", "0", "--repeats", "1"]) == 0
    out = capsys.readouterr().out
    assert "(a) full-frame search" in out and "(c)/(a)" in out and "coverage (default)" in out
    assert "load average" in out
    assert "own samples only" in out and "across sd" in out
    assert "(a')" not in out  # timed only with --own-samples
    assert main(["bench", "detector", "--frames", "2", "--min-excess", "0", "300"]) == 2
    assert "--min-excess 0 300" in capsys.readouterr().err
