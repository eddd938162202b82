"""Finger counts on rendered hands (0-5 fingers, turned, tilted, scaled, at 1.5-3 m) in the left camera."""

from __future__ import annotations

import numpy as np
import pytest

from trackerd.config.interaction import HandConfig
from trackerd.interaction.hand import FingerDebouncer, HandDetector, half_resolution_rgb
from trackerd.sim.hand import HandRenderer, random_hand_pose


@pytest.fixture(scope="module")
def hands(renderer):
    return HandRenderer(renderer, 0)


def test_half_resolution_takes_each_bayer_cell_as_one_pixel():
    image = np.zeros((4, 4), np.uint8)
    image[0::2, 0::2], image[0::2, 1::2], image[1::2, 0::2], image[1::2, 1::2] = 200, 100, 50, 10  # R G G B
    assert half_resolution_rgb(image, "BayerRG8").tolist() == [[[200, 75, 10]] * 2] * 2


def test_finger_counts_on_rendered_hands(hands):
    # 36 hands, six of each count; `trackerd bench interaction` counts 120 and reports the figures.
    rng = np.random.default_rng(8)
    detector = HandDetector(HandConfig(enabled=True))
    detector.learn_background(hands.empty(rng), hands.pixel_format)
    right = {f: 0 for f in range(6)}
    for k in range(36):
        pose = random_hand_pose(k % 6, rng, 1920, 1080)
        rendered = hands.render(pose, rng)
        seen = detector.look(rendered.image, rendered.pixel_format)
        assert seen is not None, f"no hand found: {pose}"
        assert np.hypot(*(np.array(seen.centre_px) - rendered.palm_px)) < 0.6 * seen.palm_radius_px + 6
        right[pose.fingers] += seen.fingers == pose.fingers
    assert sum(right.values()) >= 30, right
    assert all(right[f] >= 5 for f in range(1, 6)), right


def test_an_empty_room_and_skin_coloured_things_that_never_move_are_no_hand(hands):
    rng = np.random.default_rng(9)
    detector = HandDetector(HandConfig(enabled=True))
    detector.learn_background(hands.empty(rng), hands.pixel_format)
    assert detector.look(hands.empty(rng), hands.pixel_format) is None


def test_debouncing_publishes_a_count_seen_on_consecutive_looks():
    debouncer = FingerDebouncer(3)
    assert [debouncer.add(n) for n in (2, 2, 3, 2, 2, 2, 2)] == [False, False, False, False, False, True, False]
    assert debouncer.stable == 2
