"""What the pair source does with the frames its camera threads hand it (trackerd/acquisition/live.py).

The camera threads call the source's frame-sink side (``observe_clock``, ``deliver``,
``camera_back``); here the test plays those threads, with frames whose timing it chooses,
so the timing that a loaded machine produces only now and then is reproduced every time.
"""

from __future__ import annotations

import numpy as np
from acq_helpers import quick_rig

from trackerd.acquisition.frame import Frame
from trackerd.acquisition.live import CLOCK_WARMUP_FRAMES, AravisPairSource
from trackerd.acquisition.pairing import Arrival
from trackerd.config.models import RigConfig

PERIOD_NS = 16_666_667
TRANSFER_NS = 2_000_000
"""Every frame's usual delay from capture to host arrival."""
_IMAGE = np.zeros((2, 2), np.uint8)


class CameraThread:
    """Plays one camera thread: device clock offset, connection epoch, frames by trigger tick."""

    def __init__(self, source: AravisPairSource, index: int, device_offset_ns: int) -> None:
        self.source, self.index, self.device_offset_ns = source, index, device_offset_ns
        self.epoch = 0

    def reconnect(self) -> None:
        self.epoch += 1
        self.source.camera_lost(self.index)
        self.source.camera_back(self.index)

    def frame(self, tick: int, captured_ns: int, arrived_ns: int, device_ns: int | None = None) -> list:
        """Hands the source one frame; returns the pairs it completed (the source queues only two)."""
        device = captured_ns - self.device_offset_ns if device_ns is None else device_ns
        frame = Frame(f"cam{self.index}", tick + 1, device, arrived_ns, "Mono8", _IMAGE)
        capture_ns = self.source.observe_clock(self.index, device, arrived_ns)
        by_tick = self.source.rig.acquisition.trigger == "software"
        self.source.deliver(Arrival(self.index, frame, capture_ns, self.epoch, tick if by_tick else None))
        out = []
        while (pair := self.source.next_pair(0)) is not None:
            out.append(pair)
        return out


def test_a_reconnected_camera_frame_captured_far_from_its_partner_is_never_paired(simulated_rig: RigConfig) -> None:
    # Software trigger: frames pair by tick, and the capture-time skew check is the only guard
    # against a frame that answered its trigger late. Right after a reconnection the camera's
    # clock estimate has seen one frame, so its capture time is that frame's arrival time.
    # Here the left camera answers tick 100 on time but its first frame comes in 28 ms late,
    # while the right camera answers 26 ms late and arrives at once: arrival times agree,
    # true capture times are 26 ms apart.
    source = AravisPairSource(quick_rig(simulated_rig, trigger="software"))
    left, right = CameraThread(source, 0, 5_000_000_000), CameraThread(source, 1, -3_000_000_000)
    published = []
    for tick in range(20):
        t = tick * PERIOD_NS
        published += left.frame(tick, t, t + TRANSFER_NS)
        published += right.frame(tick, t, t + TRANSFER_NS)
    assert len(published) == 20 - CLOCK_WARMUP_FRAMES + 1  # the 8th frame is the 8th observation
    left.reconnect()
    t = 100 * PERIOD_NS
    published = left.frame(100, t, t + 28_000_000) + right.frame(100, t + 26_000_000, t + 28_000_000)
    assert published == [], [p.skew_ns for p in published]
    # Once its estimate has settled, the reconnected camera pairs again, with its true skew.
    for tick in range(101, 101 + CLOCK_WARMUP_FRAMES + 5):
        t = tick * PERIOD_NS
        published += left.frame(tick, t, t + TRANSFER_NS)
        published += right.frame(tick, t + 300_000, t + 300_000 + TRANSFER_NS)
    first = 100 + CLOCK_WARMUP_FRAMES - 1  # tick 100 was its first observation
    assert [p.frames[0].frame_id - 1 for p in published] == list(range(first, 101 + CLOCK_WARMUP_FRAMES + 5))
    assert all(abs(p.skew_ns - 300_000) < 1_000 for p in published)
    assert source.status().dropped_frames.get("clock_warmup", 0) >= CLOCK_WARMUP_FRAMES


def test_frames_without_device_timestamps_pair_on_arrival_time(simulated_rig: RigConfig) -> None:
    # A camera that sends no device timestamps (0) has no clock to settle: its frames are
    # paired on arrival times from the first one, not held back forever.
    source = AravisPairSource(quick_rig(simulated_rig, trigger="free_running"))
    left, right = CameraThread(source, 0, 0), CameraThread(source, 1, 0)
    published = []
    for n in range(5):
        t = 1_000_000_000 + n * PERIOD_NS
        published += left.frame(n, t, t + TRANSFER_NS, device_ns=0)
        published += right.frame(n, t, t + TRANSFER_NS + 100_000, device_ns=0)
    assert [p.skew_ns for p in published] == [100_000] * 5
    assert "clock_warmup" not in source.status().dropped_frames
