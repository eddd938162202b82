"""A ball's outline fitted where it is visible (trackerd/detect/ballfit.py), on analytic frames whose
truth is exact: the disc's centre, whatever hides part of it."""

from __future__ import annotations

import numpy as np
import pytest
from detect_synthetic import BLUE, RED, ROD, WALL, Scene, Shape

from trackerd.config.models import DetectorConfig
from trackerd.detect import ColourEndDetector
from trackerd.detect.ballfit import (
    RESTING_ERROR_SHARE,
    BallLook,
    _bilinear_windows,
    _leaning_shift,
    arc_deformation_covariance,
    fit_ball,
    fit_balls,
    fit_looks,
    independent_rims,
)
from trackerd.detect.circle import robust_circle
from trackerd.detect.colour import sample_grid

FORMATS = ("BayerRG8", "BayerGB8", "RGB8")


def _fit(frame, fmt, x, y, r, **kw):
    grid = sample_grid(fmt, frame.shape[1], frame.shape[0])
    return fit_ball(frame, grid, "red", x, y, r, **kw)


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_whole_ball_is_found_to_a_small_fraction_of_a_pixel(fmt, detect_rng) -> None:
    errors = []
    for k in range(6):
        x, y = 100.3 + 0.37 * k, 70.6 - 0.29 * k
        frame, _ = Scene(shapes=[Shape(x, y, RED, radius=11.0)]).render(fmt, detect_rng)
        fit = _fit(frame, fmt, x + 1.5, y - 1.0, 8.0)  # a rough start, as a blob's centre gives
        assert fit.found, fit.reason
        errors.append(np.hypot(*(fit.centre_px - [x, y])))
        assert abs(fit.radius_px - 11.0) < 0.4
        assert fit.rim_fraction > 0.9
    assert np.median(errors) < 0.08 and max(errors) < 0.2


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_ball_partly_hidden_keeps_its_centre_where_the_blob_centroid_moves(fmt, detect_rng) -> None:
    """A skin-coloured finger over part of the ball: the detector's centroid moves by most of a pixel,
    the fitted outline stays on the ball's centre (its rim inside the finger is left out)."""
    x, y, r = 100.4, 75.2, 12.0
    finger = Shape(x + 10.0, y + 3.0, (0.80, 0.58, 0.47), radius=9.0)
    frame, _ = Scene(shapes=[Shape(x, y, RED, radius=r), finger]).render(fmt, detect_rng)
    detector = ColourEndDetector(DetectorConfig(), fmt, frame.shape[1], frame.shape[0])
    red = detector.detect(frame).red
    assert red.found
    moved = np.hypot(*(red.centroid_px - [x, y]))
    assert moved > 0.5
    fit = _fit(frame, fmt, *red.centroid_px, np.sqrt(red.area_px / np.pi))
    assert fit.found, fit.reason
    assert np.hypot(*(fit.centre_px - [x, y])) < min(0.2, moved / 4)
    assert 0.5 < fit.rim_fraction < 0.95  # the finger's arc is not counted as the ball's


def test_a_dim_shaded_ball_is_measured_whole_where_the_thresholds_take_only_its_lit_side(detect_rng) -> None:
    """A ball at a third of the light the thresholds were set for, shaded top to bottom: the detector
    keeps only its lit part (or nothing); the outline is found from the ball's own contrast."""
    x, y, r = 96.7, 70.1, 12.0
    dim = tuple(0.35 * c for c in RED)
    frame, _ = Scene(background=tuple(0.35 * c for c in WALL), shapes=[Shape(x, y, dim, radius=r, shading=0.4)]).render(
        "BayerRG8", detect_rng, noise=1.5
    )
    detector = ColourEndDetector(DetectorConfig(), "BayerRG8", frame.shape[1], frame.shape[0])
    red = detector.detect(frame).red
    assert not red.found or red.area_px < 0.6 * np.pi * r * r
    fit = _fit(frame, "BayerRG8", x - 2.0, y - 3.0, 7.0)
    assert fit.found, fit.reason
    assert np.hypot(*(fit.centre_px - [x, y])) < 0.25
    assert abs(fit.radius_px - r) < 0.8


def test_the_rod_side_is_left_out_when_the_axis_is_given(detect_rng) -> None:
    """The rod meets the ball along the pointer's axis; with the axis given, those rays are not used."""
    x, y, r = 100.2, 75.1, 11.0
    scene = Scene(shapes=[Shape(x, y, RED, radius=r)], rods=[(x, y, x + 60.0, y + 10.0, 3.5)])
    frame, _ = scene.render("BayerRG8", detect_rng)
    with_axis = _fit(frame, "BayerRG8", x, y, r, axis=(60.0, 10.0))
    assert with_axis.found and np.hypot(*(with_axis.centre_px - [x, y])) < 0.12


def test_nothing_round_there_is_said_so(detect_rng) -> None:
    frame, _ = Scene(shapes=[Shape(100.0, 75.0, RED, half_size=(30.0, 3.0))]).render("BayerRG8", detect_rng)
    fit = _fit(frame, "BayerRG8", 100.0, 75.0, 10.0)
    assert not fit.found and fit.reason
    blank, _ = Scene(background=WALL).render("BayerRG8", detect_rng)
    assert not _fit(blank, "BayerRG8", 100.0, 75.0, 10.0).found


def test_a_size_range_finds_the_ball_beside_a_larger_disc_of_its_colour(detect_rng) -> None:
    """A ball overlapping a larger disc of its own paint (a sticker, a slide's dot): told the ball's
    size, the fit takes the ball's arc; without it, it may take either."""
    x, y = 95.3, 72.8
    frame, _ = Scene(
        shapes=[
            Shape(x + 22.0, y + 6.0, RED, radius=20.0),
            Shape(x, y, ROD, radius=10.5),
            Shape(x, y, RED, radius=10.0),
        ]
    ).render("BayerRG8", detect_rng)
    fit = _fit(frame, "BayerRG8", x, y, 10.0, radius_range_px=(8.0, 12.5))
    assert fit.found, fit.reason
    assert np.hypot(*(fit.centre_px - [x, y])) < 0.3 and abs(fit.radius_px - 10.0) < 0.8


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_dark_ball_before_a_brighter_surface_of_its_hue_is_found_where_the_geometry_says(fmt, detect_rng) -> None:
    """A shaded ball half in front of a bright block of its own paint's hue (a slide's red letter): its
    colour excess rises into the block at its rim. Told where and how large the ball is (the joint
    search's look), the rising rims give the outline on that side too; without them there is too little
    rim to fit, as there was for such balls in `bench robustness` (found on no ray into the block)."""
    x, y, r = 99.6, 74.3, 11.0
    dark = tuple(0.45 * c for c in RED)
    block = Shape(x - 30.0, y, (0.95, 0.05, 0.05), radius=31.0)  # covers the ball's left half and beyond
    frame, _ = Scene(shapes=[block, Shape(x, y, dark, radius=r)]).render(fmt, detect_rng)
    guided = dict(radius_range_px=(r / 1.15, r * 1.15))
    plain = _fit(frame, fmt, x + 1.0, y - 1.0, r, **guided)
    rising = _fit(frame, fmt, x + 1.0, y - 1.0, r, rising_rims=True, **guided)
    assert rising.found, rising.reason
    assert np.hypot(*(rising.centre_px - [x, y])) < 0.35 and abs(rising.radius_px - r) < 0.6
    assert rising.rim_fraction > 0.8
    assert not plain.found or plain.rim_fraction < 0.6  # only the half against the wall


def test_a_circle_held_up_by_one_rim_point_says_how_far_its_centre_moves_without_it() -> None:
    """A short arc of a ball's outline (100 degrees: a body hides the rest) and one rim point across the ball,
    where the colour falls at the body's edge: the circle goes through that point, smaller than the ball and
    its centre off, and agrees with every point it kept. Leaving the point out moves the centre by most of
    that error; on a whole outline no point holds the circle up, and nothing moves."""
    rng = np.random.default_rng(4)
    angles = np.radians(np.linspace(130.0, 230.0, 13))
    arc = np.column_stack([15.0 * np.cos(angles), 15.0 * np.sin(angles)]) + rng.normal(0.0, 0.15, (13, 2))
    points = np.vstack([arc, [11.0, 1.0]])
    circle = robust_circle(points, radius_range_px=(12.0, 18.0))
    assert circle is not None
    centre, radius, weights, _ = circle
    assert np.all(weights > 0) and radius < 14.0 and np.hypot(*centre) > 1.5
    shift = _leaning_shift(points, weights, centre, radius, (12.0, 18.0))
    assert shift is not None and np.hypot(*shift) > 0.6 * np.hypot(*centre)
    assert np.dot(shift, -centre) > 0  # towards the ball's centre
    around = np.linspace(0.0, 2.0 * np.pi, 48, endpoint=False)
    whole = np.column_stack([15.0 * np.cos(around), 15.0 * np.sin(around)]) + rng.normal(0.0, 0.15, (48, 2))
    circle = robust_circle(whole)
    assert circle is not None
    assert np.all(_leaning_shift(whole, circle[2], circle[0], circle[1], None) == 0.0)


def test_a_refit_that_jumps_far_away_counts_as_no_circle_at_all() -> None:
    """A flat arc (the edge of something larger, 40 px in radius, beside the ball) and one rim point across:
    the circle through both is the ball's size, and without the point the arc's own circle is 26 px away.
    That says the centre rests on one point, no more: the shift is the half radius a centre with no circle
    left is given (RESTING_ERROR_SHARE), along the way the refit went."""
    rng = np.random.default_rng(0)
    angles = np.radians(np.linspace(165.0, 195.0, 11))
    arc = np.column_stack([25.0 + 40.0 * np.cos(angles), 40.0 * np.sin(angles)]) + rng.normal(0.0, 0.1, (11, 2))
    points = np.vstack([arc, [12.0, 1.0]])
    circle = robust_circle(points)
    assert circle is not None
    centre, radius, weights, _ = circle
    assert np.all(weights > 0) and 13.0 < radius < 15.0
    refit = robust_circle(arc)
    assert refit is not None and np.hypot(*(refit[0] - centre)) > 1.5 * radius  # what the refit jumps to
    shift = _leaning_shift(points, weights, centre, radius, None)
    assert shift is not None
    assert np.hypot(*shift) == pytest.approx(RESTING_ERROR_SHARE * radius, rel=1e-9)
    assert shift[0] > 0.99 * np.hypot(*shift)  # towards the arc's own centre


def test_the_rays_samples_are_bilinear_and_nan_outside() -> None:
    rng = np.random.default_rng(5)
    image = rng.uniform(0, 255, (7, 9)).astype(np.float32)
    u = rng.uniform(-1.0, 9.0, 200)
    v = rng.uniform(-1.0, 7.0, 200)
    sampled = _bilinear_windows([image], u[None], v[None])[0]
    inside = (u >= 0) & (v >= 0) & (u <= 8) & (v <= 6)
    assert np.all(np.isnan(sampled[~inside]))
    for uu, vv, got in zip(u[inside], v[inside], sampled[inside], strict=True):
        c, r = min(int(uu), 7), min(int(vv), 5)
        fu, fv = uu - c, vv - r
        expected = (image[r, c] * (1 - fu) + image[r, c + 1] * fu) * (1 - fv) + (
            image[r + 1, c] * (1 - fu) + image[r + 1, c + 1] * fu
        ) * fv
        assert got == pytest.approx(expected, abs=1e-9)


@pytest.mark.parametrize("phase", np.linspace(0.0, np.pi, 7))
def test_a_waved_partial_outline_moves_its_centre_by_what_its_arc_covariance_says(phase) -> None:
    """Issue 13: an outline that departs from a circle by a smooth wave (blur, shading, a hand's mixed
    pixels) fitted on half of it moves the centre; the arc covariance says by how much, for any phase of
    the wave (whitened shift 1), and a whole outline is not moved and says so."""
    angles = np.linspace(-0.5 * np.pi, 0.5 * np.pi, 25)
    radius, amplitude = 10.0, 0.4
    rim = radius + amplitude * np.cos(2.0 * angles + phase)
    points = np.column_stack([rim * np.cos(angles), rim * np.sin(angles)])
    fitted = robust_circle(points)
    assert fitted is not None
    centre, _, weights, _ = fitted
    directions = (points - centre) / np.linalg.norm(points - centre, axis=1, keepdims=True)
    covariance = arc_deformation_covariance(directions, weights, amplitude)
    z = float(centre @ np.linalg.solve(covariance, centre))
    assert np.hypot(*centre) > 0.1  # half an outline is moved
    assert z < 1.5**2
    whole = np.linspace(0.0, 2.0 * np.pi, 48, endpoint=False)
    around = np.column_stack([np.cos(whole), np.sin(whole)])
    assert np.max(np.abs(arc_deformation_covariance(around, np.ones(48), amplitude))) < 1e-12


def test_rims_closer_than_the_lattice_share_their_noise() -> None:
    """On a Bayer lattice (2 px) the 48 rays cross a 5 px ball's rim 0.65 px apart: about ten independent
    rims; on a 30 px ball they are 4 px apart and all count."""
    assert 9.0 < independent_rims(48, 5.0, 2.0) < 12.0
    assert independent_rims(48, 30.0, 2.0) == 48.0
    assert independent_rims(48, 5.0, 1.0) == pytest.approx(2.0 * independent_rims(48, 5.0, 2.0))


@pytest.mark.parametrize("fmt", ("BayerRG8", "RGB8"))
def test_balls_fitted_together_are_each_fitted_as_alone(fmt, detect_rng) -> None:
    """The search fits every seed of a frame in one go (fit_balls): balls of different sizes (rays of
    different lengths, padded to one array), one partly hidden, a start on the bare wall and one at the
    frame's edge must each come out exactly as fit_ball gives them one at a time."""
    shapes = [
        Shape(40.3, 50.2, RED, radius=6.0),
        Shape(110.6, 45.1, RED, radius=14.0),
        Shape(60.2, 112.7, RED, radius=22.0),
        Shape(70.0, 120.0, (0.80, 0.58, 0.47), radius=12.0),  # a finger over the large one
    ]
    frame, _ = Scene(shapes=shapes).render(fmt, detect_rng)
    grid = sample_grid(fmt, frame.shape[1], frame.shape[0])
    starts = np.array(
        [[41.0, 49.0, 5.0], [112.0, 46.0, 11.0], [58.0, 110.0, 18.0], [165.0, 100.0, 9.0], [2.0, 3.0, 8.0]]
    )
    together = fit_balls(frame, grid, "red", starts)
    alone = [fit_ball(frame, grid, "red", *start) for start in starts]
    assert [fit.found for fit in alone] == [True, True, True, False, False]
    for batched, single in zip(together, alone, strict=True):
        assert batched.found == single.found and batched.reason == single.reason
        if single.found:
            assert np.array_equal(batched.centre_px, single.centre_px)
            assert batched.radius_px == single.radius_px and batched.centre_sigma_px == single.centre_sigma_px
            assert np.array_equal(batched.rim_px, single.rim_px)
            assert np.array_equal(batched.arc_covariance_px, single.arc_covariance_px)
    # Each start with its own radius range, rising rims taken (how the split search fits its seeds).
    ranges = np.column_stack([0.6 * starts[:, 2], 1.6 * starts[:, 2]])
    together = fit_balls(frame, grid, "red", starts, radius_range_px=ranges, rising_rims=True)
    alone = [
        fit_ball(frame, grid, "red", *start, radius_range_px=tuple(bounds), rising_rims=True)
        for start, bounds in zip(starts, ranges, strict=True)
    ]
    assert sum(fit.found for fit in alone) >= 3
    for batched, single in zip(together, alone, strict=True):
        assert batched.found == single.found and batched.reason == single.reason
        if single.found:
            assert np.array_equal(batched.centre_px, single.centre_px)
            assert batched.radius_px == single.radius_px and batched.centre_sigma_px == single.centre_sigma_px


def test_every_cameras_ends_fitted_together_are_each_fitted_as_alone(detect_rng) -> None:
    """A refined pair fits every camera's ends in one go (fit_looks): two frames of different formats (sample
    lattices of 2 and 1 px), both colours, the rod's axis left out at each ball, one ball in a view's units;
    each must come out exactly as fit_ball gives it one at a time."""
    pointer = [Shape(80.4, 60.2, RED, radius=9.0), Shape(150.7, 90.1, BLUE, radius=12.0)]
    rod = [(80.4, 60.2, 150.7, 90.1, 3.0)]
    bayer, _ = Scene(shapes=pointer, rods=rod).render("BayerRG8", detect_rng)
    rgb, _ = Scene(shapes=[Shape(60.1, 100.3, RED, radius=14.0), Shape(40.2, 30.6, BLUE, radius=7.0)]).render(
        "RGB8", detect_rng
    )
    bayer_grid = sample_grid("BayerRG8", bayer.shape[1], bayer.shape[0])
    rgb_grid = sample_grid("RGB8", rgb.shape[1], rgb.shape[0])
    axis = (70.3, 29.9)
    looks = [
        BallLook(bayer, bayer_grid, "red", 81.0, 59.0, 8.0, axis),
        BallLook(bayer, bayer_grid, "blue", 150.0, 91.0, 10.0, (-axis[0], -axis[1])),
        BallLook(rgb, rgb_grid, "red", 61.0, 99.0, 12.0),
        BallLook(rgb, rgb_grid, "blue", 41.0, 31.0, 6.0),
        BallLook(rgb, rgb_grid, "blue", 170.0, 20.0, 6.0),  # nothing there
        # In a view's units (a ball far off a wide lens's axis), as the search fits a seed again.
        BallLook(bayer, bayer_grid, "red", 81.0, 59.0, 8.0, view=np.array([[1.04, 0.02], [0.02, 0.97]])),
    ]
    together = fit_looks(looks)
    alone = [fit_ball(k.frame, k.grid, k.colour, k.x_px, k.y_px, k.radius_px, axis=k.axis, view=k.view) for k in looks]
    assert [fit.found for fit in alone] == [True, True, True, True, False, True]
    for batched, single in zip(together, alone, strict=True):
        assert batched.found == single.found and batched.reason == single.reason
        if single.found:
            assert np.array_equal(batched.centre_px, single.centre_px)
            assert batched.radius_px == single.radius_px and batched.centre_sigma_px == single.centre_sigma_px
            assert batched.independent_rims == single.independent_rims
