"""The pointer fit (trackerd/geometry/pointer_fit.py) and the cone of a ball's outline (sphere.py)."""

from __future__ import annotations

import numpy as np
import pytest

from trackerd.errors import GeometryError
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.pointer_fit import (
    DROPPED_VARIANCE,
    EndViews,
    fit_pointer,
    fit_pointer_robust,
    fit_pointer_step,
    hit_covariance,
    predict,
)
from trackerd.geometry.sphere import fit_sphere_direction, view_map

K = np.array([[1600.0, 0.0, 960.0], [0.0, 1600.0, 540.0], [0.0, 0.0, 1.0]])


def _camera(name: str, position, target=(1.7, 0.9, 1.8)) -> CameraModel:
    """A camera at ``position`` looking at ``target`` (x right, y down in its image, world y up)."""
    position = np.asarray(position, float)
    forward = np.asarray(target, float) - position
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    return CameraModel.from_pose(name, 1920, 1080, K, np.zeros(0), position, np.column_stack([right, down, forward]))


def _behind_pair() -> list[CameraModel]:
    """Two cameras high at the back of the room, looking at the wall past the presenter: the
    interpretation planes of a pointer aimed at the wall between them are nearly parallel."""
    return [_camera("a", [0.6, 1.5, 5.5]), _camera("b", [2.9, 1.5, 5.5])]


def _arrays(cameras: list[CameraModel]):
    return np.stack([c.rotation for c in cameras]), np.stack([c.translation_m for c in cameras])


FRONT = np.array([1.7, 0.9, 1.6])
BACK = np.array([1.78, 0.98, 2.03])  # 0.45 m behind, aimed at the wall (z = 0)


def test_exact_measurements_give_the_ends_back_from_a_poor_start() -> None:
    cameras = _behind_pair()
    rot, trans = _arrays(cameras)
    measured = predict(rot, trans, FRONT, BACK)
    covariances = np.tile(np.eye(2) * (0.1 / 1600) ** 2, (2, 2, 1, 1))
    length = float(np.linalg.norm(FRONT - BACK))
    views = EndViews.of(rot, trans, measured, covariances, length, 0.003)
    fit = fit_pointer(views, FRONT + np.array([0.05, -0.03, 0.1]), BACK - 0.04)
    assert np.allclose(fit.front_m, FRONT, atol=1e-7) and np.allclose(fit.back_m, BACK, atol=1e-7)
    assert fit.chi2 < 1e-8 and fit.inflation == 1.0


def test_one_step_from_the_last_pairs_ends_is_the_full_fit() -> None:
    """A tracked pair's fit (one Gauss-Newton step from ends a hand's pace away, 12 mm) gives the full fit's
    ends to tens of micrometres, and its chi-square and covariance, on noisy measurements from cameras behind
    the presenter."""
    cameras = _behind_pair()
    rot, trans = _arrays(cameras)
    rng = np.random.default_rng(11)
    length = float(np.linalg.norm(FRONT - BACK))
    covariances = np.tile(np.eye(2) * (0.3 / 1600) ** 2, (2, 2, 1, 1))
    for _ in range(20):
        noisy = predict(rot, trans, FRONT, BACK) + rng.normal(0.0, 0.3 / 1600, (2, 2, 2))
        views = EndViews.of(rot, trans, noisy, covariances, length, 0.003)
        full = fit_pointer(views, FRONT, BACK)
        away = rng.normal(size=3)
        away *= 0.012 / np.linalg.norm(away)
        step = fit_pointer_step(views, FRONT + away, BACK + away)
        # Tens of micrometres at the ends: a twentieth of a millimetre on the wall 2 m beyond.
        np.testing.assert_allclose(step.front_m, full.front_m, atol=5e-5)
        np.testing.assert_allclose(step.back_m, full.back_m, atol=5e-5)
        assert step.chi2 == pytest.approx(full.chi2, rel=0.05, abs=0.05)  # against a gate at 4 per dof
        # The covariance is the start's linearisation, 12 mm away: each element within 2 % of the largest.
        scale = float(np.max(np.diag(full.covariance)))
        np.testing.assert_allclose(step.covariance, full.covariance, rtol=0.0, atol=0.02 * scale)


def test_the_covariance_describes_the_scatter_of_fits_to_noisy_measurements() -> None:
    """Monte Carlo: the fitted front end's errors, whitened by the fit's own covariance, have unit
    variance (the uncertainty the daemon publishes is not made up)."""
    cameras = [*_behind_pair(), _camera("c", [-1.0, 1.8, 3.0])]
    rot, trans = _arrays(cameras)
    truth = predict(rot, trans, FRONT, BACK)
    sigma = 0.2 / 1600
    covariances = np.tile(np.eye(2) * sigma**2, (3, 2, 1, 1))
    length = float(np.linalg.norm(FRONT - BACK))
    rng = np.random.default_rng(4)
    z = []
    for _ in range(300):
        noisy = truth + rng.normal(0.0, sigma, truth.shape)
        fit = fit_pointer(EndViews.of(rot, trans, noisy, covariances, length, 1e-4), FRONT, BACK)
        # Without inflation: the scatter itself is what is checked.
        raw = fit.covariance / fit.inflation
        error = fit.front_m - FRONT
        z.append(float(error @ np.linalg.inv(raw[:3, :3]) @ error))
    # chi-square with 3 degrees of freedom: mean 3.
    assert 2.6 < np.mean(z) < 3.4


def test_weights_that_understate_the_errors_still_give_the_fits_true_scatter() -> None:
    """Monte Carlo (issue 13, honest uncertainty): the measurements weighed as 0.2 px, but one camera's
    truly off by 0.8 px along one direction (a partly hidden ball). Given those errors, the fit's
    covariance is that of the weighted estimate (the sandwich), and describes the fits' scatter; the
    estimate itself is the one the weights give, whatever the errors said."""
    cameras = [*_behind_pair(), _camera("c", [-1.0, 1.8, 3.0])]
    rot, trans = _arrays(cameras)
    truth = predict(rot, trans, FRONT, BACK)
    sigma = 0.2 / 1600
    weights = np.tile(np.eye(2) * sigma**2, (3, 2, 1, 1))
    errors = weights.copy()
    errors[1, 0] = np.diag([(0.8 / 1600) ** 2, sigma**2])
    length = float(np.linalg.norm(FRONT - BACK))
    rng = np.random.default_rng(5)
    chol = np.linalg.cholesky(errors)
    fronts, covariances = [], []
    for _ in range(400):
        noisy = truth + np.einsum("ceij,cej->cei", chol, rng.normal(size=truth.shape))
        weighted = fit_pointer(EndViews.of(rot, trans, noisy, weights, length, 1e-4), FRONT, BACK)
        honest = fit_pointer(
            EndViews.of(rot, trans, noisy, weights, length, 1e-4, error_covariances=errors), FRONT, BACK
        )
        assert np.allclose(honest.front_m, weighted.front_m, atol=1e-12)
        fronts.append(honest.front_m - FRONT)
        covariances.append(honest.covariance[:3, :3] / honest.inflation)
    scatter = np.cov(np.array(fronts).T)
    claimed = np.mean(covariances, axis=0)
    # The trace (the mean squared error) within 15 %; the weights alone claim less than half of it.
    assert 0.85 < np.trace(claimed) / np.trace(scatter) < 1.15
    weighted_only = fit_pointer(EndViews.of(rot, trans, truth, weights, length, 1e-4), FRONT, BACK).covariance
    assert np.trace(weighted_only[:3, :3]) < 0.5 * np.trace(scatter)


def test_one_measurement_pulled_by_an_occluder_is_left_out() -> None:
    """Four cameras, one end in one camera 6 px off (an outline fitted to the wrong arc): the robust fit
    drops it and lands on the truth; the plain fit is pulled by it."""
    cameras = [*_behind_pair(), _camera("c", [-1.0, 1.8, 3.0]), _camera("d", [4.5, 1.8, 3.0])]
    rot, trans = _arrays(cameras)
    measured = predict(rot, trans, FRONT, BACK)
    measured[1, 0] += np.array([6.0, -2.0]) / 1600
    covariances = np.tile(np.eye(2) * (0.1 / 1600) ** 2, (4, 2, 1, 1))
    length = float(np.linalg.norm(FRONT - BACK))
    plain = fit_pointer(EndViews.of(rot, trans, measured, covariances, length, 0.003), FRONT, BACK)
    robust = fit_pointer_robust(EndViews.of(rot, trans, measured, covariances, length, 0.003), FRONT, BACK)
    assert np.linalg.norm(plain.front_m - FRONT) > 2e-3
    assert robust.dropped == ((1, 0),)
    assert np.linalg.norm(robust.front_m - FRONT) < 1e-6


def test_a_missing_measurement_weighs_nothing() -> None:
    cameras = [*_behind_pair(), _camera("c", [-1.0, 1.8, 3.0])]
    rot, trans = _arrays(cameras)
    measured = predict(rot, trans, FRONT, BACK)
    covariances = np.tile(np.eye(2) * (0.1 / 1600) ** 2, (3, 2, 1, 1))
    measured[2, 1] = [0.3, -0.2]  # nonsense, but "not there"
    covariances[2, 1] = np.eye(2) * DROPPED_VARIANCE
    views = EndViews.of(rot, trans, measured, covariances, float(np.linalg.norm(FRONT - BACK)), 0.003)
    fit = fit_pointer(views, FRONT, BACK)
    assert np.linalg.norm(fit.back_m - BACK) < 1e-6


def test_a_missing_end_is_no_degree_of_freedom_of_the_inflation() -> None:
    """Monte Carlo: three cameras, one of which misses the back end; every measurement truly off by twice
    the error it states. The inflation (reduced chi-square above 1) finds the factor of four in variance:
    the missing end, whose residuals are zero, is not counted among the degrees of freedom (counted, it
    made the inflation 5/7 of what the cameras' disagreement says)."""
    cameras = [*_behind_pair(), _camera("c", [-1.0, 1.8, 3.0])]
    rot, trans = _arrays(cameras)
    truth = predict(rot, trans, FRONT, BACK)
    sigma = 0.2 / 1600
    covariances = np.tile(np.eye(2) * sigma**2, (3, 2, 1, 1))
    covariances[2, 1] = np.eye(2) * DROPPED_VARIANCE
    length = float(np.linalg.norm(FRONT - BACK))
    rng = np.random.default_rng(6)
    inflations = []
    for _ in range(300):
        noisy = truth + rng.normal(0.0, 2.0 * sigma, truth.shape)
        fit = fit_pointer(EndViews.of(rot, trans, noisy, covariances, length, 1e-5), FRONT, BACK)
        assert fit.dof == 5  # five measurements of two coordinates, six unknowns less the length's one
        inflations.append(fit.inflation)
    assert 3.5 < np.mean(inflations) < 4.6, np.mean(inflations)


def test_the_hit_covariance_is_the_linearised_hit() -> None:
    """hit_covariance against finite differences of the line's intersection with z = 0."""
    normal, offset = np.array([0.0, 0.0, 1.0]), 0.0
    axes = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])

    def hit(params: np.ndarray) -> np.ndarray:
        f, b = params[:3], params[3:]
        u = -(normal @ b + offset) / (normal @ (f - b))
        return axes @ (b + u * (f - b))

    params = np.concatenate([FRONT, BACK])
    jac = np.zeros((2, 6))
    for k in range(6):
        step = np.zeros(6)
        step[k] = 1e-6
        jac[:, k] = (hit(params + step) - hit(params - step)) / 2e-6
    covariance = np.diag(np.arange(1.0, 7.0)) * 1e-6
    expected = jac @ covariance @ jac.T
    assert np.allclose(hit_covariance(FRONT, BACK, covariance, normal, offset, axes), expected, rtol=1e-5)
    with pytest.raises(GeometryError):
        hit_covariance(FRONT, FRONT + np.array([1.0, 0.0, 0.0]), covariance, normal, offset, axes)


def _grazing_circle(centre, radius: float, points: int = 40):
    """Where the rays from the origin that graze a sphere touch it: a circle on the sphere (its outline)."""
    d = float(np.linalg.norm(centre))
    u = centre / d
    e1 = np.cross(u, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    angles = np.linspace(0, 2 * np.pi, points, endpoint=False)
    return (centre - radius**2 / d * u) + radius * np.sqrt(1 - (radius / d) ** 2) * (
        np.cos(angles)[:, None] * e1 + np.sin(angles)[:, None] * e2
    )


@pytest.mark.parametrize("distortion", [np.zeros(0), np.array([-0.3, 0.1, 0.001, -0.001, 0.0])])
def test_a_balls_outline_gives_its_centres_direction_exactly(distortion) -> None:
    """The rim of a sphere, projected through a distorted lens and undistorted again, fits a cone whose
    axis is the ray through the sphere's centre, off-axis where the image ellipse's centre is not."""
    cam = CameraModel("c", 1920, 1080, K, distortion, np.eye(3), np.zeros(3))
    centre = np.array([0.9, -0.4, 2.0])  # far off-axis
    radius = 0.03
    d = np.linalg.norm(centre)
    ring = _grazing_circle(centre, radius)
    rim_px = cam.project(ring)
    cone = fit_sphere_direction(cam.normalized_from_pixels(rim_px))
    assert cone is not None
    assert np.allclose(cone.normalised, centre[:2] / centre[2], atol=1e-9)
    assert abs(np.sin(cone.half_angle_rad) - radius / d) < 1e-9
    # Half the rim (the other half hidden) still gives the centre.
    half = fit_sphere_direction(cam.normalized_from_pixels(rim_px[:20]))
    assert half is not None and np.allclose(half.normalised, centre[:2] / centre[2], atol=1e-9)


@pytest.mark.parametrize("distortion", [np.zeros(0), np.array([-0.3, 0.1, 0.001, -0.001, 0.0])])
def test_a_balls_outline_is_a_circle_of_its_angular_size_in_the_view_map(distortion) -> None:
    """A sphere 35 degrees off the axis images as an ellipse stretched away from the axis by about
    1 / cos(35 deg) = 1.22 (less through a barrel lens); mapped by the view map at its image, its rim is
    a circle of radius focal * tan(half-angle) about the image of its centre (to the map's linearisation
    over the ball)."""
    cam = CameraModel("c", 1920, 1080, K, distortion, np.eye(3), np.zeros(3))
    assert np.allclose(view_map(cam, np.array([960.0, 540.0])), np.eye(2), atol=1e-6)
    centre = np.array([0.9, -0.95, 1.9])  # 35 degrees off-axis
    radius, d = 0.02, float(np.linalg.norm(np.array([0.9, -0.95, 1.9])))
    ring = _grazing_circle(centre, radius)
    rim_px = cam.project(ring)
    at = cam.project(centre[None])[0]
    in_pixels = np.linalg.norm(rim_px - rim_px.mean(axis=0), axis=1)
    if not distortion.size:  # (a barrel lens undoes part of the stretch)
        assert in_pixels.max() / in_pixels.min() > 1.15  # not a circle in pixels
    mapped = (rim_px - at) @ view_map(cam, at).T
    distances = np.linalg.norm(mapped, axis=1)
    expected = cam.focal_px * radius / np.sqrt(d * d - radius * radius)
    assert np.all(np.abs(distances - expected) < 0.02 * expected), (distances.min(), distances.max(), expected)


def test_near_parallel_interpretation_planes_a_good_line_and_an_honest_uncertainty() -> None:
    """Cameras behind the presenter with the pointer's line, extended back, passing between them: their
    planes through the pointer are within a few degrees of each other, and the line rests on where the
    ends are along it. The fit is at least as good there as the two triangulated points the old code fell
    back to, and the hit's covariance it reports covers its errors as a covariance should (whitened
    squared errors averaging 2, the wall's two axes)."""
    from trackerd.geometry.pointer_line import estimate_pointer_line
    from trackerd.geometry.wall import Plane, intersect_line_plane

    front, back = np.array([1.72, 0.6, 1.6]), np.array([1.78, 0.605, 2.02])
    # Both cameras 5.5 m from the wall, close to the plane that holds the pointer and the wall's x axis.
    at_back = back + (5.5 - back[2]) / (back[2] - front[2]) * (back - front)
    cameras = [
        _camera("a", at_back + np.array([-1.3, 0.012, 0.0]), [1.75, 0.6, 1.0]),
        _camera("b", at_back + np.array([0.6, 0.02, 0.0]), [1.75, 0.6, 1.0]),
    ]
    rot, trans = _arrays(cameras)
    truth = predict(rot, trans, front, back)
    wall = Plane(np.array([0.0, 0.0, 1.0]), 0.0)
    axes = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    true_hit = intersect_line_plane(back, front, wall).point_m
    rng = np.random.default_rng(9)
    old_errors, fit_errors, whitened = [], [], []
    for _ in range(200):
        measured = truth.copy()
        covariances = np.zeros((2, 2, 2, 2))
        for c in range(2):
            along = truth[c, 0] - truth[c, 1]
            along /= np.linalg.norm(along)
            across = np.array([-along[1], along[0]])
            # Outline measurements: 0.05 px across the pointer, 0.4 px along it (where the rod meets the ball).
            measured[c] += rng.normal(0, 0.05 / 1600, (2, 1)) * across + rng.normal(0, 0.4 / 1600, (2, 1)) * along
            covariances[c] = (np.outer(across, across) * 0.05**2 + np.outer(along, along) * 0.4**2) / 1600**2
        dirs = np.einsum("cej,cjk->cek", np.concatenate([measured, np.ones((2, 2, 1))], axis=2), rot)
        old = estimate_pointer_line(np.stack([c.centre_m for c in cameras]), dirs[:, 0], dirs[:, 1])
        assert old.plane_angle_sin < 0.08 and old.method == "points"
        old_errors.append(np.linalg.norm(intersect_line_plane(old.back_m, old.front_m, wall).point_m - true_hit))
        fit = fit_pointer(EndViews.of(rot, trans, measured, covariances, 0.42, 1e-4), old.front_m, old.back_m)
        hit = intersect_line_plane(fit.back_m, fit.front_m, wall).point_m
        fit_errors.append(np.linalg.norm(hit - true_hit))
        cov = hit_covariance(fit.front_m, fit.back_m, fit.covariance / fit.inflation, wall.normal, 0.0, axes)
        error = axes @ (hit - true_hit)
        whitened.append(float(error @ np.linalg.inv(cov) @ error))
    assert np.median(fit_errors) <= np.median(old_errors)
    assert 1.6 < np.mean(whitened) < 2.5


def test_the_step_with_correlated_ends_states_the_scatter_of_the_wall_hit() -> None:
    """Monte Carlo: each camera's two ends err together (correlation 0.6 across the pointer's image and
    along it, as tracked ends do, trackerd/tracked_ends.py END_CORRELATION). The step's covariance given
    that correlation describes the hits' scatter on the wall; stated as if independent it overstates it
    (the common part shifts the line, and only the turn is magnified on the wall)."""
    from trackerd.geometry.pointer_fit import end_cross_covariances

    cameras = _behind_pair()
    rot, trans = _arrays(cameras)
    truth = predict(rot, trans, FRONT, BACK)
    sigma = 0.3 / 1600
    covariances = np.tile(np.eye(2) * sigma**2, (2, 2, 1, 1))
    length = float(np.linalg.norm(FRONT - BACK))
    # Each camera's four coordinates (front x, y, back x, y) with the cross blocks the fit is told of.
    cross = end_cross_covariances(truth, covariances, 0.6)
    joint = np.zeros((2, 4, 4))
    joint[:, :2, :2] = covariances[:, 0]
    joint[:, 2:, 2:] = covariances[:, 1]
    joint[:, :2, 2:] = cross
    joint[:, 2:, :2] = np.swapaxes(cross, 1, 2)
    chol = np.linalg.cholesky(joint)
    normal, offset = np.array([0.0, 0.0, 1.0]), 0.0
    axes = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    rng = np.random.default_rng(8)
    hits, stated, independent = [], [], []
    for _ in range(400):
        noise = np.einsum("cij,cj->ci", chol, rng.normal(size=(2, 4))).reshape(2, 2, 2)
        views = EndViews.of(rot, trans, truth + noise, covariances, length, 1e-4)
        fit = fit_pointer_step(views, FRONT, BACK, end_correlation=0.6)
        alone = fit_pointer_step(views, FRONT, BACK)
        direction = fit.front_m - fit.back_m
        hits.append(fit.back_m - (fit.back_m @ normal + offset) / (direction @ normal) * direction)
        for out, one in ((stated, fit), (independent, alone)):
            covariance = hit_covariance(one.front_m, one.back_m, one.covariance / one.inflation, normal, offset, axes)
            out.append(float(np.trace(covariance)))
    spread = float(np.mean(np.sum((np.array(hits)[:, :2] - np.mean(np.array(hits)[:, :2], axis=0)) ** 2, axis=1)))
    assert np.mean(stated) == pytest.approx(spread, rel=0.15)
    assert np.mean(independent) > 1.3 * spread
