"""Cameras that are not there yet, and connections that deliver nothing (simulated GigE Vision
cameras in network namespaces): the daemon's source waits for the first, and calls neither streaming."""

from __future__ import annotations

import logging
import time

import pytest
from acq_helpers import TEST_PREFIX, TEST_SUBNET, needs_aravis, needs_netns, quick_rig, wait_until

from trackerd.config.models import RigConfig

pytestmark = [pytest.mark.aravis, pytest.mark.root, needs_aravis, needs_netns]


def _virtual(rig: RigConfig, out_dir):
    from trackerd.sim.rig import VirtualRig

    return VirtualRig(rig, synthetic=True, network="netns", prefix=TEST_PREFIX, subnet=TEST_SUBNET, out_dir=out_dir)


def _messages(caplog, text: str) -> list[logging.LogRecord]:
    return [r for r in caplog.records if r.name == "trackerd.acquisition.worker" and text in r.getMessage()]


def test_the_daemons_source_waits_for_a_camera_switched_on_after_it(simulated_rig, out_dir, caplog) -> None:
    from trackerd.acquisition.connection import REMINDER_S
    from trackerd.cli.run import aravis_source
    from trackerd.pipeline.daemon import Pipeline
    from trackerd.sim.gvcamera import read_tag

    caplog.set_level(logging.INFO, logger="trackerd.acquisition")
    with _virtual(quick_rig(simulated_rig, trigger="software"), out_dir) as virtual:
        virtual.kill_camera(1)  # the right camera is still switched off
        source = aravis_source(virtual.daemon_rig)  # what `trackerd run` starts
        waiting_since = time.monotonic()
        with source:  # start() does not fail for the missing camera
            status = source.status()
            assert [c.state for c in status.cameras][1] == "connecting"
            assert status.cameras[1].last_error == "no answer from 10.213.200.6 (GVCP discovery)"
            assert wait_until(lambda: source.status().cameras[0].frames > 10, 5.0), source.status().to_json()
            assert source.next_pair(0.2) is None
            assert source.status().dropped_frames.get("partner_lost", 0) > 0
            # The pipeline stays "starting", so READY=1 is not sent yet.
            pipeline = Pipeline(virtual.daemon_rig, lambda r: source, lambda r: None)
            assert pipeline.build_status(source.status()).state == "starting"

            virtual.restart_camera(1)  # switched on
            pairs = []
            assert wait_until(
                lambda: (pair := source.next_pair(0.1)) is not None and pairs.append(pair) is None and len(pairs) >= 10,
                10.0,
            ), source.status().to_json()
            waited_s = time.monotonic() - waiting_since
            status = source.status()
    assert [c.state for c in status.cameras] == ["streaming", "streaming"]
    right = status.cameras[1]
    # A first connection, not a reconnection: every reconnection follows a loss (on a busy machine the
    # quick rig's 300 ms loss timeout can pass once after the camera came up).
    assert right.reconnects == right.losses
    assert pipeline.build_status(status).state == "running"
    # Software-trigger pairs: the n-th frame served by each camera (one served-count difference).
    tags = [[read_tag(f.image) for f in p.frames] for p in pairs]
    assert len({a.served - b.served for a, b in tags}) == 1
    # Each attempt's reason is logged at warning (the default level) when it changes, and reminded
    # only every REMINDER_S.
    waiting = _messages(caplog, "camera right not available yet")
    assert waiting and all(r.levelno == logging.WARNING for r in waiting)
    assert "no answer from 10.213.200.6" in waiting[0].getMessage()
    if waited_s < REMINDER_S:
        assert len(waiting) == 1
    if right.losses == 0:
        assert _messages(caplog, "camera right streaming, after waiting")
    else:  # on a busy machine its first frame came after the quick rig's 300 ms loss timeout
        assert _messages(caplog, "camera right streaming again")


def test_a_connection_that_delivers_no_frame_is_never_streaming(simulated_rig, out_dir) -> None:
    from trackerd.acquisition.live import AravisPairSource
    from trackerd.pipeline.daemon import Pipeline

    # Hardware trigger with nothing wired to the line: the cameras open and configure, and send nothing.
    rig = quick_rig(simulated_rig, trigger="hardware")
    with _virtual(rig, out_dir) as virtual:
        seen: set[str] = set()
        with AravisPairSource(virtual.daemon_rig, wait_for_cameras=True) as source:
            pipeline = Pipeline(virtual.daemon_rig, lambda r: source, lambda r: None)
            states: list[str] = []

            def lost_once() -> bool:
                status = source.status()
                seen.update(c.state for c in status.cameras)
                states.append(pipeline.build_status(status).state)
                return all(c.losses >= 1 for c in status.cameras)

            assert wait_until(lost_once, 10.0), source.status().to_json()
            # ... and reconnected, connected again, still without a frame.
            assert wait_until(
                lambda: (
                    lost_once() and all(c.state == "connected" and c.reconnects >= 1 for c in source.status().cameras)
                ),
                10.0,
            )
            status = source.status()
    assert "connected" in seen and "streaming" not in seen
    assert all(c.frames == 0 for c in status.cameras)
    assert all(c.frame_rate_hz == 0.0 for c in status.cameras)
    assert set(states) == {"starting"}  # never "running": READY=1 is not sent
