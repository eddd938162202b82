"""The compressed and windowed recording modes: lossless round trips, the live hits from windows, a
recorder killed mid-write, hostile compressed data, and readers that do not know a mode."""

from __future__ import annotations

import json
import os
import shutil
import signal
import struct
import subprocess
import sys
import threading
import time
import zlib
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
import zstandard
from rec_helpers import one_line_error, replay_and_listen, trackerd, without_publish_time

from trackerd.acquisition.frame import Frame, FramePair
from trackerd.errors import RecordingError
from trackerd.recording import format as format_module
from trackerd.recording import reader as reader_module
from trackerd.recording.codec import WINDOW, WINDOWS_HEADER, Canvases, Window
from trackerd.recording.convert import convert_recording
from trackerd.recording.decoding import FrameDecoder
from trackerd.recording.format import (
    ENCODING_WINDOWS,
    ENCODING_ZSTD,
    FILE_HEADER,
    FLAG_KEYFRAME,
    INDEX_ENTRY,
    FrameEntry,
    IndexEntry,
    RecordHeader,
    pack_index_entry,
    pack_record_header,
)
from trackerd.recording.reader import Recording
from trackerd.recording.replay import ReplayPairSource
from trackerd.recording.writer import RecordingWriter

NOISE_DN = 2.0


@pytest.fixture(scope="module")
def noisy(bundle, tmp_path_factory) -> Path:
    """The bundled pairs with 2 DN of sensor noise added (seeded), as a raw recording: what the
    windows must reproduce the tracker's view of, pixel noise and all."""
    out = tmp_path_factory.mktemp("modes") / "noisy.trec"
    rng = np.random.default_rng(7)
    with Recording.open(bundle) as source:
        writer = None
        for index in range(len(source)):
            pair = source.pair(index)
            frames = tuple(
                Frame(
                    f.camera_id,
                    f.frame_id,
                    f.device_timestamp_ns,
                    f.host_timestamp_ns,
                    f.pixel_format,
                    np.clip(f.image + rng.normal(0.0, NOISE_DN, f.image.shape), 0, 255).astype(np.uint8),
                )
                for f in pair.frames
            )
            noisy_pair = FramePair(frames, pair.timestamp_ns, pair.skew_ns, pair.sequence)
            writer = writer or RecordingWriter(out, source.metadata)
            writer.write(noisy_pair)
        writer.close("rendered, noise added")
    return out


def _frames(path: Path) -> list[list[np.ndarray]]:
    with Recording.open(path) as recording:
        assert not recording.problems, recording.problems
        return [[np.array(image) for image in recording.images(i)] for i in range(len(recording))]


def test_compressed_is_lossless_and_converts_back_to_the_same_frames(noisy, tmp_path) -> None:
    compressed, back = tmp_path / "c.trec", tmp_path / "back.trec"
    run = trackerd("recording", "convert", noisy, compressed, "--mode", "compressed", "--keyframe-interval", "0.3")
    assert run.returncode == 0, run.stderr
    assert "compressed" in run.stdout and "keyframes" in run.stdout
    meta = json.loads((compressed / "recording.json").read_text())
    assert (meta["mode"], meta["format_version"], meta["keyframe_interval_s"]) == ("compressed", "2.0", 0.3)
    with Recording.open(compressed) as recording:
        encodings = [recording.header(i).frames[0].encoding for i in range(len(recording))]
        keyframes = [bool(recording.header(i).flags & FLAG_KEYFRAME) for i in range(len(recording))]
        # Keyframes at the interval (pairs are 1/15 s apart), differences between them.
        assert keyframes[:6] == [True, False, False, False, False, True], keyframes
        assert set(encodings) == {2, 3}
        # Read out of order: a difference is rebuilt from its keyframe whatever was read before.
        original = _frames(noisy)
        for i in (13, 2, 9, 3):
            assert all(np.array_equal(a, b) for a, b in zip(recording.images(i), original[i], strict=True)), i
    assert all(
        np.array_equal(a, b)
        for got, want in zip(_frames(compressed), original, strict=True)
        for a, b in zip(got, want, strict=True)
    )
    run = trackerd("recording", "convert", compressed, back, "--mode", "raw")
    assert run.returncode == 0, run.stderr
    # Raw again: the pairs.dat of the source byte for byte (headers, timestamps, frames) after the file header.
    assert (back / "pairs.dat").read_bytes()[FILE_HEADER.size :] == (noisy / "pairs.dat").read_bytes()[
        FILE_HEADER.size :
    ]
    assert os.path.getsize(compressed / "pairs.dat") < 0.75 * os.path.getsize(noisy / "pairs.dat")


def test_a_windowed_recording_replays_to_exactly_the_hits_of_the_full_frames(noisy, tmp_path) -> None:
    windowed = tmp_path / "w.trec"
    run = trackerd("recording", "convert", noisy, windowed, "--mode", "windowed")
    assert run.returncode == 0, run.stderr
    with Recording.open(windowed) as recording:
        full = [bool(recording.header(i).flags & FLAG_KEYFRAME) for i in range(len(recording))]
        assert recording.metadata.mode == "windowed"
    # The first pair, and the pairs where the pointer is lost and found again, are whole; the others windows.
    assert full[0] and sum(full) < len(full) - 8, full
    assert os.path.getsize(windowed / "pairs.dat") < os.path.getsize(noisy / "pairs.dat") / 3
    outcomes = []
    for k, path in enumerate((noisy, windowed)):
        # At the recorded pace (16 pairs, about a second): as fast as possible on a loaded machine, the
        # pipeline's drop-oldest queue before the publisher may drop a pair, which is not what is tested.
        replay, messages = replay_and_listen(path, "--json", endpoint=f"ipc://{tmp_path}/r{k}.sock")
        assert replay.returncode == 0, replay.stderr
        outcomes.append(without_publish_time(messages))
    hits = [m for m in outcomes[0] if m.startswith("hit ")]
    assert len(hits) >= 12
    assert outcomes[1] == outcomes[0]


def test_a_compressed_replay_decodes_each_camera_on_its_own_thread_to_the_raw_frames(
    noisy, tmp_path, monkeypatch
) -> None:
    """Replaying a compressed recording, the reader thread rebuilds the first camera's frame while a
    thread of its pool rebuilds the second's (replay.THREADED_DECODE_MODES); every pair delivered is
    the raw source's, pixel for pixel, keyframes and differences alike."""
    compressed = tmp_path / "c.trec"
    with Recording.open(noisy) as source:
        convert_recording(source, compressed, "compressed", keyframe_interval_s=0.3)
    decoded_on: dict[int, set[str]] = {0: set(), 1: set()}
    frame = FrameDecoder.frame

    def noting_the_thread(self: FrameDecoder, index: int, k: int, header: RecordHeader, verify: bool) -> np.ndarray:
        decoded_on[k].add(threading.current_thread().name)
        return frame(self, index, k, header, verify)

    monkeypatch.setattr(FrameDecoder, "frame", noting_the_thread)
    replay = ReplayPairSource(compressed, speed=None)
    replay.start()
    try:
        replayed = []
        while not replay.finished:
            pair = replay.next_pair(5.0)
            assert pair is not None, "the replay stopped delivering"
            replayed.append([np.array(image) for image in pair.images])
    finally:
        replay.stop()
    assert decoded_on[0] == {"trackerd-replay-reader"}
    assert len(decoded_on[1]) == 1 and next(iter(decoded_on[1])).startswith("trackerd-replay-decode")
    original = _frames(noisy)
    assert len(replayed) == len(original)
    assert all(
        np.array_equal(a, b)
        for got, want in zip(replayed, original, strict=True)
        for a, b in zip(got, want, strict=True)
    )


def test_a_damaged_frame_of_a_compressed_recording_is_named_alike_on_one_thread_or_two(noisy, tmp_path) -> None:
    """With the decode pool, the error of a pair whose second camera's frame is damaged is the one
    a single thread gives, and the pairs after it (differences building on it) are refused alike."""
    compressed = tmp_path / "c.trec"
    with Recording.open(noisy) as source:
        convert_recording(source, compressed, "compressed", keyframe_interval_s=0.3)
    with Recording.open(compressed) as recording:
        header = recording.header(2)
        offset = recording.entries[2].offset + header.header_bytes + header.frames[0].stored_bytes + 100
    with (compressed / "pairs.dat").open("r+b") as data:
        data.seek(offset)
        byte = data.read(1)
        data.seek(offset)
        data.write(bytes([byte[0] ^ 0xFF]))
    outcomes = []
    with ThreadPoolExecutor(1) as pool:
        for use in (None, pool):
            with Recording.open(compressed) as recording:
                seen = []
                for index in range(6):
                    try:
                        recording.images(index, pool=use)
                        seen.append("ok")
                    except RecordingError as err:
                        seen.append(str(err))
                outcomes.append(seen)
    assert outcomes[0] == outcomes[1]
    assert outcomes[0][:2] == ["ok", "ok"] and "pair 2, camera" in outcomes[0][2] and "checksum" in outcomes[0][2]
    assert "cannot be read" in outcomes[0][3]


_KILLED_WRITER = """
import sys, itertools, dataclasses, time
from trackerd.config.recording import RecordingConfig
from trackerd.recording.reader import Recording
from trackerd.recording.replay import ReplayPairSource
from trackerd.recording.recorder import Recorder
source = Recording.open(sys.argv[1])
pairs = [source.pair(i) for i in range(len(source))]
config = RecordingConfig(mode=sys.argv[3], keyframe_interval_s=0.3, queue_pairs=4)
recorder = Recorder(sys.argv[2], source.rig(), producer="test: killed", config=config).start()
step = pairs[-1].timestamp_ns - pairs[0].timestamp_ns + 66_666_667
for n in itertools.count():
    pair = pairs[n % len(pairs)]
    shift = (n // len(pairs)) * step
    recorder.put(dataclasses.replace(pair, timestamp_ns=pair.timestamp_ns + shift, sequence=n))
    time.sleep(0.005)
"""


@pytest.mark.parametrize("mode", ["compressed", "windowed"])
def test_a_recording_process_killed_mid_write_keeps_every_complete_pair(noisy, tmp_path, mode) -> None:
    out = tmp_path / f"killed-{mode}.trec"
    process = subprocess.Popen(
        [sys.executable, "-c", _KILLED_WRITER, str(noisy), str(out), mode],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    index = out / "pairs.idx"
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and process.poll() is None:
            if index.exists() and index.stat().st_size >= FILE_HEADER.size + 24 * INDEX_ENTRY.size:
                break
            time.sleep(0.02)
        os.kill(process.pid, signal.SIGKILL)
    finally:
        process.wait(10)
        _, stderr = process.communicate()
    assert process.returncode == -signal.SIGKILL, stderr
    check = trackerd("recording", "check", out, "--json")
    report = json.loads(check.stdout)
    assert check.returncode == 1 and not report["closed"] and report["mode"] == mode
    assert report["pairs"] >= 24 and report["replayable"] == report["pairs"], report
    original = _frames(noisy)
    with Recording.open(out) as recording:
        for i in range(len(recording)):
            images = recording.images(i)
            if mode == "compressed":
                want = original[recording.header(i).sequence % len(original)]
                assert all(np.array_equal(a, b) for a, b in zip(images, want, strict=True)), i


def _append_record(folder: Path, payloads: list[bytes], encodings: list[int], flags: int) -> None:
    """Append one well-formed record (checksums right) holding these payloads, and its index entry."""
    with Recording.open(folder) as recording:
        last = recording.header(len(recording) - 1)
        entry = recording.entries[-1]
        pairs = len(recording)
    frames = tuple(
        FrameEntry(f.frame_id + 1, f.device_timestamp_ns, f.host_timestamp_ns, len(p), zlib.crc32(p), e)
        for f, p, e in zip(last.frames, payloads, encodings, strict=True)
    )
    header = RecordHeader(pairs, last.sequence + 1, last.timestamp_ns + 66_666_667, 0, 0, frames, flags)
    record = pack_record_header(header) + b"".join(payloads)
    with open(folder / "pairs.dat", "ab") as data:
        data.write(record)
    with open(folder / "pairs.idx", "ab") as idx:
        idx.write(pack_index_entry(IndexEntry(entry.end, len(record), pairs, header.sequence, header.timestamp_ns)))
    meta = json.loads((folder / "recording.json").read_text())
    meta["end"] = None
    (folder / "recording.json").write_text(json.dumps(meta))


@pytest.fixture(scope="module")
def windowed_bundle(bundle, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("windowed") / "bundle.trec"
    with Recording.open(bundle) as source:
        convert_recording(source, out, "windowed")
    return out


@pytest.mark.parametrize("case", ["huge", "garbage", "window outside", "window over itself"])
def test_hostile_compressed_frames_are_one_clear_line_each(windowed_bundle, tmp_path, case) -> None:
    folder = tmp_path / f"{case.replace(' ', '-')}.trec"
    shutil.copytree(windowed_bundle, folder)
    width, height = 1920, 1080
    good = zstandard.ZstdCompressor().compress(bytes(width * height))
    flags = FLAG_KEYFRAME
    if case == "huge":
        # A frame that claims gigabytes (zeros compress to almost nothing): refused before allocating.
        bad, encoding, expect = zstandard.ZstdCompressor().compress(bytes(1 << 30)), ENCODING_ZSTD, "holds 1073741824"
    elif case == "garbage":
        bad, encoding, expect = good[:8] + bytes(len(good) - 8), ENCODING_ZSTD, "does not decompress"
    else:
        x = width - 4 if case == "window outside" else 0
        base = 16 if case == "window over itself" else 0
        table = WINDOWS_HEADER.pack(base, 1) + WINDOW.pack(x, 0, 8, 8) + bytes(64)
        bad, encoding, flags = zstandard.ZstdCompressor().compress(table), ENCODING_WINDOWS, 0
        expect = "not inside the 1920x1080 frame" if case == "window outside" else "not an earlier pair"
    _append_record(folder, [bad, good], [encoding, ENCODING_ZSTD], flags)
    with Recording.open(folder) as recording:
        assert len(recording) == 17
        with pytest.raises(RecordingError, match=expect) as err:
            recording.images(16)
        assert "\n" not in str(err.value) and "pair 16, camera 'left'" in str(err.value)
        assert np.array_equal(recording.images(15)[1], recording.images(15)[1])  # the rest still reads
    run = trackerd("recording", "check", folder)
    assert run.returncode == 1 and "Traceback" not in run.stderr
    problems = [line for line in run.stdout.splitlines() if "pair 16" in line]
    assert len(problems) == 1 and expect in problems[0], run.stdout
    assert "16 of 17 pairs pass their checksums; 1 damaged" in run.stdout


def test_a_reader_refuses_a_mode_it_does_not_know_in_one_line(bundle, tmp_path, monkeypatch) -> None:
    compressed, raw = tmp_path / "c.trec", tmp_path / "r.trec"
    with Recording.open(bundle) as source:
        convert_recording(source, compressed, "compressed")
        convert_recording(source, raw, "raw")
    assert struct.unpack_from("<HH", (compressed / "pairs.dat").read_bytes(), 8) == (2, 0)
    assert struct.unpack_from("<HH", (raw / "pairs.dat").read_bytes(), 8) == (1, 1)
    # A trackerd that reads MAJOR 1 only (every trackerd before the compressed and windowed modes).
    with monkeypatch.context() as old:
        # The version check (format.check_major) and the metadata's upgrades (reader) each read them.
        old.setattr(format_module, "FORMAT_MAJOR", 1)
        old.setattr(format_module, "FORMAT_VERSION", "1.0")
        old.setattr(reader_module, "FORMAT_MAJOR", 1)
        with pytest.raises(RecordingError, match=r"format 2\.x is newer than this trackerd reads \(1\.0\)"):
            Recording.open(compressed)
        with Recording.open(raw) as recording:  # a raw recording stays readable by it
            assert len(recording) == 16 and recording.images(3)[0].shape == (1080, 1920)
    # A mode newer than this trackerd's, in a MAJOR it reads.
    meta = json.loads((compressed / "recording.json").read_text())
    (compressed / "recording.json").write_text(json.dumps({**meta, "mode": "holographic"}))
    one_line_error(
        trackerd("replay", compressed, "--speed", "max"),
        "replay",
        "recording mode 'holographic'",
        "newer than this trackerd reads (raw, compressed, windowed)",
    )


def test_a_rebuilt_frame_never_changes_while_someone_holds_it() -> None:
    """codec.Canvases reuses a canvas only when nothing else refers to it (replay hands frames to the
    pipeline and its colour-watch thread, which may keep them past the next pair)."""
    key = np.arange(64, dtype=np.uint8).reshape(8, 8)
    canvases = Canvases()

    def window(x: int, value: int) -> tuple[Window, memoryview]:
        return Window(x, 0, 2, 2), memoryview(bytes([value] * 4))

    held = canvases.frame(5, key, [window(0, 200)])
    assert held[0, 0] == 200 and not held.flags.writeable
    for value in range(10, 30):
        frame = canvases.frame(5, key, [window(4, value)])
        # The held frame keeps its window; every other pixel is the keyframe's, old windows put back.
        assert held[0, 0] == 200 and frame[0, 0] == key[0, 0] and frame[0, 4] == value
        expected = key.copy()
        expected[0:2, 4:6] = value
        assert np.array_equal(frame, expected)
        del frame
    assert len(canvases._canvases) == 2  # the held one and one reused 20 times


def test_canvases_are_reused_across_keyframes_without_touching_a_held_frame() -> None:
    """A new keyframe overwrites a free canvas in place rather than making a new one; a frame still
    held over the old keyframe keeps its pixels, and a keyframe decoded again (a new array for the
    same record: a looped replay) is never taken for the canvases still over the old array."""
    first = np.arange(64, dtype=np.uint8).reshape(8, 8)
    second = first[::-1].copy()
    canvases = Canvases()
    window = Window(2, 2, 2, 2)

    def frame(index: int, key: np.ndarray, value: int) -> np.ndarray:
        return canvases.frame(index, key, [(window, memoryview(bytes([value] * 4)))])

    held = frame(0, first, 7)
    loose = frame(0, first, 8)
    del loose
    over_second = frame(9, second, 9)
    expected = second.copy()
    expected[2:4, 2:4] = 9
    assert np.array_equal(over_second, expected)
    assert canvases.allocations == 2 and canvases.copies == 3  # the second canvas taken over, not a third made
    expected_held = first.copy()
    expected_held[2:4, 2:4] = 7
    assert np.array_equal(held, expected_held)
    del over_second, held
    again = first.copy()
    again[0, 0] = 99  # not what the canvases over ``first`` hold: it must be copied in
    looped = frame(0, again, 5)
    expected = again.copy()
    expected[2:4, 2:4] = 5
    assert np.array_equal(looped, expected)
    assert canvases.allocations == 2


def test_windows_too_small_for_the_tracker_become_keyframes_and_the_hits_stay_the_same(noisy, tmp_path) -> None:
    """The planner's check, not its guess of the windows, is what guarantees the hits: with windows
    cut far smaller than the tracker reads, pairs fail the check and are stored whole ('mismatch'),
    and the recording still gives exactly the raw recording's hits."""
    from trackerd.recording.export import export_recording
    from trackerd.recording.replay_rig import replay_rig
    from trackerd.recording.windowed import WindowPlanner

    small = tmp_path / "small-windows.trec"
    with Recording.open(noisy) as source:
        planner = WindowPlanner.for_metadata(source.metadata, margin_px=-12)
        writer = RecordingWriter(
            small, source.metadata.model_copy(update={"end": None}), mode="windowed", planner=planner
        )
        for index in range(len(source)):
            writer.write(source.pair(index))
        writer.close("test")
    assert planner.keyframes.get("mismatch", 0) >= 1, planner.keyframes
    assert writer.keyframes < writer.pairs, planner.keyframes  # and some pairs still pass as windows
    csvs = []
    for path in (noisy, small):
        with Recording.open(path) as recording:
            rig, _ = replay_rig(recording, None, None)
            export_recording(recording, tmp_path / path.stem, rig, images=False)
        csvs.append((tmp_path / path.stem / "hits.csv").read_text())
    assert csvs[1] == csvs[0] and csvs[0].count("\n") == 17
