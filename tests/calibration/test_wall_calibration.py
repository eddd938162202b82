"""The wall solve: exact on exact observations, robust to a bad one, honest about its residuals."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackerd.calibration import CalibrationError
from trackerd.calibration.inputs import default_targets
from trackerd.calibration.wall import Pointing, Target, Touch, corner_targets, fit_wall
from trackerd.geometry.rotation import rotation_from_rvec

WIDTH, HEIGHT = 3.6576, 0.9144
RADIUS = 0.02


def true_frame(rvec: tuple[float, float, float], origin: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """A wall frame somewhere in a camera's frame: world-from-wall rotation and origin."""
    return rotation_from_rvec(np.array(rvec)), np.array(origin)


def wall_point(rotation: np.ndarray, origin: np.ndarray, xy: np.ndarray, lift: float = 0.0) -> np.ndarray:
    return origin + rotation @ np.array([xy[0], xy[1], lift])


def touches(rotation, origin, targets, rng=None, noise_m=0.0, size=(WIDTH, HEIGHT)) -> list[Touch]:
    out = []
    scale = np.array(size) / np.array([WIDTH, HEIGHT])
    for target in targets:
        tip = wall_point(rotation, origin, target.wall_xy_m * (scale if target.scalable else 1.0), RADIUS)
        back = tip + 0.45 * (rotation @ np.array([0.2, 0.3, 0.93]))
        if rng is not None:
            tip = tip + rng.normal(0, noise_m, 3)
        out.append(Touch(target, tip, back))
    return out


def pointings(rotation, origin, targets, places, rng=None, noise_m=0.0) -> list[Pointing]:
    out = []
    for target in targets:
        aim = wall_point(rotation, origin, target.wall_xy_m)
        for place in places:
            tip = wall_point(rotation, origin, np.array(place[:2]), place[2])
            direction = (aim - tip) / np.linalg.norm(aim - tip)
            if rng is not None:
                tip = tip + rng.normal(0, noise_m, 3)
            out.append(Pointing(target, tip, tip - 0.45 * direction))
    return out


PLACES = [(0.8, 1.0, 1.5), (1.8, 0.6, 2.0), (2.9, 1.1, 1.2)]


@settings(max_examples=25, deadline=None)
@given(
    rvec=st.tuples(*[st.floats(-1.0, 1.0)] * 3),
    origin=st.tuples(*[st.floats(-3.0, 3.0)] * 3),
)
def test_exact_touches_of_the_corners_give_the_frame_exactly(rvec, origin) -> None:
    rotation, o = true_frame(rvec, origin)
    fit = fit_wall(touches(rotation, o, corner_targets(WIDTH, HEIGHT).values()), [], (WIDTH, HEIGHT), RADIUS)
    assert np.allclose(fit.rotation, rotation, atol=1e-7)
    assert np.allclose(fit.origin_m, o, atol=1e-7)
    assert fit.size_fitted  # touched corners pin the size
    assert (fit.width_m, fit.height_m) == pytest.approx((WIDTH, HEIGHT), abs=1e-7)
    assert fit.implied_size_m == pytest.approx((WIDTH, HEIGHT), abs=1e-7)
    assert all(abs(r.plane_mm) < 1e-4 and r.in_plane_mm < 1e-4 for r in fit.residuals)


def test_exact_pointings_from_three_places_give_the_frame_and_the_display_size() -> None:
    rotation, o = true_frame((0.3, -2.1, 0.2), (-2.4, 0.7, 2.5))
    display = (WIDTH * 1.01, HEIGHT * 0.99)  # the display is not quite its nominal size
    nominal = default_targets(WIDTH, HEIGHT)
    aimed = pointings(rotation, o, default_targets(*display).values(), PLACES)
    observed = [Pointing(nominal[p.target.label], p.tip_m, p.back_m) for p in aimed]
    # By default pointing keeps the configured size, and reports the size the targets imply.
    kept = fit_wall([], observed, (WIDTH, HEIGHT), RADIUS)
    assert not kept.size_fitted and (kept.width_m, kept.height_m) == (WIDTH, HEIGHT)
    assert kept.implied_size_m == pytest.approx(display, abs=1e-7)
    fit = fit_wall([], observed, (WIDTH, HEIGHT), RADIUS, fit_size=True)
    assert np.allclose(fit.rotation, rotation, atol=1e-7)
    assert np.allclose(fit.origin_m, o, atol=1e-7)
    assert (fit.width_m, fit.height_m) == pytest.approx(display, abs=1e-7)
    assert max(r.miss_mm for r in fit.residuals) < 1e-4


def test_noisy_pointings_give_millimetre_figures_and_a_bad_line_is_left_out() -> None:
    rng = np.random.default_rng(4)
    rotation, o = true_frame((0.1, 0.2, -0.1), (0.5, -0.3, 3.0))
    targets = list(default_targets(WIDTH, HEIGHT).values())
    observed = pointings(rotation, o, targets, PLACES, rng, noise_m=0.001)
    # One line was a wrong blob: it passes 80 mm from its target.
    bad = observed[5]
    aim = wall_point(rotation, o, bad.target.wall_xy_m) + rotation @ np.array([0.08, 0.0, 0.0])
    direction = (aim - bad.tip_m) / np.linalg.norm(aim - bad.tip_m)
    observed[5] = Pointing(bad.target, bad.tip_m, bad.tip_m - 0.45 * direction)
    fit = fit_wall([], observed, (WIDTH, HEIGHT), RADIUS)
    flagged = [r for r in fit.residuals if not r.used]
    assert len(flagged) == 1 and flagged[0].label == bad.target.label and flagged[0].miss_mm > 60
    assert fit.rms_mm < 3.0
    assert np.degrees(np.arccos(np.clip(fit.rotation[:, 2] @ rotation[:, 2], -1, 1))) < 0.1
    assert np.linalg.norm(fit.origin_m - o) < 0.005
    # Without the robust weights the bad line drags the wall by millimetres.
    plain = fit_wall([], observed, (WIDTH, HEIGHT), RADIUS, robust=False)
    assert np.linalg.norm(plain.origin_m - o) > np.linalg.norm(fit.origin_m - o)


def test_a_wrong_corner_shows_in_its_residual_and_the_implied_size() -> None:
    rotation, o = true_frame((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    corners = corner_targets(WIDTH, HEIGHT)
    observed = touches(rotation, o, corners.values())
    # The operator touched 10 cm left of the top-right corner.
    tr = next(t for t in observed if t.target.label == "tr")
    observed[observed.index(tr)] = Touch(tr.target, tr.tip_m - np.array([0.10, 0.0, 0.0]), tr.back_m)
    fit = fit_wall(observed, [], (WIDTH, HEIGHT), RADIUS, robust=False)
    worst = max(fit.residuals, key=lambda r: r.worst_mm)
    assert worst.worst_mm > 20
    assert abs(fit.implied_size_m[0] - WIDTH) > 0.02


def test_touches_without_a_known_place_pin_the_plane_only() -> None:
    rng = np.random.default_rng(2)
    rotation, o = true_frame((0.05, -0.3, 0.02), (-1.0, 0.2, 2.0))
    marks = [Target("m1", np.array([1.6, 0.1])), Target("m2", np.array([2.1, 0.8]))]
    anywhere = [Target("", None) for _ in range(4)]
    observed = touches(rotation, o, marks) + [
        Touch(
            t,
            wall_point(rotation, o, rng.uniform([0, 0], [WIDTH, HEIGHT]), RADIUS),
            wall_point(rotation, o, np.array([1.0, 1.0]), 0.5),
        )
        for t in anywhere
    ]
    fit = fit_wall(observed, [], (WIDTH, HEIGHT), RADIUS)
    assert not fit.size_fitted
    assert np.allclose(fit.rotation, rotation, atol=1e-6)
    assert np.allclose(fit.origin_m, o, atol=1e-6)


def test_camera_poses_are_re_expressed_in_the_wall_frame() -> None:
    rotation, o = true_frame((0.2, 0.4, -0.3), (1.0, -0.5, 4.0))
    fit = fit_wall(touches(rotation, o, corner_targets(WIDTH, HEIGHT).values()), [], (WIDTH, HEIGHT), RADIUS)
    cam_r, cam_t = rotation_from_rvec(np.array([0.1, 0.2, 0.3])), np.array([0.3, -0.2, 1.0])
    new_r, new_t = fit.camera_in_wall_frame(cam_r, cam_t)
    point_wall = np.array([1.2, 0.4, 0.0])
    point_world = o + rotation @ point_wall
    assert np.allclose(new_r @ point_wall + new_t, cam_r @ point_world + cam_t, atol=1e-9)


def test_too_few_places_is_a_clear_error() -> None:
    rotation, o = true_frame((0, 0, 0), (0, 0, 0))
    two = list(corner_targets(WIDTH, HEIGHT).values())[:2]
    with pytest.raises(CalibrationError, match="three or more places"):
        fit_wall(touches(rotation, o, two), [], (WIDTH, HEIGHT), RADIUS)
    # Pointed at from a single place each, no target is located.
    with pytest.raises(CalibrationError, match="got 0"):
        fit_wall([], pointings(rotation, o, two, PLACES[:1]), (WIDTH, HEIGHT), RADIUS)
    unknown = [Target(f"t{k}", None) for k in range(4)]
    with pytest.raises(CalibrationError, match="at least two of the places must be known"):
        fit_wall(
            touches(rotation, o, [])
            + [Touch(t, np.array([k, k % 2, 0.02]), np.array([k, k % 2, 0.5])) for k, t in enumerate(unknown)],
            [],
            (WIDTH, HEIGHT),
            RADIUS,
        )


def test_a_fit_above_the_limit_is_refused_naming_the_observations_that_are_off() -> None:
    from trackerd.calibration.wall import DEFAULT_MAX_RMS_MM, fit_problem

    rng = np.random.default_rng(5)
    rotation, o = true_frame((0.1, 0.2, -0.1), (0.5, -0.3, 3.0))
    marks = {
        k: Target(k, np.array(xy), False)
        for k, xy in {"m1": (1.6, 0.15), "m2": (2.1, 0.15), "m3": (2.1, 0.75), "m4": (1.6, 0.75)}.items()
    }
    good = touches(rotation, o, marks.values(), rng, noise_m=0.0005)
    fit = fit_wall(good, [], (WIDTH, HEIGHT), RADIUS)
    assert fit.rms_mm < 2.0 and fit_problem(fit, DEFAULT_MAX_RMS_MM) is None
    # Labels shifted by one target (the operator touched m2 when asked for m1, and so on).
    labels = ["m4", "m1", "m2", "m3"]
    shifted = [Touch(marks[label], t.tip_m, t.back_m) for label, t in zip(labels, good, strict=True)]
    fit = fit_wall(shifted, [], (WIDTH, HEIGHT), RADIUS)
    problem = fit_problem(fit, DEFAULT_MAX_RMS_MM)
    assert problem is not None and fit.rms_mm > 50
    assert problem.startswith(f"wall RMS residual {fit.rms_mm:.2f} mm exceeds --max-rms-mm 10.0 mm: not written;")
    assert all(f"touch {label} " in problem for label in labels)
    assert all(r.fit_mm > 10 for r in fit.residuals)
