"""Acquisition settings: how trackerd drives the cameras and pairs their frames (trackerd/acquisition).

Two tables: ``[acquisition]`` at the top level of a rig file holds what the
cameras must share (trigger, frame rate, pairing, loss handling, clocks), and
each ``[[cameras]]`` entry may carry an ``acquisition`` table with what is
particular to one camera (exposure, gain, region offset, GigE Vision
transport). docs/acquisition.md explains how to choose the values.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from trackerd.config.base import ConfigModel

TriggerMode = Literal["free_running", "software", "hardware"]
TriggerActivation = Literal["RisingEdge", "FallingEdge", "AnyEdge", "LevelHigh", "LevelLow"]


class CameraAcquisition(ConfigModel):
    """Per-camera acquisition settings (the ``acquisition`` table of a ``[[cameras]]`` entry).

    Resolution and pixel format are the camera's ``width_px``, ``height_px`` and
    ``pixel_format``; the frame rate and trigger are the rig's ``[acquisition]``.
    """

    exposure_us: float | None = Field(default=None, gt=0.0)
    """Exposure time in microseconds; omit to keep the camera's own setting (or its auto exposure)."""
    gain_db: float | None = None
    """Analogue gain in dB (GenICam ``Gain``; cameras with only ``GainRaw`` take it in raw counts).
    Omit to keep the camera's setting."""
    offset_x_px: int = Field(default=0, ge=0)
    """Left edge of the region of interest on the sensor; the region is ``width_px`` wide."""
    offset_y_px: int = Field(default=0, ge=0)
    """Top edge of the region of interest on the sensor; the region is ``height_px`` high."""
    buffer_count: int = Field(default=8, ge=2, le=256)
    """Number of Aravis buffers allocated once per connection and recycled for every frame."""
    packet_size_bytes: int | None = Field(default=None, ge=576, le=16384)
    """GigE Vision stream packet size (``GevSCPSPacketSize``). Omit to negotiate the largest size the
    network path carries (Aravis's automatic packet size test); 8192-9000 needs jumbo frames (MTU 9000)."""
    packet_delay_ns: int = Field(default=0, ge=0)
    """Inter-packet delay (``GevSCPD``) in nanoseconds. Spreads a frame's packets in time so two
    cameras sharing one link or switch port do not overrun it; 0 sends at line rate."""
    socket_buffer_bytes: int | None = Field(default=None, gt=0)
    """Receive socket buffer of the stream. Omit to let Aravis size it from the frame size; the kernel
    caps any value at ``net.core.rmem_max`` (docs/acquisition.md)."""
    packet_resend: bool = True
    """Ask the camera to resend missing packets (``packet-resend`` of the Aravis stream)."""
    packet_timeout_us: int = Field(default=20_000, gt=0)
    """Aravis ``packet-timeout``: how long a missing packet is awaited before a resend is requested."""
    initial_packet_timeout_us: int = Field(default=1_000, gt=0)
    """Aravis ``initial-packet-timeout``: delay before the first resend request for a missing packet."""
    frame_retention_us: int = Field(default=100_000, gt=0)
    """Aravis ``frame-retention``: how long an incomplete frame is kept waiting for its packets
    before it is given up (and counted as failed)."""
    packet_request_ratio: float = Field(default=0.25, gt=0.0, le=2.0)
    """Aravis ``packet-request-ratio``: largest share of a frame's packets that may be re-requested."""
    packet_socket: bool = True
    """Let Aravis receive with a raw packet socket when it can (needs CAP_NET_RAW; lower CPU use).
    False forces ordinary UDP sockets."""


class RigAcquisition(ConfigModel):
    """Settings shared by all cameras: trigger, pairing, loss detection (the top-level ``[acquisition]`` table)."""

    trigger: TriggerMode = "free_running"
    """free_running: each camera exposes on its own clock at frame_rate_hz and frames are paired by
    time; software: trackerd fires every camera together (TriggerSoftware) at frame_rate_hz and
    frames are paired by trigger count; hardware: an external pulse on hardware_trigger_line starts
    each exposure and frames are paired by time."""
    frame_rate_hz: float = Field(default=60.0, gt=0.0, le=1000.0)
    """Frames per second: the cameras' acquisition rate when free running, the trigger rate in
    software mode, and the expected pulse rate in hardware mode (used for the pairing tolerance)."""
    trigger_selector: str = Field(default="FrameStart", pattern=r"^[A-Za-z0-9_]{1,64}$")
    """GenICam ``TriggerSelector`` configured in the trigger modes."""
    hardware_trigger_line: str = Field(default="Line0", pattern=r"^[A-Za-z0-9_]{1,64}$")
    """GenICam ``TriggerSource`` for hardware triggering, the camera input the pulse is wired to."""
    hardware_trigger_activation: TriggerActivation = "RisingEdge"
    """GenICam ``TriggerActivation``: which edge (or level) of the pulse starts an exposure."""
    max_outstanding_triggers: int = Field(default=2, ge=1, le=16)
    """Software triggers a camera may have unanswered (fired, frame not yet received). A tick
    finding any camera at this limit is skipped for every camera, so their frame counters stay in
    step; 1 fires only when every previous frame is in."""
    pairing_tolerance_us: float | None = Field(default=None, gt=0.0)
    """Largest capture-time difference between the frames of one pair. Omit for half a frame period.
    A frame with no partner this close is dropped and counted."""
    frame_queue_length: int = Field(default=4, ge=1, le=64)
    """Frames per camera kept waiting for a partner; beyond this the oldest is dropped and counted."""
    pair_queue_length: int = Field(default=2, ge=1, le=64)
    """Pairs kept waiting for the consumer; beyond this the oldest is dropped and counted, so
    latency stays bounded when processing falls behind."""
    loss_timeout_ms: float = Field(default=1000.0, gt=0.0)
    """A camera that delivers no frame for this long (or whose control channel is lost) is marked
    lost and reconnected. Give it several frame periods."""
    reconnect_min_backoff_ms: float = Field(default=100.0, gt=0.0)
    """First wait between attempts to reach a lost camera; it doubles after each failed attempt."""
    reconnect_max_backoff_ms: float = Field(default=2000.0, gt=0.0)
    """Longest wait between attempts to reach a lost camera."""
    ptp: bool = False
    """Enable IEEE 1588 (PTP) on cameras that support it (``PtpEnable`` or ``GevIEEE1588``). When every
    camera reports Master or Slave, frames are paired by device time; otherwise by host time."""
    ptp_poll_interval_ms: float = Field(default=1000.0, gt=0.0)
    """How often each camera's PTP state is read (and a faulty state re-armed)."""
    clock_window_s: float = Field(default=2.0, gt=0.0)
    """Span of recent frames over which each camera's device-to-host clock offset is estimated
    (the smallest observed delay wins, so transfer jitter does not enter the estimate)."""

    @property
    def frame_period_us(self) -> float:
        """One frame period in microseconds."""
        return 1e6 / self.frame_rate_hz

    @property
    def tolerance_us(self) -> float:
        """The pairing tolerance in effect: the configured one, or half a frame period."""
        if self.pairing_tolerance_us is not None:
            return self.pairing_tolerance_us
        return self.frame_period_us / 2.0

    @model_validator(mode="after")
    def _consistent(self) -> RigAcquisition:
        period_us = self.frame_period_us
        if self.pairing_tolerance_us is not None and self.pairing_tolerance_us >= period_us:
            raise ValueError(
                f"pairing_tolerance_us ({self.pairing_tolerance_us:g}) must be below one frame period"
                f" ({period_us:.0f} us at {self.frame_rate_hz:g} Hz), or frames of different"
                " periods could pair"
            )
        if self.reconnect_min_backoff_ms > self.reconnect_max_backoff_ms:
            raise ValueError("reconnect_min_backoff_ms must not exceed reconnect_max_backoff_ms")
        if self.loss_timeout_ms < 2.0 * period_us / 1000.0:
            raise ValueError(
                f"loss_timeout_ms ({self.loss_timeout_ms:g}) must cover at least two frame periods"
                f" ({2.0 * period_us / 1000.0:.1f} ms at {self.frame_rate_hz:g} Hz)"
            )
        return self
