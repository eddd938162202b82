"""The centre from every pixel, both ends at once on flat arrays, against the plain reference.

trackerd.detect.coverage and trackerd.detect.window_measure measure both ends together on
flat arrays where a neighbour is an index offset; a wrong offset or a stale
buffer shifts centres by hundredths of a pixel, which the accuracy tests would
not single out. So on synthetic frames that exercise every rule (a rod across a
ball, a dark background behind part of a rim, shading, all four Bayer layouts)
the results must equal those of the first, plain implementation
(coverage_reference.py) to float32 rounding.
"""

from __future__ import annotations

import numpy as np
import pytest
from coverage_reference import rim_centre
from detect_synthetic import BLUE, RED, Scene, Shape, pointer

from trackerd.config.models import DetectorConfig, PointerConfig
from trackerd.detect import ColourEndDetector
from trackerd.detect.centroid import measure, sample
from trackerd.detect.colour import Threshold, sample_grid
from trackerd.detect.coverage import rim_centres
from trackerd.detect.flat import WorkspaceCache
from trackerd.detect.window_measure import ANY_SHAPE, measure_windows, window_interior, window_origin

BAYER = ("BayerRG8", "BayerGB8", "BayerGR8", "BayerBG8")
CFG = DetectorConfig()
POINTER = PointerConfig(length_m=0.45, end_diameter_m=0.04)
THRESHOLDS = {
    "red": Threshold(CFG.red.min_excess, CFG.red.min_value),
    "blue": Threshold(CFG.blue.min_excess, CFG.blue.min_value),
}
DARK = (0.08, 0.08, 0.09)
WHITE = (0.98, 0.98, 0.98)
REDDISH = (0.55, 0.38, 0.36)


def scenes(rng: np.random.Generator) -> list[Scene]:
    """Pointers with a rod into each ball, some shaded, a dark or a reddish panel behind the lower
    half of the red ball, a thin white line touching the blue ball (pixels brighter than the
    background beside them)."""
    out = []
    for k in range(4):
        x, y = 60.0 + 5.0 * rng.random(), 55.0 + 5.0 * rng.random()
        dx, dy = 70.0 + 10.0 * rng.random(), 20.0 * rng.random() - 10.0
        radius = 6.0 + 4.0 * rng.random()
        shapes = pointer(x, y, dx, dy, radius, shading=0.3 * (k % 2))
        if k >= 2:  # a dark display behind the lower half of the red ball's rim
            panel = Shape(x, y + 2.0 * radius, DARK, half_size=(2.0 * radius, 1.5 * radius))
            shapes.insert(0, panel)
        else:  # a reddish surface there, faintly of the end's colour
            panel = Shape(x, y + 2.0 * radius, REDDISH, half_size=(2.0 * radius, 1.5 * radius))
            shapes.insert(0, panel)
        line = Shape(x + dx + radius + 0.8, y + dy, WHITE, half_size=(0.6, 0.7 * radius))
        shapes.insert(0, line)
        out.append(Scene(width=200, height=130, shapes=shapes, rods=[(x, y, x + dx, y + dy, 2.0)]))
    return out


def reference(frame, grid, colour: str, region) -> tuple[float, float, float]:
    """The end in ``region`` measured as the detector did end by end: own samples, then rim."""
    samples = sample(frame, grid, colour, THRESHOLDS[colour], region)
    m = measure(samples, True)
    assert m is not None and m.rim is not None and not m.on_border
    centre = rim_centre(frame, grid, m.rim)
    assert centre is not None
    return centre


@pytest.mark.parametrize("pixel_format", BAYER)
def test_flat_arrays_compute_what_the_plain_reference_computes(pixel_format: str, detect_rng) -> None:
    for scene in scenes(detect_rng):
        frame, _ = scene.render(pixel_format, detect_rng)
        grid = sample_grid(pixel_format, scene.width, scene.height)
        cache = WorkspaceCache()
        half = 9
        ends, regions, expected = [], [], []
        for colour in ("red", "blue"):
            shape = next(s for s in scene.shapes if s.rgb == (RED if colour == "red" else BLUE))
            dr, dc = grid.offset(colour)
            row, col = round((shape.y - dr) / 2.0), round((shape.x - dc) / 2.0)
            region = (row - half, row + half + 1, col - half, col + half + 1)
            ends.append((colour, float(2 * col + dc), float(2 * row + dr)))
            regions.append(region)
            expected.append(reference(frame, grid, colour, region))

        # Both ends at once from the windows (the tracking path and the chosen blobs).
        found = measure_windows(frame, grid, ends, half, THRESHOLDS, ANY_SHAPE, cache)
        assert found is not None
        for m, (x, y, area) in zip(found, expected, strict=True):
            assert abs(m.x_px - x) < 2e-4 and abs(m.y_px - y) < 2e-4, (m.x_px - x, m.y_px - y)
            assert abs(m.area_px - area) < 1e-3 * area

        # The own samples' centre alone (rim_pixels=False), both ends at once.
        own = measure_windows(frame, grid, ends, half, THRESHOLDS, ANY_SHAPE, cache, every_pixel=False)
        assert own is not None
        for m, (colour, *_), region in zip(own, ends, regions, strict=True):
            expected_own = measure(sample(frame, grid, colour, THRESHOLDS[colour], region), True)
            assert expected_own is not None
            assert abs(m.x_px - expected_own.x_px) < 2e-4 and abs(m.y_px - expected_own.y_px) < 2e-4
            assert abs(m.area_px - expected_own.area_px) < 1e-3 * expected_own.area_px
            assert m.bbox_px == expected_own.bbox_px

        # Both ends at once from what the own samples left (the other blobs' path).
        rims = [
            measure(sample(frame, grid, c, THRESHOLDS[c], r), True).rim
            for (c, *_), r in zip(ends, regions, strict=True)
        ]
        for got, (x, y, area) in zip(rim_centres(frame, grid, rims, cache), expected, strict=True):
            assert got is not None
            assert abs(got[0] - x) < 2e-4 and abs(got[1] - y) < 2e-4
            assert abs(got[2] - area) < 1e-3 * area


def test_the_detector_gives_the_reference_centres_searching_and_tracking(detect_rng) -> None:
    """Full search (chosen blobs measured together) and tracking (windows) match the reference."""
    det = None
    for step in range(4):
        shapes = pointer(70.3 + 2.1 * step, 60.7 + 1.2 * step, 80.0, 15.0, 8.0)
        scene = Scene(width=240, height=150, shapes=shapes)
        frame, _ = scene.render("BayerRG8", detect_rng)
        det = det or ColourEndDetector(CFG, "BayerRG8", scene.width, scene.height, POINTER)
        result = det.detect(frame)
        assert result.search == ("full" if step == 0 else "window")
        grid = det.grid
        for colour in ("red", "blue"):
            end = result.end(colour)
            dr, dc = grid.offset(colour)
            x, y = end.centroid_px
            row, col = round((y - dr) / 2.0), round((x - dc) / 2.0)
            x, y, area = reference(frame, grid, colour, (row - 8, row + 9, col - 8, col + 9))
            assert np.allclose(end.centroid_px, (x, y), atol=2e-4)
            assert abs(end.area_px - area) < 1e-3 * area


def test_rims_at_the_frame_edge_keep_the_own_samples_centre(detect_rng) -> None:
    """An end whose ring of cells would leave the frame is not measured from every pixel."""
    scene = Scene(width=120, height=90, shapes=pointer(9.0, 45.3, 90.0, 5.0, 7.0))
    frame, _ = scene.render("BayerRG8", detect_rng)
    grid = sample_grid("BayerRG8", scene.width, scene.height)
    rims = [
        measure(sample(frame, grid, "red", THRESHOLDS["red"], (14, 32, 1, 12)), True).rim,
        measure(sample(frame, grid, "blue", THRESHOLDS["blue"], (14, 32, 40, 59)), True).rim,
    ]
    got = rim_centres(frame, grid, rims, WorkspaceCache())
    assert got[0] is None  # the red ball's rim reaches the region's (and frame's) left edge
    assert got[1] is not None


def test_windows_placed_by_the_caller_are_the_ones_measured(detect_rng) -> None:
    """detect_all_cameras hands measure_windows the windows it has placed already (``origins``):
    given window_origin's, for some ends or all, the measurement is the same to the bit; a window
    given elsewhere is measured there (here one without the ball: nothing measured)."""
    x, y, half = 80.0, 60.0, 8
    scene = Scene(width=200, height=130, shapes=pointer(x, y, 70.0, 10.0, 6.0))
    frame, _ = scene.render("BayerRG8", detect_rng)
    grid = sample_grid("BayerRG8", scene.width, scene.height)
    ends = [("red", x, y), ("blue", x + 70.0, y + 10.0)]
    origins = [window_origin(frame.shape, grid, *end, half) for end in ends]
    assert None not in origins
    placed = measure_windows(frame, grid, ends, half, THRESHOLDS, ANY_SHAPE, WorkspaceCache())
    assert placed is not None
    for given in (origins, [None, origins[1]], [origins[0], None]):
        again = measure_windows(frame, grid, ends, half, THRESHOLDS, ANY_SHAPE, WorkspaceCache(), origins=given)
        assert again == placed
    r0, c0, dr, dc = origins[0]
    away = [(r0 + 2 * half + 4, c0, dr, dc), origins[1]]  # below the red ball, clear of it
    assert measure_windows(frame, grid, ends, half, THRESHOLDS, ANY_SHAPE, WorkspaceCache(), origins=away) is None


def test_a_window_is_slid_back_into_the_frame_or_refused() -> None:
    """window_origin against its plain statement (clamp the first cell to the frame, ring included)
    for ends in, at the edges of and beyond a frame, in every Bayer layout."""
    for layout in BAYER:
        grid = sample_grid(layout, 60, 40)
        for half in (1, 4, 9, 13):
            rows = 2 * half + 3
            for colour in ("red", "blue"):
                dr, dc = grid.red if colour == "red" else grid.blue
                for y in np.arange(-5.0, 46.0, 1.5):
                    for x in np.arange(-5.0, 66.0, 2.5):
                        r0 = max(1, min(round((y - dr) / 2.0) - half, (40 - dr) // 2 - rows + 1))
                        c0 = max(1, min(round((x - dc) / 2.0) - half, (60 - dc) // 2 - rows + 1))
                        fits = 2 * r0 - 2 + dr + 2 * rows <= 40 and 2 * c0 - 2 + dc + 2 * rows <= 60
                        got = window_origin((40, 60), grid, colour, float(x), float(y), half)
                        assert got == ((r0, c0, dr, dc) if fits else None)


def test_a_larger_window_measures_what_the_own_window_does_or_nothing(detect_rng) -> None:
    """detect_all_cameras measures every camera's ends in windows of the largest size any needs, with
    each end kept inside the interior of the window its camera would use alone (window_interior).
    Then a larger window gives the own window's result, and refuses whatever the own window would
    not measure: here a red sticker that reaches the own window's border but lies well inside the
    larger one."""
    x, y, radius = 80.0, 60.0, 6.0
    own_half, large_half = 6, 12  # cells
    clean = Scene(width=200, height=130, shapes=pointer(x, y, 70.0, 10.0, radius))
    sticker = Shape(x - 2.0 * own_half - 1.0, y, RED, radius=2.5)  # on the own window's left border
    cluttered = Scene(width=200, height=130, shapes=[*pointer(x, y, 70.0, 10.0, radius), sticker])
    for scene, own_measures in ((clean, True), (cluttered, False)):
        frame, _ = scene.render("BayerRG8", detect_rng)
        grid = sample_grid("BayerRG8", scene.width, scene.height)
        cache = WorkspaceCache()
        ends = [("red", x, y), ("blue", x + 70.0, y + 10.0)]
        own = measure_windows(frame, grid, ends, own_half, THRESHOLDS, ANY_SHAPE, cache)
        inside = [window_interior(frame.shape, grid, *end, own_half) for end in ends]
        assert None not in inside
        guarded = measure_windows(frame, grid, ends, large_half, THRESHOLDS, ANY_SHAPE, cache, within=inside)
        unguarded = measure_windows(frame, grid, ends, large_half, THRESHOLDS, ANY_SHAPE, cache)
        assert (own is not None) == own_measures
        if own_measures:
            assert own is not None and guarded is not None
            for a, b in zip(own, guarded, strict=True):
                assert abs(a.x_px - b.x_px) < 1e-4 and abs(a.y_px - b.y_px) < 1e-4
                assert abs(a.area_px - b.area_px) < 1e-4 * a.area_px and a.bbox_px == b.bbox_px
        else:
            # The own window stops at the sticker; the larger window alone would measure ball and
            # sticker as one end (ANY_SHAPE); the guard refuses it, as the own window does.
            assert guarded is None
            assert unguarded is not None
