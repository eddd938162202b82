"""The pylon backend on pylon's emulated cameras (PYLON_CAMEMU=2): frames, pairing, triggers, loss, refusals.

The emulated cameras serve numbered images from files (each image is filled with
its number), so a pair's two frames can be checked to answer the same trigger.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from acq_helpers import quick_rig, wait_until

from trackerd.acquisition.arv import CameraConfigError
from trackerd.acquisition.pylon import pylon_missing_reason
from trackerd.config.models import RigConfig
from trackerd.errors import CameraError
from trackerd.sim.camemu import emulated_rig

PYLON_MISSING = pylon_missing_reason()
pytestmark = [
    pytest.mark.pylon,
    pytest.mark.skipif(
        PYLON_MISSING is not None, reason=f"needs pypylon (pip install 'trackerd[gentl]'): {PYLON_MISSING}"
    ),
]

WIDTH, HEIGHT = 640, 480
N_IMAGES = 7


@pytest.fixture(autouse=True)
def two_emulated_cameras(monkeypatch: pytest.MonkeyPatch) -> None:
    # pylon reads it at every enumeration.
    monkeypatch.setenv("PYLON_CAMEMU", "2")


@pytest.fixture
def numbered_images(tmp_path: Path) -> list[Path]:
    """One directory per camera of N_IMAGES images, image k filled with 10 + k (the same for both)."""
    dirs = []
    for cam in ("left", "right"):
        cam_dir = tmp_path / cam
        cam_dir.mkdir()
        for k in range(N_IMAGES):
            assert cv2.imwrite(str(cam_dir / f"{k:03d}.bmp"), np.full((HEIGHT, WIDTH), 10 + k, np.uint8))
        dirs.append(cam_dir)
    return dirs


def small_rig(rig: RigConfig, image_dirs: list[Path] | None, **acquisition: object) -> RigConfig:
    """The simulated rig on two emulated cameras at 640x480 (uncalibrated: nothing here tracks)."""
    emulated = emulated_rig(rig, image_dirs, **acquisition)
    cameras = tuple(
        cam.model_copy(
            update={
                "width_px": WIDTH,
                "height_px": HEIGHT,
                "intrinsics": None,
                "extrinsics": None,
                "acquisition": cam.acquisition.model_copy(update={"exposure_us": 1000.0}),
            }
        )
        for cam in emulated.cameras
    )
    return RigConfig.model_validate({**emulated.model_dump(), "cameras": [c.model_dump() for c in cameras]})


def collect(source: Any, count: int, timeout_s: float = 30.0) -> list:
    """The next ``count`` pairs (within a generous deadline)."""
    pairs = []
    deadline = time.monotonic() + timeout_s
    while len(pairs) < count and time.monotonic() < deadline:
        pair = source.next_pair(0.5)
        if pair is not None:
            pairs.append(pair)
    assert len(pairs) == count, f"only {len(pairs)} pairs: {source.status().to_json()}"
    return pairs


def test_software_trigger_pairs_frames_of_the_same_trigger(simulated_rig: RigConfig, numbered_images) -> None:
    from trackerd.acquisition.live import LivePairSource

    rig = small_rig(simulated_rig, numbered_images, trigger="software", frame_rate_hz=50.0)
    opened: dict[str, Any] = {}
    source = LivePairSource(rig, on_open=lambda camera_id, camera: opened.__setitem__(camera_id, camera))
    with source:
        pairs = collect(source, 30)
        status = source.status()
    for pair in pairs:
        left, right = pair.frames
        assert (left.camera_id, right.camera_id) == ("left", "right")
        assert left.image.shape == (HEIGHT, WIDTH) and left.pixel_format == "BayerRG8"
        assert not left.image.flags.writeable
        # Emulated cameras send no device timestamps: capture times are host times.
        assert left.device_timestamp_ns == 0 and left.host_timestamp_ns > 0
    # Every trigger both cameras take moves each one image on: the two frames of a pair answer one trigger,
    # so the cameras' images stay the same distance apart (not necessarily none: each connection's first
    # trigger is its own, fired before the shared ticks start, so one camera may be an image ahead).
    shifts = {(int(p.frames[0].image[0, 0]) - int(p.frames[1].image[0, 0])) % N_IMAGES for p in pairs}
    assert len(shifts) == 1, shifts
    # And the frame counter counts images: a gap in the ids (a trigger whose pair was dropped) skips images.
    values = [int(p.frames[0].image[0, 0]) for p in pairs]
    ids = [p.frames[0].frame_id for p in pairs]
    assert len(set(values)) == N_IMAGES
    steps = zip(values, values[1:], ids, ids[1:], strict=False)
    assert all((b - a) % N_IMAGES == (j - i) % N_IMAGES for a, b, i, j in steps)
    assert [p.timestamp_ns for p in pairs] == sorted(p.timestamp_ns for p in pairs)
    # Without a camera clock, a frame's capture time is when its trigger was sent, before it arrived.
    assert all(p.timestamp_ns < min(f.host_timestamp_ns for f in p.frames) for p in pairs)
    assert status.pairing == "trigger count"
    assert [c.state for c in status.cameras] == ["streaming", "streaming"]
    assert [c.device for c in status.cameras] == ["Emulation (0815-0000)", "Emulation (0815-0001)"]
    # Stopped: every grab result handed back, grabbing stopped, the cameras closed.
    for worker in source.workers:
        assert worker.last_session is not None and worker.last_session.buffers_released()
    assert all(not camera.IsOpen() for camera in opened.values()) and len(opened) == 2
    assert source.status().cameras[0].state == "stopped"


def test_free_running_pairs_by_host_time(simulated_rig: RigConfig, numbered_images) -> None:
    from trackerd.acquisition.live import LivePairSource

    rig = small_rig(simulated_rig, numbered_images, trigger="free_running", frame_rate_hz=40.0)
    with LivePairSource(rig) as source:
        pairs = collect(source, 20)
        status = source.status()
    tolerance_ns = rig.acquisition.tolerance_us * 1000
    assert all(p.skew_ns <= tolerance_ns for p in pairs)
    assert status.pairing == "host time" and status.trigger == "free_running"
    # Each camera counts its frames: within a camera, ids only increase.
    for i in range(2):
        ids = [p.frames[i].frame_id for p in pairs]
        assert ids == sorted(set(ids))


def test_failed_buffers_are_counted_and_a_silent_camera_is_lost_and_reopened(
    simulated_rig: RigConfig, numbered_images
) -> None:
    from trackerd.acquisition.live import LivePairSource

    rig = quick_rig(small_rig(simulated_rig, numbered_images, trigger="software", frame_rate_hz=50.0))
    cameras: dict[str, Any] = {}
    lock = threading.Lock()

    def on_open(camera_id: str, camera: Any) -> None:
        with lock:
            cameras[camera_id] = camera

    with LivePairSource(rig, on_open=on_open) as source:
        collect(source, 5)
        right = cameras["right"]
        # The emulation fails the next 60 buffers (over a second at 50 fps): no good frame for longer
        # than loss_timeout_ms (300 ms), so the camera is lost, dropped and opened again.
        right.ForceFailedBufferCount.Value = 60
        right.ForceFailedBuffer.Execute()

        def back() -> bool:
            cam = source.status().cameras[1]
            return cam.reconnects >= 1 and cam.state == "streaming"

        assert wait_until(back, 30.0), source.status().cameras[1]
        status = source.status()
        sequence = status.pairs
        # Pairs made before the failure may still wait in the source's queue; every pair numbered past the
        # count at the moment the camera was back holds a frame of the reopened stream.
        after = [pair for pair in collect(source, 10 + rig.acquisition.pair_queue_length) if pair.sequence > sequence]
    right_status = status.cameras[1]
    assert right_status.losses >= 1 and "no frame for 300 ms" in (right_status.last_error or "")
    assert sum(right_status.failed_buffers.values()) > 0
    assert all(cause.startswith("error-0x") for cause in right_status.failed_buffers)
    assert status.cameras[0].losses == 0
    # While the right camera was away the left one's frames had no partner; pairs came again after.
    assert status.dropped_frames.get("partner_lost", 0) > 0
    assert len(after) >= 10, [pair.sequence for pair in after]
    # The reopened camera's image sequence started again on its own, so its images are shifted against the
    # other camera's; pairs by trigger keep that shift constant (both step one image per trigger).
    shifts = {(int(p.frames[0].image[0, 0]) - int(p.frames[1].image[0, 0])) % N_IMAGES for p in after}
    assert len(shifts) == 1, shifts


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (
            {"acquisition": {"exposure_us": 5e7}},
            r"acquisition\.exposure_us = 5e\+07 is refused by the camera, which allows 1 to 1e\+07 us",
        ),
        ({"width_px": 5000}, r"width_px = 5000 is refused by the camera, which allows 1 to 4096 px"),
        ({"features": {"NoSuchFeature": 3}}, r"features\.NoSuchFeature = 3: the camera has no feature NoSuchFeature"),
        (
            {"features": {"TestImageSelector": "Testimage9"}},
            r"features\.TestImageSelector = 'Testimage9' is refused by the camera, which allows one of Off, Testimage1",
        ),
    ],
)
def test_a_refused_setting_names_the_camera_the_setting_and_what_it_allows(
    simulated_rig: RigConfig, change: dict, expected: str
) -> None:
    from trackerd.acquisition.live import LivePairSource

    rig = small_rig(simulated_rig, None, trigger="software")
    data = rig.model_dump()
    camera = data["cameras"][1]
    for key, value in change.items():
        camera[key] = {**camera[key], **value} if isinstance(value, dict) and camera.get(key) else value
    rig = RigConfig.model_validate(data)
    with pytest.raises(CameraConfigError, match=r"camera 'right' \(pylon serial 0815-0001\): " + expected):
        LivePairSource(rig, wait_for_cameras=True).start()


def test_a_camera_pylon_does_not_see_is_named(simulated_rig: RigConfig) -> None:
    from trackerd.acquisition.live import LivePairSource

    rig = small_rig(simulated_rig, None, trigger="software")
    cameras = (rig.cameras[0], rig.cameras[1].model_copy(update={"serial": "0815-0009"}))
    with pytest.raises(CameraError, match=r"camera 'right' \(pylon, serial 0815-0009\) not found; `trackerd cameras`"):
        LivePairSource(rig.model_copy(update={"cameras": cameras})).start()
