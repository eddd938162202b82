"""The baselines: OpenCV's demosaic + HSV + inRange + moments, and the report's eq. 12."""

from __future__ import annotations

import numpy as np
import pytest
from detect_synthetic import RED, Scene, Shape, pointer

from trackerd.config.models import DetectorConfig
from trackerd.detect.reference import opencv_reference, report_baseline, to_bgr
from trackerd.pixelformat import to_bgr as pixelformat_to_bgr

FORMATS = ("BayerRG8", "BayerGB8", "BayerGR8", "BayerBG8", "RGB8", "BGR8")


@pytest.mark.parametrize("pixel_format", FORMATS)
def test_baselines_find_lone_balls(pixel_format: str, detect_rng) -> None:
    scene = Scene(shapes=pointer(60.4, 70.7, 70.0, 10.0, 9.0))
    frame, truth = scene.render(pixel_format, detect_rng)
    assert np.array_equal(to_bgr(frame, pixel_format), pixelformat_to_bgr(frame, pixel_format))
    for result in (
        opencv_reference(frame, pixel_format, DetectorConfig()),
        report_baseline(frame, pixel_format, DetectorConfig()),
    ):
        for end, true in ((result.red, truth[0]), (result.blue, truth[1])):
            assert end.found
            # Demosaicing blurs the rim; within a pixel is what these methods can do.
            assert np.hypot(*(end.centroid_px - true)) < 1.0


def test_baselines_are_pulled_by_clutter(detect_rng) -> None:
    """Neither baseline chooses among blobs: a red sticker drags the red end's centre."""
    scene = Scene(
        width=300,
        shapes=[*pointer(200.0, 70.0, 40.0, 20.0, 8.0), Shape(30.0, 30.0, RED, radius=8.0)],
    )
    frame, truth = scene.render("BayerRG8", detect_rng)
    for method in (opencv_reference, report_baseline):
        result = method(frame, "BayerRG8", DetectorConfig())
        assert np.hypot(*(result.red.centroid_px - truth[0])) > 20
    empty, _ = Scene().render("BayerRG8", detect_rng)
    assert not opencv_reference(empty, "BayerRG8", DetectorConfig()).red.found
    assert not report_baseline(empty, "BayerRG8", DetectorConfig()).blue.found
