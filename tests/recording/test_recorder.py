"""The recorder: drops counted instead of waiting, a full disk stops it cleanly, limits, recording on demand."""

from __future__ import annotations

import itertools
import json
import time
from pathlib import Path

import pytest
import zmq
from rec_helpers import one_line_error, trackerd

from trackerd.acquisition.arv import aravis_missing_reason
from trackerd.acquisition.memory import MemoryPairSource
from trackerd.cli.run import build_extensions
from trackerd.config.recording import RecordingConfig
from trackerd.pipeline.daemon import Pipeline
from trackerd.pipeline.extensions import ExtensionContext
from trackerd.publish import Publisher
from trackerd.recording.reader import Recording
from trackerd.recording.recorder import Recorder
from trackerd.recording.writer import DiskFullError

pytestmark = pytest.mark.serial  # records paced sources to disk


@pytest.fixture(scope="module")
def bundle_pairs(bundle):
    with Recording.open(bundle) as recording:
        rig = recording.rig()
        pairs = [recording.pair(i) for i in range(len(recording))]
    return rig, pairs


def test_a_writer_that_falls_behind_drops_the_oldest_pairs_and_counts_them(bundle_pairs, tmp_path) -> None:
    rig, pairs = bundle_pairs
    recorder = Recorder(
        tmp_path / "burst.trec",
        rig,
        producer="test",
        config=RecordingConfig(queue_pairs=2, compression="deflate", compression_level=9),
    ).start()
    for pair in pairs:  # all at once: far faster than deflate at level 9 can write them
        recorder.put(pair)
    assert recorder.stop(30.0)
    status = recorder.status()
    assert status.dropped_pairs > 0
    assert status.pairs + status.dropped_pairs == len(pairs)
    with Recording.open(tmp_path / "burst.trec") as recording:
        headers = [recording.header(i) for i in range(len(recording))]
        assert recording.metadata.end is not None and recording.metadata.end.dropped_pairs == status.dropped_pairs
    # Each record says how many pairs were dropped just before it (the bundle's sequences count up by one).
    assert sum(h.dropped_before for h in headers) == status.dropped_pairs
    assert all(b.sequence - a.sequence - 1 == b.dropped_before for a, b in itertools.pairwise(headers))


def test_a_full_disk_stops_the_recording_cleanly_and_what_was_written_stays_readable(bundle_pairs, small_disk) -> None:
    rig, pairs = bundle_pairs
    path = small_disk / "full.trec"
    recorder = Recorder(path, rig, producer="test", config=RecordingConfig(min_free_space_mb=0)).start()
    for pair in pairs:
        recorder.put(pair)
    recorder.stop(10.0)
    assert isinstance(recorder.error, DiskFullError)
    status = recorder.status()
    assert status.state == "failed" and "disk full" in (status.detail or "")
    assert 1 <= status.pairs < len(pairs)
    with Recording.open(path) as recording:
        assert len(recording) == status.pairs
        assert recording.metadata.end is not None and recording.metadata.end.reason.startswith("disk full")
        for i in range(len(recording)):
            recording.images(i, verify=True)
    check = trackerd("recording", "check", path)
    assert check.returncode == 0, check.stdout  # closed cleanly: nothing is damaged, it just ends early
    assert f"pairs: {status.pairs} readable" in check.stdout and "closed: disk full" in check.stdout


def test_the_free_space_limit_stops_before_the_disk_is_full(bundle_pairs, small_disk) -> None:
    rig, pairs = bundle_pairs
    recorder = Recorder(
        small_disk / "limited.trec", rig, producer="test", config=RecordingConfig(min_free_space_mb=6)
    ).start()
    for pair in pairs[:3]:
        recorder.put(pair)
    recorder.stop(10.0)
    assert isinstance(recorder.error, DiskFullError)
    assert "must leave 6 MB (min_free_space_mb)" in str(recorder.error)
    assert recorder.status().pairs == 1


def test_import_onto_a_full_disk_says_so_in_one_line(bundle_pairs, small_disk, tmp_path) -> None:
    import cv2

    _, pairs = bundle_pairs
    folder = tmp_path / "images"
    folder.mkdir()
    for k, pair in enumerate(pairs[:4]):
        for frame in pair.frames:
            cv2.imwrite(str(folder / f"{k:02d}-{frame.camera_id}.png"), frame.image)
    run = trackerd("recording", "import", folder, small_disk / "imported.trec", "--config", "config/simulated.toml")
    one_line_error(run, "recording", "imported.trec", "disk full")
    with Recording.open(small_disk / "imported.trec") as recording:
        assert 1 <= len(recording) < 4


def test_recording_on_demand_starts_and_stops_with_reloads(bundle_pairs, tmp_path) -> None:
    """[recording] enabled switched by reloads (SIGHUP in the daemon): one recording per enabled span,
    and the published status tells its state."""
    rig, pairs = bundle_pairs
    directory = tmp_path / "recordings"
    endpoint = f"ipc://{tmp_path}/pub.sock"
    zmq_cfg = rig.outputs.zmq.model_copy(update={"endpoints": (endpoint,), "status_interval_ms": 100.0})
    outputs = rig.outputs.model_copy(update={"zmq": zmq_cfg})
    off = rig.model_copy(update={"outputs": outputs, "recording": RecordingConfig(directory=directory)})
    on = off.model_copy(update={"recording": RecordingConfig(directory=directory, enabled=True)})
    images = [pair.images for pair in pairs]
    pipeline = Pipeline(
        off,
        lambda r: MemoryPairSource(r, images, rate_hz=60.0),
        lambda r: Publisher(r.outputs.zmq),
        extensions=build_extensions(off, ExtensionContext()),
    )
    ctx = zmq.Context()
    sub = ctx.socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"status")
    sub.connect(endpoint)
    states: list[str] = []
    written = [0]

    def listen(seconds: float, until: str | None = None, pairs_over: int | None = None) -> None:
        """Statuses for at most ``seconds``, until the recording's state is ``until`` (a slow disk may
        take a while to finish a recording: the next reload must not overtake it) or until it has
        written more than ``pairs_over`` pairs."""
        end = time.monotonic() + seconds

        def arrived() -> bool:
            if until is not None:
                return bool(states) and states[-1] == until
            return pairs_over is not None and written[0] > pairs_over

        while time.monotonic() < end and not arrived():
            if sub.poll(20):
                status = json.loads(sub.recv_multipart()[1])
                recording = status.get("recording") or {}
                written[0] = recording.get("pairs", 0)
                if not states or states[-1] != recording.get("state"):
                    states.append(recording.get("state"))

    try:
        pipeline.start()
        listen(20.0, until="idle")
        pipeline.request_reload(on)
        listen(20.0, until="recording")
        listen(20.0, pairs_over=5)  # some pairs into this recording
        pipeline.request_reload(off)
        listen(20.0, until="stopped")
        pipeline.request_reload(on)
        listen(20.0, until="recording")
        listen(20.0, pairs_over=5)
    finally:
        pipeline.stop()
        sub.close(0)
        ctx.term()
    assert pipeline.failure is None
    assert [s for s in states if s != "finishing"] == ["idle", "recording", "stopped", "recording"]
    recordings = sorted(directory.glob("*.trec"))
    assert len(recordings) == 2
    for path in recordings:
        with Recording.open(path) as recording:
            assert recording.problems == [] and len(recording) > 5
            assert recording.metadata.producer.startswith("trackerd run")
            assert recording.metadata.rig["recording"]["enabled"] is True


@pytest.mark.skipif(aravis_missing_reason() is not None, reason=f"needs Aravis: {aravis_missing_reason()}")
def test_what_the_cameras_say_and_the_rig_file_reach_the_metadata_when_passed_in(bundle_pairs, tmp_path) -> None:
    """The recorder side of recording on demand: a CameraInfo given to the source as its open hook
    (here called with Aravis's own Fake camera, as a source calls it) and the rig file, passed to the
    Recorder, fill vendor, model, rig_file and calibration_file."""
    from trackerd.acquisition.arv import load_aravis
    from trackerd.recording.cameras import CameraInfo

    aravis, _ = load_aravis()
    aravis.enable_interface("Fake")
    rig, pairs = bundle_pairs
    rig = rig.model_copy(update={"calibration": Path("wall-calibration.toml")})
    rig_file = tmp_path / "rigs" / "datawall.toml"
    info = CameraInfo()
    recorder = Recorder(tmp_path / "described.trec", rig, producer="test", camera_info=info, rig_file=rig_file)
    for cam in rig.cameras:  # the cameras open after the recorder is made, before the first pair
        info.on_open(cam.id, aravis.Camera.new("Fake_1"))
    recorder.start()
    recorder.put(pairs[0])
    assert recorder.stop(10.0) and recorder.error is None
    with Recording.open(tmp_path / "described.trec") as recording:
        meta = recording.metadata
        assert [(c.vendor, c.model) for c in meta.cameras] == [("Aravis", "Fake")] * len(rig.cameras)
        assert meta.rig_file == str(rig_file)
        assert meta.calibration_file == str((tmp_path / "rigs" / "wall-calibration.toml").resolve())
