"""One camera's connection state machine (trackerd/acquisition/connection.py), on a clock the test advances.

No camera and no sleeping: each test plays what the worker's thread reports (attempts,
connections, frames, losses) at the times it chooses, and checks the states, the figures the
status shows, the back-off and the log lines the tracker asks for.
"""

from __future__ import annotations

import logging

import pytest

from trackerd.acquisition.connection import FIRST_FRAME_GRACE_NS, REMINDER_S, ConnectionTracker, Notice

LOSS_TIMEOUT_MS = 1000.0
NO_ANSWER = "no answer from 10.213.0.6 (GVCP discovery)"


class FakeClock:
    """A monotonic clock in ns that moves only when the test advances it."""

    def __init__(self) -> None:
        self.now_ns = 5_000_000_000

    def __call__(self) -> int:
        return self.now_ns

    def advance(self, seconds: float) -> None:
        self.now_ns += round(seconds * 1e9)


@pytest.fixture
def clock() -> FakeClock:
    return FakeClock()


@pytest.fixture
def tracker(clock: FakeClock) -> ConnectionTracker:
    return ConnectionTracker(
        "right", loss_timeout_ms=LOSS_TIMEOUT_MS, min_backoff_ms=100.0, max_backoff_ms=1000.0, clock_ns=clock
    )


def streaming(tracker: ConnectionTracker, clock: FakeClock) -> None:
    """Start-up with the camera there: opened at once, first frame 50 ms later."""
    tracker.begin()
    tracker.attempting()
    tracker.connected()
    clock.advance(0.05)
    assert tracker.frame() == Notice(logging.INFO, "camera right streaming")


def test_a_camera_there_at_start_goes_connecting_connected_streaming(tracker, clock) -> None:
    assert tracker.figures().state == "connecting"
    tracker.begin()
    tracker.attempting()
    assert tracker.figures().state == "connecting"
    tracker.connected()
    assert tracker.figures().state == "connected"
    clock.advance(0.05)
    assert tracker.frame() == Notice(logging.INFO, "camera right streaming")
    figures = tracker.figures()
    assert (figures.state, figures.losses, figures.reconnects, figures.last_error) == ("streaming", 0, 0, None)
    assert tracker.frame() is None  # only a connection's first frame is news


def test_waiting_for_a_camera_is_logged_when_the_reason_changes_and_every_reminder(tracker, clock) -> None:
    tracker.begin()
    first = tracker.unavailable(NO_ANSWER, record=True)
    assert first == Notice(logging.WARNING, f"camera right not available yet (attempt 1, 0 s): {NO_ANSWER}; retrying")
    clock.advance(1.0)
    assert tracker.unavailable(NO_ANSWER) is None  # same reason, no reminder due yet
    clock.advance(REMINDER_S - 1.0 - 0.001)
    assert tracker.unavailable(NO_ANSWER) is None
    clock.advance(0.001)  # exactly REMINDER_S after the first line
    reminder = tracker.unavailable(NO_ANSWER)
    assert reminder is not None and reminder.message.startswith("camera right not available yet (attempt 4, 30 s)")
    clock.advance(1.0)
    other = tracker.unavailable("camera 'right' not found")
    assert other is not None and "(attempt 5, 31 s): camera 'right' not found; retrying" in other.message
    figures = tracker.figures()
    assert (figures.state, figures.last_error, figures.losses) == ("connecting", "camera 'right' not found", 0)

    tracker.attempting()
    tracker.connected()
    clock.advance(0.2)
    back = tracker.frame()
    # Logged at warning as the wait was; the successful attempt counts.
    assert back == Notice(logging.WARNING, "camera right streaming, after waiting 31.2 s for it (6 attempts)")
    assert tracker.figures().reconnects == 0  # a first connection is no reconnection


def test_a_camera_not_there_yet_is_reported_at_warning_whatever_the_level_asked(tracker) -> None:
    tracker.begin()
    notice = tracker.unavailable("no answer", level=logging.INFO)
    assert notice is not None and notice.level == logging.WARNING
    refused = tracker.unavailable("the camera refuses ExposureTime 5", level=logging.ERROR)
    assert refused is not None and refused.level == logging.ERROR


def test_a_loss_and_a_return_tell_the_story_in_three_lines(tracker, clock) -> None:
    streaming(tracker, clock)
    clock.advance(60.0)
    lost_at_ns = clock.now_ns
    loss = tracker.lost("no frame for 1000 ms", " (triggers unanswered: 3)")
    assert loss == Notice(logging.WARNING, "camera right lost: no frame for 1000 ms (triggers unanswered: 3)")
    figures = tracker.figures()
    assert (figures.state, figures.losses, figures.lost_since_ns, figures.last_error) == (
        "lost",
        1,
        lost_at_ns,
        "no frame for 1000 ms",
    )

    # Silence after a loss is the loss going on: last_error keeps its reason (record=False).
    retry = tracker.unavailable(NO_ANSWER, record=False)
    assert retry == Notice(logging.INFO, f"camera right still lost (attempt 1, 0 s): {NO_ANSWER}; retrying")
    assert tracker.figures().last_error == "no frame for 1000 ms"
    clock.advance(6.0)
    assert tracker.unavailable(NO_ANSWER, record=False) is None

    tracker.attempting()
    assert tracker.figures().state == "reconnecting"
    tracker.connected()
    assert (tracker.figures().state, tracker.figures().reconnects) == ("connected", 1)
    clock.advance(0.3)
    back = tracker.frame()
    assert back == Notice(logging.WARNING, "camera right streaming again after 6.3 s (reconnect 1)")
    figures = tracker.figures()
    assert (figures.state, figures.lost_since_ns, figures.losses, figures.reconnects) == ("streaming", None, 1, 1)


def test_a_connection_that_never_delivers_continues_its_outage_and_is_not_logged_every_cycle(tracker, clock) -> None:
    # A hardware-triggered camera with nothing on its line: opens, delivers nothing, lost, again and again.
    streaming(tracker, clock)
    clock.advance(10.0)
    lost_since = clock.now_ns
    assert tracker.lost("no frame for 1000 ms") == Notice(logging.WARNING, "camera right lost: no frame for 1000 ms")
    lines = []
    for _ in range(20):  # 20 cycles: open, wait out the grace and the timeout (2 s), lose it
        tracker.attempting()
        tracker.connected()
        clock.advance(2.1)
        assert tracker.overdue()
        lines.append(tracker.lost("no frame for 1000 ms"))
    # Not logged again for the same reason until REMINDER_S (30 s) after the first loss: the 15th cycle,
    # 31.5 s on; and then as the loss of a connection that never delivered.
    reminded = [(cycle, n) for cycle, n in enumerate(lines, start=1) if n is not None]
    assert reminded == [
        (15, Notice(logging.WARNING, "camera right lost: no frame for 1000 ms (no frame since it was opened)"))
    ]
    figures = tracker.figures()
    assert (figures.state, figures.losses, figures.reconnects) == ("lost", 21, 20)
    assert figures.lost_since_ns == lost_since  # the outage started with the first loss


def test_a_new_connection_gets_a_grace_for_its_first_frame_then_the_loss_timeout(tracker, clock) -> None:
    tracker.begin()
    tracker.attempting()
    tracker.connected()
    clock.advance((LOSS_TIMEOUT_MS * 1e6 + FIRST_FRAME_GRACE_NS) / 1e9)
    assert not tracker.overdue()  # exactly at the limit: not yet
    clock.now_ns += 1
    assert tracker.overdue()
    tracker.frame()
    clock.advance(LOSS_TIMEOUT_MS / 1000)
    assert not tracker.overdue()
    clock.now_ns += 1
    assert tracker.overdue()
    assert tracker.ns_since_frame() == round(LOSS_TIMEOUT_MS * 1e6) + 1


def test_the_backoff_doubles_to_its_maximum_and_starts_again_after_a_connection(tracker, clock) -> None:
    assert [tracker.next_backoff_s() for _ in range(6)] == [0.1, 0.2, 0.4, 0.8, 1.0, 1.0]
    tracker.begin()
    tracker.attempting()
    tracker.connected()
    tracker.lost("control lost")
    assert [tracker.next_backoff_s() for _ in range(2)] == [0.1, 0.2]


def test_stopping_and_a_crash_show_in_the_figures(tracker, clock) -> None:
    streaming(tracker, clock)
    tracker.failed("camera 'right': acquisition thread failed: ValueError()")
    tracker.stopped()
    figures = tracker.figures()
    assert (figures.state, figures.last_error) == ("stopped", "camera 'right': acquisition thread failed: ValueError()")
