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
    line = one_line_error(run, "recording", "imported.trec", "disk full")
    with Recording.open(small_disk / "imported.trec") as recording:
        assert 1 <= len(recording) < 4
        # The error says what is left, and the recording says it is not the whole import.
        assert f"the {len(recording)} pairs imported before it are left in {small_disk / 'imported.trec'}" in line
        assert any("ended with an error" in problem for problem in recording.problems), recording.problems


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


def _status_states(endpoint: str, seconds: float, until, topics: list[dict]) -> None:
    """Status messages from ``endpoint`` into ``topics`` until ``until(status)`` holds (or ``seconds`` pass)."""
    ctx = zmq.Context()
    sub = ctx.socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"status")
    sub.connect(endpoint)
    try:
        end = time.monotonic() + seconds
        while time.monotonic() < end and not (topics and until(topics[-1])):
            if sub.poll(20):
                topics.append(json.loads(sub.recv_multipart()[1]))
    finally:
        sub.close(0)
        ctx.term()


def test_a_reload_that_first_asks_for_recording_and_interaction_builds_them(bundle_pairs, tmp_path) -> None:
    """A daemon started without ``[recording] directory`` and with interaction off: a reload that adds the
    directory (enabled) and turns smoothing on starts a recording and the interaction stage, as a start
    with that rig would have (before, a reload only reloaded the extensions built at the start, so
    neither happened and nothing said so)."""
    from trackerd.cli.run import extension_kinds

    rig, pairs = bundle_pairs
    directory = tmp_path / "recordings"
    endpoint = f"ipc://{tmp_path}/pub.sock"
    zmq_cfg = rig.outputs.zmq.model_copy(update={"endpoints": (endpoint,), "status_interval_ms": 100.0})
    plain = rig.model_copy(
        update={
            "outputs": rig.outputs.model_copy(update={"zmq": zmq_cfg}),
            "recording": RecordingConfig(),
            "interaction": rig.interaction.model_copy(
                update={
                    "smoothing": rig.interaction.smoothing.model_copy(update={"enabled": False}),
                    "pointing": rig.interaction.pointing.model_copy(update={"enabled": False}),
                }
            ),
        }
    )
    assert not plain.interaction.any_enabled
    asking = plain.model_copy(
        update={
            "recording": RecordingConfig(directory=directory, enabled=True),
            "interaction": plain.interaction.model_copy(
                update={"smoothing": plain.interaction.smoothing.model_copy(update={"enabled": True})}
            ),
        }
    )
    context = ExtensionContext()
    images = [pair.images for pair in pairs]
    pipeline = Pipeline(
        plain,
        lambda r: MemoryPairSource(r, images, rate_hz=60.0),
        lambda r: Publisher(r.outputs.zmq),
        extensions=build_extensions(plain, context),
        extension_kinds=extension_kinds(),
        extension_context=context,
    )
    statuses: list[dict] = []
    try:
        pipeline.start()
        _status_states(endpoint, 20.0, lambda s: True, statuses)
        assert statuses and statuses[-1]["recording"] is None and statuses[-1]["interaction"] is None
        pipeline.request_reload(asking)
        _status_states(
            endpoint, 20.0, lambda s: (s.get("recording") or {}).get("pairs", 0) > 5 and s["interaction"], statuses
        )
    finally:
        pipeline.stop()
    assert pipeline.failure is None
    assert [e.name for e in pipeline.extensions] == ["recording", "interaction"]
    last = statuses[-1]
    assert last["recording"]["state"] == "recording" and last["interaction"] is not None, last
    (path,) = directory.glob("*.trec")
    with Recording.open(path) as recording:
        assert recording.problems == [] and len(recording) > 5


def _fed_until(extension, pairs, done) -> int:
    """Pairs given to ``extension`` in turn (round and round) until ``done()``; how many."""
    deadline = time.monotonic() + 30.0
    count = 0
    while not done():
        assert time.monotonic() < deadline, extension.status()
        extension.on_pair(pairs[count % len(pairs)])
        count += 1
        time.sleep(0.005)  # at most a pair every 5 ms: the writer thread keeps up
    return count


def test_after_a_recording_stops_at_its_limit_the_console_can_start_another(bundle_pairs, tmp_path) -> None:
    """A recording that ended at its pair limit is no longer the current one: ``record start`` starts the
    next (it answered "already recording into" the finished one) and ``record stop`` says nothing is
    being recorded (it answered "finishing" it)."""
    from trackerd.recording.extension import RecordingExtension

    rig, pairs = bundle_pairs
    directory = tmp_path / "recordings"
    extension = RecordingExtension(
        rig.model_copy(update={"recording": RecordingConfig(directory=directory, enabled=True, max_pairs=3)})
    )
    try:
        _fed_until(extension, pairs, lambda: (extension.status() or {}).get("state") == "stopped")
        assert extension.status()["detail"] == "pair limit"
        assert extension.stop_now() == "not recording"
        assert extension.start_now() == "a recording starts with the next pair"
        assert extension.on_pair(pairs[0]) is True  # a recording starts with it
        assert extension.status()["state"] == "recording"
        assert extension.start_now().startswith("already recording into ")
        _fed_until(extension, pairs, lambda: (extension.status() or {}).get("state") == "stopped")
    finally:
        extension.close()
    recordings = sorted(directory.glob("*.trec"))
    assert len(recordings) == 2
    for path in recordings:
        with Recording.open(path) as recording:
            assert recording.problems == [] and len(recording) == 3


def test_a_recording_folder_that_cannot_be_made_is_reported_failed_with_why(bundle_pairs, tmp_path) -> None:
    """The status says the recording failed and why, as docs/recording.md's ``failed`` state promises (it
    said ``idle``, "enabled = false"); a reload clears it and tries again."""
    from trackerd.recording.extension import RecordingExtension

    rig, pairs = bundle_pairs
    (tmp_path / "a-file").write_text("not a folder")
    blocked = tmp_path / "a-file" / "recordings"
    extension = RecordingExtension(
        rig.model_copy(update={"recording": RecordingConfig(directory=blocked, enabled=True)})
    )
    try:
        assert extension.on_pair(pairs[0]) is False
        assert extension.status() == {
            "state": "failed",
            "path": None,
            "detail": f"cannot create {blocked}: Not a directory",
        }
        assert extension.start_now() == (
            "a recording is tried again with the next pair (the last one failed:"
            f" cannot create {blocked}: Not a directory)"
        )
        assert extension.on_pair(pairs[1]) is False
        assert extension.status()["state"] == "failed"
        good = tmp_path / "recordings"
        extension.reload(rig.model_copy(update={"recording": RecordingConfig(directory=good, enabled=True)}))
        assert extension.status() == {"state": "idle", "detail": "starts with the next pair"}
        assert extension.on_pair(pairs[2]) is True
        assert extension.status()["state"] == "recording"
    finally:
        extension.close()
    assert len(list(good.glob("*.trec"))) == 1


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
