"""The one conversion to the wire: a pair's fix and its extensions' events, in the order published.

A real fix of the simulated rig (located from projected centroids), with each
kind of extension event and a smoothed hit, turned into messages as the
publishing thread does; and two extensions' answers merged as the processing
thread merges them.
"""

from __future__ import annotations

import numpy as np
import pytest

from trackerd.locator import Locator
from trackerd.pipeline.events import (
    NOTHING,
    CommandIssued,
    CursorHit,
    Dwelt,
    Entered,
    Gestured,
    HandSeen,
    Left,
    PairEvents,
    WallPoint,
)
from trackerd.publish.from_fix import event_message, messages_from_fix, pair_messages, published_hit
from trackerd.publish.messages import CommandMessage, GestureMessage, HitMessage

CAPTURE_NS = 1_700_000_000_000_000_000
AT = WallPoint(1.25, 0.5, 2600.0, 1080.0)


@pytest.fixture(scope="module")
def located(simulated_rig):
    locator = Locator(simulated_rig)
    front, back = np.array([1.8, 0.45, 1.5]), np.array([1.85, 0.5, 1.95])
    centroids = []
    for camera in locator.cameras:
        front_px, back_px = camera.project(np.array([front, back]))
        centroids.append({locator.front_colour: front_px, locator.back_colour: back_px})
    fix = locator.locate_centroids(tuple(centroids))
    assert fix.status == "hit"
    return locator, fix


def test_without_events_a_pair_is_published_as_the_locator_found_it(located):
    locator, fix = located
    plain = messages_from_fix(fix, locator, sequence=7, capture_ns=CAPTURE_NS)
    assert pair_messages(fix, locator.front_colour, sequence=7, capture_ns=CAPTURE_NS, events=NOTHING) == plain
    assert published_hit(fix) is fix.hit


def test_a_smoothed_hit_keeps_the_located_one_as_raw(located):
    locator, fix = located
    plain = messages_from_fix(fix, locator, sequence=7, capture_ns=CAPTURE_NS)[1]
    assert isinstance(plain, HitMessage)
    events = PairEvents(hit=CursorHit(3, AT, smoothed_on_wall=False))
    hit = pair_messages(fix, locator.front_colour, sequence=7, capture_ns=CAPTURE_NS, events=events)[1]
    assert isinstance(hit, HitMessage)
    assert (hit.wall_x_m, hit.wall_y_m, hit.display_x_px, hit.display_y_px) == (1.25, 0.5, 2600.0, 1080.0)
    assert hit.on_wall is False and hit.cursor_id == 3
    assert (hit.raw_wall_x_m, hit.raw_wall_y_m) == (plain.wall_x_m, plain.wall_y_m)
    assert (hit.raw_display_x_px, hit.raw_display_y_px) == (plain.display_x_px, plain.display_y_px)
    assert hit.distance_m == plain.distance_m and hit.ray_gap_mm == plain.ray_gap_mm
    # Smoothing off: the located position, only the session added.
    unsmoothed = pair_messages(
        fix, locator.front_colour, sequence=7, capture_ns=CAPTURE_NS, events=PairEvents(hit=CursorHit(3, None))
    )[1]
    assert unsmoothed == plain.model_copy(update={"cursor_id": 3})


def test_events_go_before_and_after_the_pair_s_own_messages(located):
    locator, fix = located
    left = Left(sequence=6, capture_ns=CAPTURE_NS - 1, cursor_id=2, at=AT, reason="lost", duration_ms=12.5)
    entered = Entered(sequence=7, capture_ns=CAPTURE_NS, cursor_id=3, at=AT)
    hand = HandSeen(
        sequence=5,
        capture_ns=CAPTURE_NS - 2,
        camera="left",
        present=True,
        fingers=2,
        fingers_now=2,
        centre_px=(100.0, 200.0),
        area_px=5000.0,
    )
    events = PairEvents(earlier=[left], events=[entered, hand])
    topics = [
        (m.topic, m.sequence)
        for m in pair_messages(fix, locator.front_colour, sequence=7, capture_ns=CAPTURE_NS, events=events)
    ]
    assert topics == [("leave", 6), ("pointer", 7), ("hit", 7), ("enter", 7), ("hand", 5)]


def test_a_second_extension_s_answer_wraps_the_first_s():
    one = PairEvents(earlier=["a0"], hit=CursorHit(1, None), events=["a1"])  # type: ignore[list-item]
    two = PairEvents(earlier=["b0"], events=["b1"])  # type: ignore[list-item]
    merged = one.then(two)
    assert (list(merged.earlier), merged.hit, list(merged.events)) == (["b0", "a0"], CursorHit(1, None), ["a1", "b1"])
    assert one.then(NOTHING) is one and NOTHING.then(one) == one


def test_each_event_becomes_its_topic_s_message():
    gesture = Gestured(
        sequence=9,
        capture_ns=CAPTURE_NS,
        cursor_id=4,
        at=AT,
        name="swipe_left",
        score=0.912345,
        start_ns=CAPTURE_NS - 250_000_000,
        end_ns=CAPTURE_NS,
        path_m=0.61,
        start_x_m=1.9,
        start_y_m=0.5,
        runner_up=None,
        runner_up_score=0.0,
    )
    message = event_message(gesture)
    assert isinstance(message, GestureMessage)
    assert (message.score, message.duration_ms, message.runner_up_score) == (0.9123, 250.0, None)
    assert (message.start_wall_x_m, message.display_x_px, message.cursor_id) == (1.9, 2600.0, 4)
    dwell = event_message(Dwelt(sequence=9, capture_ns=CAPTURE_NS, cursor_id=4, at=AT, dwell_ms=800.0))
    assert (dwell.topic, dwell.dwell_ms) == ("dwell", 800.0)  # type: ignore[attr-defined]
    command = event_message(
        CommandIssued(sequence=9, capture_ns=CAPTURE_NS, command="back", trigger="swipe_left", cause=gesture)
    )
    assert isinstance(command, CommandMessage)
    assert (command.trigger_topic, command.cursor_id, command.wall_x_m) == ("gesture", 4, 1.25)
    hand = HandSeen(
        sequence=9,
        capture_ns=CAPTURE_NS,
        camera="left",
        present=False,
        fingers=3,
        fingers_now=1,
        centre_px=(1.0, 2.0),
        area_px=10.0,
    )
    by_hand = event_message(CommandIssued(sequence=9, capture_ns=CAPTURE_NS, command="c", trigger="hand_3", cause=hand))
    assert isinstance(by_hand, CommandMessage)
    assert (by_hand.trigger_topic, by_hand.cursor_id, by_hand.wall_x_m) == ("hand", None, None)
