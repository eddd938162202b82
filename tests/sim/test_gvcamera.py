"""The simulated GigE Vision camera (trackerd/sim/gvcamera.py): its frames, tags, clocks and truth."""

from __future__ import annotations

import io
import json
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from trackerd.acquisition.arv import aravis_missing_reason
from trackerd.pixelformat import BAYER_LAYOUTS, to_rgb
from trackerd.sim.gvcamera import FillServer, FrameLoop, FrameTag, SimClock, read_tag, write_tag

ARAVIS_MISSING = aravis_missing_reason()
needs_aravis = pytest.mark.skipif(ARAVIS_MISSING is not None, reason=f"needs Aravis: {ARAVIS_MISSING}")


def test_a_tag_reads_back() -> None:
    image = np.full((8, 400), 90, np.uint8)
    tag = FrameTag(loop_index=117, served=9001, capture_ns=1_234_567_890_123)
    write_tag(image, tag)
    assert read_tag(image) == tag
    assert read_tag(np.full((8, 400), 90, np.uint8)) is None


@pytest.mark.parametrize("pattern", sorted(BAYER_LAYOUTS))
def test_a_tag_shows_no_colour_in_any_bayer_layout(pattern: str) -> None:
    """Demosaiced, the tag is grey to within less than the detector's colour threshold."""
    image = np.full((8, 400), 120, np.uint8)
    write_tag(image, FrameTag(0xA5A5A5A5, 0x5A5A5A5A, 0x0F0F0F0F0F0F0F0F))
    rgb = to_rgb(image, pattern).astype(int)
    excess = rgb - np.delete(rgb, 0, axis=-1).max(axis=-1, keepdims=True)  # red over the others
    blue_excess = rgb[..., 2] - rgb[..., :2].max(axis=-1)
    assert excess[..., 0].max() < 40 and blue_excess.max() < 40


def test_a_tag_gives_the_detector_nothing_to_find(simulated_rig) -> None:
    from trackerd.detect import ColourEndDetector

    cam = simulated_rig.cameras[0]
    image = np.full((cam.height_px, cam.width_px), 120, np.uint8)
    write_tag(image, FrameTag(0xA5A5A5A5, 0x5A5A5A5A, 0x0F0F0F0F0F0F0F0F))
    detections = ColourEndDetector(simulated_rig.detector, cam.pixel_format, cam.width_px, cam.height_px).detect(image)
    assert not detections.red.found and not detections.blue.found


def test_the_loop_frame_follows_the_shared_start() -> None:
    loop = FrameLoop(np.zeros((4, 2, 2), np.uint8), content_fps=10.0, start_ns=1_000_000_000)
    assert [loop.index_at(1_000_000_000 + k * 50_000_000) for k in range(10)] == [0, 0, 1, 1, 2, 2, 3, 3, 0, 0]


def test_a_simulated_clock_has_its_own_offset_and_rate() -> None:
    clock = SimClock(offset_ns=5_000_000_000, drift_ppm=20.0, origin_ns=10**9)
    assert clock.device_ns(10**9) == 6 * 10**9
    assert clock.device_ns(11 * 10**9) - clock.device_ns(10**9) == 10**10 + 200_000


@needs_aravis
def test_the_fill_callback_serves_the_loop_frame_with_tag_clock_and_truth() -> None:
    """Drives an in-process ArvFakeCamera's fill_buffer, as Aravis's camera thread does."""
    import gi

    gi.require_version("Aravis", "0.8")
    from gi.repository import Aravis

    rng = np.random.default_rng(5)
    frames = rng.integers(0, 256, size=(3, 48, 400), dtype=np.uint8)
    truth = tuple({"loop_index": i, "present": True, "front_m": [i, 0, 0]} for i in range(3))
    start = time.monotonic_ns()
    loop = FrameLoop(frames, content_fps=1000.0, start_ns=start, truth=truth)
    fake = Aravis.FakeCamera.new("TEST-FILL")
    fake.write_register(0x100, 400)  # Width
    fake.write_register(0x104, 48)  # Height
    out = io.StringIO()
    server = FillServer(fake, loop, label="left", clock=SimClock(7_000_000_000, 0.0, start), truth_out=out)
    server.install()
    buffer = Aravis.Buffer.new_allocate(400 * 48)
    try:
        fake.fill_buffer(buffer)
    finally:
        server.uninstall()
    image = np.frombuffer(bytes(buffer.get_data() or b""), np.uint8)
    if image.size == 0:  # the fake camera leaves the received size at 0; read the payload
        from trackerd.acquisition.arv import image_bytes

        image = np.frombuffer(image_bytes(buffer, 400 * 48, 400 * 48), np.uint8)
    image = image.reshape(48, 400)
    tag = read_tag(image)
    assert tag is not None and tag.served == 1
    np.testing.assert_array_equal(image[2:], frames[tag.loop_index][2:])
    np.testing.assert_array_equal(image[:2, 320:], frames[tag.loop_index][:2, 320:])
    assert buffer.get_timestamp() == tag.capture_ns + 7_000_000_000
    record = json.loads(out.getvalue())
    assert record["camera"] == "left" and record["loop_index"] == tag.loop_index
    assert record["front_m"] == [tag.loop_index, 0, 0]
    assert record["device_timestamp_ns"] == buffer.get_timestamp()


@needs_aravis
@pytest.mark.aravis
def test_the_camera_process_speaks_gige_vision_until_sigterm() -> None:
    """`python -m trackerd.sim.gvcamera` on 127.0.0.1, read by a plain Aravis client over GVCP/GVSP."""
    import gi

    gi.require_version("Aravis", "0.8")
    from gi.repository import Aravis

    offset_ns = 3_000_000_000
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "trackerd.sim.gvcamera",
            "--serial",
            "TEST-GV",
            "--synthetic",
            "640x480",
            "--clock-offset-ns",
            str(offset_ns),
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        ready = proc.stdout.readline()
        if not ready.startswith("ready"):
            pytest.skip(f"no simulated camera on 127.0.0.1 (is another one running?): {ready.strip()}")
        camera = Aravis.Camera.new("127.0.0.1")
        assert camera.get_device_serial_number() == "TEST-GV"
        camera.set_pixel_format_from_string("BayerRG8")
        camera.set_region(0, 0, 640, 480)
        stream = camera.create_stream(None, None)
        for _ in range(4):
            stream.push_buffer(Aravis.Buffer.new_allocate(camera.get_payload()))
        camera.start_acquisition()
        tags, stamps = [], []
        for _ in range(3):
            buffer = stream.timeout_pop_buffer(2_000_000)
            assert buffer is not None and buffer.get_status() == Aravis.BufferStatus.SUCCESS
            tags.append(read_tag(np.frombuffer(buffer.get_image_data(), np.uint8).reshape(480, 640)))
            stamps.append(buffer.get_timestamp())
            stream.push_buffer(buffer)
        camera.stop_acquisition()
        del stream, camera
        assert [t.served for t in tags] == sorted(t.served for t in tags)
        assert [s - t.capture_ns for s, t in zip(stamps, tags, strict=True)] == [offset_ns] * 3
    finally:
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=10)
    assert proc.returncode == 0
    assert out.strip().startswith("served")
