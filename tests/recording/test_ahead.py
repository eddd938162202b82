"""A replay at max speed locating ahead in a worker process (trackerd.recording.ahead): the same
messages as locating in the pipeline, frames read only when looked at, a lost worker said plainly."""

from __future__ import annotations

import os
import signal
import threading

import numpy as np
import pytest
from rec_helpers import replay_and_listen, without_publish_time

from trackerd.locator import Locator
from trackerd.pipeline.queues import DropOldestQueue
from trackerd.recording.convert import convert_recording
from trackerd.recording.decoding import FrameDecoder
from trackerd.recording.format import RecordHeader
from trackerd.recording.reader import Recording
from trackerd.recording.replay import ReplayPairSource
from trackerd.recording.replay_rig import replay_rig


@pytest.fixture(scope="module")
def windowed(bundle, tmp_path_factory):
    out = tmp_path_factory.mktemp("ahead") / "windowed.trec"
    with Recording.open(bundle) as source:
        convert_recording(source, out, "windowed")
    return out


@pytest.mark.parametrize("mode", ["raw", "windowed"])
def test_located_ahead_a_replay_publishes_what_it_does_located_in_the_pipeline(bundle, windowed, mode, tmp_path):
    """Two passes (the second starts afresh), the pointer lost and found again in each (pairs 10
    and 11 have none): every message but the statuses, bit for bit, as `--one-process` publishes."""
    path = bundle if mode == "raw" else windowed
    outcomes = []
    for k, extra in enumerate((["--one-process"], [])):
        run, messages = replay_and_listen(
            path, "--speed", "max", "--passes", "2", *extra, endpoint=f"ipc://{tmp_path}/a{k}.sock"
        )
        assert run.returncode == 0, run.stderr
        assert "Traceback" not in run.stderr, run.stderr
        outcomes.append(without_publish_time(messages))
    assert sum(m.startswith("hit ") for m in outcomes[0]) == 2 * 14
    assert outcomes[1] == outcomes[0]


def test_frames_located_ahead_are_read_only_when_looked_at_and_are_the_recorded_ones(windowed, monkeypatch):
    """The pairs come with the worker's fixes, which are what a locator in this process finds; no
    frame is rebuilt in this process until something looks at it, and then it is the recorded frame."""
    rebuilt: list[tuple[int, int]] = []
    frame = FrameDecoder.frame

    def counting(self: FrameDecoder, index: int, k: int, header: RecordHeader, verify: bool) -> np.ndarray:
        rebuilt.append((index, k))
        return frame(self, index, k, header, verify)

    monkeypatch.setattr(FrameDecoder, "frame", counting)
    with Recording.open(windowed) as recording:
        rig, _ = replay_rig(recording, None, ["tcp://127.0.0.1:*"])
        source = ReplayPairSource(recording, speed=None, locate_with=rig)
        with source:
            pairs = []
            while not source.finished:
                pair = source.next_pair(30.0)
                assert pair is not None, "the replay stopped delivering"
                pairs.append(pair)
        assert len(pairs) == len(recording) and rebuilt == []
        assert all(pair.located is not None for pair in pairs)
        here = Locator(rig)
        for index, pair in enumerate(pairs):
            expected = here.locate(recording.images(index))
            if expected.status == "not_found":
                here.reset()
            ahead = pair.located
            assert ahead is not None and ahead.status == expected.status, index
            if expected.hit is not None:
                assert ahead.hit is not None and ahead.hit.wall_xy_m.tolist() == expected.hit.wall_xy_m.tolist()
        rebuilt.clear()
        looked_at = [pairs[5].frames[1].image, *pairs[5].images]
        assert rebuilt == [(5, 0), (5, 1)]  # the pair's frames, once, when one of them was looked at
        recorded = recording.images(5)
        assert np.array_equal(looked_at[0], recorded[1])
        assert all(np.array_equal(a, b) for a, b in zip(looked_at[1:], recorded, strict=True))


def test_a_worker_that_dies_ends_the_replay_with_one_clear_line(bundle):
    with Recording.open(bundle) as recording:
        rig, _ = replay_rig(recording, None, ["tcp://127.0.0.1:*"])
        source = ReplayPairSource(recording, speed=None, locate_with=rig, loop=True)
        with source:
            assert source.next_pair(30.0) is not None  # the worker is running and has sent fixes
            worker = source._worker
            assert worker is not None
            os.kill(worker._process.pid, signal.SIGKILL)
            delivered = 0
            while not source.finished:
                if source.next_pair(30.0) is not None:
                    delivered += 1
                    assert delivered < 10_000, "the replay went on without its worker"
        assert source.failure == "the replay's locating process ended unexpectedly (killed by signal 9)"
        assert source.problems == [source.failure]


def test_a_queue_that_waits_for_room_loses_nothing_and_still_stops():
    queue: DropOldestQueue[int] = DropOldestQueue(2)
    stop = threading.Event()
    taken: list[int] = []

    def slow_consumer() -> None:
        while len(taken) < 50:
            item = queue.get(5.0)
            assert item is not None
            taken.append(item)

    consumer = threading.Thread(target=slow_consumer)
    consumer.start()
    for k in range(50):
        assert queue.put_waiting(k, stop)
    consumer.join(30.0)
    assert taken == list(range(50)) and queue.dropped == 0
    # With nobody taking, a stop lets the producer go on (dropping the oldest, as put does).
    queue.put(50)
    queue.put(51)
    stop.set()
    assert queue.put_waiting(52, stop) is False and queue.dropped == 1
