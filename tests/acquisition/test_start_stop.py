"""AravisPairSource start/stop against real simulated cameras: buffers, threads, errors.

These run without root: one GigE Vision camera on 127.0.0.1 (a child process)
and Aravis's in-process Fake camera, free running (the Fake camera ignores
software triggers).
"""

from __future__ import annotations

import json
import logging
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


def test_a_camera_another_source_holds_is_refused_saying_what_to_check(loopback_rig) -> None:
    """A second daemon on the same rig retried for ever on Aravis's "write_register timeout" alone: a GigE
    Vision camera takes one controller, and the line now says so."""
    from trackerd.acquisition.live import AravisPairSource

    holder = AravisPairSource(loopback_rig.daemon_rig, on_open=loopback_rig.on_open)
    with holder:
        assert holder.next_pair(5.0) is not None, holder.status()
        with pytest.raises(CameraError) as refused:
            AravisPairSource(loopback_rig.daemon_rig).start()
    assert "camera 'left' (address 127.0.0.1)" in str(refused.value)
    assert "a camera takes one controller: is another program, a trackerd daemon or a viewer, holding it?" in str(
        refused.value
    )


def test_a_region_the_camera_cannot_give_is_refused(simulated_rig: RigConfig, out_dir: Path) -> None:
    from trackerd.acquisition.arv import CameraConfigError, open_session
    from trackerd.sim.rig import VirtualRig

    with VirtualRig(simulated_rig, synthetic=True, network="loopback", out_dir=out_dir) as virtual:
        cam = virtual.daemon_rig.cameras[0].model_copy(update={"width_px": 4096})
        with pytest.raises(CameraConfigError) as refused:
            open_session(cam, virtual.daemon_rig.acquisition, "127.0.0.1")
    assert refused.value.exit_code == 2  # a configuration error: the unit is not restarted
    assert str(refused.value).startswith(
        "camera 'left' (address 127.0.0.1): region (acquisition.offset_x_px, acquisition.offset_y_px,"
        " width_px, height_px) = (0, 0, 4096, 1080) is refused by the camera, which allows width 1-2048"
    )
    assert "[Width] Value '4096' greater than allowed maximum '2048'" in str(refused.value)


def _with_exposure(rig: RigConfig, index: int, exposure_us: float) -> RigConfig:
    cameras = list(rig.cameras)
    acquisition = cameras[index].acquisition.model_copy(update={"exposure_us": exposure_us})
    cameras[index] = cameras[index].model_copy(update={"acquisition": acquisition})
    return rig.model_copy(update={"cameras": tuple(cameras)})


def test_a_value_the_camera_refuses_fails_start_even_when_waiting_for_cameras(loopback_rig) -> None:
    from trackerd.acquisition.arv import CameraConfigError
    from trackerd.acquisition.live import AravisPairSource

    rig = _with_exposure(loopback_rig.daemon_rig, 0, 5e7)
    source = AravisPairSource(rig, on_open=loopback_rig.on_open, wait_for_cameras=True)
    with pytest.raises(CameraConfigError) as refused:
        source.start()
    assert refused.value.exit_code == 2
    assert str(refused.value) == (
        "camera 'left' (address 127.0.0.1): acquisition.exposure_us = 5e+07 is refused by the camera, which"
        " allows 10 to 1e+07 us ([ExposureTimeAbs] Value '5e+07' greater than allowed maximum '1e+07')"
    )
    assert acquisition_threads() == []


def test_trackerd_run_exits_2_with_one_line_for_a_refused_value(loopback_rig, tmp_path: Path) -> None:
    import subprocess
    import sys

    from trackerd.config.loader import dump_rig

    rig = _with_exposure(loopback_rig.daemon_rig, 0, 5e7)
    zmq_cfg = rig.outputs.zmq.model_copy(update={"endpoints": (f"ipc://{tmp_path}/pub.sock",)})
    rig = rig.model_copy(update={"outputs": rig.outputs.model_copy(update={"zmq": zmq_cfg})})
    path = tmp_path / "rig.toml"
    path.write_text(dump_rig(rig))
    result = subprocess.run(
        [sys.executable, "-m", "trackerd", "run", "--config", str(path), "--seconds", "30"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("trackerd run: camera 'left' (address 127.0.0.1): acquisition.exposure_us = 5e+07")
    assert "which allows 10 to 1e+07 us" in lines[0]


@pytest.mark.parametrize(
    ("backend", "message"),
    [
        ("aravis", "camera 'right' has no serial, address or device_id in the rig file"),
        ("pylon", r"camera 'right' \(backend pylon\) has no serial or device_id in the rig file"),
    ],
)
def test_a_camera_the_rig_gives_no_way_to_find_is_a_configuration_error(
    simulated_rig: RigConfig, backend: str, message: str, caplog: pytest.LogCaptureFixture
) -> None:
    from trackerd.acquisition.arv import CameraConfigError
    from trackerd.acquisition.live import AravisPairSource

    cameras = list(simulated_rig.cameras)
    cameras[1] = cameras[1].model_copy(update={"serial": None, "address": None, "device_id": None, "backend": backend})
    rig = simulated_rig.model_copy(update={"cameras": tuple(cameras)})
    with caplog.at_level(logging.DEBUG), pytest.raises(CameraConfigError, match=message) as err:
        AravisPairSource(rig, wait_for_cameras=True).start()
    assert err.value.exit_code == 2
    # Waiting cannot supply the key: no camera was looked for (camera 'left', not on this machine,
    # was waited for a second, with a warning, before the error named camera 'right').
    assert not [record.getMessage() for record in caplog.records if "camera left" in record.getMessage()]


def test_the_daemons_status_carries_stream_counters_and_pairing_mode(loopback_rig) -> None:
    from trackerd.acquisition.live import AravisPairSource
    from trackerd.pipeline.daemon import Pipeline

    with AravisPairSource(loopback_rig.daemon_rig, on_open=loopback_rig.on_open) as source:
        for _ in range(5):
            assert source.next_pair(5.0) is not None
    status = source.status()  # after stop: the counters read as each connection closed
    pipeline = Pipeline(loopback_rig.daemon_rig, lambda r: source, lambda r: None)
    message = pipeline.build_status(status)
    left = message.cameras[0]
    assert {"n_missing_packets", "n_resend_requests", "n_underruns"} <= set(left.stream)
    assert left.stream["n_completed_buffers"] >= 5
    assert left.stream == status.cameras[0].stream
    assert left.ptp_state is None  # the rig does not enable PTP
    assert message.pairing.mode == "host time"
    assert "n_missing_packets" in message.model_dump_json()
