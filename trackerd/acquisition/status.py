"""A snapshot of a pair source's health, as plain data the daemon can publish as JSON."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from typing import Any, Literal

CameraState = Literal["connecting", "connected", "streaming", "lost", "reconnecting", "stopped"]
"""connecting: being opened for the first time (or waiting to appear, see ``wait_for_cameras``);
connected: open and configured, waiting for its first complete frame; streaming: its connection
has delivered a complete frame (a camera stays streaming until it is lost); lost: not delivering
and not answering; reconnecting: answering again and being reopened (then connected); stopped."""


@dataclass(frozen=True)
class CameraStatus:
    """One camera's state and counters. Counters are totals since the source started."""

    camera_id: str
    state: CameraState
    device: str
    """How the camera was found: its address, serial or device id."""
    frames: int = 0
    """Complete frames delivered to the pairing stage."""
    frame_rate_hz: float = 0.0
    """Delivered frames per second over the last second or so."""
    failed_buffers: dict[str, int] = field(default_factory=dict)
    """Buffers that never reached the pipeline, by cause (Aravis buffer status such as
    ``missing-packets`` or ``timeout``, or ``wrong-format`` / ``wrong-size``)."""
    stream: dict[str, int] = field(default_factory=dict)
    """Aravis stream counters (``n_underruns``, ``n_missing_packets``, ``n_resend_requests``, ...)."""
    losses: int = 0
    """Times the camera was marked lost."""
    reconnects: int = 0
    """Times it was opened again after a loss."""
    lost_since_ns: int | None = None
    """When the current loss was detected (monotonic clock), None while streaming. A connection
    that is lost again before its first frame does not restart it."""
    last_error: str | None = None
    """The most recent problem, in one line."""
    ptp_state: str | None = None
    """IEEE 1588 port state (Master, Slave, Listening, Faulty, ...) when PTP is enabled."""
    clock_offset_ns: int | None = None
    """Estimated host-monotonic minus device timestamp (lowest recent delay)."""
    notes: tuple[str, ...] = ()
    """Settings the camera could not honour (a feature it lacks), reported once per connection."""


@dataclass(frozen=True)
class SourceStatus:
    """The whole source: pairing counters and every camera's status."""

    running: bool
    trigger: str
    """free_running, software or hardware."""
    pairing: str
    """What pairs frames: ``trigger count``, ``device time (PTP)``, ``host time`` or ``recorded`` (a replay)."""
    pairs: int = 0
    """Pairs formed."""
    pair_rate_hz: float = 0.0
    """Pairs formed per second over the last second or so."""
    delivered: int = 0
    """Pairs handed to the consumer by next_pair()."""
    dropped_frames: dict[str, int] = field(default_factory=dict)
    """Complete frames that never became part of a pair, by cause: ``no_partner`` (nothing close
    enough in time or trigger count), ``queue_full`` (too many waiting), ``resync`` (discarded when a
    camera reconnected), ``skew`` (partner found but too far apart), ``partner_lost`` (another camera
    was lost), ``clock_warmup`` (a camera's first frames, while its clock offset settles)."""
    dropped_pairs: int = 0
    """Pairs discarded because the consumer did not take them in time (oldest dropped first)."""
    skew_p50_us: float | None = None
    """Median pair skew over the recent pairs."""
    skew_p99_us: float | None = None
    """99th percentile pair skew over the recent pairs."""
    skew_max_us: float | None = None
    """Largest pair skew over the recent pairs."""
    releasing: int = 0
    """Connections to lost cameras that Aravis is still giving up on (each holds its buffers until then)."""
    cameras: tuple[CameraStatus, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    @property
    def frames_dropped(self) -> int:
        """All complete frames that did not become part of a pair."""
        return sum(self.dropped_frames.values())
