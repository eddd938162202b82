"""The colour watch: the status says when something in view comes close to the pointer's colours."""

from __future__ import annotations

import logging
import time

import numpy as np
import pytest

from tests.rooms import BLANK, RED_PICTURE, room, waved
from trackerd.acquisition.memory import MemoryPairSource
from trackerd.calibration.colours import ColourLearner
from trackerd.config.loader import with_learned_colours
from trackerd.locator import Locator
from trackerd.pipeline.colourwatch import WATCH_EVERY_S, ColourWatch
from trackerd.pipeline.daemon import Pipeline
from trackerd.publish import Publisher
from trackerd.publish.messages import ColourWatchPart

pytestmark = pytest.mark.serial  # runs the pipeline on paced sources


def _pairs(renderer, content, count: int, offset: float, seed: int):
    rng = np.random.default_rng(seed)
    for pose in waved(count, offset):
        yield [renderer.render(i, pose, rng, content=content).image for i in range(len(renderer.cameras))]


def _watch(rig, renderer, watch: ColourWatch, content, *, count: int = 2, offset: float = 0.3) -> str | None:
    """Locate and measure ``count`` pairs of the room showing ``content``; the warning after them."""
    locator = Locator(rig, cameras=renderer.cameras)
    for images in _pairs(renderer, content, count, offset, seed=4):
        locator.reset()
        fix = locator.locate(images)
        assert fix.found, fix.reason
        watch.measure(images, ["BayerRG8"] * len(images), fix)
    return watch.warning()


def test_a_red_picture_put_up_after_the_colours_were_learned_is_warned_of_and_the_warning_clears(caplog):
    rig, renderer = room()
    learner = ColourLearner(rig, renderer.cameras, wanted=4)
    for images in _pairs(renderer, BLANK, 4, 0.0, seed=1):
        learner.feed([(cam.camera_id, image, "BayerRG8") for cam, image in zip(renderer.cameras, images, strict=True)])
    learned = with_learned_colours(rig, learner.result("2026-12-02").colours)
    watch = ColourWatch(learned, renderer.cameras)
    assert watch.to_json() is None  # nothing measured yet
    assert _watch(learned, renderer, watch, BLANK) is None
    caplog.set_level(logging.INFO, logger="trackerd.pipeline.colourwatch")
    warning = _watch(learned, renderer, watch, RED_PICTURE, count=3)
    assert warning is not None and warning.startswith("red: something in camera ")
    # Logged once, not at every measurement (the figures in it change every time).
    assert [r.levelno for r in caplog.records] == [logging.WARNING]
    assert "when learned" in warning and "blue:" not in warning
    part = ColourWatchPart.model_validate(watch.to_json())
    assert part.learned and part.warning == warning
    assert part.red.room_excess > part.red.ball_excess > part.red.baseline_excess
    assert part.red.threshold == learned.detector.red.min_excess
    # The picture taken down: the warning goes, and that is logged too.
    assert _watch(learned, renderer, watch, BLANK) is None
    assert [r.levelno for r in caplog.records] == [logging.WARNING, logging.INFO]


def test_without_learned_colours_the_room_at_start_is_the_baseline_and_the_threshold_the_limit():
    rig, renderer = room()
    watch = ColourWatch(rig, renderer.cameras)
    assert _watch(rig, renderer, watch, BLANK) is None
    warning = _watch(rig, renderer, watch, RED_PICTURE)
    assert warning is not None and "at start" in warning and f"the threshold {rig.detector.red.min_excess}" in warning
    assert ColourWatchPart.model_validate(watch.to_json()).red.ball_excess is None


def test_the_watch_measures_a_located_pair_every_few_seconds_only():
    rig, renderer = room()
    images = next(_pairs(renderer, BLANK, 1, 0.5, seed=2))
    fix = Locator(rig, cameras=renderer.cameras).locate(images)
    assert fix.found
    watch = ColourWatch(rig, renderer.cameras)
    start = 10**12
    assert watch.due(fix, start)
    assert not watch.due(fix, start + int(0.5 * WATCH_EVERY_S * 1e9))
    assert watch.due(fix, start + int(1.01 * WATCH_EVERY_S * 1e9))
    # Only where the pointer was located: the balls must be cleared from the room's figure.
    lost = Locator(rig, cameras=renderer.cameras).locate([np.zeros_like(image) for image in images])
    assert not lost.found and not watch.due(lost, start + int(10 * WATCH_EVERY_S * 1e9))


def test_the_daemons_status_carries_the_colour_watch(simulated_rig, rendered_sweep):
    image_sets, _ = rendered_sweep
    count = len(image_sets)
    pipeline = Pipeline(
        simulated_rig,
        lambda r: MemoryPairSource(r, image_sets, rate_hz=None, count=count),
        lambda r: Publisher(r.outputs.zmq.model_copy(update={"endpoints": ("tcp://127.0.0.1:*",)})),
    )
    try:
        pipeline.start()
        deadline = time.monotonic() + 60.0  # a guard only: the loop ends when every pair is published
        while pipeline.pairs_published < count and pipeline.failure is None and time.monotonic() < deadline:
            pipeline.wait(0.02)
        # The watch measures on a thread of its own: until it has.
        while pipeline.colour_watch.to_json() is None and pipeline.failure is None and time.monotonic() < deadline:
            pipeline.wait(0.02)
    finally:
        pipeline.stop()
    assert pipeline.failure is None and pipeline.pairs_published == count
    status = pipeline.build_status(None)
    # The first located pair was measured: the simulated room, whose clutter holds red and blue balls.
    assert status.colours is not None and not status.colours.learned
    assert status.colours.red.threshold == simulated_rig.detector.red.min_excess
    assert status.colours.red.camera in {c.id for c in simulated_rig.cameras}
    assert status.colours.warning is None  # nothing changed since it was first measured
