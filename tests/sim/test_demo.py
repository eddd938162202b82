"""`trackerd demo`: its options and the summary it ends with."""

from __future__ import annotations

import pytest

from trackerd.cli.demo import quoted_status, summary_line
from trackerd.cli.main import build_parser

pytestmark = pytest.mark.serial  # runs the demo on a virtual rig


def test_demo_runs_the_rig_on_jumbo_frames_under_its_own_prefix_if_asked() -> None:
    default = build_parser().parse_args(["demo"])
    assert (default.prefix, default.subnet, default.mtu) == ("trkd", "10.213.0.0/24", 9000)
    chosen = build_parser().parse_args(["demo", "--prefix", "mine", "--subnet", "10.213.90.0/24", "--mtu", "1500"])
    assert (chosen.prefix, chosen.subnet, chosen.mtu) == ("mine", "10.213.90.0/24", 1500)


def _status(samples: int, p50: float | None, p99: float | None, uptime: float) -> dict:
    return {
        "uptime_s": uptime,
        "fixes": {"hit": 40, "not_found": 2},
        "processing": {"samples": samples, "p50_ms": p50, "p99_ms": p99},
    }


def test_the_summary_quotes_the_last_status_period_that_processed_pairs() -> None:
    busy = _status(55, 21.3456, 48.02, 19.4)
    stopping = _status(0, None, None, 20.1)  # the last status, sent while stopping
    line = summary_line({"hits": 40, "status": stopping, "busy_status": busy})
    assert line == (
        "40 hits received in 20 s; pairs processed by outcome: hit 40, not_found 2; the daemon's own processing"
        " latency (last frame of a pair received to hit published; the status lines' latency counts from capture)"
        " p50 21.3 ms, p99 48.0 ms over the 55 pairs of the last status period"
    )
    assert "None" not in summary_line({"hits": 0, "status": stopping, "busy_status": None})
    assert summary_line({"hits": 0, "status": None, "busy_status": None}).endswith("no pair was processed")


def test_a_short_last_period_does_not_replace_a_full_one_in_the_summary() -> None:
    """The status sent as the demo stops can cover two or three pairs: their percentiles are not the run's."""
    full = _status(60, 5.5, 8.2, 14.0)
    tail = _status(2, 8.0, 8.1, 15.0)
    stopping = _status(0, None, None, 15.1)
    quoted = None
    for status in (full, tail, stopping):
        quoted = quoted_status(quoted, status)
    assert quoted is full
    # A period as busy as the last one quoted, or nearly, takes its place.
    assert quoted_status(full, _status(40, 6.0, 9.0, 16.0))["processing"]["samples"] == 40
