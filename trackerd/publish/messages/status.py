"""The ``status`` topic: the daemon's health, and the parts it is made of."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from trackerd.publish.messages.envelope import Message, Part

DaemonState = Literal["starting", "running", "degraded", "reloading", "stopping"]
CameraState = Literal["connecting", "connected", "streaming", "lost", "reconnecting", "stopped"]


class CameraStatusPart(Part):
    """One camera's state in a status message."""

    id: str
    """The camera's id in the rig (``left``, ``right``, ...)."""
    state: CameraState
    """connecting (first open, or waiting for the camera to appear), connected (open, waiting for
    its first complete frame; 1.2), streaming (its connection has delivered frames), lost (no
    frames, no answer), reconnecting, stopped. Treat a state you do not know as not streaming."""
    frame_rate_hz: float = Field(ge=0.0)
    """Frames delivered per second over the last two seconds; 0 until half a second of frames."""
    frames: int = Field(default=0, ge=0)
    """Complete frames delivered since the daemon started."""
    dropped: dict[str, int] = Field(default_factory=dict)
    """Frames lost before pairing, by cause (``missing-packets``, ``timeout``, ``wrong-size``, ...);
    totals since start."""
    losses: int = Field(default=0, ge=0)
    """Times the camera was marked lost."""
    reconnects: int = Field(default=0, ge=0)
    """Times it was opened again after a loss."""
    last_error: str | None = None
    """The most recent problem, in one line."""
    stream: dict[str, int] = Field(default_factory=dict)
    """(1.2) Aravis stream counters, totals since start, by Aravis's names: ``n_missing_packets``,
    ``n_resend_requests``, ``n_resent_packets``, ``n_underruns`` (no buffer free), ``n_timeouts``,
    ``n_completed_buffers``, ... (docs/acquisition.md); those the camera's stream has. Empty for
    sources without Aravis (a replay)."""
    ptp_state: str | None = None
    """(1.2) The camera's IEEE 1588 port state (``Master``, ``Slave``, ``Listening``, ``Faulty``,
    ...) when the rig enables PTP and the camera supports it; null otherwise."""


class LatencyPart(Part):
    """Percentiles of capture-to-publish latency over the last status period."""

    samples: int = Field(ge=0)
    """Messages the figures are taken over (0: no pair was processed; the figures are null)."""
    p50_ms: float | None = None
    """Median latency in milliseconds."""
    p90_ms: float | None = None
    """90th percentile."""
    p99_ms: float | None = None
    """99th percentile."""
    max_ms: float | None = None
    """Largest latency."""


class PairingPart(Part):
    """The frame pairing stage: how many synchronized pairs were formed and how well they line up."""

    pair_rate_hz: float = Field(ge=0.0)
    """Pairs formed per second over the last second or so."""
    pairs: int = Field(default=0, ge=0)
    """Pairs formed since the daemon started."""
    dropped_frames: dict[str, int] = Field(default_factory=dict)
    """Complete frames that never became part of a pair, by cause (``no_partner``, ``queue_full``,
    ``resync``, ``skew``, ``partner_lost``: another camera was lost or not there yet,
    ``clock_warmup``: a camera's first frames while its clock offset settles); totals since start."""
    dropped_pairs: int = Field(default=0, ge=0)
    """Pairs discarded because processing fell behind (the oldest is dropped)."""
    skew_p50_us: float | None = None
    """Median capture-time difference between the frames of a pair, microseconds."""
    skew_p99_us: float | None = None
    """99th percentile pair skew, microseconds."""
    mode: str | None = None
    """(1.2) What frames are paired by: ``trigger count`` (software trigger), ``device time (PTP)``
    (every camera PTP-locked), ``host time`` (estimated capture times) or ``recorded`` (a replay: the
    recording's pairs); null when the source does not say."""


class SpreadPart(Part):
    """Percentiles of a quantity over recent fixes."""

    p50: float | None = None
    """Median."""
    p95: float | None = None
    """95th percentile."""
    max: float | None = None
    """Largest."""


class CalibrationHealthPart(Part):
    """How well the cameras still agree: a bumped camera shows up here as a jump (docs/calibration.md)."""

    fixes: int = Field(ge=0)
    """Recent fixes the figures are taken over."""
    total_fixes: int = Field(ge=0)
    """Fixes measured since start."""
    ray_gap_mm: SpreadPart
    """How far the two cameras' rays through an end miss each other, millimetres."""
    reprojection_px: SpreadPart
    """Distance between each detected end and the projection of its triangulated centre, pixels."""
    suspect: bool
    """True when the figures exceed the limits a sound calibration stays within."""
    reason: str | None = None
    """Why the figures are suspect, or why they cannot be judged yet."""


class ColourFigurePart(Part):
    """One end's colour against the room, in grey levels of colour excess (docs/detection.md, "The colour watch")."""

    threshold: int
    """The detector's ``min_excess`` for this end."""
    room_excess: int
    """The highest excess anything but the pointer reaches now, over a block of 2 x 2 samples (every camera)."""
    camera: str | None = None
    """The camera that sees it."""
    at_px: tuple[float, float] | None = None
    """Where in that camera's image, pixels (x, y)."""
    ball_excess: int | None = None
    """What the end's paint reaches, as ``trackerd calibrate pointer`` learned it; null without learned colours."""
    baseline_excess: int | None = None
    """The room's excess when the colours were learned, or (without) when the watch first measured it."""


class ColourWatchPart(Part):
    """(1.4) The room's colours against the pointer's: whether something in view came close to an end's colour."""

    learned: bool
    """Whether the figures compared with are from ``trackerd calibrate pointer`` (else from the daemon's start)."""
    age_s: float = Field(ge=0.0)
    """Seconds since the last measurement (taken every few seconds on a pair where the pointer was located)."""
    red: ColourFigurePart
    """The red end."""
    blue: ColourFigurePart
    """The blue end."""
    warning: str | None = None
    """One line when the margin has shrunk (a new picture on the wall nearly the pointer's colour); else null."""


class InteractionStatusPart(Part):
    """The interaction stage's figures in a status message (docs/interaction.md)."""

    smoothing: bool
    """Whether hits are smoothed."""
    pointing: bool
    """Whether the pointer is entered on the display now."""
    cursor_id: int | None = None
    """The current pointing session, or the last one."""
    events: dict[str, int] = Field(default_factory=dict)
    """Events and commands sent since start, by topic."""
    gestures: dict[str, int] = Field(default_factory=dict)
    """Gestures recognised since start, by name."""
    templates: int = Field(default=0, ge=0)
    """Gesture templates loaded."""
    strokes_rejected: int = Field(default=0, ge=0)
    """Strokes that were no gesture (too poor a match, ambiguous, or kinematics that do not fit)."""
    hand: bool = False
    """Whether hand poses are looked for."""
    tuio_packets: int | None = None
    """TUIO bundles sent since start; null when TUIO is off."""
    tuio_errors: int | None = None
    """TUIO bundles that could not be sent; null when TUIO is off."""
    cost_p50_us: float | None = None
    """Median time the stage took per pair over the last status period, microseconds."""
    cost_p99_us: float | None = None
    """99th percentile of that time."""
    cost_max_us: float | None = None
    """Largest of that time (a hand look lands on one pair in every_n_pairs)."""


class RecordingStatusPart(Part):
    """The daemon's recorder (docs/recording.md); present when the rig sets ``[recording] directory``."""

    state: Literal["idle", "recording", "finishing", "stopped", "failed"]
    """idle: available, not recording; recording; finishing: writing what is queued after a stop
    request; stopped: on request or at a limit; failed: a full disk or an error stopped it, or its folder
    could not be made (see detail)."""
    path: str | None = None
    """The recording being written, or the last one; null when the last one could not be started."""
    pairs: int = Field(default=0, ge=0)
    """Pairs written to it."""
    written_mb: float = Field(default=0.0, ge=0.0)
    """Its size so far, MB (10^6 bytes)."""
    write_rate_mb_s: float = Field(default=0.0, ge=0.0)
    """Write rate over the last two seconds, MB/s."""
    pair_rate_hz: float = Field(default=0.0, ge=0.0)
    """Pairs written per second over the last two seconds."""
    dropped_pairs: int = Field(default=0, ge=0)
    """Pairs not recorded because the disk fell behind (the recorder's queue dropped its oldest)."""
    queued_pairs: int = Field(default=0, ge=0)
    """Pairs waiting to be written."""
    recorded_s: float = Field(default=0.0, ge=0.0)
    """Recorded time, from its first pair to the last written, seconds."""
    free_space_mb: float | None = None
    """Free space left on the recording's disk, MB."""
    detail: str | None = None
    """Why it stopped or failed, in one line."""


class StatusMessage(Message):
    """The daemon's health: sent about once a second, on every change, and to every new subscriber."""

    topic: Literal["status"] = "status"
    """Always ``status``."""
    state: DaemonState
    """starting (cameras not all streaming yet), running, degraded (a camera lost), reloading, stopping."""
    version: str
    """trackerd's version."""
    uptime_s: float = Field(ge=0.0)
    """Seconds since the daemon started."""
    rig: str
    """The rig's name (``name`` in the rig file)."""
    cameras: tuple[CameraStatusPart, ...]
    """Every camera of the rig, in rig order."""
    pairing: PairingPart
    """Frame pairing figures."""
    latency: LatencyPart
    """Capture-to-publish latency over the last status period."""
    processing: LatencyPart | None = None
    """The daemon's own latency over the last status period: from the arrival of the last frame
    of a pair to its messages being handed to ZeroMQ."""
    stages: dict[str, LatencyPart] = Field(default_factory=dict)
    """Time spent per pair in each stage (``detect``, ``triangulate``, ``publish``) over the last
    status period."""
    calibration: CalibrationHealthPart | None = None
    """Calibration health from the pointers tracked recently (null before any fix)."""
    fixes: dict[str, int] = Field(default_factory=dict)
    """Processed pairs since start by outcome: hit, off_wall, away, parallel, rejected, not_found."""
    messages: dict[str, int] = Field(default_factory=dict)
    """Messages published since start, by topic; filled in by the publisher."""
    dropped_messages: int = Field(default=0, ge=0)
    """Messages the publisher discarded because its own queue was full (never a subscriber's fault)."""
    detail: str | None = None
    """One line for humans: why the state is what it is (which camera is lost, ...)."""
    interaction: InteractionStatusPart | None = None
    """(1.1) Smoothing, events, gestures, hand poses and TUIO (docs/interaction.md); null when
    the interaction stage is off."""
    recording: RecordingStatusPart | None = None
    """(1.1) The daemon's recorder (docs/recording.md); null when the rig makes no recording available."""
    colours: ColourWatchPart | None = None
    """(1.4) The pointer's colours against the room's (docs/detection.md, "The colour watch"); null until
    first measured."""
