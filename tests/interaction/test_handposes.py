"""Hand poses beside the pipeline: on a thread of their own behind a one-slot drop-oldest mailbox, or inline.

Rendered frames of the left camera (an empty room, a hand showing two fingers,
the room again) go through :class:`HandPoses` both ways: looked at in the
calling thread, as a replay does, and on the look thread, waiting for each
look, as the daemon does when it keeps up. Both must give the same events;
the threaded one with the sequence and capture time of the pair each look was
made for. A look thread that falls behind keeps only the newest frame and
counts the drop; it stops when asked, and a look that crashes fails the caller.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from trackerd.acquisition.frame import Frame, FramePair
from trackerd.config.interaction import HandConfig
from trackerd.config.rig_geometry import wall_frame
from trackerd.interaction.grammar import Grammar
from trackerd.interaction.hand import HandDetector, HandObservation
from trackerd.interaction.handposes import HandPoses
from trackerd.interaction.outcomes import EventMaker
from trackerd.pipeline.events import CommandIssued, Event, HandSeen
from trackerd.sim.hand import HandRenderer, random_hand_pose

CONFIG = HandConfig(enabled=True, every_n_pairs=1, debounce_pairs=2)
EPOCH_NS = 1_800_000_000 * 10**9
GUARD_S = 60.0
"""Only against a hang: every wait here is for something to happen, not for a time."""


@pytest.fixture(scope="module")
def pairs(renderer):
    """Eight pairs: the empty room twice, the hand four times, the room twice (the right camera's
    frame is never looked at)."""
    rng = np.random.default_rng(3)
    hands = HandRenderer(renderer, 0)
    pose = random_hand_pose(2, np.random.default_rng(5), 1920, 1080)
    empty = hands.empty(rng)
    images = [empty, empty] + [hands.render(pose, rng).image for _ in range(4)] + [empty, empty]
    out = []
    for sequence, image in enumerate(images, start=1):
        time_ns = sequence * 33_000_000
        frames = tuple(Frame(camera, sequence, 0, time_ns, hands.pixel_format, image) for camera in ("left", "right"))
        out.append(FramePair(frames, time_ns, 0, sequence))
    return out


def _poses(simulated_rig, *, threaded: bool, detector: HandDetector | None = None) -> HandPoses:
    assert simulated_rig.wall is not None
    maker = EventMaker(wall_frame(simulated_rig.wall), Grammar({"hand_2": "two"}, set()), smoothing=True)
    return HandPoses(CONFIG, 0, "left", maker, threaded=threaded, detector=detector)


def _wait_until(condition) -> None:
    deadline = time.monotonic() + GUARD_S
    while not condition():
        assert time.monotonic() < deadline, "gave up waiting"
        time.sleep(0.001)


def _hand_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == "trackerd-hand"]


def test_the_look_thread_gives_the_events_of_looks_made_inline(simulated_rig, pairs):
    inline = _poses(simulated_rig, threaded=False)
    expected: list[Event] = []
    for pair in pairs:
        expected += inline.offer(pair, pair.timestamp_ns + EPOCH_NS)
    expected += inline.end_session(pairs[-1].sequence, pairs[-1].timestamp_ns + EPOCH_NS)
    # The hand counted (twice in a row), its command, and its going.
    assert [(e.kind, getattr(e, "present", None)) for e in expected] == [
        ("hand", True),
        ("command", None),
        ("hand", True),
        ("hand", True),
        ("hand", False),
    ]
    assert isinstance(expected[1], CommandIssued) and expected[1].command == "two"

    threaded = _poses(simulated_rig, threaded=True)
    got: list[Event] = []
    try:
        for k, pair in enumerate(pairs):
            got += threaded.offer(pair, pair.timestamp_ns + EPOCH_NS)
            _wait_until(lambda k=k: threaded.looked == k + 1)
        got += threaded.take()
        got += threaded.end_session(pairs[-1].sequence, pairs[-1].timestamp_ns + EPOCH_NS)
    finally:
        threaded.stop()
    assert got == expected
    assert threaded.dropped == 0
    hand = next(e for e in got if isinstance(e, HandSeen))
    assert hand.sequence == 4 and hand.capture_ns == pairs[3].timestamp_ns + EPOCH_NS  # the pair looked at


class _HeldDetector(HandDetector):
    """Looks only when let through (one look per ``go``), and sees a one-finger hand."""

    def __init__(self) -> None:
        super().__init__(CONFIG)
        self.go = threading.Semaphore(0)
        self.looking = threading.Event()

    def look(self, image, pixel_format):
        self.looking.set()
        assert self.go.acquire(timeout=GUARD_S)
        return HandObservation(1, (10.0, 20.0), 5.0, 300.0)


def test_a_look_thread_that_falls_behind_keeps_the_newest_frame_and_counts_the_rest(simulated_rig, pairs):
    detector = _HeldDetector()
    poses = _poses(simulated_rig, threaded=True, detector=detector)
    try:
        poses.offer(pairs[0], 1)
        assert detector.looking.wait(GUARD_S)  # the first look is under way and held
        for pair in pairs[1:]:
            poses.offer(pair, pair.sequence)  # each replaces the one waiting
        assert poses.dropped == len(pairs) - 2
        detector.go.release(2)
        _wait_until(lambda: poses.looked == 2)
        events = poses.take()
    finally:
        detector.go.release(10)
        poses.stop()
    # Debounced over the two looks made: the first pair's and the newest one's.
    assert [(e.kind, e.sequence) for e in events] == [("hand", pairs[-1].sequence)]
    assert not _hand_threads()


def test_the_look_thread_starts_with_the_first_look_and_stops_when_asked(simulated_rig, pairs):
    poses = _poses(simulated_rig, threaded=True)
    assert not _hand_threads()
    poses.offer(pairs[0], 1)
    assert len(_hand_threads()) == 1
    poses.stop()
    assert not _hand_threads()
    poses.stop()  # idempotent


class _BrokenDetector(HandDetector):
    def look(self, image, pixel_format):
        raise ValueError("a broken look")


def test_a_look_that_crashes_fails_the_processing_thread(simulated_rig, pairs):
    poses = _poses(simulated_rig, threaded=True, detector=_BrokenDetector(CONFIG))
    try:
        poses.offer(pairs[0], 1)
        with pytest.raises(RuntimeError, match="hand-pose thread failed"):
            _wait_until(lambda: bool(poses.take()) and False)
    finally:
        poses.stop()
