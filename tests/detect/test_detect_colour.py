"""The colour tests on raw planes: uint8 arithmetic, sample positions, symmetric excess."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from trackerd.detect.colour import (
    EXCESS_SCALE,
    Threshold,
    _exceeds,
    brightest_at,
    channel_windows,
    coarse_masks,
    excess_window,
    green_at,
    sample_grid,
)
from trackerd.errors import ImageError
from trackerd.pixelformat import BAYER_LAYOUTS, from_rgb

FORMATS = ("BayerRG8", "BayerGB8", "BayerGR8", "BayerBG8", "RGB8", "BGR8")


@settings(max_examples=200, deadline=None)
@given(
    arrays(np.uint8, 64),
    arrays(np.uint8, 64),
    st.integers(1, 255),
    st.integers(0, 255),
)
def test_uint8_test_is_the_integer_test(value, others, min_excess, min_value) -> None:
    """value >= others + min_excess and value >= min_value, with no overflow anywhere."""
    expected = (value.astype(int) >= others.astype(int) + min_excess) & (value >= min_value)
    got = _exceeds(value, others.copy(), Threshold(min_excess, min_value))
    assert np.array_equal(got, expected)


@pytest.mark.parametrize("pixel_format", FORMATS)
def test_each_colour_sample_is_at_its_own_pixel(pixel_format: str) -> None:
    """A frame whose every pixel's value encodes its (x, y): the grid's offsets find R and B."""
    height, width = 12, 16
    rng = np.random.default_rng(1)
    rgb = rng.integers(0, 256, (height, width, 3), dtype=np.uint8)
    frame = from_rgb(rgb, pixel_format)
    grid = sample_grid(pixel_format, width, height)
    for colour, channel in (("red", 0), ("blue", 2)):
        dr, dc = grid.offset(colour)
        for i, j in ((1, 1), (2, 5), (4, 3)):
            y, x = grid.cell_px * i + dr, grid.cell_px * j + dc
            _, value = excess_window(frame, grid, colour, (i, i + 1, j, j + 1))
            assert value[0, 0] == rgb[y, x, channel]
    if pixel_format in BAYER_LAYOUTS:
        assert grid.red == BAYER_LAYOUTS[pixel_format].red
        assert grid.blue == BAYER_LAYOUTS[pixel_format].blue


@pytest.mark.parametrize("pixel_format", FORMATS)
def test_excess_and_channels_of_a_flat_colour(pixel_format: str) -> None:
    rgb = np.empty((20, 24, 3), dtype=np.uint8)
    rgb[:] = (200, 50, 80)
    frame = from_rgb(rgb, pixel_format)
    grid = sample_grid(pixel_format, 24, 20)
    red, _ = excess_window(frame, grid, "red", grid.interior())
    blue, _ = excess_window(frame, grid, "blue", grid.interior())
    assert np.all(red == EXCESS_SCALE * (200 - 80))
    assert np.all(blue == EXCESS_SCALE * (80 - 200))
    r_mask, b_mask = coarse_masks(frame, grid, Threshold(100, 150), Threshold(1, 0), grid.interior(), 2)
    assert r_mask is not None and b_mask is not None
    assert r_mask.all() and not b_mask.any()
    r_mask, _ = coarse_masks(frame, grid, Threshold(121, 0), None, grid.interior(), 2)
    assert r_mask is not None and not r_mask.any()
    # Each colour's samples see the frame's own channel, green and the other colour, in grey levels.
    red_channels = channel_windows(frame, grid, "red", grid.interior())
    assert red_channels.shape == (3, *red.shape)
    assert np.all(red_channels == np.array([200, 50, 80], dtype=np.float32)[:, None, None])
    blue_channels = channel_windows(frame, grid, "blue", grid.interior())
    assert np.all(blue_channels == np.array([80, 50, 200], dtype=np.float32)[:, None, None])


@pytest.mark.parametrize("pixel_format", [f for f in FORMATS if f.startswith("Bayer")])
@pytest.mark.parametrize("colour", ["red", "blue"])
def test_excess_is_symmetric_about_each_sample(pixel_format: str, colour: str) -> None:
    """A mosaic symmetric about one of the colour's samples gives an excess symmetric about it.

    Point reflection through a red (blue) pixel maps the mosaic onto itself colour
    for colour, so a colour test that compares each sample with neighbours
    interpolated *at its own position* must come out symmetric too. This is why the
    centroid of the excess has no pull towards where green and the other colour sit
    in the Bayer cell (a cell-based test fails this).
    """
    grid0 = sample_grid(pixel_format, 8, 8)
    dr, dc = grid0.offset(colour)
    rows, cols = 2 * (20 + dr) + 1, 2 * (24 + dc) + 1  # centre pixel (rows // 2, cols // 2)
    cy, cx = rows // 2, cols // 2
    assert (cy % 2, cx % 2) == (dr, dc)
    rng = np.random.default_rng(2)
    mosaic = rng.integers(0, 256, (rows, cols), dtype=np.uint8)
    index = np.arange(rows * cols).reshape(rows, cols)
    mosaic = np.where(index <= index[cy, cx], mosaic, mosaic[::-1, ::-1])
    assert np.array_equal(mosaic, mosaic[::-1, ::-1])
    grid = sample_grid(pixel_format, cols, rows)
    i, j, k = (cy - dr) // 2, (cx - dc) // 2, 5
    excess, _ = excess_window(mosaic, grid, colour, (i - k, i + k + 1, j - k, j + k + 1))
    assert excess.shape == (2 * k + 1, 2 * k + 1)
    assert np.array_equal(excess, excess[::-1, ::-1])
    # So are all three channels at the colour's samples (the guided look's tint, trackerd/detect/guided.py).
    channels = channel_windows(mosaic, grid, colour, (i - k, i + k + 1, j - k, j + k + 1))
    assert np.array_equal(channels, channels[:, ::-1, ::-1])


def test_green_at_reads_green_pixels() -> None:
    rgb = np.zeros((10, 12, 3), dtype=np.uint8)
    rgb[..., 1] = 77
    rgb[..., 0] = 200
    rgb[..., 2] = 10
    for fmt in FORMATS:
        frame = from_rgb(rgb, fmt)
        grid = sample_grid(fmt, 12, 10)
        points = np.array([[0.2, 0.1], [5.4, 3.6], [10.9, 8.7], [-3.0, 40.0]])
        assert np.all(green_at(frame, grid, points) == 77)


def test_brightest_at_reads_the_brightest_sample_of_a_pixels_cell() -> None:
    """On a mosaic, the largest of the four samples of the 2 x 2 cell holding the nearest pixel (a red
    surface is bright there though its green is dark; the rod is dark in all), the cell kept inside the
    frame; on RGB8 / BGR8, the nearest pixel's largest channel."""
    mosaic = np.arange(8 * 8, dtype=np.uint8).reshape(8, 8)  # every sample different, larger down and right
    mosaic[2, 5] = 250  # one bright sample: its cell is rows 2-3, columns 4-5
    grid = sample_grid("BayerRG8", 8, 8)
    points = np.array([[0.2, 0.1], [4.4, 3.4], [5.0, 2.0], [6.6, 0.4], [7.9, 7.9], [-3.0, 40.0]])
    # cells (rows, cols): (0-1, 0-1), (2-3, 4-5), (2-3, 4-5), (0-1, 6-7), clamped (6-7, 6-7), clamped (6-7, 0-1)
    expected = [mosaic[1, 1], 250, 250, mosaic[1, 7], mosaic[7, 7], mosaic[7, 1]]
    assert brightest_at(mosaic, grid, points).tolist() == [float(v) for v in expected]
    rgb = np.zeros((8, 8, 3), dtype=np.uint8)
    rgb[2, 5] = (200, 10, 30)
    rgb[7, 7] = (5, 90, 7)
    for fmt, frame in (("RGB8", rgb), ("BGR8", rgb[..., ::-1].copy())):
        grid = sample_grid(fmt, 8, 8)
        got = brightest_at(frame, grid, np.array([[5.2, 1.6], [4.4, 2.0], [9.0, 7.0]]))
        assert got.tolist() == [200.0, 0.0, 90.0], fmt


def test_mono_and_unknown_formats_are_refused() -> None:
    with pytest.raises(ImageError, match="Mono8"):
        sample_grid("Mono8", 64, 48)
    with pytest.raises(ImageError, match="too small"):
        sample_grid("BayerRG8", 4, 4)
