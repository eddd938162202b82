"""trackerd.detect.margin: a colour's excess per cell, the ball's core and the room's top patch."""

from __future__ import annotations

import numpy as np

from trackerd.detect.colour import sample_grid
from trackerd.detect.margin import Disc, cell_excess, colour_samples, unhidden
from trackerd.pixelformat import BAYER_LAYOUTS


def _mosaic(rgb: np.ndarray, pixel_format: str) -> np.ndarray:
    """A Bayer frame sampling an RGB image (H, W, 3) as ``pixel_format`` lays its colours out."""
    layout = BAYER_LAYOUTS[pixel_format]
    out = np.empty(rgb.shape[:2], dtype=np.uint8)
    for (dr, dc), channel in ((layout.red, 0), (layout.green_a, 1), (layout.green_b, 1), (layout.blue, 2)):
        out[dr::2, dc::2] = rgb[dr::2, dc::2, channel]
    return out


def _room(height: int = 120, width: int = 160, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.clip(rng.normal(110, 6, (height, width, 3)), 0, 255).astype(np.uint8)


def _paint(rgb: np.ndarray, x: float, y: float, radius: float, colour) -> None:
    ys, xs = np.mgrid[0 : rgb.shape[0], 0 : rgb.shape[1]]
    rgb[(xs - x) ** 2 + (ys - y) ** 2 <= radius**2] = colour


def test_cell_excess_is_the_colour_over_the_larger_other_channel_as_the_coarse_test_takes_it():
    rgb = _room()
    _paint(rgb, 60, 50, 12, (200, 40, 60))
    # RGB: every pixel, red minus the larger of green and blue.
    excess, value, xs, ys = cell_excess(rgb, sample_grid("RGB8", 160, 120), "red")
    reference = rgb[..., 0].astype(int) - np.maximum(rgb[..., 1], rgb[..., 2]).astype(int)
    assert np.array_equal(excess, reference) and np.array_equal(value, rgb[..., 0])
    assert xs[0] == 0 and ys[0] == 0
    # Bayer: per interior cell, the red sample against the brighter green and the blue sample of that cell.
    for fmt in BAYER_LAYOUTS:
        frame = _mosaic(rgb, fmt)
        grid = sample_grid(fmt, 160, 120)
        excess, value, xs, ys = cell_excess(frame, grid, "blue")
        layout = BAYER_LAYOUTS[fmt]
        i, j = 10, 7  # the cell at row 1 + 10, column 1 + 7 (the interior starts at cell 1)
        cell = frame[2 * (i + 1) : 2 * (i + 1) + 2, 2 * (j + 1) : 2 * (j + 1) + 2].astype(int)
        own = cell[layout.blue]
        others = max(cell[layout.green_a], cell[layout.green_b], cell[layout.red])
        assert excess[i, j] == own - others and value[i, j] == own
        assert (xs[j], ys[i]) == (2 * (j + 1) + layout.blue[1], 2 * (i + 1) + layout.blue[0])


def test_the_ball_core_and_the_rooms_top_patch_are_told_apart():
    rgb = _room()
    _paint(rgb, 50, 60, 14, (210, 50, 40))  # the red ball: excess 160
    _paint(rgb, 130, 30, 5, (150, 70, 60))  # a reddish picture elsewhere: excess 80
    rgb[100, 20] = (255, 0, 0)  # one hot pixel is not a patch
    discs = {"red": Disc(50, 60, 14), "blue": Disc(90, 90, 8)}
    samples = colour_samples(rgb, sample_grid("RGB8", 160, 120), "red", discs)
    assert samples.ball_excess.size > 100 and np.all(samples.ball_excess == 160)
    assert samples.background_excess == 80
    assert samples.background_at_px is not None
    # Without the picture, the room's top block is the grey's noise, not the hot pixel.
    rgb[:, 110:] = _room()[:, 110:]
    samples = colour_samples(rgb, sample_grid("RGB8", 160, 120), "red", discs)
    assert samples.background_excess < 40


def test_the_rooms_figure_needs_a_block_of_samples_and_the_rod_is_left_out_of_the_core():
    rgb = _room()
    _paint(rgb, 50, 60, 14, (210, 50, 40))
    # The rod runs from the red ball's centre towards the blue ball, over the red ball's core.
    for t in np.linspace(0, 1, 200):
        x, y = 50 + t * 60, 60 + t * 0
        _paint(rgb, x, y, 2.5, (30, 30, 30))
    discs = {"red": Disc(50, 60, 14), "blue": Disc(110, 60, 8)}
    grid = sample_grid("RGB8", 160, 120)
    with_rod = colour_samples(rgb, grid, "red", discs)
    assert with_rod.ball_excess.min() == 0  # the grey rod's samples are in the core
    without_rod = colour_samples(rgb, grid, "red", discs, rod_half_width_px=4.0)
    assert without_rod.ball_excess.min() == 160
    # A line of samples is not a block (a Bayer mosaic's colour fringe along an edge is such a line);
    # two by two samples are.
    room = _room()
    room[5, 140:150] = (200, 60, 60)
    assert colour_samples(room, grid, "red", discs).background_excess < 40
    room[6, 140:142] = (200, 60, 60)
    samples = colour_samples(room, grid, "red", discs)
    assert samples.background_excess == 140 and samples.background_at_px == (140.0, 5.0)


def test_unhidden_leaves_out_what_covers_part_of_a_ball_and_keeps_its_shading():
    rng = np.random.default_rng(1)
    ball = np.round(rng.normal(150, 8, 300)).astype(np.int16)  # shading and noise
    hand = np.round(rng.normal(-20, 10, 60)).astype(np.int16)  # a sixth of the core hidden
    kept = unhidden(np.concatenate([ball, hand]))
    assert kept.size == ball.size and np.array_equal(np.sort(kept), np.sort(ball))
    assert unhidden(np.array([], dtype=np.int16)).size == 0
    # Samples with no excess of the colour at all (the ball hidden, or not the ball): the median's stay,
    # never none (the pointer's colour learning took the smallest of what was kept, and raised).
    flat = np.full(40, -10, dtype=np.int16)
    assert np.array_equal(unhidden(flat), flat)
    # A quarter of a widely shaded core hidden (the case of a ball half behind the rod seen along it):
    # the hidden samples go all the same.
    wide = np.round(rng.uniform(87, 143, 20)).astype(np.int16)
    hidden = np.round(rng.uniform(-51, 32, 8)).astype(np.int16)
    assert np.array_equal(np.sort(unhidden(np.concatenate([wide, hidden]))), np.sort(wide))
