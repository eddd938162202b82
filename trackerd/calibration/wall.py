"""The wall's plane and 2D frame, from what the calibrated cameras see of the pointer.

Three kinds of observation, usable together:

* a **touch**: the pointer's tip ball held against the wall at a known place (a
  display corner, a taped mark). The triangulated tip centre lies one ball radius
  in front of the wall plane, at the known wall coordinates;
* a **touch anywhere**: the same without a known place; it only pins the plane;
* a **pointing**: the pointer aimed at a known target (a cross shown on the display,
  a laser dot on it); the target lies on the pointer's line. From two or more
  places the lines meet at the target, so targets the cameras cannot see (the
  display's far corners) are reached too.

The report measured three points by hand and took the plane through them (eq.
23-25); here every observation is a residual of one least-squares problem whose
unknowns are the wall frame (origin, x along the wall, y up, normal into the
room) and, when the targets are defined by the display (its corners, display
pixels), the display's size. Each observation's residual is reported, so a
wrong corner or a moved camera stands out.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from trackerd.calibration import CalibrationError
from trackerd.errors import GeometryError
from trackerd.geometry.rotation import rotation_from_rvec
from trackerd.geometry.triangulation import triangulate_least_squares
from trackerd.geometry.wall import WallFrame, fit_plane

Array = NDArray[np.float64]

CORNER_LABELS = {"bl": (0.0, 0.0), "br": (1.0, 0.0), "tr": (1.0, 1.0), "tl": (0.0, 1.0)}
"""Display corners as fractions of the wall's width and height."""


@dataclass(frozen=True)
class Target:
    """A place on the wall: its coordinates in metres (x right, y up from the display's bottom-left).

    ``scalable`` targets are defined by the display (its corners, display pixels) and
    move with its size when the size is solved for; marks measured with a tape are not.
    """

    label: str
    wall_xy_m: Array | None
    scalable: bool = False


def corner_targets(width_m: float, height_m: float) -> dict[str, Target]:
    """The display's corners bl, br, tr, tl as scalable targets."""
    return {
        label: Target(label, np.array([fx * width_m, fy * height_m]), True) for label, (fx, fy) in CORNER_LABELS.items()
    }


@dataclass(frozen=True)
class Touch:
    """The tip ball held against the wall: its triangulated centre and the back ball's."""

    target: Target
    tip_m: Array
    back_m: Array


@dataclass(frozen=True)
class Pointing:
    """The pointer aimed at a target: its triangulated ends (the line through them meets the target)."""

    target: Target
    tip_m: Array
    back_m: Array

    @property
    def direction(self) -> Array:
        axis = self.tip_m - self.back_m
        return axis / np.linalg.norm(axis)


@dataclass(frozen=True)
class Residual:
    """How one observation fits the solved wall."""

    label: str
    kind: str
    """'touch' or 'pointing'."""
    plane_mm: float | None
    """Signed distance from the wall plane (touches: of the ball's near surface; pointings: of
    the point where that target's lines meet, when there are two or more). Positive: in front."""
    in_plane_mm: float | None
    """Distance from the target's place within the plane (touches with a known place)."""
    miss_mm: float | None
    """Pointings: how far the pointer's line passes from the target."""
    used: bool = True
    """False when the observation was left out of the fit as an outlier."""

    @property
    def worst_mm(self) -> float:
        return max(abs(v) for v in (self.plane_mm, self.in_plane_mm, self.miss_mm) if v is not None)

    @property
    def fit_mm(self) -> float:
        """The residual the solve minimised for this observation (what the RMS is made of): a
        touch's distance from where it should be, a pointing's miss. A pointing's ``plane_mm`` is
        left out: where a target's lines meet is only loosely fixed along the lines."""
        if self.kind == "pointing":
            return float(self.miss_mm or 0.0)
        return float(np.hypot(self.plane_mm or 0.0, self.in_plane_mm or 0.0))


@dataclass(frozen=True)
class WallFit:
    """The solved wall in the cameras' (current world) frame."""

    rotation: Array
    """World-from-wall rotation (3, 3): columns are the wall's x (along), y (up) and normal (into the room)."""
    origin_m: Array
    """The display's bottom-left corner, world coordinates."""
    width_m: float
    height_m: float
    size_fitted: bool
    """Whether width and height were solved for (display-defined targets) or taken as given."""
    residuals: tuple[Residual, ...]
    rms_mm: float
    """RMS of the residuals of the observations used."""
    scale: Array = field(default_factory=lambda: np.ones(2))
    """Solved size over nominal size, along x and y (ones when the size was not solved for)."""
    implied_size_m: tuple[float, float] | None = None
    """The display size the targets imply (solved for whether or not the frame uses it), when the
    display-defined targets span the display; a wrong corner or a mis-sized display shows here."""

    @property
    def frame(self) -> WallFrame:
        return WallFrame(
            self.origin_m.copy(), self.rotation[:, 0].copy(), self.rotation[:, 1].copy(), self.width_m, self.height_m
        )

    @property
    def corners_m(self) -> Array:
        """(4, 3) bottom-left, bottom-right, top-right, top-left in the world frame."""
        return self.frame.corners_m

    def camera_in_wall_frame(self, rotation: Array, translation_m: Array) -> tuple[Array, Array]:
        """A camera's world-to-camera (R, t) re-expressed with the wall frame as the world.

        ``x_cam = R x_world + t`` and ``x_world = W x_wall + o`` give
        ``x_cam = (R W) x_wall + (R o + t)``.
        """
        rotation = np.asarray(rotation, dtype=np.float64)
        return rotation @ self.rotation, rotation @ self.origin_m + np.asarray(translation_m, dtype=np.float64)


ROBUST_SCALE_FLOOR_M = 0.001
"""The robust weighting never treats residuals under about this as noise worth down-weighting."""
LEFT_OUT_WEIGHT = 0.2
"""Observations whose final weight is below this (residual beyond about five robust standard
deviations) are reported as left out: a wrong blob, the pointer knocked during capture."""


DEFAULT_MAX_RMS_MM = 10.0
"""The wall step writes nothing above this RMS residual. A good fit gives 1.5-4 mm on the
simulated DataWall (docs/calibration.md); a target touched in the wrong place, a label
swapped or a moved camera gives tens to hundreds of millimetres."""


def fit_problem(fit: WallFit, max_rms_mm: float) -> str | None:
    """Why ``fit`` must not be written (its RMS above ``max_rms_mm``), naming the observations
    that are off by more than the limit, worst first; None when it may be written."""
    if np.isfinite(fit.rms_mm) and fit.rms_mm <= max_rms_mm:
        return None
    ranked = sorted((r for r in fit.residuals), key=lambda r: r.fit_mm, reverse=True)
    off = [r for r in ranked if r.fit_mm > max_rms_mm]
    which = "off by more than the limit" if off else "largest residuals"
    names = ", ".join(
        f"{r.kind} {r.label} {r.fit_mm:.1f} mm{'' if r.used else ' (left out)'}" for r in (off or ranked[:3])
    )
    rms = f"{fit.rms_mm:.2f} mm" if np.isfinite(fit.rms_mm) else "undefined (every observation left out)"
    return (
        f"wall RMS residual {rms} exceeds --max-rms-mm {max_rms_mm:.1f} mm: not written; {which}:"
        f" {names} (a target touched or aimed at in the wrong place, a wrong label, or a camera"
        " moved since it was calibrated: redo those)"
    )


def fit_wall(
    touches: Sequence[Touch],
    pointings: Sequence[Pointing],
    size_m: tuple[float, float],
    tip_radius_m: float,
    *,
    fit_size: bool | None = None,
    robust: bool = True,
) -> WallFit:
    """Solve the wall frame (and optionally its size) from touches and pointings.

    ``size_m`` is the display's configured width and height. When the targets
    defined by the display reach across most of it both ways, the size they
    imply is always solved for and reported (``implied_size_m``); whether the
    frame that is returned uses it (``fit_size``) defaults to whether those
    targets were touched. Pointing fixes a target only through where lines
    from different places cross, which leaves the wall's distance and its size
    nearly interchangeable (a wall 4 mm further back and 8 mm wider fits the
    same lines), so for pointing the configured size is kept.

    With ``robust`` the least squares is iteratively reweighted with Cauchy
    weights ``1 / (1 + (r / c)^2)``, ``c`` being 2.4 robust standard deviations
    of the observations' residuals (from their median): a pointer line that
    misses by centimetres, as a wrong blob makes it, barely moves the wall.
    Observations left with a small weight are reported with ``used`` False.
    Raises CalibrationError when the observations cannot fix a wall.
    """
    touches, pointings = list(touches), list(pointings)
    touched = [t.target for t in touches if t.target.wall_xy_m is not None]
    spans = _spans_display(touched + [p.target for p in pointings], size_m)
    if fit_size is None:
        fit_size = spans and _spans_display(touched, size_m)
    fit_size = bool(fit_size)
    fit = _solve(touches, pointings, size_m, tip_radius_m, fit_size, robust)
    if spans:
        implied = fit if fit_size else _solve(touches, pointings, size_m, tip_radius_m, True, robust)
        fit = replace(fit, implied_size_m=(implied.width_m, implied.height_m))
    return fit


def _solve(
    touches: list[Touch],
    pointings: list[Pointing],
    size_m: tuple[float, float],
    tip_radius_m: float,
    fit_size: bool,
    robust: bool,
) -> WallFit:
    estimates = _initial_points(touches, pointings)
    if len(estimates) < 3:
        raise CalibrationError(
            f"the wall needs three or more places (touched, or pointed at from two or more places);"
            f" got {len(estimates)}"
        )
    labelled = {label: xy for label, (_, xy, _) in estimates.items() if xy is not None}
    if len(labelled) < 2:
        raise CalibrationError("at least two of the places must be known on the wall (corners or marks)")
    room_side = _room_side(touches, pointings)
    rotation, origin = _initial_frame(estimates, room_side, tip_radius_m)
    params = np.zeros(8 if fit_size else 6)
    weights = np.ones(len(touches) + len(pointings))
    for _ in range(8 if robust else 1):

        def residual_vector(p: Array, w: Array = weights) -> Array:
            return _residuals(p, rotation, origin, touches, pointings, tip_radius_m, np.sqrt(w))

        params = _gauss_newton(residual_vector, params)
        if not robust:
            break
        magnitudes = _magnitudes(params, rotation, origin, touches, pointings, tip_radius_m)
        scale = max(1.4826 * float(np.median(magnitudes)), ROBUST_SCALE_FLOOR_M)
        new_weights = 1.0 / (1.0 + (magnitudes / (2.385 * scale)) ** 2)
        converged = float(np.max(np.abs(new_weights - weights))) < 0.01
        weights = new_weights
        if converged:
            break
    rot, org, scale_xy = _unpack(params, rotation, origin)
    used = weights >= LEFT_OUT_WEIGHT
    residuals = _report(rot, org, scale_xy, touches, pointings, tip_radius_m, used)
    magnitudes = _magnitudes(params, rotation, origin, touches, pointings, tip_radius_m)
    rms = float(np.sqrt(np.mean(magnitudes[used] ** 2))) * 1000.0 if np.any(used) else float("nan")
    width, height = size_m[0] * scale_xy[0], size_m[1] * scale_xy[1]
    return WallFit(rot, org, float(width), float(height), fit_size, residuals, rms, scale_xy)


def _magnitudes(
    params: Array,
    rotation0: Array,
    origin0: Array,
    touches: Sequence[Touch],
    pointings: Sequence[Pointing],
    tip_radius_m: float,
) -> Array:
    """Each observation's residual length in metres (touches first, then pointings, input order)."""
    rotation, origin, scale = _unpack(params, rotation0, origin0)
    out = [float(np.linalg.norm(_touch_residual(t, rotation, origin, scale, tip_radius_m))) for t in touches]
    out += [float(np.linalg.norm(_pointing_residual(p, rotation, origin, scale))) for p in pointings]
    return np.array(out)


def _spans_display(targets: Sequence[Target], size_m: tuple[float, float]) -> bool:
    xy = np.array([t.wall_xy_m for t in targets if t.scalable and t.wall_xy_m is not None])
    if len(xy) < 3:
        return False
    span = xy.max(axis=0) - xy.min(axis=0)
    return bool(span[0] > 0.5 * size_m[0] and span[1] > 0.5 * size_m[1])


def _initial_points(
    touches: Sequence[Touch], pointings: Sequence[Pointing]
) -> dict[str, tuple[Array, Array | None, str]]:
    """A first 3D position for each place: label -> (point, wall xy or None, 'touch' / 'pointing')."""
    out: dict[str, tuple[Array, Array | None, str]] = {}
    for index, touch in enumerate(touches):
        label = touch.target.label or f"touch {index + 1}"
        key = label if label not in out else f"{label} #{index + 1}"
        out[key] = (np.asarray(touch.tip_m, dtype=np.float64), touch.target.wall_xy_m, "touch")
    groups: dict[str, list[Pointing]] = {}
    for pointing in pointings:
        groups.setdefault(pointing.target.label, []).append(pointing)
    for label, group in groups.items():
        if len(group) < 2:
            continue
        try:
            point, _ = triangulate_least_squares(
                np.array([p.tip_m for p in group]), np.array([p.direction for p in group])
            )
        except GeometryError:
            continue
        out.setdefault(label, (point, group[0].target.wall_xy_m, "pointing"))
    return out


def _room_side(touches: Sequence[Touch], pointings: Sequence[Pointing]) -> Array:
    """A direction from the wall into the room: from the tip toward the back ball, averaged."""
    ends: list[Touch | Pointing] = [*touches, *pointings]
    vectors = [np.asarray(o.back_m) - np.asarray(o.tip_m) for o in ends]
    mean = np.mean([v / np.linalg.norm(v) for v in vectors], axis=0)
    return np.asarray(mean / np.linalg.norm(mean), dtype=np.float64)


def _initial_frame(
    estimates: dict[str, tuple[Array, Array | None, str]], room_side: Array, tip_radius_m: float
) -> tuple[Array, Array]:
    """Plane through the first estimates, then the in-plane rotation and origin from the known places."""
    points = np.array([p for p, _, _ in estimates.values()])
    try:
        plane, _ = fit_plane(points)
    except GeometryError as err:
        raise CalibrationError(f"the wall places do not fix a plane: {err}") from err
    normal = plane.normal if plane.normal @ room_side > 0 else -plane.normal
    # Touched tip centres sit one radius in front of the wall.
    shifted = {k: (p - tip_radius_m * normal if kind == "touch" else p, xy) for k, (p, xy, kind) in estimates.items()}
    seed = np.cross(normal, [0.0, 0.0, 1.0])
    if np.linalg.norm(seed) < 0.1:
        seed = np.cross(normal, [1.0, 0.0, 0.0])
    e1 = seed / np.linalg.norm(seed)
    e2 = np.cross(normal, e1)
    in_plane = np.array([[p @ e1, p @ e2] for p, xy in shifted.values() if xy is not None])
    wall_xy = np.array([xy for _, xy in shifted.values() if xy is not None])
    # 2D Kabsch: in_plane ~ R2 wall_xy + t, a rotation (no reflection: the normal is fixed).
    mean_p, mean_q = in_plane.mean(axis=0), wall_xy.mean(axis=0)
    cov = (wall_xy - mean_q).T @ (in_plane - mean_p)
    angle = np.arctan2(cov[0, 1] - cov[1, 0], cov[0, 0] + cov[1, 1])
    c, s = np.cos(angle), np.sin(angle)
    r2 = np.array([[c, -s], [s, c]])
    t2 = mean_p - r2 @ mean_q
    x_axis = r2[0, 0] * e1 + r2[1, 0] * e2
    y_axis = r2[0, 1] * e1 + r2[1, 1] * e2
    offset = -plane.offset_m if plane.normal @ room_side > 0 else plane.offset_m
    origin = t2[0] * e1 + t2[1] * e2 + offset * normal
    return np.column_stack([x_axis, y_axis, normal]), origin


def _unpack(params: Array, rotation0: Array, origin0: Array) -> tuple[Array, Array, Array]:
    rotation = rotation0 @ rotation_from_rvec(params[:3])
    origin = origin0 + params[3:6]
    scale = np.exp(params[6:8]) if len(params) == 8 else np.ones(2)
    return rotation, origin, scale


def _target_point(target: Target, rotation: Array, origin: Array, scale: Array, lift_m: float = 0.0) -> Array:
    xy = np.asarray(target.wall_xy_m, dtype=np.float64) * (scale if target.scalable else 1.0)
    return np.asarray(origin + rotation @ np.array([xy[0], xy[1], lift_m]), dtype=np.float64)


def _touch_residual(touch: Touch, rotation: Array, origin: Array, scale: Array, tip_radius_m: float) -> Array:
    """Where the tip centre is minus where it should be (3,), or its distance error from the plane (1,)."""
    if touch.target.wall_xy_m is None:
        return np.array([rotation[:, 2] @ (touch.tip_m - origin) - tip_radius_m])
    return touch.tip_m - _target_point(touch.target, rotation, origin, scale, tip_radius_m)


def _pointing_residual(pointing: Pointing, rotation: Array, origin: Array, scale: Array) -> Array:
    """The target's offset from the pointer's line, perpendicular to it (3,)."""
    rel = _target_point(pointing.target, rotation, origin, scale) - pointing.tip_m
    d = pointing.direction
    return rel - (rel @ d) * d


def _residuals(
    params: Array,
    rotation0: Array,
    origin0: Array,
    touches: Sequence[Touch],
    pointings: Sequence[Pointing],
    tip_radius_m: float,
    root_weights: Array,
) -> Array:
    rotation, origin, scale = _unpack(params, rotation0, origin0)
    parts = [_touch_residual(t, rotation, origin, scale, tip_radius_m) for t in touches]
    parts += [_pointing_residual(p, rotation, origin, scale) for p in pointings]
    if not parts:
        return np.zeros(0)
    return np.concatenate([w * part for w, part in zip(root_weights, parts, strict=True)])


def _gauss_newton(func: Callable[[Array], Array], params: Array, iterations: int = 50) -> Array:
    """Minimise |func(p)|^2 by Gauss-Newton with a numerical Jacobian and step halving."""
    step = 1e-7
    current = func(params)
    cost = float(current @ current)
    for _ in range(iterations):
        jac = np.empty((len(current), len(params)))
        for k in range(len(params)):
            delta = np.zeros(len(params))
            delta[k] = step
            jac[:, k] = (func(params + delta) - func(params - delta)) / (2 * step)
        update, *_ = np.linalg.lstsq(jac, -current, rcond=None)
        factor = 1.0
        while factor > 1e-4:
            trial = params + factor * update
            value = func(trial)
            trial_cost = float(value @ value)
            if trial_cost <= cost:
                break
            factor /= 2.0
        else:
            break
        converged = cost - trial_cost < 1e-18 + 1e-12 * cost
        params, current, cost = trial, value, trial_cost
        if converged:
            break
    return params


def _report(
    rotation: Array,
    origin: Array,
    scale: Array,
    touches: Sequence[Touch],
    pointings: Sequence[Pointing],
    tip_radius_m: float,
    used: NDArray[np.bool_],
) -> tuple[Residual, ...]:
    """Residuals of every observation (touches, then pointings grouped by target in first-seen order)."""
    normal = rotation[:, 2]
    out: list[Residual] = []
    used_t = {id(t) for t, u in zip(touches, used[: len(touches)], strict=True) if u}
    used_p = {id(p) for p, u in zip(pointings, used[len(touches) :], strict=True) if u}
    for touch in touches:
        plane = float(normal @ (touch.tip_m - origin) - tip_radius_m) * 1000.0
        in_plane = None
        if touch.target.wall_xy_m is not None:
            diff = touch.tip_m - _target_point(touch.target, rotation, origin, scale, tip_radius_m)
            in_plane = float(np.linalg.norm(diff - (diff @ normal) * normal)) * 1000.0
        out.append(Residual(touch.target.label, "touch", plane, in_plane, None, id(touch) in used_t))
    groups: dict[str, list[Pointing]] = {}
    for pointing in pointings:
        groups.setdefault(pointing.target.label, []).append(pointing)
    for label, group in groups.items():
        meet = None
        lines = [p for p in group if id(p) in used_p]
        if len(lines) >= 2:
            try:
                point, _ = triangulate_least_squares(
                    np.array([p.tip_m for p in lines]), np.array([p.direction for p in lines])
                )
                meet = float(normal @ (point - origin)) * 1000.0
            except GeometryError:
                meet = None
        for pointing in group:
            rel = _target_point(pointing.target, rotation, origin, scale) - pointing.tip_m
            miss = float(np.linalg.norm(rel - (rel @ pointing.direction) * pointing.direction)) * 1000.0
            out.append(Residual(label, "pointing", meet, None, miss, id(pointing) in used_p))
    return tuple(out)
