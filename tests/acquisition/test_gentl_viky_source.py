"""The gentl backend (harvesters) on genicam's test producer viky.cti: pairs, buffers, refusals.

viky.cti offers three virtual devices drawing a bouncing ball, in RGBa8 or Mono8, free running
only (no TriggerMode, no TriggerSoftware) and without buffer timestamps (docs/acquisition.md).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from acq_helpers import quick_rig, wait_until
from viky_helpers import HEIGHT, VIKY_DEVICES, WIDTH, needs_viky, viky_rig

from trackerd.acquisition.arv import CameraConfigError
from trackerd.acquisition.gentl import producer
from trackerd.config.models import RigConfig

pytestmark = [pytest.mark.gentl, needs_viky]


def collect(source: Any, count: int, timeout_s: float = 30.0) -> list:
    pairs = []
    deadline = time.monotonic() + timeout_s
    while len(pairs) < count and time.monotonic() < deadline:
        pair = source.next_pair(0.5)
        if pair is not None:
            pairs.append(pair)
    assert len(pairs) == count, f"only {len(pairs)} pairs: {source.status().to_json()}"
    return pairs


def test_two_viky_devices_free_running_give_pairs_and_hand_every_buffer_back(simulated_rig: RigConfig) -> None:
    from trackerd.acquisition.live import LivePairSource

    rig = viky_rig(simulated_rig, frame_rate_hz=30.0)
    opened: dict[str, Any] = {}
    source = LivePairSource(rig, on_open=lambda camera_id, camera: opened.__setitem__(camera_id, camera))
    with source:
        pairs = collect(source, 15)
        status = source.status()
    tolerance_ns = rig.acquisition.tolerance_us * 1000
    assert all(p.skew_ns <= tolerance_ns for p in pairs)
    assert [p.timestamp_ns for p in pairs] == sorted(p.timestamp_ns for p in pairs)
    for i in range(2):
        ids = [p.frames[i].frame_id for p in pairs]
        assert ids == sorted(set(ids))
    frame = pairs[-1].frames[0]
    # viky's RGBa8 read as the rig's RGB8: the padding byte dropped, the drawing kept.
    assert frame.pixel_format == "RGB8" and frame.image.shape == (HEIGHT, WIDTH, 3) and frame.image.dtype == np.uint8
    assert len({p.frames[0].image.tobytes() for p in pairs}) > 1  # the ball moves: frames are fresh
    assert status.pairing == "host time" and status.trigger == "free_running"
    assert [c.state for c in status.cameras] == ["streaming", "streaming"]
    assert [c.device for c in status.cameras] == list(VIKY_DEVICES)
    # Stopped: every buffer queued back, acquisition stopped on both devices.
    for worker in source.workers:
        assert worker.last_session is not None and worker.last_session.buffers_released()
    assert len(opened) == 2 and all(not acquirer.is_acquiring() for acquirer in opened.values())
    assert source.status().cameras[0].state == "stopped"


def test_a_software_trigger_is_refused_naming_what_the_device_allows(simulated_rig: RigConfig) -> None:
    from trackerd.acquisition.live import LivePairSource

    rig = viky_rig(simulated_rig, trigger="software")
    with pytest.raises(CameraConfigError) as info:
        LivePairSource(rig).start()
    message = str(info.value)
    assert "\n" not in message
    assert "camera 'left'" in message and "trigger = 'software'" in message
    assert "allows only trigger = 'free_running'" in message


def test_a_refused_value_names_the_setting_and_the_range(simulated_rig: RigConfig) -> None:
    from trackerd.acquisition.live import LivePairSource

    rig = viky_rig(simulated_rig)
    cameras = [rig.cameras[0].model_copy(update={"width_px": 5000}), rig.cameras[1]]
    rig = rig.model_copy(update={"cameras": tuple(cameras)})
    with pytest.raises(CameraConfigError) as info:
        LivePairSource(rig).start()
    message = str(info.value)
    assert "\n" not in message
    assert "camera 'left'" in message
    assert "width_px = 5000 is refused by the camera, which allows 100 to 800 px" in message


def test_a_pixel_format_the_device_lacks_is_named_with_what_it_offers(simulated_rig: RigConfig) -> None:
    from trackerd.acquisition.live import LivePairSource

    rig = viky_rig(simulated_rig)
    cameras = [rig.cameras[0], rig.cameras[1].model_copy(update={"pixel_format": "BayerRG8"})]
    rig = rig.model_copy(update={"cameras": tuple(cameras)})
    with pytest.raises(
        CameraConfigError,
        match=r"camera 'right'.*pixel_format = 'BayerRG8' is not offered by the"
        r" camera, which offers RGBa8, Mono8",
    ):
        LivePairSource(rig).start()
    # The left device, opened before the right one refused, was closed again: nothing of the producer is open.
    assert producer(Path(rig.cameras[0].producer)).open_count == 0


def test_a_missing_producer_file_is_named(simulated_rig: RigConfig, tmp_path: Path) -> None:
    from trackerd.acquisition.live import LivePairSource

    rig = viky_rig(simulated_rig)
    missing = tmp_path / "grabber.cti"
    cameras = [rig.cameras[0].model_copy(update={"producer": str(missing)}), rig.cameras[1]]
    rig = rig.model_copy(update={"cameras": tuple(cameras)})
    # Waiting for cameras does not wait for a file: it is a configuration error at start.
    with pytest.raises(CameraConfigError) as info:
        LivePairSource(rig, wait_for_cameras=True).start()
    message = str(info.value)
    assert "\n" not in message and "camera 'left'" in message
    assert f"producer = '{missing}': no such file" in message


def test_a_device_that_stops_sending_is_lost_reopened_and_pairs_again(simulated_rig: RigConfig) -> None:
    """The right device's acquisition is stopped behind trackerd's back (AcquisitionStop): no frame comes,
    the camera is lost after loss_timeout_ms and reopened on the same loaded producer."""
    from trackerd.acquisition.live import LivePairSource

    rig = quick_rig(viky_rig(simulated_rig, frame_rate_hz=30.0))
    opened: dict[str, list[Any]] = {}
    with LivePairSource(
        rig, on_open=lambda camera_id, camera: opened.setdefault(camera_id, []).append(camera)
    ) as source:
        collect(source, 3)
        opened["right"][-1].remote_device.node_map.AcquisitionStop.execute()

        def back() -> bool:
            source.next_pair(0.1)
            right = source.status().cameras[1]
            return right.reconnects >= 1 and right.state == "streaming"

        assert wait_until(back, 30.0), source.status().to_json()
        pairs = collect(source, 5)
        status = source.status()
    assert status.cameras[1].losses == 1 and status.cameras[1].last_error == "no frame for 300 ms"
    assert status.cameras[0].losses == 0
    assert len(opened["right"]) == 2 and len(opened["left"]) == 1
    # Frames after the reconnection start a new epoch: the right device counts from 1 again.
    assert pairs[-1].frames[1].frame_id < pairs[-1].frames[0].frame_id
    for worker in source.workers:
        assert worker.last_session is not None and worker.last_session.buffers_released()
