"""The rig's clocks: each camera's device-to-host mapping, and the one mapping PTP allows.

Without PTP every camera has its own :class:`~trackerd.acquisition.clock.DeviceClock` (pairing by
host time, with each camera's offset estimated and tracked); with PTP enabled and every camera in
Master or Slave state, one shared mapping is used, so pairs are formed by device time.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from trackerd.acquisition.arv import PTP_LOCKED_STATES
from trackerd.acquisition.clock import DeviceClock
from trackerd.acquisition.pairing import Arrival

CLOCK_WARMUP_FRAMES = 8
"""A camera's first frames after (re)connecting are not paired: its device-to-host offset
estimate has seen too few transfer delays to be trusted yet. Pairing by time needs it for
the match; pairing by trigger count needs it for the skew check, which would otherwise
compare a frame's arrival time (a fresh estimate is just that) with the other camera's
capture time, and let frames captured tens of milliseconds apart through."""


class RigClocks:
    """Maps each camera's device timestamps to the host's monotonic clock."""

    def __init__(self, cameras: int, window_ns: int, ptp: bool, ptp_states: Callable[[], Sequence[str | None]]) -> None:
        """``ptp_states()`` gives every camera's IEEE 1588 port state now (empty before the cameras
        are there); the shared mapping is used only while each is locked."""
        self._per_camera = [DeviceClock(window_ns) for _ in range(cameras)]
        self._shared = DeviceClock(window_ns) if ptp else None
        self._ptp_states = ptp_states

    def reset_all(self) -> None:
        """Forget every estimate (the cameras are about to be opened again)."""
        for clock in [*self._per_camera, *([self._shared] if self._shared else [])]:
            clock.reset()

    def reset(self, camera_index: int) -> None:
        """Forget one camera's estimate (it has reconnected)."""
        self._per_camera[camera_index].reset()

    def observe(self, camera_index: int, device_ns: int, host_ns: int) -> int:
        """Learn from a frame's device and host times; its capture time on the host's clock."""
        if device_ns == 0:
            return host_ns
        self._per_camera[camera_index].observe(device_ns, host_ns)
        if self._shared is not None:
            self._shared.observe(device_ns, host_ns)
        return self.clock_for(camera_index).to_host_ns(device_ns, host_ns)

    def ptp_locked(self) -> bool:
        """Whether PTP is on and every camera is locked (then pairs are formed by device time)."""
        if self._shared is None:
            return False
        states = self._ptp_states()
        return bool(states) and all(s in PTP_LOCKED_STATES for s in states)

    def settling(self, arrival: Arrival) -> bool:
        """The frame's capture time is its camera's offset estimate still settling (a camera
        without device timestamps has no estimate: its capture times are arrival times)."""
        if arrival.frame.device_timestamp_ns == 0:
            return False
        return self.clock_for(arrival.camera_index).observations < CLOCK_WARMUP_FRAMES

    def clock_for(self, camera_index: int) -> DeviceClock:
        """The mapping in use for a camera now."""
        if self._shared is not None and self.ptp_locked():
            return self._shared
        return self._per_camera[camera_index]
