"""A pointing session never ends silently: reset, reload and stop of the interaction extension.

The extension is fed real pairs with fixes built from scripted wall hits (the
locator is not needed to say where the hit is), its events turned into messages
as the publisher does (trackerd.publish.from_fix), and a UDP socket on
loopback decodes the TUIO bundles with the test's own OSC decoder. The last
test runs the real pipeline on rendered frames and stops it with the pointer
on the display, as `kill -TERM` does.
"""

from __future__ import annotations

import json
import socket
import time

import numpy as np
import pytest
import zmq

from tests.gated import GatedPairSource, wait_for_status
from tests.interaction.osc_decode import decode_bundle
from trackerd.acquisition.frame import Frame, FramePair
from trackerd.geometry.pointer_line import PointerLine
from trackerd.interaction.extension import InteractionExtension, create
from trackerd.interaction.scripted import RATE_HZ, rest, swipe_path
from trackerd.locator import PointerFix, WallHit
from trackerd.pipeline.daemon import Pipeline
from trackerd.pipeline.extensions import Located
from trackerd.publish import Publisher
from trackerd.publish.from_fix import event_messages, pair_messages
from trackerd.publish.messages import Message
from trackerd.sim.motion import Stage
from trackerd.sim.scene import pose_aimed_at

pytestmark = pytest.mark.serial  # runs the pipeline on paced sources

EPOCH_NS = 1_800_000_000 * 10**9
"""The publishing clock at the first pair."""
IMAGE = np.zeros((8, 8), np.uint8)
LINE = PointerLine(np.array([0.0, 0.0, 2.0]), np.array([0.0, 0.0, 2.45]), 0.0005, 0.0005, "planes", 1.0)


def _fix_at(point_m: np.ndarray) -> PointerFix:
    """A fix whose published hit is at ``point_m`` on the wall."""
    hit = WallHit(np.array([float(point_m[0]), float(point_m[1])]), np.zeros(3), None, True, 2.5)
    return PointerFix(status="hit", reason=None, centroids_px=(), line=LINE, hit=hit)


@pytest.fixture
def udp():
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.bind(("127.0.0.1", 0))
    client.setblocking(False)
    yield client
    client.close()


def _bundles(client: socket.socket) -> list[list[tuple[str, list]]]:
    """Every bundle received so far (loopback UDP is delivered by the time sendto returns)."""
    out = []
    while True:
        try:
            out.append(decode_bundle(client.recv(65536))[1])
        except BlockingIOError:
            return out


def _alive(bundle) -> list:
    return next(args for _, args in bundle if args[0] == "alive")[1:]


def _fseq(bundle) -> int:
    return next(args for _, args in bundle if args[0] == "fseq")[1]


def _rig(simulated_rig, tuio_port: int | None, **commands: str):
    interaction = simulated_rig.interaction.model_validate(
        {
            "commands": commands,
            "tuio": {"enabled": tuio_port is not None, "port": tuio_port or 3333},
        }
    )
    return simulated_rig.model_copy(update={"interaction": interaction})


class Feeder:
    """Pairs at 60 per second with a hit where the scripted hit is, through one extension; what it
    makes of them as the publisher sends it (the pointer messages left out)."""

    def __init__(self, extension: InteractionExtension) -> None:
        self.extension = extension
        self.sequence = 0
        self.stalled_ns = 0
        """Time without pairs so far (a camera lost: the source made none, and numbered none)."""

    def feed(self, points: np.ndarray) -> list[Message]:
        out: list[Message] = []
        for point in points:
            time_ns = 10**12 + int(self.sequence * 1e9 / RATE_HZ) + self.stalled_ns
            capture_ns = time_ns - 10**12 + EPOCH_NS
            frames = tuple(Frame(camera, self.sequence, 0, time_ns, "Mono8", IMAGE) for camera in ("left", "right"))
            fix = _fix_at(point)
            events = self.extension.on_located(Located(FramePair(frames, time_ns, 0, self.sequence), fix, capture_ns))
            out += [
                m
                for m in pair_messages(fix, "red", sequence=self.sequence, capture_ns=capture_ns, events=events)
                if m.topic != "pointer"
            ]
            self.sequence += 1
        return out


def _events(messages: list[Message]) -> list[Message]:
    return [m for m in messages if m.topic != "hit"]


def _comparable(message: Message, sequence_shift: int) -> dict:
    """A message as it would be had it come ``sequence_shift`` pairs earlier, without its session id."""
    data = message.model_dump(exclude={"cursor_id"})
    data["sequence"] -= sequence_shift
    shift_ns = round(sequence_shift * 1e9 / RATE_HZ)
    for key in ("capture_ns", "start_ns", "end_ns"):
        if data.get(key) is not None:
            data[key] -= shift_ns
    return data


def _session(rng) -> np.ndarray:
    """Rest (enter, dwell), a swipe right, rest: 1.85 s, the pointer still on the display at the end."""
    start = np.array([1.0, 0.5])
    swipe = swipe_path("swipe_right", start, 0.8, 0.25, rng)
    points = np.vstack([rest(start, 1.0, rng), swipe, rest(swipe[-1], 0.6, rng)])
    return points + rng.normal(0, 0.0015, points.shape)


def test_reset_ends_the_session_and_the_same_pairs_then_give_the_same_messages(simulated_rig, udp, rng):
    rig = _rig(simulated_rig, udp.getsockname()[1], leave="bye", swipe_right="next_slide", swipe_left="back")
    extension = create(rig)
    assert extension is not None
    feeder = Feeder(extension)
    points = _session(rng)
    try:
        first = feeder.feed(points)
        before_reset = _bundles(udp)
        extension.reset()
        second = feeder.feed(points)
        after_reset = _bundles(udp)
    finally:
        extension.close()
    assert [m.topic for m in _events(first)] == ["enter", "dwell", "gesture", "command"]
    assert _alive(before_reset[-1]) == [1]
    # The next pair's messages begin with the end of the session: a leave at its last pair, its command.
    leave, bye = second[:2]
    assert leave.topic == "leave" and leave.cursor_id == 1 and leave.reason == "lost"
    assert leave.sequence == len(points) - 1 and leave.capture_ns == first[-1].capture_ns
    assert (bye.command, bye.trigger) == ("bye", "leave")
    # Then exactly what a fresh start gives (no swipe_left from the jump back), in a new session.
    second = second[2:]
    assert [_comparable(m, len(points)) for m in second] == [_comparable(m, 0) for m in first]
    assert {m.cursor_id for m in second if m.topic != "command" and m.cursor_id is not None} == {2}
    # TUIO: the cursor is removed at the reset, the next session is a new one, fseq keeps counting.
    assert _alive(after_reset[0]) == []
    assert {tuple(_alive(b)) for b in after_reset[1:]} >= {(2,)} and (1,) not in {tuple(_alive(b)) for b in after_reset}
    frames = [_fseq(b) for b in before_reset + after_reset]
    assert frames == list(range(frames[0], frames[0] + len(frames)))


def test_a_reload_ends_the_session_with_a_leave_and_removes_the_tuio_cursor(simulated_rig, udp, rng):
    rig = _rig(simulated_rig, udp.getsockname()[1], enter="hello", leave="bye")
    extension = create(rig)
    assert extension is not None
    feeder = Feeder(extension)
    still = rest(np.array([1.5, 0.5]), 0.5, rng)
    try:
        entered = _events(feeder.feed(still))
        extension.reload(_rig(simulated_rig, None, enter="hello", leave="bye"))  # TUIO off
        bundles = _bundles(udp)
        after = _events(feeder.feed(still))
        assert extension.tuio is None and not _bundles(udp)
        extension.reload(rig)  # TUIO on again
        feeder.feed(still)
        back = _bundles(udp)
    finally:
        extension.close()
    assert [(m.topic, m.cursor_id) for m in entered] == [("enter", 1), ("command", 1)]
    # The old socket's last word removes the cursor: an empty alive, numbered after the others.
    assert _alive(bundles[-2]) == [1] and _alive(bundles[-1]) == [] and _fseq(bundles[-1]) == len(bundles)
    # The session ends with a leave (stamped with its last pair), and the next has a new id.
    assert [(m.topic, m.cursor_id) for m in after] == [("leave", 1), ("command", 1), ("enter", 2), ("command", 2)]
    assert after[0].sequence == len(still) - 1 and after[1].command == "bye"
    # With TUIO back, the frame count goes on from where it was (a client would drop lower ones as late).
    assert _fseq(back[0]) == len(bundles) + 1 and {tuple(_alive(b)) for b in back} == {(), (3,)}


def test_a_failed_reload_keeps_the_session(simulated_rig, udp, rng):
    extension = create(_rig(simulated_rig, udp.getsockname()[1], leave="bye"))
    assert extension is not None
    feeder = Feeder(extension)
    still = rest(np.array([1.5, 0.5]), 0.5, rng)
    try:
        feeder.feed(still)
        extension.reload(_rig(simulated_rig, udp.getsockname()[1], leave="bye", bogus_trigger="x"))
        after = _events(feeder.feed(still))
    finally:
        extension.close()
    # The session goes on: no leave, no new enter, the same id (the rest becomes a dwell).
    assert [(m.topic, m.cursor_id) for m in after] == [("dwell", 1)] and extension.engine.inside


def test_finish_returns_the_leave_and_close_removes_the_cursor(simulated_rig, udp, rng):
    extension = create(_rig(simulated_rig, udp.getsockname()[1], leave="bye"))
    assert extension is not None
    Feeder(extension).feed(rest(np.array([1.5, 0.5]), 0.5, rng))
    assert _alive(_bundles(udp)[-1]) == [1]
    ending = event_messages(extension.finish())
    assert [(m.topic, m.cursor_id) for m in ending] == [("leave", 1), ("command", 1)]
    assert extension.finish() == []
    extension.close()  # nothing more to say: the cursor is already removed
    assert [_alive(b) for b in _bundles(udp)] == [[]]
    assert extension.status()["events"]["leave"] == 1


def test_stopping_the_pipeline_with_the_pointer_on_the_display_removes_the_tuio_cursor(
    simulated_rig, renderer, udp, tmp_path
):
    rng = np.random.default_rng(8)
    stage = Stage.from_rig(simulated_rig)
    pose = pose_aimed_at(stage.hand_m, renderer.wall.from_wall_m(np.array([1.5, 0.5])), simulated_rig.pointer.length_m)
    pointing = [renderer.render(i, pose, rng).image for i in range(2)]
    rig = _rig(simulated_rig, udp.getsockname()[1])
    rig = rig.model_copy(
        update={
            "outputs": rig.outputs.model_copy(
                update={"zmq": rig.outputs.zmq.model_copy(update={"endpoints": (f"ipc://{tmp_path}/pub.sock",)})}
            )
        }
    )
    extension = create(rig)
    assert extension is not None
    # Half a second of the empty room first, then the pointer, served once the subscriber is connected.
    empty = [renderer.render(i, None, rng).image for i in range(2)]
    sets = [empty] * 15 + [pointing] * 3000
    sources: list[GatedPairSource] = []

    def source_for(r):
        sources.append(GatedPairSource(r, sets, rate_hz=30.0, loop=False))
        return sources[-1]

    pipeline = Pipeline(rig, source_for, lambda r: Publisher(r.outputs.zmq), extensions=[extension])
    ctx = zmq.Context()
    sub = ctx.socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"")
    sub.connect(f"ipc://{tmp_path}/pub.sock")
    topics: list[str] = []
    bundles: list = []
    pipeline.start()
    try:
        topics += [topic for topic, _ in wait_for_status(sub)]
        sources[0].open()
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline and not (any(_alive(b) for b in bundles) and "enter" in topics):
            while sub.poll(20):
                topics.append(sub.recv_multipart()[0].decode())
            bundles += _bundles(udp)
    finally:
        pipeline.stop()
    while sub.poll(500):
        topics.append(sub.recv_multipart()[0].decode())
    sub.close(0)
    ctx.term()
    bundles += _bundles(udp)
    assert pipeline.failure is None
    assert any(_alive(b) == [1] for b in bundles), "the pointer never entered"
    assert _alive(bundles[-1]) == []
    # Subscribers hear the session end too: a leave, published before the publisher closed.
    assert topics.count("enter") == 1 and topics.count("leave") == 1
    assert topics.index("leave") > max(i for i, t in enumerate(topics) if t == "hit")
    frames = [_fseq(b) for b in bundles]
    assert frames == sorted(frames) and len(set(frames)) == len(frames)


def test_a_source_that_stalls_ends_the_session_once_no_pair_has_come_for_half_a_second(simulated_rig, udp, rng):
    """A camera lost or the cameras stalled: no pair comes, and none would decide the ``leave`` (it was
    decided when the next pair arrived), so a client kept its cursor for the whole outage. Once no pair has
    come for QUIET_LEAVE_MS the session ends as a reset ends it; TUIO's empty ``alive`` then goes on once
    a second. Replayed, the output follows from the pairs alone: nothing is ended by time."""
    from trackerd.interaction.extension import QUIET_LEAVE_MS

    extension = create(_rig(simulated_rig, udp.getsockname()[1], leave="bye"))
    assert extension is not None
    feeder = Feeder(extension)
    feeder.feed(rest(np.array([1.5, 0.5]), 0.5, rng))
    assert extension.engine.inside and _alive(_bundles(udp)[-1]) == [1]
    last_ns = 10**12 + int((feeder.sequence - 1) * 1e9 / RATE_HZ)
    assert extension.on_quiet(last_ns + int(0.9 * QUIET_LEAVE_MS * 1e6)) == []  # a late pair, not an outage
    assert _bundles(udp) == []
    ending = event_messages(extension.on_quiet(last_ns + int(1.1 * QUIET_LEAVE_MS * 1e6)))
    assert [(m.topic, m.cursor_id) for m in ending] == [("leave", 1), ("command", 1)]
    assert ending[0].reason == "lost" and ending[0].sequence == feeder.sequence - 1  # stamped with its last pair
    assert not extension.engine.inside and [_alive(b) for b in _bundles(udp)] == [[]]
    assert extension.on_quiet(last_ns + int(1.2 * QUIET_LEAVE_MS * 1e6)) == [] and _bundles(udp) == []
    extension.on_quiet(last_ns + int(1.1 * QUIET_LEAVE_MS * 1e6) + 1_100_000_000)  # a second on: alive again
    assert [_alive(b) for b in _bundles(udp)] == [[]]
    # The pointer back: a new session, the next cursor id.
    feeder.feed(rest(np.array([1.5, 0.5]), 0.5, rng))
    assert extension.engine.inside and extension.engine.cursor_id == 2

    replayed = InteractionExtension(_rig(simulated_rig, None), threaded_hands=False, live=False)
    Feeder(replayed).feed(rest(np.array([1.5, 0.5]), 0.5, rng))
    assert replayed.engine.inside and replayed.on_quiet(10**12 + 60 * 10**9) == [] and replayed.engine.inside


def test_a_replay_of_a_stall_gives_the_events_the_live_run_gave(simulated_rig, rng):
    """Live, the stalled source's session ends during the wait (on_quiet); replayed, no wait happens, and
    the pair after the gap decides the same from the pairs' times: the same leave, the same next session
    (before, the replay kept the session and sent a dwell the live run never did)."""
    from trackerd.interaction.extension import QUIET_LEAVE_MS

    before = rest(np.array([1.5, 0.5]), 0.5, rng)
    after = rest(np.array([1.0, 0.4]), 2.5, rng)
    runs = []
    for live in (True, False):
        extension = InteractionExtension(_rig(simulated_rig, None, leave="bye"), threaded_hands=False, live=live)
        feeder = Feeder(extension)
        messages = feeder.feed(before)
        last_ns = 10**12 + int((feeder.sequence - 1) * 1e9 / RATE_HZ)
        messages += event_messages(extension.on_quiet(last_ns + int(2 * QUIET_LEAVE_MS * 1e6)))
        feeder.stalled_ns = 2_000_000_000  # two seconds without a pair
        messages += feeder.feed(after)
        runs.append([m.model_dump() for m in _events(messages)])
    live_events, replayed_events = runs
    assert [(e["topic"], e.get("reason")) for e in live_events][:4] == [
        ("enter", None),
        ("leave", "lost"),
        ("command", None),
        ("enter", None),
    ]
    assert replayed_events == live_events


def test_a_slow_processing_thread_is_no_stall_the_session_goes_on(simulated_rig, rng):
    """Two seconds between two located pairs whose numbers say the source made the pairs between (the
    processing thread was busy: a search, a loaded machine, and the queue kept the newest): no leave."""
    extension = InteractionExtension(_rig(simulated_rig, None), threaded_hands=False, live=True)
    feeder = Feeder(extension)
    messages = feeder.feed(rest(np.array([1.5, 0.5]), 0.5, rng))
    feeder.sequence += int(2.0 * RATE_HZ)  # made, numbered, not located
    messages += feeder.feed(rest(np.array([1.5, 0.5]), 0.5, rng))
    assert [m.topic for m in _events(messages)].count("leave") == 0 and extension.engine.inside


def test_the_pipeline_publishes_the_leave_of_a_session_its_stalled_source_ended(simulated_rig, renderer, tmp_path):
    """The real pipeline on rendered frames: the source serves the pointer for two seconds and then nothing
    (as when a camera is lost); the ``leave`` is published while the daemon runs, and the status says
    nothing points."""
    rng = np.random.default_rng(9)
    stage = Stage.from_rig(simulated_rig)
    pose = pose_aimed_at(stage.hand_m, renderer.wall.from_wall_m(np.array([1.5, 0.5])), simulated_rig.pointer.length_m)
    pointing = [renderer.render(i, pose, rng).image for i in range(2)]
    endpoint = f"ipc://{tmp_path}/pub.sock"
    rig = simulated_rig.model_copy(
        update={
            "outputs": simulated_rig.outputs.model_copy(
                update={
                    "zmq": simulated_rig.outputs.zmq.model_copy(
                        update={"endpoints": (endpoint,), "status_interval_ms": 100.0}
                    )
                }
            )
        }
    )
    extension = create(rig)
    assert extension is not None
    sources: list[GatedPairSource] = []

    def source_for(r):
        sources.append(GatedPairSource(r, [pointing] * 60, rate_hz=30.0, loop=False))
        return sources[-1]

    pipeline = Pipeline(rig, source_for, lambda r: Publisher(r.outputs.zmq), extensions=[extension])
    ctx = zmq.Context()
    sub = ctx.socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"")
    sub.connect(endpoint)
    received: list[tuple[str, dict]] = []
    pipeline.start()
    try:
        received += wait_for_status(sub)
        sources[0].open()
        deadline = time.monotonic() + 30.0
        # Until the leave, and a status after it that no longer says the pointer is pointing.
        while time.monotonic() < deadline and not (
            any(t == "leave" for t, _ in received)
            and received[-1][0] == "status"
            and not (received[-1][1].get("interaction") or {}).get("pointing", True)
        ):
            if sub.poll(50):
                topic, payload = sub.recv_multipart()
                received.append((topic.decode(), json.loads(payload)))
        running = pipeline.state == "running" or pipeline.state == "degraded"
    finally:
        pipeline.stop()
        sub.close(0)
        ctx.term()
    assert pipeline.failure is None and running
    topics = [t for t, _ in received]
    assert topics.count("enter") == 1 and topics.count("leave") == 1, topics
    leave = next(m for t, m in received if t == "leave")
    assert leave["reason"] == "lost"
    assert topics.index("leave") > max(i for i, t in enumerate(topics) if t == "hit")
