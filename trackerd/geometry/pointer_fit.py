"""The pointer's two end centres fitted to every camera's measurements at once, with the known length.

The interpretation planes (trackerd/geometry/pointer_line.py) use only what each
camera sees *across* the pointer, and are ill-conditioned when the cameras' planes
through it are nearly parallel (cameras behind the presenter, looking along the
pointer); the report's two triangulated points (eq. 15-17, 26) use everything
each camera sees, including the ends' positions *along* the pointer, which a
partly hidden ball shifts. Neither is right for every rig. Here the two centres
F and B are the maximum-likelihood estimate given

* each end's measured position in each camera's undistorted normalised image
  plane, with its own 2x2 covariance (small across the pointer, where the
  measurement is good; larger along it where a ball is partly hidden; large in
  every direction for a poor measurement), and
* the pointer's known length, |F - B| = L, within its manufacturing tolerance,

by Gauss-Newton on the whitened residuals. So each camera and each direction
weighs by how well it is measured, two or more cameras are used alike, and the
covariance of (F, B) comes out of the same normal equations: the hit's
uncertainty is that covariance carried through eq. 26-28 to the wall, inflated
when the cameras disagree by more than their stated errors (reduced chi-square
above 1).

Shapes: C cameras; world-to-camera rotations (C, 3, 3) and translations (C, 3);
measurements (C, 2 ends, 2) with covariances (C, 2, 2, 2); ends are [front, back].
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from trackerd.errors import GeometryError

Array = NDArray[np.float64]


@dataclass(frozen=True)
class EndViews:
    """What the fit is given: C cameras' poses, their measurements of both ends, and the pointer's length."""

    rotations: Array
    """World-to-camera rotations (C, 3, 3)."""
    translations_m: Array
    """World-to-camera translations (C, 3)."""
    measured: Array
    """Each end in each camera's normalised image plane (C, 2 ends (front, back), 2)."""
    covariances: Array
    """Their covariances (C, 2, 2, 2); DROPPED_VARIANCE times the identity where a camera does not see an end."""
    length_m: float
    length_sigma_m: float
    """The length prior's standard deviation."""
    ball_radius_m: float = 0.0
    """> 0: each measurement is the centre of the ball's image ellipse (a centroid); 0: the projection of
    the ball's centre (a fitted outline)."""
    error_covariances: Array | None = None
    """(C, 2, 2, 2): the covariances of the measurements' actual errors where they exceed the weights
    ``covariances`` give them (None: the same). The fit weighs by ``covariances``; its covariance is that
    of the weighted estimate under these errors (:func:`fit_pointer`)."""

    @staticmethod
    def of(
        rotations: Array,
        translations_m: Array,
        measured: Array,
        covariances: Array,
        length_m: float,
        length_sigma_m: float,
        ball_radius_m: float = 0.0,
        error_covariances: Array | None = None,
    ) -> EndViews:
        """The views as float64 arrays (the covariances copied: the robust fit changes them)."""
        return EndViews(
            np.asarray(rotations, dtype=np.float64),
            np.asarray(translations_m, dtype=np.float64),
            np.asarray(measured, dtype=np.float64),
            np.array(covariances, dtype=np.float64),
            float(length_m),
            float(length_sigma_m),
            float(ball_radius_m),
            None if error_covariances is None else np.array(error_covariances, dtype=np.float64),
        )


@dataclass(frozen=True)
class PointerFit:
    """The fitted end centres and what they rest on."""

    front_m: Array
    back_m: Array
    covariance: Array
    """6x6 covariance of (front, back), world metres, already inflated by :attr:`inflation`."""
    chi2: float
    """Sum of squared whitened residuals (length prior included)."""
    dof: int
    inflation: float
    """Factor the covariance was multiplied by: max(1, chi2 / dof), the chi-square taken against the
    measurements' error covariances where they are given."""
    iterations: int
    dropped: tuple[tuple[int, int], ...] = ()
    """(camera, end) measurements left out as not agreeing with the others (a ball's outline fitted
    to the wrong arc, say)."""


OUTLIER_SIGMAS = 4.0
"""A measurement is left out when its absence lowers the fit's chi-square by more than this squared."""

INCONSISTENT = 2.0
"""A fit whose chi-square exceeds this times its degrees of freedom looks for a measurement to leave out."""


def fit_pointer_robust(
    views: EndViews, front0_m: Array, back0_m: Array, rounds: int = 2, min_cameras: int = 2
) -> PointerFit:
    """:func:`fit_pointer`, leaving out measurements that do not agree with the others.

    While the measurements disagree (reduced chi-square above INCONSISTENT), the fit is redone without
    each measurement in turn; the one whose absence lowers the chi-square most is left out for good if it
    lowers it by more than OUTLIER_SIGMAS squared (a deletion test: that measurement alone is that many
    standard errors from where the others put it). Up to ``rounds`` of them, never so many that an end
    is measured by fewer than ``min_cameras`` cameras. Leaving each out in turn, rather than the one with
    the largest residual, is what finds the culprit: a bad measurement pulls the fit towards itself, and
    the largest residuals are then often the good ones; where the cameras are nearly in line, it can
    pull the fit so far along their common direction that its own residual is small.
    """
    cov = np.array(views.covariances, dtype=np.float64)  # a copy: measurements left out change it
    errors = None if views.error_covariances is None else np.array(views.error_covariances, dtype=np.float64)
    present = np.array([[float(np.trace(cov[c, e])) < DROPPED_VARIANCE for e in range(2)] for c in range(len(cov))])
    dropped: list[tuple[int, int]] = []
    fit = fit_pointer(replace(views, covariances=cov, error_covariances=errors), front0_m, back0_m)
    for _ in range(rounds):
        if fit.chi2 <= INCONSISTENT * _dof(present):
            break
        best: tuple[float, tuple[int, int], PointerFit] | None = None
        for c, e in zip(*np.nonzero(present), strict=True):
            if int(np.count_nonzero(present[:, e])) <= min_cameras:
                continue
            trial = cov.copy()
            trial[c, e] = np.eye(2) * DROPPED_VARIANCE
            trial_errors = None if errors is None else errors.copy()
            if trial_errors is not None:
                trial_errors[c, e] = np.eye(2) * DROPPED_VARIANCE
            try:
                candidate = fit_pointer(
                    replace(views, covariances=trial, error_covariances=trial_errors), fit.front_m, fit.back_m
                )
            except GeometryError:
                continue
            if best is None or candidate.chi2 < best[0]:
                best = (candidate.chi2, (int(c), int(e)), candidate)
        if best is None or fit.chi2 - best[0] <= OUTLIER_SIGMAS**2:
            break
        _, (c, e), fit = best
        cov[c, e] = np.eye(2) * DROPPED_VARIANCE
        if errors is not None:
            errors[c, e] = np.eye(2) * DROPPED_VARIANCE
        present[c, e] = False
        dropped.append((c, e))
    if dropped:
        fit = PointerFit(
            fit.front_m, fit.back_m, fit.covariance, fit.chi2, fit.dof, fit.inflation, fit.iterations, tuple(dropped)
        )
    return fit


def _dof(present: Array) -> int:
    """Degrees of freedom of a fit to the measurements present: two each, one for the length, less six."""
    return max(2 * int(np.count_nonzero(present)) + 1 - 6, 1)


DROPPED_VARIANCE = 1e4
"""The covariance (normalised units squared) of a measurement that is not there: it weighs nothing."""


def predict(
    rotations: Array, translations_m: Array, front_m: Array, back_m: Array, ball_radius_m: float = 0.0
) -> Array:
    """Where the fit puts each end in each camera's normalised image plane: (C, 2 ends, 2)."""
    ends = np.stack([np.asarray(front_m, dtype=np.float64), np.asarray(back_m, dtype=np.float64)])
    xc = np.einsum("cij,ej->cei", rotations, ends) + translations_m[:, None, :]
    z = xc[..., 2]
    factor = 1.0 / (1.0 - ball_radius_m**2 / (z * z)) if ball_radius_m > 0 else 1.0
    return np.stack([xc[..., 0] / z * factor, xc[..., 1] / z * factor], axis=-1)


def fit_pointer(views: EndViews, front0_m: Array, back0_m: Array, max_iterations: int = 8) -> PointerFit:
    """Fit F and B (see the module) to ``views``, from F = ``front0_m`` and B = ``back0_m``."""
    rot, trans, obs, cov = views.rotations, views.translations_m, views.measured, views.covariances
    length_m, length_sigma_m, ball_radius_m = views.length_m, views.length_sigma_m, views.ball_radius_m
    cameras = rot.shape[0]
    whiten = _whitening(cov)
    params = np.concatenate([np.asarray(front0_m, dtype=np.float64), np.asarray(back0_m, dtype=np.float64)])
    k2 = ball_radius_m * ball_radius_m
    iterations = 0
    for _ in range(max_iterations):
        iterations += 1
        residuals, jacobian = _linearise(params, rot, trans, obs, whiten, k2, length_m, length_sigma_m, cameras)
        jtj = jacobian.T @ jacobian
        gradient = jacobian.T @ residuals
        try:
            step = np.linalg.solve(jtj + 1e-12 * np.trace(jtj) * np.eye(6), -gradient)
        except np.linalg.LinAlgError as err:
            raise GeometryError("the cameras do not constrain the pointer (singular fit)") from err
        params = params + step
        if float(np.max(np.abs(step))) < 1e-7:
            break
    residuals, jacobian = _linearise(params, rot, trans, obs, whiten, k2, length_m, length_sigma_m, cameras)
    chi2 = float(residuals @ residuals)
    jtj = jacobian.T @ jacobian
    try:
        covariance = np.asarray(np.linalg.inv(jtj), dtype=np.float64)  # float64 already: typed, not copied
    except np.linalg.LinAlgError as err:
        raise GeometryError("the cameras do not constrain the pointer (singular fit)") from err
    # A camera's missing end (DROPPED_VARIANCE) has residuals of ~0 and is no degree of freedom.
    present = np.trace(cov, axis1=2, axis2=3) < DROPPED_VARIANCE
    dof = _dof(present)
    disagreement = chi2
    if views.error_covariances is not None:
        covariance, disagreement = _sandwich(covariance, jacobian, residuals, whiten, views.error_covariances)
    inflation = max(1.0, disagreement / dof)
    return PointerFit(params[:3].copy(), params[3:].copy(), covariance * inflation, chi2, dof, inflation, iterations)


def fit_pointer_step(views: EndViews, front0_m: Array, back0_m: Array, end_correlation: float = 0.0) -> PointerFit:
    """One Gauss-Newton step of :func:`fit_pointer` from F = ``front0_m``, B = ``back0_m``, its chi-square
    and covariance taken from the same linearisation (the residuals after the step predicted linearly).

    For a start within millimetres of the answer (a tracked pair, from the last pair's ends): from 12 mm
    away, the full fit's ends to tens of micrometres (a twentieth of a millimetre on a wall 2 m beyond),
    its covariance to 2 % and its chi-square to 5 % (tests/geometry/test_pointer_fit.py), at a third of its
    cost. ``views.error_covariances`` is not used. ``end_correlation``: the correlation of one camera's two
    ends' errors, across the pointer's image and along it alike (:func:`end_cross_covariances`); the
    covariance is then that of the step under those errors (the weights stay per end)."""
    rot, trans, obs, cov = views.rotations, views.translations_m, views.measured, views.covariances
    whiten = _whitening(cov)
    params = np.concatenate([np.asarray(front0_m, dtype=np.float64), np.asarray(back0_m, dtype=np.float64)])
    residuals, jacobian = _linearise(
        params,
        rot,
        trans,
        obs,
        whiten,
        views.ball_radius_m**2,
        views.length_m,
        views.length_sigma_m,
        rot.shape[0],
    )
    jtj = jacobian.T @ jacobian
    try:
        covariance = np.asarray(np.linalg.inv(jtj + 1e-12 * np.trace(jtj) * np.eye(6)), dtype=np.float64)
    except np.linalg.LinAlgError as err:
        raise GeometryError("the cameras do not constrain the pointer (singular fit)") from err
    step = -covariance @ (jacobian.T @ residuals)
    after = residuals + jacobian @ step
    chi2 = float(after @ after)
    dof = _dof(np.trace(cov, axis1=2, axis2=3) < DROPPED_VARIANCE)
    inflation = max(1.0, chi2 / dof)
    params = params + step
    if end_correlation:
        covariance = _correlated(covariance, jacobian, whiten, end_cross_covariances(obs, cov, end_correlation))
    return PointerFit(params[:3].copy(), params[3:].copy(), covariance * inflation, chi2, dof, inflation, 1)


def end_cross_covariances(measured: Array, covariances: Array, correlation: float) -> Array:
    """(C, 2, 2): the covariance of each camera's front end's error with its back end's, when they correlate
    by ``correlation`` across the pointer's image and along it: rho (s_f s_b a a^T + t_f t_b u u^T), with u
    the unit vector along the camera's image of the pointer, a across it, s and t each end's standard errors
    across and along (from ``covariances`` (C, 2, 2, 2))."""
    along = measured[:, 0] - measured[:, 1]
    along = along / np.maximum(np.linalg.norm(along, axis=-1, keepdims=True), 1e-300)
    # Columns: across the pointer's image (along turned a quarter), along it.
    basis = np.stack([along[:, ::-1] * np.array([-1.0, 1.0]), along], axis=-1)  # (C, 2, 2)
    rotated = np.swapaxes(basis, 1, 2)[:, None] @ covariances @ basis[:, None]  # (C, 2 ends, 2, 2)
    sigmas = np.sqrt(np.maximum(np.diagonal(rotated, axis1=2, axis2=3), 0.0))  # (C, 2 ends, across / along)
    cross: Array = (basis * (correlation * sigmas[:, 0] * sigmas[:, 1])[:, None, :]) @ np.swapaxes(basis, 1, 2)
    return cross


def _correlated(covariance: Array, jacobian: Array, whiten: Array, cross: Array) -> Array:
    """The covariance of a fit weighted per end when each camera's two ends' errors have the cross-covariance
    ``cross`` (C, 2, 2) besides the variances the weights ``whiten`` were made from: the sandwich (see
    :func:`_sandwich`) with the whitened residuals' covariance I + the blocks W_f X W_b^T between a camera's
    two ends, that is H^-1 (J^T J + K + K^T) H^-1 with K the sum over cameras of J_f^T W_f X W_b^T J_b."""
    cameras = whiten.shape[0]
    blocks = whiten[:, 0] @ cross @ np.swapaxes(whiten[:, 1], 1, 2)  # (C, 2, 2)
    rows = jacobian[: 4 * cameras].reshape(cameras, 2, 2, 6)  # camera, end, coordinate, parameter
    coupling = (np.swapaxes(rows[:, 0], 1, 2) @ blocks @ rows[:, 1]).sum(axis=0)
    middle = jacobian.T @ jacobian + coupling + coupling.T
    return np.asarray(covariance @ middle @ covariance, dtype=np.float64)


def _whitening(cov: Array) -> Array:
    """L^T with L L^T = cov^-1, per camera and end (C, 2, 2, 2). Raises GeometryError."""
    try:
        whiten: Array = np.linalg.cholesky(np.linalg.inv(cov)).transpose(0, 1, 3, 2)
    except np.linalg.LinAlgError as err:
        raise GeometryError("a measurement's covariance is not positive definite") from err
    return whiten


def _sandwich(
    covariance: Array, jacobian: Array, residuals: Array, whiten: Array, error_covariances: Array
) -> tuple[Array, float]:
    """The covariance of the weighted fit when the measurements' errors have ``error_covariances`` (C, 2,
    2, 2) rather than the covariances the weights ``whiten`` were made from, and the chi-square of the
    residuals against those errors.

    The estimate is linear in the whitened residuals r: d(params) = -H^-1 J^T r with H = J^T J (the
    ``covariance`` given is H^-1); if r has covariance S, the estimate has H^-1 J^T S J H^-1 (the
    "sandwich"). A measurement's whitened error is its raw error times its whitening W, so S holds W E
    W^T in its 2x2 blocks (E: its error covariance), and 1 for the length prior, whose weight is its
    error."""
    blocks = np.einsum("cekl,celm,ceqm->cekq", whiten, error_covariances, whiten)  # (C, 2, 2, 2)
    count = blocks.shape[0] * 2
    spread = np.zeros((2 * count + 1, 2 * count + 1))
    for index, block in enumerate(blocks.reshape(count, 2, 2)):
        spread[2 * index : 2 * index + 2, 2 * index : 2 * index + 2] = block
    spread[-1, -1] = 1.0
    middle = jacobian.T @ spread @ jacobian
    sandwich = np.asarray(covariance @ middle @ covariance, dtype=np.float64)
    # The residuals against the errors' own covariances: what the errors do not explain.
    try:
        information = np.linalg.inv(spread)
    except np.linalg.LinAlgError:
        return sandwich, float(residuals @ residuals)
    return sandwich, float(residuals @ information @ residuals)


def _linearise(
    params: Array,
    rot: Array,
    trans: Array,
    obs: Array,
    whiten: Array,
    k2: float,
    length_m: float,
    length_sigma_m: float,
    cameras: int,
) -> tuple[Array, Array]:
    """Whitened residuals (4C + 1,) and their Jacobian (4C + 1, 6) at ``params``."""
    ends = params.reshape(2, 3)
    # Camera coordinates of both ends in every camera: (C, 2, 3).
    xc = np.einsum("cij,ej->cei", rot, ends) + trans[:, None, :]
    z = xc[..., 2]
    if np.any(z <= 1e-6):
        raise GeometryError("an end would be behind a camera")
    scale = 1.0 / z
    # The centre of a sphere's image ellipse lies 1 / (1 - r^2 / z^2) further out than its centre's projection.
    factor = 1.0 / (1.0 - k2 / (z * z)) if k2 > 0.0 else np.ones_like(z)
    px = xc[..., 0] * scale * factor
    py = xc[..., 1] * scale * factor
    predicted = np.stack([px, py], axis=-1)
    raw = predicted - obs  # (C, 2, 2)
    # d(predicted)/d(xc), ignoring the ellipse factor's own derivative (a fraction of a percent).
    d = np.zeros((cameras, 2, 2, 3))
    d[..., 0, 0] = scale * factor
    d[..., 0, 2] = -xc[..., 0] * scale * scale * factor
    d[..., 1, 1] = scale * factor
    d[..., 1, 2] = -xc[..., 1] * scale * scale * factor
    # d(predicted)/d(end) = d(predicted)/d(xc) @ R.
    d_end = np.einsum("ceki,cij->cekj", d, rot)
    white = np.einsum("cekl,cel->cek", whiten, raw)
    white_jac = np.einsum("cekl,celj->cekj", whiten, d_end)  # (C, 2, 2, 3)
    jacobian = np.zeros((cameras, 2, 2, 6))
    jacobian[:, 0, :, 0:3] = white_jac[:, 0]
    jacobian[:, 1, :, 3:6] = white_jac[:, 1]
    axis = ends[0] - ends[1]
    length = float(np.linalg.norm(axis))
    if length < 1e-9:
        raise GeometryError("the pointer's ends coincide")
    unit = axis / length
    length_row = np.concatenate([unit, -unit]) / length_sigma_m
    residuals = np.concatenate([white.reshape(-1), [(length - length_m) / length_sigma_m]])
    jacobian_rows = np.vstack([jacobian.reshape(-1, 6), length_row[None, :]])
    return residuals, jacobian_rows


def hit_covariance(
    front_m: Array, back_m: Array, covariance: Array, plane_normal: Array, plane_offset_m: float, wall_axes: Array
) -> Array:
    """2x2 covariance of the wall hit (in the wall's x, y axes, metres) of the line back -> front, from the
    6x6 covariance of (front, back): eq. 26-28 linearised.

    The hit is ``B + u (F - B)`` with ``u = -(n . B + d) / (n . (F - B))``; ``wall_axes`` (2, 3) are the
    wall frame's x and y axes.
    """
    front = np.asarray(front_m, dtype=np.float64)
    back = np.asarray(back_m, dtype=np.float64)
    normal = np.asarray(plane_normal, dtype=np.float64)
    direction = front - back
    denominator = float(normal @ direction)
    if abs(denominator) < 1e-12:
        raise GeometryError("the pointer is parallel to the wall")
    u = -(float(normal @ back) + plane_offset_m) / denominator
    eye = np.eye(3)
    # du/dF and du/dB.
    du_df = u * (-normal / denominator)
    du_db = (-normal - u * (-normal)) / denominator
    # dH/dF = u I + direction du/dF^T ; dH/dB = (1 - u) I + direction du/dB^T.
    dh_df = u * eye + np.outer(direction, du_df)
    dh_db = (1.0 - u) * eye + np.outer(direction, du_db)
    jac = np.asarray(wall_axes, dtype=np.float64) @ np.hstack([dh_df, dh_db])  # (2, 6)
    return jac @ covariance @ jac.T
