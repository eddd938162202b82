"""The rig's clocks: a camera's own mapping, or the shared one while every camera is PTP-locked."""

from __future__ import annotations

import numpy as np

from trackerd.acquisition.frame import Frame
from trackerd.acquisition.pairing import Arrival
from trackerd.acquisition.rig_clocks import CLOCK_WARMUP_FRAMES, RigClocks

WINDOW_NS = 2_000_000_000


def arrival(camera_index: int, device_ns: int) -> Arrival:
    frame = Frame(f"cam{camera_index}", 1, device_ns, 0, "BayerRG8", np.zeros((2, 2), np.uint8))
    return Arrival(camera_index, frame, 0, epoch=1)


def test_a_camera_without_device_time_is_captured_when_it_arrives() -> None:
    clocks = RigClocks(2, WINDOW_NS, ptp=False, ptp_states=lambda: [])
    assert clocks.observe(0, 0, 123_456) == 123_456
    assert not clocks.settling(arrival(0, 0))


def test_each_camera_has_its_own_offset_without_ptp() -> None:
    clocks = RigClocks(2, WINDOW_NS, ptp=False, ptp_states=lambda: ["Slave", "Slave"])
    # Camera 0's clock runs 5 s behind the host, camera 1's 9 s; 1 ms transfer delay each.
    assert clocks.observe(0, 10_000_000_000, 15_001_000_000) == 15_001_000_000
    assert clocks.observe(1, 10_000_000_000, 19_001_000_000) == 19_001_000_000
    assert clocks.clock_for(0).offset_ns == 5_001_000_000
    assert clocks.clock_for(1).offset_ns == 9_001_000_000
    assert not clocks.ptp_locked()  # the rig does not enable PTP, whatever the cameras say


def test_the_shared_clock_is_used_only_while_every_camera_is_locked() -> None:
    states = ["Slave", "Listening"]
    clocks = RigClocks(2, WINDOW_NS, ptp=True, ptp_states=lambda: states)
    clocks.observe(0, 10_000_000_000, 10_002_000_000)
    clocks.observe(1, 10_000_000_000, 10_001_000_000)
    assert not clocks.ptp_locked()
    assert clocks.clock_for(0).offset_ns == 2_000_000  # its own
    states[1] = "Master"
    assert clocks.ptp_locked()
    assert clocks.clock_for(0).offset_ns == 1_000_000  # the smallest delay either camera saw
    assert clocks.clock_for(0) is clocks.clock_for(1)


def test_no_cameras_yet_is_not_locked() -> None:
    assert not RigClocks(2, WINDOW_NS, ptp=True, ptp_states=lambda: []).ptp_locked()


def test_a_camera_settles_after_the_warmup_frames_and_again_after_a_reset() -> None:
    clocks = RigClocks(1, WINDOW_NS, ptp=False, ptp_states=lambda: [])
    for k in range(CLOCK_WARMUP_FRAMES):
        assert clocks.settling(arrival(0, 1_000 + k))
        clocks.observe(0, 1_000 + k, 2_000 + k)
    assert not clocks.settling(arrival(0, 2_000))
    clocks.reset(0)
    assert clocks.settling(arrival(0, 2_000))
    clocks.observe(0, 3_000, 4_000)
    clocks.reset_all()
    assert clocks.clock_for(0).observations == 0
