"""AravisPairSource start/stop against real simulated cameras: buffers, threads, errors.

These run without root: one GigE Vision camera on 127.0.0.1 (a child process)
and Aravis's in-process Fake camera, free running (the Fake camera ignores
software triggers).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from acq_helpers import acquisition_threads, needs_aravis, quick_rig, settled_resources

from trackerd.config.models import RigConfig
from trackerd.errors import CameraError

pytestmark = [pytest.mark.aravis, needs_aravis]


@pytest.fixture
def loopback_rig(simulated_rig: RigConfig, out_dir: Path):
    from trackerd.sim.rig import VirtualRig

    rig = quick_rig(simulated_rig, trigger="free_running")
    with VirtualRig(rig, synthetic=True, network="loopback", out_dir=out_dir) as virtual:
        yield virtual


def run_once(virtual, n_pairs: int = 10):
    """Start a source on the virtual rig, take ``n_pairs`` pairs, stop it; the stopped source."""
    from trackerd.acquisition.live import AravisPairSource

    source = AravisPairSource(virtual.daemon_rig, on_open=virtual.on_open)
    with source:
        for _ in range(n_pairs):
            assert source.next_pair(5.0) is not None, source.status()
    return source


def test_a_start_stop_cycle_returns_every_buffer(loopback_rig) -> None:
    source = run_once(loopback_rig)
    assert acquisition_threads() == []  # stop() joined every thread it started
    for worker in source.workers:
        pool = worker.last_pool
        assert len(pool) == worker.cam.acquisition.buffer_count
        # Each Aravis buffer is referenced by the pool alone: the stream holds none.
        assert [buffer.__grefcount__ for buffer in pool] == [1] * len(pool)


def test_repeated_start_stop_leaks_no_thread_or_descriptor(loopback_rig) -> None:
    run_once(loopback_rig, 3)
    baseline = settled_resources()
    for _ in range(3):
        run_once(loopback_rig, 3)
    assert settled_resources() == baseline


def test_the_status_is_plain_json(loopback_rig) -> None:
    from trackerd.acquisition.live import AravisPairSource

    with AravisPairSource(loopback_rig.daemon_rig, on_open=loopback_rig.on_open) as source:
        for _ in range(10):
            assert source.next_pair(5.0) is not None
        status = json.loads(source.status().to_json())
    assert status["running"] is True
    assert status["pairing"] == "host time"
    assert [c["camera_id"] for c in status["cameras"]] == ["left", "right"]
    assert all(c["state"] == "streaming" and c["frames"] > 0 for c in status["cameras"])
    assert "n_completed_buffers" in status["cameras"][0]["stream"]
    assert source.status().running is False


def test_frames_carry_what_the_pipeline_needs(loopback_rig) -> None:
    from trackerd.acquisition.live import AravisPairSource

    with AravisPairSource(loopback_rig.daemon_rig, on_open=loopback_rig.on_open) as source:
        pairs = [source.next_pair(5.0) for _ in range(5)]
    assert all(p is not None for p in pairs)
    assert [p.sequence for p in pairs] == sorted(p.sequence for p in pairs)
    stamps = [p.timestamp_ns for p in pairs]
    assert stamps == sorted(stamps)
    for pair in pairs:
        assert [f.camera_id for f in pair.frames] == ["left", "right"]
        for frame in pair.frames:
            assert frame.pixel_format == "BayerRG8"
            assert frame.image.shape == (1080, 1920)
            assert not frame.image.flags.writeable  # the frame's own, read-only copy
            assert frame.device_timestamp_ns > 0 and frame.host_timestamp_ns > 0


def test_a_camera_that_is_not_there_fails_start_naming_it(simulated_rig: RigConfig) -> None:
    from trackerd.acquisition.live import AravisPairSource

    cameras = [
        cam.model_copy(update={"address": f"10.213.250.{2 + 4 * i}", "serial": None})
        for i, cam in enumerate(simulated_rig.cameras)
    ]
    rig = simulated_rig.model_copy(update={"cameras": tuple(cameras)})
    with pytest.raises(CameraError, match=r"camera 'left' \(address 10\.213\.250\.2\): cannot open"):
        AravisPairSource(rig).start()
    assert acquisition_threads() == []


def test_a_region_the_camera_cannot_give_is_refused(simulated_rig: RigConfig, out_dir: Path) -> None:
    from trackerd.acquisition.arv import open_session
    from trackerd.sim.rig import VirtualRig

    with VirtualRig(simulated_rig, synthetic=True, network="loopback", out_dir=out_dir) as virtual:
        cam = virtual.daemon_rig.cameras[0].model_copy(update={"width_px": 4096})
        with pytest.raises(CameraError, match=r"camera 'left' \(address 127.0.0.1\): \[Width\] Value '4096'"):
            open_session(cam, virtual.daemon_rig.acquisition, "127.0.0.1")
