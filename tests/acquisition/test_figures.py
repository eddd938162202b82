"""A camera's status figures across connections (trackerd/acquisition/figures.py), with stand-in sessions."""

from __future__ import annotations

from trackerd.acquisition.connection import ConnectionFigures
from trackerd.acquisition.figures import COUNTER_PERIOD_NS, CameraFigures

STREAMING = ConnectionFigures("streaming", losses=1, reconnects=1, lost_since_ns=None, last_error="control lost")


class Session:
    """What the figures read of a connection: its address, notes, stream counters and PTP state."""

    def __init__(self, address: str | None, counters: dict[str, int], ptp: str | None = None) -> None:
        self.address = address
        self.notes = ["GevSCPD set to 0"]
        self._counters = counters
        self.ptp_feature = "PtpStatus" if ptp else None
        self._ptp = ptp
        self.reads = 0
        self.ptp_reads = 0

    def counters(self) -> dict[str, int]:
        self.reads += 1
        return dict(self._counters)

    def ptp_state(self) -> str | None:
        self.ptp_reads += 1
        return self._ptp


def test_stream_counters_add_up_across_connections_and_polls_follow_their_periods() -> None:
    figures = CameraFigures(ptp_poll_interval_ms=2500.0)
    first = Session("10.213.0.6:3956", {"n_missing_packets": 3, "n_resend_requests": 5}, ptp="Slave")
    figures.opened(first, now_ns=0)
    figures.poll(first, 0)
    figures.poll(first, COUNTER_PERIOD_NS - 1)  # not due
    assert (first.reads, first.ptp_reads) == (1, 1)
    figures.poll(first, COUNTER_PERIOD_NS)
    assert (first.reads, first.ptp_reads) == (2, 1)  # PTP is read on its own, longer period
    figures.poll(first, 3 * COUNTER_PERIOD_NS)
    assert (first.reads, first.ptp_reads) == (3, 2)
    figures.closed()  # lost: the counters as last read join the totals

    second = Session(None, {"n_missing_packets": 1})
    figures.opened(second, now_ns=10 * COUNTER_PERIOD_NS)
    figures.poll(second, 10 * COUNTER_PERIOD_NS)
    for cause in ("missing-packets", "missing-packets", "wrong-size"):
        figures.failure(cause)
    status = figures.status("right", "serial SIM-RIGHT", STREAMING, clock_offset_ns=-42)
    assert status.stream == {"n_missing_packets": 4, "n_resend_requests": 5}
    assert status.failed_buffers == {"missing-packets": 2, "wrong-size": 1}
    assert status.device == "10.213.0.6:3956"  # a connection without an address keeps the last one
    assert (status.ptp_state, status.notes, status.clock_offset_ns) == ("Slave", ("GevSCPD set to 0",), -42)
    assert (status.state, status.losses, status.reconnects, status.last_error) == ("streaming", 1, 1, "control lost")

    figures.closed({"n_missing_packets": 2})  # stopped: the final counters, read as it closes
    assert figures.status("right", "serial SIM-RIGHT", STREAMING, None).stream == {
        "n_missing_packets": 5,
        "n_resend_requests": 5,
    }


def test_before_any_connection_the_camera_is_named_by_how_it_is_looked_up() -> None:
    figures = CameraFigures(ptp_poll_interval_ms=1000.0)
    status = figures.status("left", "serial SIM-LEFT", STREAMING, None)
    assert (status.device, status.frames, status.frame_rate_hz, status.stream) == ("serial SIM-LEFT", 0, 0.0, {})
