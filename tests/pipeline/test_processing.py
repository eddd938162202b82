"""Which fixes the calibration health measures (the schedule alone; the whole stage is test_daemon's)."""

from __future__ import annotations

import dataclasses

import numpy as np

from trackerd.pipeline.processing import HEALTH_EVERY, measures_health


def test_every_fourth_fix_with_a_line_is_measured_rejected_or_not(simulated_rig, renderer, rendered_sweep):
    from trackerd.locator import Locator

    image_sets, _ = rendered_sweep
    locator = Locator(simulated_rig)
    fixes = [locator.locate(images) for images in image_sets]
    with_line = next(f for f in fixes if f.line is not None)
    assert [measures_health(i, with_line) for i in range(2 * HEALTH_EVERY)] == [True, False, False, False] * 2
    # Rejected fixes have a line too (a bumped camera's): they are what the record is for.
    assert measures_health(0, dataclasses.replace(with_line, status="rejected"))
    blank = locator.locate([np.zeros_like(image) for image in image_sets[0]])
    assert blank.line is None and not measures_health(0, blank)
