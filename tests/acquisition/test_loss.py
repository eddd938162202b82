"""Losing a camera mid-run and getting it back (simulated GigE Vision cameras, network namespaces)."""

from __future__ import annotations

import itertools
import threading

import numpy as np
import pytest
from acq_helpers import TEST_PREFIX, TEST_SUBNET, needs_aravis, needs_netns, quick_rig, settled_resources, wait_until

from trackerd.config.models import RigConfig

pytestmark = [pytest.mark.aravis, pytest.mark.root, needs_aravis, needs_netns]


class Consumer:
    """Takes pairs from a source on its own thread, as the daemon's pipeline would."""

    def __init__(self, source) -> None:
        self.source = source
        self.pairs: list = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="test-consumer")
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            pair = self.source.next_pair(0.2)
            if pair is not None:
                self.pairs.append(pair)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()


LOSS_TIMEOUT_MS = 1000.0
"""The daemon's default. These tests assert that the camera *not* killed is never marked lost; with the
quick rig's 300 ms, a loaded 2-core machine that stalls that camera's process or the receiving thread
for a third of a second (the new camera process starting beside them, a CPU hog) made it lost now and
then (1 of 11 kills in a CI-like run), which is the timeout working as configured, not camera 0's loss
reaching camera 1. A second without frames is a real fault on any machine."""


@pytest.fixture
def virtual(simulated_rig: RigConfig, out_dir):
    from trackerd.sim.rig import VirtualRig

    rig = quick_rig(simulated_rig, trigger="software", loss_timeout_ms=LOSS_TIMEOUT_MS)
    with VirtualRig(
        rig, synthetic=True, network="netns", prefix=TEST_PREFIX, subnet=TEST_SUBNET, mtu=9000, out_dir=out_dir
    ) as rig_:
        yield rig_


def state(source, index: int) -> str:
    return source.status().cameras[index].state


def lose_and_recover(virtual, source, consumer: Consumer) -> dict:
    """Kill camera 0, check the loss is seen and camera 1 keeps going, restart it, wait for pairs."""
    timeout_s = virtual.rig.acquisition.loss_timeout_ms / 1000
    before = source.status().cameras[0].losses
    virtual.kill_camera(0)
    assert wait_until(lambda: source.status().cameras[0].losses > before, timeout_s + 1.0), source.status().to_json()
    other = source.status().cameras[1].frames
    assert wait_until(lambda: source.status().cameras[1].frames > other + 5, 2.0), "camera 1 stopped too"
    assert state(source, 1) == "streaming"
    virtual.restart_camera(0)
    assert wait_until(lambda: state(source, 0) == "streaming", 5.0), source.status().to_json()
    pairs = len(consumer.pairs)
    assert wait_until(lambda: len(consumer.pairs) > pairs + 5, 5.0), source.status().to_json()
    return {"error": source.status().cameras[0].last_error}


def check_pairs(pairs, frame_rate_hz: float, epochs: int, status) -> None:
    """Ground truth from the frames' tags: no pair mixes frames from before and after a loss
    (they would be captured the loss timeout apart), and within each connection every pair
    holds the n-th frame served by both cameras: the served-count difference changes only where a
    camera was restarted (camera 0's count starts again) or where one camera's frame was lost and
    the source counted it (a failed buffer, or a frame dropped without a partner)."""
    from trackerd.sim.gvcamera import read_tag

    tags = [[read_tag(f.image) for f in p.frames] for p in pairs]
    skews = np.array([abs(a.capture_ns - b.capture_ns) for a, b in tags])
    assert skews.max() < 1e9 / frame_rate_hz
    restarts = sum(now[0].served < before[0].served for before, now in itertools.pairwise(tags))
    assert restarts <= epochs - 1
    changes = sum(
        (now[0].served - now[1].served) != (before[0].served - before[1].served) and now[0].served >= before[0].served
        for before, now in itertools.pairwise(tags)
    )
    # A frame the source never delivered or paired shifts the count by one (seen once in 12 epochs
    # on a machine at load 13: 14 differences); one nobody counted would be lost silently.
    counted = sum(sum(camera.failed_buffers.values()) for camera in status.cameras) + sum(
        count for cause, count in status.dropped_frames.items() if cause in ("no_partner", "queue_full", "skew")
    )
    assert changes <= counted, (changes, counted, status.to_json())


def test_a_lost_camera_is_reported_the_other_keeps_running_and_it_comes_back(virtual, caplog) -> None:
    import logging
    import re

    from trackerd.acquisition.live import AravisPairSource

    caplog.set_level(logging.INFO, logger="trackerd.acquisition")
    source = AravisPairSource(virtual.daemon_rig)
    with source:
        consumer = Consumer(source)
        try:
            assert wait_until(lambda: len(consumer.pairs) > 10, 5.0), source.status().to_json()
            outcome = lose_and_recover(virtual, source, consumer)
        finally:
            consumer.stop()
        status = source.status()
    assert outcome["error"] in (
        f"no frame for {LOSS_TIMEOUT_MS:g} ms",
        "Aravis reported control lost (no heartbeat answer)",
    ) or ("software trigger failed" in outcome["error"])
    left = status.cameras[0]
    assert left.losses == left.reconnects >= 1  # see the ten-loss test for why not always 1
    assert status.cameras[1].losses == 0
    assert status.dropped_frames.get("partner_lost", 0) > 0  # camera 1's frames while camera 0 was away
    check_pairs(consumer.pairs, virtual.rig.acquisition.frame_rate_hz, epochs=left.reconnects + 1, status=status)
    sequences = [p.sequence for p in consumer.pairs]
    assert sequences == sorted(set(sequences))
    stamps = [p.timestamp_ns for p in consumer.pairs]
    assert stamps == sorted(stamps)
    # The loss and the return are both in the log, at warning, the return with how long it took.
    logged = [(r.levelno, r.getMessage()) for r in caplog.records if r.name == "trackerd.acquisition.worker"]
    assert any(level == logging.WARNING and text.startswith("camera left lost: ") for level, text in logged)
    back = [
        re.fullmatch(r"camera left streaming again after (\d+\.\d) s \(reconnect (\d+)\)", text)
        for level, text in logged
        if level == logging.WARNING
    ]
    back = [m for m in back if m]
    assert back, logged
    assert 0.0 < float(back[-1].group(1)) < 30.0 and int(back[-1].group(2)) == left.reconnects


@pytest.mark.slow
def test_ten_losses_leak_no_thread_or_descriptor(virtual) -> None:
    from trackerd.acquisition.live import AravisPairSource

    source = AravisPairSource(virtual.daemon_rig)
    with source:
        consumer = Consumer(source)
        try:
            assert wait_until(lambda: len(consumer.pairs) > 10, 5.0)
            lose_and_recover(virtual, source, consumer)
            assert wait_until(lambda: source.status().releasing == 0, 15.0)
            baseline = settled_resources()
            for _ in range(10):
                lose_and_recover(virtual, source, consumer)
            assert wait_until(lambda: source.status().releasing == 0, 15.0)
            after = settled_resources()
        finally:
            consumer.stop()
        status = source.status()
    print(
        f"\n11 kills: {status.cameras[0].losses} losses detected, {status.cameras[0].reconnects} reconnected,"
        f" resources (threads, fds) {baseline} -> {after}"
    )
    left = status.cameras[0]
    # Every loss recovered. Now and then (about one reconnection in thirty on the loaded
    # 2-core machine) a fresh connection's first frame does not come in time and the camera
    # is reconnected once more, so the counts may exceed the 11 kills. Ten cycles after the
    # baseline still show a leak of one thread or descriptor per cycle as a difference of ten.
    assert left.reconnects == left.losses >= 11
    assert status.cameras[1].losses == 0
    assert after == baseline
    check_pairs(consumer.pairs, virtual.rig.acquisition.frame_rate_hz, epochs=left.reconnects + 1, status=status)
