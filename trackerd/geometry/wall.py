"""The wall: its plane (eq. 23-25), where the pointer's line meets it (eq. 26-28), and its 2D frame.

A plane is stored as the report writes it, ``A x + B y + C z + D = 0`` (eq. 23),
with (A, B, C) scaled to unit length so that ``A x + B y + C z + D`` is the signed
distance of a point from the plane in metres (positive on the normal's side).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from trackerd.errors import GeometryError

Array = NDArray[np.float64]

MIN_LINE_PLANE_SIN = 1e-6
"""A line closer to parallel with the plane than this (sine of the angle) has no usable hit."""


@dataclass(frozen=True)
class Plane:
    """``normal . x + offset = 0`` with a unit normal: the report's (A, B, C) and D (eq. 23)."""

    normal: Array
    offset_m: float

    def signed_distance_m(self, points_m: Array) -> Array:
        """Signed distance of points (..., 3) from the plane; the sign says which side (section 3.7)."""
        return np.asarray(points_m, dtype=np.float64) @ self.normal + self.offset_m

    @property
    def coefficients(self) -> Array:
        """(A, B, C, D) of eq. 23, with (A, B, C) of unit length."""
        return np.array([*self.normal, self.offset_m])


def plane_from_three_points(p1_m: Array, p2_m: Array, p3_m: Array) -> Plane:
    """The plane through three points, by the report's expanded determinants (eq. 24-25).

    Raises GeometryError when the points are (nearly) colinear, where the
    report's (A, B, C) comes out as (0, 0, 0).
    """
    (x1, y1, z1), (x2, y2, z2), (x3, y3, z3) = (np.asarray(p, dtype=np.float64) for p in (p1_m, p2_m, p3_m))
    a = y1 * (z2 - z3) + y2 * (z3 - z1) + y3 * (z1 - z2)
    b = z1 * (x2 - x3) + z2 * (x3 - x1) + z3 * (x1 - x2)
    c = x1 * (y2 - y3) + x2 * (y3 - y1) + x3 * (y1 - y2)
    d = -(x1 * (y2 * z3 - y3 * z2) + x2 * (y3 * z1 - y1 * z3) + x3 * (y1 * z2 - y2 * z1))
    norm = float(np.sqrt(a * a + b * b + c * c))
    # |(A, B, C)| is twice the triangle's area; compare with the squared longest side.
    longest = max(
        float(np.sum((np.subtract(p, q)) ** 2))
        for p, q in (((x1, y1, z1), (x2, y2, z2)), ((x2, y2, z2), (x3, y3, z3)), ((x1, y1, z1), (x3, y3, z3)))
    )
    if longest == 0.0 or norm < 1e-9 * longest:
        raise GeometryError("the three wall points are colinear (or coincide): they do not fix a plane")
    return Plane(np.array([a, b, c]) / norm, d / norm)


def fit_plane(points_m: Array) -> tuple[Plane, Array]:
    """Least-squares plane through N >= 3 points, and each point's signed residual in metres.

    Shapes: (N, 3) -> (Plane, (N,)). Uses the smallest singular vector of the
    centred points, which minimises the sum of squared perpendicular distances.
    With exactly three points this is the plane of eq. 24-25.
    """
    pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 3)
    if len(pts) < 3:
        raise GeometryError(f"a plane needs three or more points, got {len(pts)}")
    centroid = pts.mean(axis=0)
    _, singular, vt = np.linalg.svd(pts - centroid)
    spread = singular[0]
    if spread == 0.0 or singular[1] < 1e-9 * spread:
        raise GeometryError("the wall points are colinear (or coincide): they do not fix a plane")
    normal = vt[2]
    plane = Plane(normal, float(-normal @ centroid))
    return plane, plane.signed_distance_m(pts)


@dataclass(frozen=True)
class LineHit:
    """Where a line ``P = P0 + u (P1 - P0)`` meets a plane (eq. 26-28)."""

    point_m: Array
    """The intersection Pi, (..., 3)."""
    u: Array
    """Line parameter of the intersection (eq. 28): u > 0 lies ahead of P0 in the direction of P1."""


def intersect_line_plane(start_m: Array, through_m: Array, plane: Plane) -> LineHit:
    """Intersect the line through ``start_m`` and ``through_m`` with a plane (eq. 26-28).

    ``u = (A rx + B ry + C rz + D) / (A (rx - bx) + B (ry - by) + C (rz - bz))`` (eq. 28),
    and the hit is ``start + u (through - start)`` (eq. 26). Shapes (..., 3).
    Raises GeometryError when the line is parallel to the plane (the denominator
    of eq. 28 vanishes) or the two points coincide.
    """
    p0 = np.asarray(start_m, dtype=np.float64)
    direction = np.asarray(through_m, dtype=np.float64) - p0
    length = np.sqrt((direction * direction).sum(axis=-1))
    if not (length > 0.0).all():
        raise GeometryError("the pointer's two ends coincide: no line to extend")
    numerator = p0 @ plane.normal + plane.offset_m
    denominator = -(direction @ plane.normal)
    if not (np.abs(denominator) >= MIN_LINE_PLANE_SIN * length).all():
        raise GeometryError("the pointer is parallel to the wall: it points at no point on it")
    u = numerator / denominator
    return LineHit(p0 + u[..., None] * direction, u)


Vec3 = tuple[float, float, float]


def as_vec3(values: Array) -> Vec3:
    """A point or vector of three coordinates (3,) as a tuple of Python floats."""
    x, y, z = (float(v) for v in np.asarray(values, dtype=np.float64).ravel())
    return x, y, z


@dataclass(frozen=True)
class WallFrame:
    """The wall's plane plus its 2D frame: origin at the display's bottom-left, x right, y up."""

    origin_m: Array
    x_axis: Array
    y_axis: Array
    width_m: float
    height_m: float
    display_width_px: int | None = None
    display_height_px: int | None = None
    fit_residuals_m: Array | None = None
    """Distance of each defining point from the fitted plane (zero for exactly three points)."""

    # Computed once, on first use: every fix reads them.
    @cached_property
    def normal(self) -> Array:
        """Unit normal x cross y: out of the display, toward the room for a wall seen from the front."""
        normal: Array = np.cross(self.x_axis, self.y_axis)
        normal.flags.writeable = False  # one array for every caller, and the plane's
        return normal

    @cached_property
    def plane(self) -> Plane:
        return Plane(self.normal, float(-self.normal @ self.origin_m))

    @cached_property
    def axes(self) -> Array:
        """(2, 3): the wall's x and y axes, rows; ``(point - origin) @ axes.T`` is :meth:`to_wall_m`."""
        axes = np.stack([self.x_axis, self.y_axis])
        axes.flags.writeable = False  # one array for every caller
        return axes

    @property
    def corners_m(self) -> Array:
        """(4, 3): bottom-left, bottom-right, top-right, top-left."""
        w, h = self.width_m * self.x_axis, self.height_m * self.y_axis
        o = self.origin_m
        return np.array([o, o + w, o + w + h, o + h])

    def to_wall_m(self, points_m: Array) -> Array:
        """World points (..., 3) on the plane -> wall coordinates (..., 2) in metres."""
        rel = np.asarray(points_m, dtype=np.float64) - self.origin_m
        return np.stack([rel @ self.x_axis, rel @ self.y_axis], axis=-1)

    def from_wall_m(self, wall_xy_m: Array) -> Array:
        """Wall coordinates (..., 2) -> world points (..., 3) on the plane."""
        xy = np.asarray(wall_xy_m, dtype=np.float64)
        return self.origin_m + xy[..., :1] * self.x_axis + xy[..., 1:2] * self.y_axis

    def on_wall(self, wall_xy_m: Array) -> NDArray[np.bool_]:
        """True where wall coordinates (..., 2) fall inside the display area."""
        xy = np.asarray(wall_xy_m, dtype=np.float64)
        return (xy[..., 0] >= 0) & (xy[..., 0] <= self.width_m) & (xy[..., 1] >= 0) & (xy[..., 1] <= self.height_m)

    @property
    def has_display(self) -> bool:
        return self.display_width_px is not None and self.display_height_px is not None

    def to_display_px(self, wall_xy_m: Array) -> Array:
        """Wall coordinates (..., 2) -> display pixels (..., 2): origin top-left, y down, as screens count.

        The display's pixel (0, 0) edge is the wall's top-left corner, so
        ``px = x / width * W`` and ``py = (1 - y / height) * H``.
        """
        if self.display_width_px is None or self.display_height_px is None:
            raise ValueError("the wall has no display size configured")
        xy = np.asarray(wall_xy_m, dtype=np.float64)
        px = xy[..., 0] / self.width_m * self.display_width_px
        py = (1.0 - xy[..., 1] / self.height_m) * self.display_height_px
        return np.stack([px, py], axis=-1)

    @classmethod
    def from_corners(
        cls,
        corners_m: Array,
        display_px: tuple[int, int] | None = None,
        planarity_tolerance_m: float = 0.01,
    ) -> WallFrame:
        """Frame from four corners (bottom-left, bottom-right, top-right, top-left)."""
        corners = np.asarray(corners_m, dtype=np.float64).reshape(4, 3)
        plane, residuals = fit_plane(corners)
        _check_planarity(residuals, planarity_tolerance_m, "corners_m")
        _check_rectangle(corners, planarity_tolerance_m)
        bottom = (corners[1] - corners[0] + corners[2] - corners[3]) / 2.0
        side = (corners[3] - corners[0] + corners[2] - corners[1]) / 2.0
        # Measured corners are only nearly coplanar: put the origin on the fitted plane.
        origin = corners[0] - plane.signed_distance_m(corners[0]) * plane.normal
        return cls._build(
            origin,
            bottom,
            side,
            plane,
            float(np.linalg.norm(bottom)),
            float(np.linalg.norm(side)),
            display_px,
            residuals,
        )

    @classmethod
    def from_points(
        cls,
        points_m: Array,
        origin_m: Array,
        x_direction: Array,
        y_direction: Array,
        width_m: float,
        height_m: float,
        display_px: tuple[int, int] | None = None,
        planarity_tolerance_m: float = 0.01,
    ) -> WallFrame:
        """Frame from three or more measured points on the plane plus an origin and axis hints."""
        pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 3)
        if len(pts) == 3:
            plane = plane_from_three_points(*pts)
            residuals = np.zeros(3)
        else:
            plane, residuals = fit_plane(pts)
            _check_planarity(residuals, planarity_tolerance_m, "points_m")
        origin = np.asarray(origin_m, dtype=np.float64)
        origin = origin - plane.signed_distance_m(origin) * plane.normal
        return cls._build(
            origin,
            np.asarray(x_direction, float),
            np.asarray(y_direction, float),
            plane,
            width_m,
            height_m,
            display_px,
            residuals,
        )

    @classmethod
    def _build(
        cls,
        origin: Array,
        x_hint: Array,
        y_hint: Array,
        plane: Plane,
        width_m: float,
        height_m: float,
        display_px: tuple[int, int] | None,
        residuals: Array,
    ) -> WallFrame:
        normal = plane.normal
        x_axis = _in_plane_axis(x_hint, normal, None, "x")
        y_axis = _in_plane_axis(y_hint, normal, x_axis, "y")
        dw, dh = display_px if display_px is not None else (None, None)
        return cls(origin, x_axis, y_axis, width_m, height_m, dw, dh, residuals)


MAX_DIRECTION_TILT_DEG = 30.0
"""How far a configured wall direction may point out of the wall's plane (or, for y, away from
square to x) before it is taken for a mistake rather than a measurement's error."""


def _in_plane_axis(hint: Array, normal: Array, x_axis: Array | None, name: str) -> Array:
    """The unit axis in the wall's plane nearest ``hint`` (square to ``x_axis`` when given).

    A hint far out of the plane (x_direction = [0, 0, 1] on a wall facing +z) would still
    project onto some in-plane direction, but an arbitrary one that the rounding of a nearly
    flat wall decides; such a hint is refused, as is a y hint close to x.
    """
    length = float(np.linalg.norm(hint))
    if not np.isfinite(length) or length < 1e-12:
        raise GeometryError(f"the wall's {name} direction has no length")
    unit = hint / length
    out_of_plane_deg = float(np.degrees(np.arcsin(min(1.0, abs(float(unit @ normal))))))
    if out_of_plane_deg > MAX_DIRECTION_TILT_DEG:
        raise GeometryError(
            f"the wall's {name} direction points {out_of_plane_deg:.1f} degrees out of the wall's"
            f" plane (at most {MAX_DIRECTION_TILT_DEG:.0f}); it must run along the wall"
        )
    axis = unit - (unit @ normal) * normal
    if x_axis is not None:
        along = float(axis @ x_axis) / float(np.linalg.norm(axis))
        off_square_deg = float(np.degrees(np.arcsin(min(1.0, abs(along)))))
        if off_square_deg > MAX_DIRECTION_TILT_DEG:
            raise GeometryError(
                f"the wall's y direction is {90.0 - off_square_deg:.1f} degrees from its x"
                f" direction (at least {90.0 - MAX_DIRECTION_TILT_DEG:.0f}); y runs up the wall,"
                " square to x"
            )
        axis = axis - (axis @ x_axis) * x_axis
    return axis / np.linalg.norm(axis)


def _check_planarity(residuals: Array, tolerance_m: float, key: str) -> None:
    worst = int(np.argmax(np.abs(residuals)))
    if abs(residuals[worst]) <= tolerance_m:
        return
    listing = ", ".join(f"{r * 1000:+.1f}" for r in residuals)
    # With four points one bad point spreads its error over all four equally, so
    # only name a culprit when there are enough points for it to stand out.
    culprit = f"; check {key}[{worst}]" if len(residuals) > 4 else ""
    raise GeometryError(
        f"{key} are not coplanar: distances from their best-fit plane are [{listing}] mm,"
        f" tolerance {tolerance_m * 1000:.1f} mm{culprit}"
    )


MAX_CORNER_ANGLE_ERROR_DEG = 1.5
"""A display's corners are right angles; a measured corner further off than this is a typo."""


def _check_rectangle(corners: Array, tolerance_m: float) -> None:
    """Refuse corners that do not form a rectangle: a mistyped coordinate inside the plane."""
    edges = {
        "bottom": corners[1] - corners[0],
        "right": corners[2] - corners[1],
        "top": corners[2] - corners[3],
        "left": corners[3] - corners[0],
    }
    lengths = {name: float(np.linalg.norm(edge)) for name, edge in edges.items()}
    for a, b in (("bottom", "top"), ("left", "right")):
        if abs(lengths[a] - lengths[b]) > 2 * tolerance_m:
            raise GeometryError(
                f"corners_m do not form a rectangle: the {a} edge is {lengths[a] * 1000:.0f} mm long and the"
                f" {b} edge {lengths[b] * 1000:.0f} mm (order: bottom-left, bottom-right, top-right, top-left)"
            )
    for first, second in (("bottom", "left"), ("bottom", "right"), ("top", "right"), ("top", "left")):
        cos = abs(float(edges[first] @ edges[second])) / (lengths[first] * lengths[second])
        error = 90.0 - float(np.degrees(np.arccos(min(cos, 1.0))))
        if error > MAX_CORNER_ANGLE_ERROR_DEG:
            raise GeometryError(
                f"corners_m do not form a rectangle: the corner between the {first} and {second} edges is"
                f" {error:.1f} degrees off square (order: bottom-left, bottom-right, top-right, top-left)"
            )
