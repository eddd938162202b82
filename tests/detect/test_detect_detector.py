"""The detector on synthetic frames, exact truth: centroids, Bayer offsets, clutter, tracking."""

from __future__ import annotations

import numpy as np
import pytest
from detect_synthetic import BLUE, RED, Scene, Shape, pointer

from trackerd.config.models import DetectorConfig, PointerConfig
from trackerd.detect import ColourEndDetector, detect_ends
from trackerd.errors import ImageError

FORMATS = ("BayerRG8", "BayerGB8", "BayerGR8", "BayerBG8", "RGB8", "BGR8")
POINTER = PointerConfig(length_m=0.45, end_diameter_m=0.04)
CFG = DetectorConfig()


def detector(pixel_format: str, scene: Scene, cfg: DetectorConfig = CFG) -> ColourEndDetector:
    return ColourEndDetector(cfg, pixel_format, scene.width, scene.height, POINTER)


@pytest.mark.parametrize("pixel_format", FORMATS)
def test_centroid_has_no_bias_in_any_pixel_format(pixel_format: str, detect_rng) -> None:
    """Over many sub-pixel positions, the mean signed error is a few hundredths of a pixel.

    In a Bayer mosaic the R and B samples sit at different corners of the 2x2 cell
    (BayerRG8: R at (0, 0), B at (1, 1)); placing a sample anywhere but at its own
    pixel would shift one colour's centroids by half a pixel in x and y for some
    of the four layouts. Every layout and both colours are checked against the
    exact coverage centroid.
    """
    errors = {"red": [], "blue": []}
    for _ in range(16):
        x, y = 50 + 4 * detect_rng.random(), 60 + 4 * detect_rng.random()
        scene = Scene(shapes=pointer(x, y, 70.0, 12.0, 6.5 + 3 * detect_rng.random()))
        frame, truth = scene.render(pixel_format, detect_rng)
        result = detector(pixel_format, scene).detect(frame)
        for colour, true in zip(("red", "blue"), truth, strict=True):
            end = result.end(colour)
            assert end.found, end.reason
            errors[colour].append(end.centroid_px - true)
    for colour, errs in errors.items():
        e = np.array(errs)
        assert np.all(np.abs(e.mean(axis=0)) < 0.06), (colour, e.mean(axis=0))
        assert np.hypot(e[:, 0], e[:, 1]).max() < 0.25, colour


def test_shading_does_not_pull_the_centre(detect_rng) -> None:
    """A ball lit from above is brighter at the top: the centre must not follow the light."""
    errors = []
    for _ in range(12):
        x, y = 60 + 4 * detect_rng.random(), 60 + 4 * detect_rng.random()
        scene = Scene(shapes=pointer(x, y, 60.0, 20.0, 9.0, shading=0.38))
        frame, truth = scene.render("BayerRG8", detect_rng)
        result = detector("BayerRG8", scene).detect(frame)
        errors += [result.red.centroid_px - truth[0], result.blue.centroid_px - truth[1]]
    e = np.array(errors)
    # Without the coverage weights, intensity weighting pulls these about 0.4 px upwards.
    assert abs(e[:, 1].mean()) < 0.15
    assert np.hypot(e[:, 0], e[:, 1]).max() < 0.3


def test_area_bbox_and_the_reports_bbox_midpoint(detect_rng) -> None:
    scene = Scene(shapes=pointer(60.3, 70.6, 60.0, 10.0, 9.0))
    frame, truth = scene.render("BayerGB8", detect_rng)
    weighted = detector("BayerGB8", scene).detect(frame)
    bbox = detector("BayerGB8", scene, DetectorConfig(centroid="bbox")).detect(frame)
    for w_end, b_end, true in (
        (weighted.red, bbox.red, truth[0]),
        (weighted.blue, bbox.blue, truth[1]),
    ):
        assert abs(w_end.area_px - np.pi * 81) < 0.08 * np.pi * 81
        x0, y0, x1, y1 = b_end.bbox_px
        assert np.allclose(b_end.centroid_px, [(x0 + x1) / 2, (y0 + y1) / 2])  # eq. 12
        assert np.hypot(*(b_end.centroid_px - true)) < 1.5
        assert x1 - x0 >= 14 and y1 - y0 >= 14
        assert w_end.bbox_px == b_end.bbox_px
        assert 0 < w_end.score <= 1 and w_end.reason is None


def test_a_sticker_of_the_right_size_loses_to_the_pointers_end(detect_rng) -> None:
    """A red disc like the red ball, but too far from the blue ball to be on one pointer."""
    scene = Scene(
        width=320,
        height=200,
        shapes=[*pointer(200.4, 120.2, 40.0, 25.0, 7.0), Shape(30.5, 30.5, RED, radius=7.2)],
        rods=[(200.4, 120.2, 240.4, 145.2, 1.5)],
    )
    frame, truth = scene.render("BayerRG8", detect_rng)
    result = detector("BayerRG8", scene).detect(frame)
    assert np.hypot(*(result.red.centroid_px - truth[0])) < 0.3
    assert np.hypot(*(result.blue.centroid_px - truth[1])) < 0.3


def test_the_rod_decides_between_two_candidates_within_reach(detect_rng) -> None:
    """Two red balls both close enough to the blue one: the one joined to it by a rod wins."""
    for decoy_first in (True, False):
        real = Shape(120.3, 100.6, RED, radius=7.0)
        decoy = Shape(200.5, 70.2, RED, radius=7.0)
        blue = Shape(160.2, 130.4, BLUE, radius=7.0)
        shapes = [decoy, real, blue] if decoy_first else [real, decoy, blue]
        scene = Scene(width=300, height=200, shapes=shapes, rods=[(120.3, 100.6, 160.2, 130.4, 2.0)])
        frame, truth = scene.render("BayerRG8", detect_rng)
        true_red = truth[shapes.index(real)]
        result = detector("BayerRG8", scene).detect(frame)
        assert np.hypot(*(result.red.centroid_px - true_red)) < 0.3


def test_strips_and_posters_are_not_ends(detect_rng) -> None:
    scene = Scene(
        width=320,
        height=200,
        shapes=[
            Shape(80, 40, RED, half_size=(60, 2.5)),  # a strip of red tape
            Shape(250, 120, BLUE, half_size=(45, 40)),  # a poster bigger than max_area_px below
        ],
    )
    frame, _ = scene.render("BayerRG8", detect_rng)
    cfg = DetectorConfig(max_area_px=3000)
    result = detector("BayerRG8", scene, cfg).detect(frame)
    assert not result.red.found and not result.blue.found
    assert result.red.reason is not None and "elongated" in result.red.reason
    assert "none ball-shaped" in result.red.reason
    assert result.blue.reason is not None and "too large" in result.blue.reason
    assert result.red.centroid_px is None and result.red.bbox_px is None


def test_an_empty_room_says_why(detect_rng) -> None:
    scene = Scene()
    frame, _ = scene.render("BayerBG8", detect_rng)
    result = detector("BayerBG8", scene).detect(frame)
    assert result.red.reason == "no red pixels above threshold"
    assert result.blue.reason == "no blue pixels above threshold"
    assert result.search == "full"


def test_one_end_hidden_still_reports_the_other(detect_rng) -> None:
    scene = Scene(shapes=[Shape(80.2, 70.7, BLUE, radius=8.0)])
    frame, truth = scene.render("RGB8", detect_rng)
    result = detect_ends(frame, "RGB8", CFG, POINTER)
    assert not result.red.found and result.blue.found
    assert np.hypot(*(result.blue.centroid_px - truth[0])) < 0.2
    assert result.end("blue") is result.blue
    with pytest.raises(ValueError, match="red"):
        result.end("green")


def test_tracking_searches_a_window_and_follows_the_pointer(detect_rng) -> None:
    det = None
    for step in range(12):
        x, y = 60.0 + 2.7 * step, 50.0 + 1.3 * step
        scene = Scene(width=480, height=320, shapes=pointer(x, y, 55.0, 20.0, 8.0))
        frame, truth = scene.render("BayerRG8", detect_rng)
        det = det or detector("BayerRG8", scene)
        result = det.detect(frame)
        assert result.search == ("full" if step == 0 else "window")
        assert np.hypot(*(result.red.centroid_px - truth[0])) < 0.3
        assert np.hypot(*(result.blue.centroid_px - truth[1])) < 0.3
    assert det is not None
    # A jump beyond the tracking window (track_window_px): found again by the full search.
    scene = Scene(width=480, height=320, shapes=pointer(330.0, 260.0, 60.0, -15.0, 8.0))
    frame, truth = scene.render("BayerRG8", detect_rng)
    result = det.detect(frame)
    assert result.search == "full"
    assert np.hypot(*(result.red.centroid_px - truth[0])) < 0.3
    assert det.detect(frame).search == "window"
    det.reset()
    assert det.detect(frame).search == "full"


def test_a_jump_predicted_off_the_frame_falls_back_to_the_full_search(detect_rng) -> None:
    """Unrelated images in a row (imported stills): a jump across the frame predicts the next
    position far beyond its edge, where only the near window still reaches in."""
    det = None
    for x, y in ((60.0, 60.0), (400.0, 250.0), (70.0, 80.0), (75.0, 82.0)):
        scene = Scene(width=480, height=320, shapes=pointer(x, y, 40.0, 10.0, 8.0))
        frame, truth = scene.render("BayerRG8", detect_rng)
        det = det or detector("BayerRG8", scene)
        result = det.detect(frame)
        assert result.red.found and result.blue.found
        assert np.hypot(*(result.red.centroid_px - truth[0])) < 0.3
        assert np.hypot(*(result.blue.centroid_px - truth[1])) < 0.3


def test_tracking_picks_the_end_out_of_a_crowded_window(detect_rng) -> None:
    """A red sticker right next to where the red ball moves: the ball is still the one measured."""
    det = None
    for step in range(6):
        x = 80.0 + 2.0 * step
        shapes = [*pointer(x, 80.0, 50.0, 15.0, 8.0), Shape(x - 17.0, 80.0, RED, radius=3.5)]
        scene = Scene(width=240, height=160, shapes=shapes)
        frame, truth = scene.render("BayerRG8", detect_rng)
        det = det or detector("BayerRG8", scene)
        result = det.detect(frame)
        assert result.search == ("full" if step == 0 else "window")
        assert np.hypot(*(result.red.centroid_px - truth[0])) < 0.3


def test_frames_that_do_not_match_the_camera_are_refused(detect_rng) -> None:
    det = ColourEndDetector(CFG, "BayerRG8", 64, 48)
    with pytest.raises(ImageError, match="does not match"):
        det.detect(np.zeros((48, 64, 3), dtype=np.uint8))
    with pytest.raises(ImageError, match="does not match"):
        det.detect(np.zeros((48, 64), dtype=np.uint16))


@pytest.mark.parametrize("gap_px", [4.0, 12.0])
def test_a_ball_beside_a_large_poster_of_its_colour(gap_px: float, detect_rng) -> None:
    """The poster's window is measured at half resolution; the ball in it must survive that."""
    radius = 7.0
    poster = Shape(150.0, 100.0, RED, half_size=(50.0, 45.0))
    shapes = [poster, *pointer(150.0 - 50.0 - gap_px - radius, 100.3, -60.0, 20.0, radius)]
    scene = Scene(width=320, height=220, shapes=shapes)
    frame, truth = scene.render("BayerRG8", detect_rng)
    result = detector("BayerRG8", scene).detect(frame)
    assert np.hypot(*(result.red.centroid_px - truth[1])) < 0.2
    assert np.hypot(*(result.blue.centroid_px - truth[2])) < 0.2


@pytest.mark.parametrize("pixel_format", ["BayerRG8", "BayerGB8", "BayerGR8", "BayerBG8"])
def test_centroid_follows_sub_pixel_offsets_without_error_at_the_bayer_period(pixel_format: str, detect_rng) -> None:
    """Regression: the centre measured from own-colour samples only had a periodic error.

    Those samples are one pixel in four, on a lattice of period 2 px, so as a ball
    moves by sub-pixel steps the coverage they see changes with its phase on the
    lattice: the centre of a noise-free ball moved in sixteenths of the period
    wobbled with period 2 px, amplitude up to 0.12 px (errors up to 0.12 px, every
    layout). Measured from every pixel of the rim: amplitude and errors below 0.035 px.
    """
    steps = np.arange(16) / 8.0
    for axis in (0, 1):
        for radius in (6.3, 8.7):
            errors: dict[str, list[float]] = {"red": [], "blue": []}
            for step in steps:
                shift = np.array([step, 0.0]) if axis == 0 else np.array([0.0, step])
                x, y = np.array([60.2, 50.4]) + shift
                scene = Scene(width=200, height=120, shapes=pointer(x, y, 70.0, 20.0, radius))
                frame, truth = scene.render(pixel_format, detect_rng, noise=0.0)
                result = detector(pixel_format, scene).detect(frame)
                for colour, true in zip(("red", "blue"), truth, strict=True):
                    errors[colour].append(float((result.end(colour).centroid_px - true)[axis]))
            for colour, errs in errors.items():
                e = np.array(errs)
                wobble = 2.0 * abs(np.mean(e * np.exp(1j * np.pi * steps)))
                assert wobble < 0.045, (colour, axis, radius, wobble)
                assert np.abs(e).max() < 0.05, (colour, axis, radius, e)


def test_own_samples_only_still_available(detect_rng) -> None:
    """``rim_pixels=False``: the centre from the own-colour samples, as before (faster, coarser)."""
    scene = Scene(shapes=pointer(60.3, 50.6, 70.0, 20.0, 8.0))
    frame, truth = scene.render("BayerRG8", detect_rng)
    fast = ColourEndDetector(CFG, "BayerRG8", scene.width, scene.height, POINTER, rim_pixels=False)
    every = detector("BayerRG8", scene)
    a, b = fast.detect(frame), every.detect(frame)
    for colour, true in zip(("red", "blue"), truth, strict=True):
        assert np.hypot(*(a.end(colour).centroid_px - true)) < 0.3
        assert np.hypot(*(b.end(colour).centroid_px - true)) < 0.1
        assert not np.allclose(a.end(colour).centroid_px, b.end(colour).centroid_px)
