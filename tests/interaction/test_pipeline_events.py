"""Every interaction event end to end: rendered frames -> the real pipeline -> ZeroMQ (and TUIO over UDP).

One scripted session, rendered through the simulated rig's cameras: the room
with a hand showing two fingers to the left camera, the pointer entering and
resting (enter, dwell -> "select"), a rendered swipe to the right (gesture ->
"next_slide"), a rest, and the pointer gone (leave). The daemon's pipeline runs
it from memory at 30 pairs per second with the interaction extension built from
the rig, and a subscriber checks what arrives; a UDP socket decodes the TUIO
bundles with the test's own OSC decoder.
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
from trackerd.interaction.extension import create
from trackerd.interaction.scripted import minimum_jerk
from trackerd.pipeline.daemon import Pipeline
from trackerd.publish import Publisher
from trackerd.publish.messages import TOPICS, decode
from trackerd.sim.hand import HandRenderer, random_hand_pose
from trackerd.sim.motion import Stage
from trackerd.sim.scene import pose_aimed_at

pytestmark = pytest.mark.serial  # waits a few seconds for every event of a paced run

RATE_HZ = 30.0


def _rig(rig, endpoint: str, tuio_port: int):
    zmq_cfg = rig.outputs.zmq.model_copy(update={"endpoints": (endpoint,), "status_interval_ms": 300.0})
    interaction = rig.interaction.model_validate(
        {
            "dwell": {"time_ms": 400.0},
            "commands": {
                "swipe_right": "next_slide",
                "dwell": "select",
                "hand_2": "two",
                "enter": "hello",
                "leave": "bye",
            },
            "hand": {"enabled": True, "every_n_pairs": 1, "debounce_pairs": 2},
            "tuio": {"enabled": True, "port": tuio_port},
        }
    )
    return rig.model_copy(
        update={"outputs": rig.outputs.model_copy(update={"zmq": zmq_cfg}), "interaction": interaction}
    )


@pytest.fixture(scope="module")
def session(simulated_rig, renderer):
    """Image sets of the scripted session and the wall x where the swipe starts and ends."""
    rng = np.random.default_rng(41)
    stage = Stage.from_rig(simulated_rig)

    def pointer_at(x_m: float, y_m: float):
        pose = pose_aimed_at(
            stage.hand_m, renderer.wall.from_wall_m(np.array([x_m, y_m])), simulated_rig.pointer.length_m
        )
        return [renderer.render(i, pose, rng).image for i in range(2)]

    empty = [renderer.render(i, None, rng).image for i in range(2)]
    hands = HandRenderer(renderer, 0)
    pose = random_hand_pose(2, np.random.default_rng(5), 1920, 1080)
    hand = [hands.render(pose, rng).image, empty[1]]
    start_x, end_x, y = 1.2, 1.9, 0.5
    rest_a = pointer_at(start_x, y)
    swipe = [
        pointer_at(start_x + (end_x - start_x) * s, y) for s in minimum_jerk(np.arange(1, 7) / 7.0)
    ]  # 0.23 s at 30 pairs/s
    rest_b = pointer_at(end_x, y)
    # The hand stays for 8 pairs; debouncing needs two in a row before the first hand message.
    sets = [empty] * 3 + [hand] * 8 + [empty] * 2 + [rest_a] * 24 + swipe + [rest_b] * 12 + [empty] * 10
    return sets, start_x, end_x, hands.render(pose, rng).palm_px


def test_every_event_reaches_a_subscriber_and_tuio(simulated_rig, session, tmp_path):
    sets, start_x, end_x, hand_centre = session
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    udp.bind(("127.0.0.1", 0))
    udp.setblocking(False)
    endpoint = f"ipc://{tmp_path}/pub.sock"
    rig = _rig(simulated_rig, endpoint, udp.getsockname()[1])
    ctx = zmq.Context()
    sub = ctx.socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"")
    sub.connect(endpoint)
    extension = create(rig)
    assert extension is not None
    count = len(sets) + 15  # a few pairs of the empty room at the end, after the loop restarts
    sets = sets + [sets[-1]] * 15
    # Every pair is served, late if the machine stalls (this is about the events, not about drops),
    # and only once the subscriber is known to be connected.
    sources: list[GatedPairSource] = []

    def source_for(r):
        sources.append(GatedPairSource(r, sets, rate_hz=RATE_HZ, count=count, drop_late=False))
        return sources[-1]

    pipeline = Pipeline(rig, source_for, lambda r: Publisher(r.outputs.zmq), extensions=[extension])
    messages, bundles = [], []
    try:
        started = time.monotonic()
        pipeline.start()
        wait_for_status(sub)
        sources[0].open()

        def receive(wait_ms: int) -> bool:
            """Whatever has arrived (waiting up to ``wait_ms`` for the first), and whether anything had."""
            got = False
            if sub.poll(wait_ms):
                while sub.poll(0):
                    topic, payload = sub.recv_multipart()
                    messages.append((topic.decode(), json.loads(payload), decode(topic, payload)))
                    got = True
            while True:
                try:
                    bundles.append(decode_bundle(udp.recv(65536)))
                    got = True
                except BlockingIOError:
                    return got

        # Until every pair has been processed and its messages handed to the publisher (not for a
        # time: a loaded machine serves the pairs late); the 120 s only guard against a hang.
        guard = time.monotonic() + 120.0
        while time.monotonic() < guard and not (pipeline.pairs_processed >= count and pipeline.backlog <= 0):
            receive(10)
        # Then until a status built after that: the publisher sends in order, so every pair's
        # messages are in by then (and the TUIO bundles, sent as the pairs were processed).
        done_s = time.monotonic() - started
        while time.monotonic() < guard and not any(t == "status" and d["uptime_s"] > done_s for t, d, _ in messages):
            receive(10)
        receive(0)
    finally:
        pipeline.stop()
        sub.close(0)
        ctx.term()
        udp.close()
    assert pipeline.failure is None
    topics = {t for t, _, _ in messages}
    assert set(TOPICS) <= topics, f"missing {set(TOPICS) - topics}"

    by_topic = {t: [d for tt, d, _ in messages if tt == t] for t in TOPICS}
    # The hand shown before the pointer appears has two fingers; later the hand holding the
    # pointer is seen too, as a fist (it is skin, and it moves).
    first_pointer = min(d["sequence"] for d in by_topic["pointer"])
    shown = [h for h in by_topic["hand"] if h["present"] and h["sequence"] < first_pointer]
    assert len(shown) >= 3 and {h["fingers"] for h in shown} == {2}
    assert all(abs(h["image_x_px"] - hand_centre[0]) < 40 and abs(h["image_y_px"] - hand_centre[1]) < 40 for h in shown)
    assert not by_topic["hand"][-1]["present"]

    (enter,) = by_topic["enter"]
    (leave,) = by_topic["leave"]
    assert leave["reason"] == "lost" and leave["cursor_id"] == enter["cursor_id"]
    assert abs(enter["wall_x_m"] - start_x) < 0.02
    dwells = by_topic["dwell"]
    assert len(dwells) == 1, "one dwell per rest: the rest after the gesture is no click"
    assert abs(dwells[0]["wall_x_m"] - start_x) < 0.01 and dwells[0]["dwell_ms"] >= 400.0
    (gesture,) = by_topic["gesture"]
    assert gesture["name"] == "swipe_right" and gesture["score"] > 0.9
    assert abs(gesture["start_wall_x_m"] - start_x) < 0.05 and abs(gesture["wall_x_m"] - end_x) < 0.05
    assert gesture["start_ns"] < gesture["end_ns"] <= gesture["capture_ns"]
    commands = [(c["command"], c["trigger"]) for c in by_topic["command"]]
    assert commands == [
        ("two", "hand_2"),
        ("hello", "enter"),
        ("select", "dwell"),
        ("next_slide", "swipe_right"),
        ("bye", "leave"),
    ]

    # Hits are smoothed, with the raw position alongside and the pointing session's id.
    hits = by_topic["hit"]
    assert all(h["raw_wall_x_m"] is not None for h in hits)
    assert any(h["cursor_id"] == enter["cursor_id"] for h in hits)
    status = [d for d in by_topic["status"] if d.get("interaction")][-1]["interaction"]
    assert status["gestures"] == {"swipe_right": 1} and status["tuio_packets"] > 0

    # TUIO: a cursor whose session id is the cursor_id, moving right, then removed.
    sets_ = [args for _, msgs in bundles for address, args in msgs if address == "/tuio/2Dcur" and args[0] == "set"]
    assert sets_ and {s[1] for s in sets_} == {enter["cursor_id"]}
    xs = [s[2] for s in sets_]
    assert xs[0] == pytest.approx(start_x / rig_width(rig), abs=0.01)
    assert xs[-1] == pytest.approx(end_x / rig_width(rig), abs=0.01)
    assert all(0.0 <= s[3] <= 1.0 for s in sets_)
    assert sets_[0][3] == pytest.approx(1.0 - 0.5 / 0.9144, abs=0.02)  # y from the top
    last_alive = [args for _, msgs in bundles for address, args in msgs if args and args[0] == "alive"][-1]
    assert last_alive == ["alive"]
    frames = [args[1] for _, msgs in bundles for address, args in msgs if args and args[0] == "fseq"]
    assert frames == sorted(frames) and len(set(frames)) == len(frames)


def rig_width(rig) -> float:
    from trackerd.config.rig_geometry import wall_frame

    return wall_frame(rig.wall).width_m
