"""``/metrics``: the daemon's figures in the Prometheus text format (official prometheus_client).

Built at scrape time from the last status message and the cumulative latency histograms the
pipeline's tap keeps (trackerd.pipeline.tap): a scrape costs the pipeline nothing. Counters are
the daemon's own totals since start (Prometheus handles restarts as counter resets).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

from prometheus_client.core import (
    CollectorRegistry,
    CounterMetricFamily,
    GaugeMetricFamily,
    HistogramMetricFamily,
    Metric,
)
from prometheus_client.exposition import generate_latest

from trackerd.pipeline.tap import LATENCY_BUCKETS_MS, ConsoleTap

CAMERA_STATES = ("connecting", "connected", "streaming", "lost", "reconnecting", "stopped")
DAEMON_STATES = ("starting", "running", "degraded", "reloading", "stopping")
EXTRA_HELP = {
    "console_viewers": "pages of the console open now",
    "console_dropped_for_slow_pages": "camera images and messages a page had not taken when the next came",
}
HISTOGRAM_HELP = {
    "processing": "last frame of a pair received to its messages handed to ZeroMQ",
    "latency": "capture to messages handed to ZeroMQ",
    "detect": "detecting both ends in every camera",
    "triangulate": "triangulating and intersecting the wall",
    "publish": "handing one pair's messages to ZeroMQ",
}


class StatusCollector:
    """A prometheus_client collector over the tap (see the module's docstring)."""

    def __init__(self, tap: ConsoleTap, extra: Callable[[], dict[str, Any]] | None = None) -> None:
        self.tap = tap
        self.extra = extra or (lambda: {})

    def collect(self) -> Iterator[Metric]:
        status = self.tap.status
        if status is None:
            return
        up = GaugeMetricFamily("trackerd_up", "1 while the daemon runs", labels=["rig", "version"])
        up.add_metric([status.rig, status.version], 1.0)
        yield up
        state = GaugeMetricFamily("trackerd_state", "the daemon's state (1 for the current one)", labels=["state"])
        for name in DAEMON_STATES:
            state.add_metric([name], 1.0 if status.state == name else 0.0)
        yield state
        yield GaugeMetricFamily("trackerd_uptime_seconds", "time since the daemon started", value=status.uptime_s)
        pairing = status.pairing
        yield CounterMetricFamily("trackerd_pairs", "synchronized pairs delivered by the cameras", value=pairing.pairs)
        yield GaugeMetricFamily("trackerd_pair_rate_hz", "pairs per second", value=pairing.pair_rate_hz)
        drops = CounterMetricFamily(
            "trackerd_dropped_frames", "frames dropped before pairing, by cause", labels=["cause"]
        )
        for cause, count in sorted(pairing.dropped_frames.items()):
            drops.add_metric([cause], count)
        yield drops
        yield CounterMetricFamily(
            "trackerd_dropped_pairs", "pairs dropped (newest kept) before publishing", value=pairing.dropped_pairs
        )
        skew = GaugeMetricFamily("trackerd_skew_microseconds", "time between a pair's two frames", labels=["quantile"])
        for quantile, value in (("0.5", pairing.skew_p50_us), ("0.99", pairing.skew_p99_us)):
            if value is not None:
                skew.add_metric([quantile], value)
        yield skew
        fixes = CounterMetricFamily("trackerd_fixes", "pairs processed, by outcome", labels=["status"])
        for outcome, count in sorted(status.fixes.items()):
            fixes.add_metric([outcome], count)
        yield fixes
        yield CounterMetricFamily(
            "trackerd_hits", "wall hits published", value=status.messages.get("hit", status.fixes.get("hit", 0))
        )
        cam_state = GaugeMetricFamily(
            "trackerd_camera_state", "each camera's state (1 for the current one)", labels=["camera", "state"]
        )
        rate = GaugeMetricFamily("trackerd_camera_frame_rate_hz", "frames per second", labels=["camera"])
        frames = CounterMetricFamily("trackerd_camera_frames", "frames received", labels=["camera"])
        dropped = CounterMetricFamily(
            "trackerd_camera_dropped_buffers", "buffers the camera's stream lost, by cause", labels=["camera", "cause"]
        )
        losses = CounterMetricFamily("trackerd_camera_losses", "times the camera was lost", labels=["camera"])
        for cam in status.cameras:
            for name in sorted({*CAMERA_STATES, cam.state}):
                cam_state.add_metric([cam.id, name], 1.0 if cam.state == name else 0.0)
            rate.add_metric([cam.id], cam.frame_rate_hz)
            frames.add_metric([cam.id], cam.frames)
            losses.add_metric([cam.id], cam.losses)
            for cause, count in sorted(cam.dropped.items()):
                dropped.add_metric([cam.id, cause], count)
        yield from (cam_state, rate, frames, dropped, losses)
        if status.calibration is not None:
            cal = status.calibration
            yield GaugeMetricFamily(
                "trackerd_calibration_suspect", "1 when the calibration looks off", value=1.0 if cal.suspect else 0.0
            )
            if cal.ray_gap_mm.p50 is not None:
                yield GaugeMetricFamily(
                    "trackerd_calibration_ray_gap_mm", "median ray gap of recent fixes", value=cal.ray_gap_mm.p50
                )
            if cal.reprojection_px.p50 is not None:
                yield GaugeMetricFamily(
                    "trackerd_calibration_reprojection_px",
                    "median reprojection error of recent fixes",
                    value=cal.reprojection_px.p50,
                )
        for name, (counts, total_ms) in sorted(self.tap.histogram_snapshot().items()):
            cumulative, buckets = 0, []
            for bound, count in zip((*LATENCY_BUCKETS_MS, float("inf")), counts, strict=True):
                cumulative += int(count)
                buckets.append(("+Inf" if bound == float("inf") else f"{bound / 1000:g}", cumulative))
            yield HistogramMetricFamily(
                f"trackerd_{name}_latency_seconds",
                HISTOGRAM_HELP.get(name, name),
                buckets=buckets,
                sum_value=total_ms / 1000.0,
            )
        for key, value in self.extra().items():
            yield GaugeMetricFamily(f"trackerd_{key}", EXTRA_HELP.get(key, key.replace("_", " ")), value=value)


def registry_for(tap: ConsoleTap, extra: Callable[[], dict[str, Any]] | None = None) -> CollectorRegistry:
    registry = CollectorRegistry(auto_describe=False)
    registry.register(StatusCollector(tap, extra))
    return registry


def exposition(registry: CollectorRegistry) -> bytes:
    """The text format, version 0.0.4."""
    return generate_latest(registry)
