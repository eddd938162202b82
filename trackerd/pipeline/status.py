"""The status message built from figures gathered at one moment (pure: no clock, no thread).

The pipeline gathers the figures on the publishing thread (trackerd.pipeline.daemon)
and this turns them into the wire's :class:`~trackerd.publish.StatusMessage`
(docs/protocol.md, ``status``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel

import trackerd
from trackerd.acquisition.status import SourceStatus
from trackerd.pipeline.stats import percentiles_ms
from trackerd.publish import StatusMessage
from trackerd.publish.messages import (
    CalibrationHealthPart,
    CameraStatusPart,
    ColourWatchPart,
    DaemonState,
    InteractionStatusPart,
    LatencyPart,
    PairingPart,
    RecordingStatusPart,
)

END_TO_END = ("latency", "processing")
"""The latency figures that are not a stage's: capture to publish, and last frame received to publish."""


@dataclass(frozen=True)
class StatusFigures:
    """What one status says, gathered at one moment."""

    sequence: int
    """The status's own count, from 1."""
    capture_ns: int
    """Now, on the publishing clock (epoch ns)."""
    uptime_s: float
    state: DaemonState
    detail: str | None
    rig_name: str
    source: SourceStatus | None
    """The pair source's status now (None: no source yet)."""
    latency_ns: Mapping[str, NDArray[np.int64]]
    """The latencies (ns) since the last status, by figure: ``latency``, ``processing`` and each stage's."""
    retired_pairs: int = 0
    """Pairs counted by sources a reload replaced (added to the current source's)."""
    retired_dropped_pairs: int = 0
    """Pairs dropped by sources a reload replaced."""
    queue_dropped_pairs: int = 0
    """Pairs whose messages the hand-over to the publishing thread dropped."""
    calibration: Mapping[str, Any] | None = None
    """The calibration health record's figures (``CalibrationHealth.to_json``), None before any fix."""
    colours: Mapping[str, Any] | None = None
    """The colour watch's figures (``ColourWatch.to_json``), None before its first look."""
    fixes: Mapping[str, int] = field(default_factory=dict)
    """Pairs processed since start by the fix's status."""
    extensions: Mapping[str, Mapping[str, Any] | None] = field(default_factory=dict)
    """Each extension's status by its name (None or empty: the field is left out)."""


def _latency_part(values_ns: NDArray[np.int64]) -> LatencyPart:
    return LatencyPart(samples=int(values_ns.size), **percentiles_ms(values_ns))


def _pairing_part(f: StatusFigures) -> PairingPart:
    source = f.source
    if source is None:
        return PairingPart(pair_rate_hz=0.0)
    return PairingPart(
        pair_rate_hz=source.pair_rate_hz,
        pairs=source.pairs + f.retired_pairs,
        dropped_frames=dict(source.dropped_frames),
        dropped_pairs=source.dropped_pairs + f.retired_dropped_pairs + f.queue_dropped_pairs,
        skew_p50_us=source.skew_p50_us,
        skew_p99_us=source.skew_p99_us,
        mode=source.pairing,
    )


def status_message(f: StatusFigures) -> StatusMessage:
    """The status message the figures make: camera states, pairing, latency, calibration, fixes."""
    cameras = f.source.cameras if f.source is not None else ()
    empty = np.zeros(0, dtype=np.int64)
    return StatusMessage(
        sequence=f.sequence,
        capture_ns=f.capture_ns,
        state=f.state,
        version=trackerd.__version__,
        uptime_s=f.uptime_s,
        rig=f.rig_name,
        cameras=tuple(
            CameraStatusPart(
                id=c.camera_id,
                state=c.state,
                frame_rate_hz=c.frame_rate_hz,
                frames=c.frames,
                dropped=dict(c.failed_buffers),
                losses=c.losses,
                reconnects=c.reconnects,
                last_error=c.last_error,
                stream=dict(c.stream),
                ptp_state=c.ptp_state,
            )
            for c in cameras
        ),
        pairing=_pairing_part(f),
        latency=_latency_part(f.latency_ns.get("latency", empty)),
        processing=_latency_part(f.latency_ns.get("processing", empty)),
        stages={name: _latency_part(values) for name, values in f.latency_ns.items() if name not in END_TO_END},
        calibration=CalibrationHealthPart.model_validate(f.calibration) if f.calibration is not None else None,
        fixes=dict(f.fixes),
        detail=f.detail,
        colours=ColourWatchPart.model_validate(f.colours) if f.colours is not None else None,
        interaction=_part(InteractionStatusPart, f.extensions.get("interaction")),
        recording=_part(RecordingStatusPart, f.extensions.get("recording")),
    )


PartT = TypeVar("PartT", bound=BaseModel)


def _part(model: type[PartT], figures: Mapping[str, Any] | None) -> PartT | None:
    """An extension's figures as the status's part for it; None when it is off or said nothing."""
    return model.model_validate(figures) if figures else None
