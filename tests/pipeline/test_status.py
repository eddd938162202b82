"""The status message from figures (pure): what each figure becomes on the wire."""

from __future__ import annotations

import numpy as np

import trackerd
from trackerd.acquisition.status import CameraStatus, SourceStatus
from trackerd.pipeline.figures import PipelineFigures
from trackerd.pipeline.status import StatusFigures, status_message

MS = 1_000_000


def _source() -> SourceStatus:
    cameras = (
        CameraStatus(
            camera_id="left",
            state="streaming",
            device="sim-left",
            frames=600,
            frame_rate_hz=60.0,
            failed_buffers={"timeout": 2},
            losses=1,
            reconnects=1,
            last_error="was lost",
        ),
        CameraStatus(camera_id="right", state="lost", device="sim-right", frames=590, frame_rate_hz=0.0),
    )
    return SourceStatus(
        running=True,
        trigger="free",
        pairing="timestamp",
        pairs=580,
        pair_rate_hz=59.5,
        dropped_frames={"left": 3},
        dropped_pairs=7,
        skew_p50_us=12.0,
        skew_p99_us=40.0,
        cameras=cameras,
    )


def _figures(**changes) -> StatusFigures:
    latency = {
        "latency": np.array([2, 3, 4, 5], dtype=np.int64) * MS,
        "processing": np.array([1, 2], dtype=np.int64) * MS,
        "detect": np.array([1], dtype=np.int64) * MS,
        "triangulate": np.zeros(0, dtype=np.int64),
        "publish": np.array([0], dtype=np.int64),
    }
    base = dict(
        sequence=5,
        capture_ns=1_795_000_000_000_000_000,
        uptime_s=12.5,
        state="degraded",
        detail="camera right not streaming",
        rig_name="wall",
        source=_source(),
        latency_ns=latency,
        retired_pairs=100,
        retired_dropped_pairs=4,
        queue_dropped_pairs=2,
        fixes={"hit": 500, "not_found": 80},
        extensions={"interaction": None, "recording": None},
    )
    return StatusFigures(**{**base, **changes})


def test_every_figure_reaches_its_field():
    message = status_message(_figures())
    assert (message.sequence, message.capture_ns, message.uptime_s) == (5, 1_795_000_000_000_000_000, 12.5)
    assert (message.state, message.detail, message.rig) == ("degraded", "camera right not streaming", "wall")
    assert message.version == trackerd.__version__
    assert [(c.id, c.state, c.frames) for c in message.cameras] == [("left", "streaming", 600), ("right", "lost", 590)]
    left = message.cameras[0]
    assert (left.dropped, left.losses, left.reconnects, left.last_error) == ({"timeout": 2}, 1, 1, "was lost")
    assert message.fixes == {"hit": 500, "not_found": 80}
    assert message.calibration is None and message.colours is None
    assert message.interaction is None and message.recording is None


def test_pairing_adds_the_replaced_sources_and_the_hand_over_drops():
    pairing = status_message(_figures()).pairing
    assert pairing.pairs == 580 + 100
    assert pairing.dropped_pairs == 7 + 4 + 2
    assert (pairing.pair_rate_hz, pairing.mode, pairing.dropped_frames) == (59.5, "timestamp", {"left": 3})
    assert (pairing.skew_p50_us, pairing.skew_p99_us) == (12.0, 40.0)
    # No source yet: no cameras, no pairs, whatever was carried over.
    empty = status_message(_figures(source=None))
    assert empty.cameras == () and empty.pairing.pairs == 0 and empty.pairing.pair_rate_hz == 0.0


def test_latencies_become_percentiles_in_ms_and_each_stage_its_own():
    message = status_message(_figures())
    assert message.latency.samples == 4 and message.latency.max_ms == 5.0 and message.latency.p50_ms == 3.5
    assert message.processing.samples == 2 and message.processing.max_ms == 2.0
    assert list(message.stages) == ["detect", "triangulate", "publish"]
    assert message.stages["detect"].p50_ms == 1.0
    assert message.stages["triangulate"].samples == 0 and message.stages["triangulate"].p50_ms is None


def test_the_stages_a_drain_gives_are_the_stages_a_status_lists():
    figures = PipelineFigures()
    figures.add_published(
        {"detect": 2 * MS, "triangulate": MS}, publish_ns=MS // 10, processing_ns=3 * MS, latency_ns=4 * MS
    )
    drained = figures.drain()
    message = status_message(_figures(latency_ns=drained))
    assert set(message.stages) == {"detect", "triangulate", "publish"}
    assert message.stages["publish"].max_ms == 0.1 and message.latency.max_ms == 4.0
    assert figures.pairs_published == 1
    # Drained: the next status period starts empty.
    assert all(values.size == 0 for values in figures.drain().values())


def test_calibration_colours_and_extensions_are_given_when_there_are_any():
    calibration = {
        "fixes": 24,
        "ray_gap_mm": {"p50": 0.9, "p95": 2.0, "max": 2.1},
        "reprojection_px": {"p50": 0.3, "p95": 0.7, "max": 0.7},
        "suspect": False,
        "reason": None,
        "total_fixes": 24,
    }
    interaction = {
        "smoothing": True,
        "events": {"enter": 1},
        "gestures": {},
        "templates": 6,
        "hand": False,
        "pointing": False,
    }
    message = status_message(_figures(calibration=calibration, extensions={"interaction": interaction}))
    assert message.calibration is not None and message.calibration.total_fixes == 24
    assert message.calibration.ray_gap_mm.p50 == 0.9
    assert message.interaction is not None and message.interaction.events == {"enter": 1}
