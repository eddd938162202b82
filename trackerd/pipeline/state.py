"""The daemon's state as the status message reports it, and when systemd hears READY.

starting -> running once every camera streams; running -> degraded when one
stops streaming after the daemon was announced ready (before that, it is still
starting); reloading while a new configuration is applied; stopping at the end,
for good. The publishing thread advances it each time it builds a status, from
the cameras' states; nothing else writes it.
"""

from __future__ import annotations

from collections.abc import Sequence

from trackerd.publish.messages import DaemonState

STREAMING = "streaming"


class DaemonStateMachine:
    """The daemon's state and the one-line detail that says why (not thread-safe: one thread advances it)."""

    def __init__(self) -> None:
        self.state: DaemonState = "starting"
        self.detail: str | None = None
        self.ready_announced = False
        """READY has been sent to systemd (the daemon once ran with every camera streaming)."""

    def observe(self, cameras: Sequence[tuple[str, str]], *, reloading: bool) -> tuple[DaemonState, str | None]:
        """Advance from the cameras' (id, state) in rig order and whether a reload is being applied;
        returns (state, detail). Once stopping, the state stays stopping."""
        if self.state == "stopping":
            return self.state, self.detail
        not_streaming = [camera_id for camera_id, state in cameras if state != STREAMING]
        if reloading:
            self.state, self.detail = "reloading", "applying a new configuration"
        elif cameras and not not_streaming:
            self.state, self.detail = "running", None
        elif self.ready_announced:
            self.state, self.detail = "degraded", f"camera {', '.join(not_streaming)} not streaming"
        else:
            self.state, self.detail = "starting", f"waiting for {', '.join(not_streaming) or 'cameras'}"
        return self.state, self.detail

    def announce_ready(self) -> bool:
        """True exactly once: the first time this is asked while running (then READY is sent)."""
        if self.state != "running" or self.ready_announced:
            return False
        self.ready_announced = True
        return True

    def stop(self) -> None:
        """The daemon is stopping: the state every later status reports."""
        self.state, self.detail = "stopping", "stopping"
