"""A small ray caster for a presentation room: walls, a display showing pictures, a presenter and a two-ball pointer.

It was written without looking at trackerd's simulator or detector, so that images made with it test trackerd on
scenes nobody tuned it for. Everything is analytic (planes, ellipsoids, cylinders, boxes) and vectorised over all
rays of one sub-pixel sample position, so a frame costs a few hundred NumPy operations, not a loop per pixel.

Units: metres; radiance in the camera's grey levels before white balance (a white Lambertian surface under an
irradiance E reads E, and the display's pixels read their emitted value). World: the wall is z = 0, x to the right
along it, y up, the room at z > 0. Cameras follow OpenCV (x right, y down, z forward, Xc = R X + t).
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
EPS = 1e-7
CHUNK = 1 << 15  # rays shaded at a time
# Inward normals of the room's six faces: front wall (z = 0, the display's), back wall, left, right, floor, ceiling.
FACE_NORMALS = np.array([[0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]], dtype=float)


def _dot(a: Array, b: Array) -> Array:
    out: Array = np.einsum("...i,...i->...", a, b)
    return out


def _unit(v: Array) -> Array:
    out: Array = v / np.linalg.norm(v, axis=-1, keepdims=True)
    return out


# ------------------------------------------------------------------------------------------------ camera model


@dataclass(frozen=True)
class Camera:
    """A pinhole camera with OpenCV's lens polynomial [k1, k2, p1, p2, k3]; pixel (0, 0) is the top-left's centre."""

    id: str
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: tuple[float, float, float, float, float]
    rotation: Array
    tvec: Array

    @property
    def centre(self) -> Array:
        return -self.rotation.T @ self.tvec

    def scaled(self, factor: float) -> Camera:
        """The same camera delivering an image `factor` times the size: pixel edges, not centres, scale."""
        return Camera(
            self.id,
            round(self.width * factor),
            round(self.height * factor),
            self.fx * factor,
            self.fy * factor,
            (self.cx + 0.5) * factor - 0.5,
            (self.cy + 0.5) * factor - 0.5,
            self.distortion,
            self.rotation,
            self.tvec,
        )


def distort(x: Array, y: Array, k: Sequence[float]) -> tuple[Array, Array]:
    """OpenCV's forward lens model on normalised coordinates."""
    k1, k2, p1, p2, k3 = k
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    return x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x), y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y


def undistort(xd: Array, yd: Array, k: Sequence[float], iterations: int = 10) -> tuple[Array, Array, Array]:
    """Invert `distort` by Newton's method with the analytic Jacobian, started at the distorted point.

    A fixed-point iteration (OpenCV's) diverges near the corners of strong barrel lenses; Newton converges wherever
    the lens is monotonic. The residual (normalised units) is returned so callers can drop points that did not.
    """
    k1, k2, p1, p2, k3 = k
    x, y = xd.copy(), yd.copy()
    for _ in range(iterations):
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        q = k1 + r2 * (2 * k2 + 3 * k3 * r2)  # d radial / d r2
        ex = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) - xd
        ey = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y - yd
        a = radial + 2 * q * x * x + 2 * p1 * y + 6 * p2 * x
        b = 2 * q * x * y + 2 * p1 * x + 2 * p2 * y
        c = radial + 2 * q * y * y + 6 * p1 * y + 2 * p2 * x
        det = a * c - b * b
        x = x - (c * ex - b * ey) / det
        y = y - (a * ey - b * ex) / det
    fx, fy = distort(x, y, k)
    return x, y, np.hypot(fx - xd, fy - yd)


def monotonic_radius(k: Sequence[float]) -> float:
    """Largest undistorted radius up to which the radial polynomial still grows (beyond it the lens folds over)."""
    r = np.linspace(0.0, 3.0, 3001)
    k1, k2, _, _, k3 = k
    slope = 1 + 3 * k1 * r**2 + 5 * k2 * r**4 + 7 * k3 * r**6
    bad = np.nonzero(slope <= 0.05)[0]
    return float(r[bad[0] - 1]) if bad.size else 3.0


def project(cam: Camera, points: Array) -> tuple[Array, Array]:
    """Pixel positions (..., 2) of world points, with their depth along the optical axis."""
    pc = points @ cam.rotation.T + cam.tvec
    z = pc[..., 2]
    x, y = distort(pc[..., 0] / z, pc[..., 1] / z, cam.distortion)
    return np.stack([cam.fx * x + cam.cx, cam.fy * y + cam.cy], axis=-1), z


def pixel_rays(cam: Camera, u: Array, v: Array) -> tuple[Array, NDArray[np.bool_]]:
    """Unit world directions of the rays through pixel positions (u, v), and whether the lens inversion converged."""
    x, y, residual = undistort((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, cam.distortion)
    local = np.stack([x, y, np.ones_like(x)], axis=-1)
    return _unit(local @ cam.rotation), residual < 1e-9


def ray_grids(cam: Camera, samples: int) -> list[Array]:
    """Rays of every pixel for each of samples x samples sub-pixel offsets; computed once per camera and reused."""
    grids = []
    v, u = np.mgrid[0 : cam.height, 0 : cam.width].astype(float)
    band = max(1, CHUNK // cam.width)
    for j in range(samples):
        for i in range(samples):
            d = np.empty((cam.height, cam.width, 3))
            for r in range(0, cam.height, band):
                rows = slice(r, r + band)
                d[rows], _ = pixel_rays(cam, u[rows] + (i + 0.5) / samples - 0.5, v[rows] + (j + 0.5) / samples - 0.5)
            grids.append(d)
    return grids


# ------------------------------------------------------------------------------------------------ shapes


@dataclass(frozen=True)
class Ellipsoid:
    """centre + axes @ u for unit vectors u: balls (axes = r I), a hand, a head."""

    centre: Array
    axes: Array  # columns are the semi-axes

    def hit(self, o: Array, d: Array) -> Array:
        inv = np.linalg.inv(self.axes)
        oo, dd = (o - self.centre) @ inv.T, d @ inv.T
        a = _dot(dd, dd)
        t0 = -_dot(oo, dd) / a
        # The squared distance of the closest approach, not b^2 - ac, keeps precision for small far-away balls.
        disc = (1 - _dot(h := oo + t0[..., None] * dd, h)) / a
        with np.errstate(invalid="ignore"):
            t = t0 - np.sqrt(disc)
        return np.where((disc >= 0) & (t > EPS), t, np.inf)

    def normal(self, p: Array) -> Array:
        inv = np.linalg.inv(self.axes)
        return _unit(((p - self.centre) @ inv.T) @ inv)

    def bound(self) -> tuple[Array, float]:
        return self.centre, float(np.linalg.norm(self.axes, axis=0).max())


@dataclass(frozen=True)
class Cylinder:
    """The side of a finite cylinder from a to b (its ends are capped by spheres or hidden in the balls)."""

    a: Array
    b: Array
    radius: float

    def hit(self, o: Array, d: Array) -> Array:
        length = float(np.linalg.norm(self.b - self.a))
        w = (self.b - self.a) / length
        oa = o - self.a
        dp = d - _dot(d, w)[..., None] * w
        op = oa - _dot(oa, w)[..., None] * w
        with np.errstate(divide="ignore", invalid="ignore"):
            a = _dot(dp, dp)
            t0 = -_dot(op, dp) / a
            disc = (self.radius**2 - _dot(h := op + t0[..., None] * dp, h)) / a
            t = t0 - np.sqrt(disc)
            s = _dot(oa, w) + t * _dot(d, w)
            return np.where((disc >= 0) & (t > EPS) & (s >= 0) & (s <= length), t, np.inf)

    def normal(self, p: Array) -> Array:
        w = _unit(self.b - self.a)
        v = p - self.a
        return _unit(v - _dot(v, w)[..., None] * w)

    def bound(self) -> tuple[Array, float]:
        return (self.a + self.b) / 2, float(np.hypot(np.linalg.norm(self.b - self.a) / 2, self.radius))


@dataclass(frozen=True)
class Box:
    """An axis-aligned box: furniture."""

    lo: Array
    hi: Array

    def hit(self, o: Array, d: Array) -> Array:
        with np.errstate(divide="ignore", invalid="ignore"):
            t1, t2 = (self.lo - o) / d, (self.hi - o) / d
            lo, hi = np.minimum(t1, t2), np.maximum(t1, t2)
            # Column-wise maxima: NumPy's reductions over a last axis of length 3 are slow.
            near = np.maximum(np.maximum(lo[..., 0], lo[..., 1]), lo[..., 2])
            far = np.minimum(np.minimum(hi[..., 0], hi[..., 1]), hi[..., 2])
            return np.where((near <= far) & (near > EPS), near, np.inf)

    def normal(self, p: Array) -> Array:
        gaps = np.concatenate([np.abs(p - self.lo), np.abs(p - self.hi)], axis=-1)
        face = gaps.argmin(axis=-1)
        n = np.zeros_like(p)
        n[np.arange(len(p)), face % 3] = np.where(face < 3, -1.0, 1.0)
        return n

    def bound(self) -> tuple[Array, float]:
        return (self.lo + self.hi) / 2, float(np.linalg.norm(self.hi - self.lo) / 2)


Shape = Ellipsoid | Cylinder | Box


@dataclass(frozen=True)
class Material:
    albedo: Array  # linear RGB
    specular: float = 0.0  # Blinn-Phong highlight weight: glossy paint shows the lamps as bright spots
    shininess: float = 20.0
    mirror: float = 0.0  # share of the room reflected: glossy balls mirror the bright display's colours


@dataclass(frozen=True)
class Thing:
    name: str
    shape: Shape
    material: Material
    group: str  # things of one group are culled together when casting shadow rays


# ------------------------------------------------------------------------------------------------ room and scene


@dataclass(frozen=True)
class Surface:
    """One face of the room: a colour modulated by tiled value noise, and optional tile seams."""

    colour: Array
    noise: Array  # (n, n), about -1 to 1, tiled
    amplitude: float
    period_m: tuple[float, float]  # size of a noise cell along the face's u and v: unequal ones make wood grain
    seams_m: float = 0.0


@dataclass(frozen=True)
class Decal:
    """A textured rectangle on a face: poster, door, whiteboard, rug. rect = (u0, v0, u1, v1) in face coordinates."""

    face: int
    rect: tuple[float, float, float, float]
    texture: Array  # (h, w, 3) linear albedo, row 0 at v1


@dataclass(frozen=True)
class Room:
    lo: Array  # (x_left, y_floor, 0)
    hi: Array  # (x_right, y_ceiling, depth)
    surfaces: tuple[Surface, ...]
    decals: tuple[Decal, ...]
    display_m: tuple[float, float]  # width, height; bottom-left corner at the origin
    bezel_m: float


@dataclass(frozen=True)
class Light:
    position: Array
    power: Array  # (3,) a white surface facing the lamp 1 m straight below reads this
    downward: float  # exponent of the fixture's cosine pattern towards the floor; 0 for a bare bulb


@dataclass(frozen=True)
class Scene:
    room: Room
    things: tuple[Thing, ...]
    lights: tuple[Light, ...]
    ambient: Array  # (3,) irradiance from everywhere (inter-reflections), unshadowed
    display: Array  # (h, w, 3) emitted radiance of the display's content, row 0 at the top

    @functools.cached_property
    def shadow_groups(self) -> list[tuple[Array, float, list[Thing]]]:
        """Things by group, with a sphere around each group (centre, radius) to cull shadow rays."""
        groups = []
        for group in dict.fromkeys(t.group for t in self.things):
            members = [t for t in self.things if t.group == group]
            bounds = [m.shape.bound() for m in members]
            centre = np.mean([c for c, _ in bounds], axis=0)
            groups.append((centre, max(float(np.linalg.norm(c - centre)) + r for c, r in bounds), members))
        return groups

    @functools.cached_property
    def glow(self) -> tuple[Array, Array, float]:
        """The display as 6 point-like emitters (centres, mean radiances, area): it lights the presenter and pointer."""
        nx = 6
        width, height = self.room.display_m
        columns = self.display.mean(axis=0)
        edges = np.linspace(0, len(columns), nx + 1).astype(int)
        radiance = np.array([columns[a:b].mean(axis=0) for a, b in itertools.pairwise(edges)])
        centres = np.stack([(np.arange(nx) + 0.5) * width / nx, np.full(nx, height / 2), np.zeros(nx)], axis=1)
        return centres, radiance, width * height / nx


def _bilinear(img: Array, u: Array, v: Array, wrap: bool) -> Array:
    """Sample img at fractional texel coordinates (u along columns, v along rows, texel centres at integers)."""
    h, w = img.shape[:2]
    if wrap:
        u, v = np.mod(u, w), np.mod(v, h)
    else:
        u, v = np.clip(u, 0, w - 1), np.clip(v, 0, h - 1)
    i0, j0 = np.floor(u).astype(np.intp), np.floor(v).astype(np.intp)
    fu, fv = u - i0, v - j0
    i1 = (i0 + 1) % w if wrap else np.minimum(i0 + 1, w - 1)
    j0, j1 = j0 * w, ((j0 + 1) % h if wrap else np.minimum(j0 + 1, h - 1)) * w  # flat indices gather faster
    flat = img.reshape(h * w, -1)
    if img.ndim == 3:
        fu, fv = fu[:, None], fv[:, None]
    else:
        flat = flat[:, 0]
    top = flat[j0 + i0] * (1 - fu) + flat[j0 + i1] * fu
    out: Array = top * (1 - fv) + (flat[j1 + i0] * (1 - fu) + flat[j1 + i1] * fu) * fv
    return out


def _face_uv(face: int, p: Array) -> tuple[Array, Array]:
    if face < 2:
        return p[:, 0], p[:, 1]
    if face < 4:
        return p[:, 2], p[:, 1]
    return p[:, 0], p[:, 2]


def _room_exit(room: Room, o: Array, d: Array) -> tuple[Array, NDArray[np.int16]]:
    """Where rays from inside the room leave it: distance and face index (the room is convex: the nearest wall)."""
    t = np.full(d.shape[:-1], np.inf)
    face = np.zeros(d.shape[:-1], dtype=np.int16)
    for axis, first in enumerate((2, 4, 0)):  # x: left/right, y: floor/ceiling, z: front/back
        da = d[..., axis]
        ahead = da > 0
        gap = np.where(ahead, room.hi[axis], room.lo[axis]) - o[..., axis]
        ta = np.divide(gap, da, out=np.full_like(da, np.inf), where=da != 0)
        nearer = ta < t
        t = np.where(nearer, ta, t)
        face = np.where(nearer, first + ahead, face).astype(np.int16)
    return t, face


def _room_surface(scene: Scene, face: NDArray[np.int16], p: Array) -> tuple[Array, Array]:
    """Albedo and emitted radiance of the room's faces at points p."""
    room = scene.room
    albedo, emitted = np.empty_like(p), np.zeros_like(p)
    for f in range(6):
        idx = np.nonzero(face == f)[0]
        if idx.size == 0:
            continue
        q = p[idx]
        u, v = _face_uv(f, q)
        s = room.surfaces[f]
        grain = _bilinear(s.noise, u / s.period_m[0], v / s.period_m[1], True)
        a = s.colour * (1 + s.amplitude * grain)[:, None]
        if s.seams_m > 0:
            gap = np.minimum(np.abs((u + s.seams_m / 2) % s.seams_m - s.seams_m / 2), np.abs(v % s.seams_m))
            a[gap < 0.006] *= 0.55
        for decal in room.decals:
            if decal.face != f:
                continue
            u0, v0, u1, v1 = decal.rect
            inside = np.nonzero((u >= u0) & (u <= u1) & (v >= v0) & (v <= v1))[0]
            th, tw = decal.texture.shape[:2]
            tu = (u[inside] - u0) / (u1 - u0) * tw - 0.5
            tv = (v1 - v[inside]) / (v1 - v0) * th - 0.5
            a[inside] = _bilinear(decal.texture, tu, tv, False)
        e = np.zeros_like(a)
        if f == 0:
            width, height = room.display_m
            b = room.bezel_m
            a[(u > -b) & (u < width + b) & (v > -b) & (v < height + b)] = 0.02
            shown = np.nonzero((u >= 0) & (u <= width) & (v >= 0) & (v <= height))[0]
            th, tw = scene.display.shape[:2]
            e[shown] = _bilinear(
                scene.display, u[shown] / width * tw - 0.5, (height - v[shown]) / height * th - 0.5, False
            )
        albedo[idx], emitted[idx] = a, e
    return albedo, emitted


def _in_cone(lamp: Array, centre: Array, radius: float, ldir: Array, dist: Array) -> NDArray[np.bool_]:
    """Which segments from points towards the lamp can meet the sphere (centre, radius): one dot product each."""
    axis = centre - lamp
    reach = float(np.linalg.norm(axis))
    if reach <= radius:
        return np.ones(len(ldir), dtype=bool)
    inside: NDArray[np.bool_] = (ldir @ (-axis / reach) > np.sqrt(1 - (radius / reach) ** 2)) & (dist > reach - radius)
    return inside


def _occluded(scene: Scene, lamp: Array, p: Array, ldir: Array, dist: Array) -> NDArray[np.bool_]:
    """Whether the segments from p towards the lamp are blocked.

    Points are culled by the cone from the lamp around each group's bounding sphere, then around each thing's, so
    that the full intersection test runs only where a shadow is possible.
    """
    blocked = np.zeros(len(p), dtype=bool)
    for centre, radius, members in scene.shadow_groups:
        group = np.nonzero(_in_cone(lamp, centre, radius, ldir, dist))[0]
        for m in members:
            near = group[~blocked[group]]
            near = near[_in_cone(lamp, *m.shape.bound(), ldir[near], dist[near])]
            if near.size:
                blocked[near] = m.shape.hit(p[near], ldir[near]) < dist[near]
    return blocked


def _shade(
    scene: Scene, p: Array, n: Array, albedo: Array, spec: Array, shine: Array, view: Array, shadows: bool
) -> Array:
    """Ambient + lamps (Lambert, Blinn-Phong highlights, hard shadows) + the display's glow (Lambert, unshadowed)."""
    irradiance = np.broadcast_to(scene.ambient, p.shape).copy()
    highlights = np.zeros_like(p)
    gloss = np.nonzero(spec > 0)[0]
    for light in scene.lights:
        ldir = light.position - p
        dist = np.sqrt(_dot(ldir, ldir))
        ldir /= dist[:, None]
        cos = _dot(n, ldir)
        falloff = np.clip(ldir[:, 1], 0, None) ** light.downward / dist**2
        e = np.where(cos > 0, cos, 0.0) * falloff
        if shadows:
            lit = np.nonzero(e > 0)[0]
            e[lit[_occluded(scene, light.position, p[lit] + 1e-5 * n[lit], ldir[lit], dist[lit])]] = 0
        irradiance += e[:, None] * light.power
        g = gloss[e[gloss] > 0]
        if g.size:
            half = _unit(ldir[g] + view[g])
            # (s + 8) / 8 keeps the highlight's energy as it narrows: glossy paint shows near-white spots.
            peak = spec[g] * (shine[g] + 8) / 8
            highlights[g] += (peak * np.clip(_dot(n[g], half), 0, None) ** shine[g] * falloff[g])[:, None] * light.power
    # The display's glow: its patches all lie in z = 0, so the geometry needs only scalar work per patch.
    centres, radiance, area = scene.glow
    front = np.nonzero(p[:, 2] > 1e-6)[0]  # the wall around the display gets none of its light
    q, m = p[front], n[front]
    np_dot, pp = _dot(m, q), _dot(q, q)
    factors = np.empty((len(q), len(centres)))
    for k, c in enumerate(centres):
        d2 = np.maximum(pp - 2 * (q[:, 0] * c[0] + q[:, 1] * c[1]) + c @ c, area)
        facing = np.clip(m[:, 0] * c[0] + m[:, 1] * c[1] - np_dot, 0, None)  # -n . (p - c)
        factors[:, k] = q[:, 2] * facing / d2**2
    irradiance[front] += (factors * (area / np.pi)) @ radiance
    return albedo * irradiance + highlights


def _reflection(scene: Scene, p: Array, n: Array, d: Array) -> Array:
    """What a glossy surface mirrors: the room's faces (the display above all), lit but without shadows."""
    r = d - 2 * _dot(d, n)[:, None] * n
    t, face = _room_exit(scene.room, p, r)
    q = p + t[:, None] * r
    albedo, emitted = _room_surface(scene, face, q)
    zero = np.zeros(len(q))
    return emitted + _shade(scene, q, FACE_NORMALS[face], albedo, zero, zero, -r, False)


def _view_half_angle(cam: Camera) -> float:
    """Largest angle between the optical axis and the ray of an image corner."""
    u = np.array([-0.5, cam.width - 0.5, -0.5, cam.width - 0.5])
    v = np.array([-0.5, -0.5, cam.height - 0.5, cam.height - 0.5])
    x, y, _ = undistort((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, cam.distortion)
    return float(np.arctan(np.hypot(x, y).max()))


def _pixel_box(cam: Camera, centre: Array, radius: float, pad: float = 2.0) -> tuple[slice, slice] | None:
    """Pixels whose rays may meet a sphere: the box around its projected silhouette circle (None: off the image).

    The lens is monotonic over the image, so the distorted silhouette bounds the distorted disc. A sphere reaching
    behind the camera, or whose silhouette leaves the lens's valid zone, gets the whole image to be safe.
    """
    everything = (slice(0, cam.height), slice(0, cam.width))
    c = cam.rotation @ centre + cam.tvec
    dist = float(np.linalg.norm(c))
    if c[2] < 1.05 * radius:
        return everything
    axis = c / dist
    if np.arccos(axis[2]) - np.arcsin(radius / dist) > _view_half_angle(cam):
        return None
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = _unit(np.cross(axis, helper))
    e2 = np.cross(axis, e1)
    ang = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    rim = radius * np.sqrt(1 - (radius / dist) ** 2)
    pts = c - axis * radius**2 / dist + rim * (np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2)
    x, y = pts[:, 0] / pts[:, 2], pts[:, 1] / pts[:, 2]
    if np.hypot(x, y).max() > monotonic_radius(cam.distortion):
        return everything
    xd, yd = distort(x, y, cam.distortion)
    u, v = cam.fx * xd + cam.cx, cam.fy * yd + cam.cy
    u0, u1 = max(int(np.floor(u.min() - pad)), 0), min(int(np.ceil(u.max() + pad)) + 1, cam.width)
    v0, v1 = max(int(np.floor(v.min() - pad)), 0), min(int(np.ceil(v.max() + pad)) + 1, cam.height)
    return (slice(v0, v1), slice(u0, u1)) if u0 < u1 and v0 < v1 else None


def _render_sample(cam: Camera, rays: Array, scene: Scene, track: Sequence[str]) -> tuple[Array, dict[str, Array]]:
    """One sub-pixel sample of every pixel, and per tracked thing its [nearest-hit count, own-hit count]."""
    o = cam.centre
    t, face = _room_exit(scene.room, o, rays)
    ids = face.astype(np.int16)
    counts = {name: np.zeros(2) for name in track}
    for k, thing in enumerate(scene.things):
        box = _pixel_box(cam, *thing.shape.bound())
        if box is None:
            continue
        tk = thing.shape.hit(o, rays[box])
        if thing.name in counts:
            counts[thing.name][1] = np.isfinite(tk).sum()
        closer = tk < t[box]
        t[box][closer] = tk[closer]
        ids[box][closer] = 6 + k
    d, idf, tf = rays.reshape(-1, 3), ids.reshape(-1), t.reshape(-1)
    seen = np.bincount(idf, minlength=6 + len(scene.things))
    for k, thing in enumerate(scene.things):
        if thing.name in counts:
            counts[thing.name][0] = seen[6 + k]
    radiance = np.empty_like(d)
    for a in range(0, len(d), CHUNK):  # small blocks stay in the CPU's caches: twice as fast as all rays at once
        radiance[a : a + CHUNK] = _shade_hits(scene, o, d[a : a + CHUNK], tf[a : a + CHUNK], idf[a : a + CHUNK])
    return radiance.reshape(rays.shape), counts


def _shade_hits(scene: Scene, o: Array, d: Array, t: Array, ids: NDArray[np.int16]) -> Array:
    """Radiance towards the camera of the nearest hits: ids 0-5 the room's faces, 6 + k the k-th thing."""
    p = o + t[:, None] * d
    n = np.empty_like(p)
    albedo = np.empty_like(p)
    emitted = np.zeros_like(p)
    spec, shine, mirror = np.zeros(len(p)), np.ones(len(p)), np.zeros(len(p))
    walls = np.nonzero(ids < 6)[0]
    albedo[walls], emitted[walls] = _room_surface(scene, ids[walls], p[walls])
    n[walls] = FACE_NORMALS[ids[walls]]
    for k in np.unique(ids[ids >= 6]) - 6:
        idx = np.nonzero(ids == 6 + k)[0]
        thing = scene.things[k]
        m = thing.material
        n[idx] = thing.shape.normal(p[idx])
        albedo[idx] = m.albedo
        spec[idx], shine[idx], mirror[idx] = m.specular, m.shininess, m.mirror
    radiance = emitted + _shade(scene, p, n, albedo, spec, shine, -d, True)
    shiny = np.nonzero(mirror > 0)[0]
    if shiny.size:
        radiance[shiny] += mirror[shiny, None] * _reflection(scene, p[shiny], n[shiny], d[shiny])
    return radiance


def render(
    cam: Camera, grids: Sequence[Array], scenes: Sequence[Scene], track: Sequence[str] = ()
) -> tuple[Array, dict[str, tuple[float, float]]]:
    """Average the sub-pixel samples; sample k sees scenes[k] (a moving pointer at that moment: motion blur).

    Returns the radiance image and, per tracked thing, (visible area, area it would cover unhidden) in the image,
    in pixels: counting the object id per sample gives the share hidden by the rod, the hand or the body.
    """
    image = np.zeros((cam.height, cam.width, 3))
    areas = {name: np.zeros(2) for name in track}
    for rays, scene in zip(grids, scenes, strict=True):
        sample, counts = _render_sample(cam, rays, scene, track)
        image += sample
        for name in track:
            areas[name] += counts[name]
    k = len(grids)
    return image / k, {name: (float(a[0] / k), float(a[1] / k)) for name, a in areas.items()}


def disc_area_outside(cam: Camera, centre: Array, radius: float, samples: int) -> float:
    """Pixel area of a ball's projection that falls outside the image, sampled like the image itself."""
    w, h = cam.width, cam.height
    big = Camera(cam.id, 3 * w, 3 * h, cam.fx, cam.fy, cam.cx + w, cam.cy + h, cam.distortion, cam.rotation, cam.tvec)
    box = _pixel_box(big, centre, radius)
    if box is None:
        return 0.0
    v, u = np.mgrid[box[0], box[1]].astype(float)
    u, v = u - w, v - h
    outside = (u < -0.5) | (u > w - 0.5) | (v < -0.5) | (v > h - 0.5)
    if not outside.any():
        return 0.0
    u, v = u[outside], v[outside]
    offsets = (np.arange(samples) + 0.5) / samples - 0.5
    total = 0
    ball = Ellipsoid(centre, radius * np.eye(3))
    for du in offsets:
        for dv in offsets:
            d, ok = pixel_rays(cam, u + du, v + dv)
            total += int((np.isfinite(ball.hit(cam.centre, d)) & ok).sum())
    return total / samples**2


# ------------------------------------------------------------------------------------------------ sensor


@dataclass(frozen=True)
class Sensor:
    white_balance: Array  # per-channel gains applied to the radiance
    vignetting: float  # relative loss of light at the image corners
    blur_px: float  # lens blur, Gaussian sigma in pixels
    read_noise: float  # grey levels
    shot_noise: float  # grey levels per square root of a grey level
    gamma: float  # 1 for a linear machine-vision output


def _blur(img: Array, sigma: float) -> Array:
    """Separable Gaussian blur with edge replication."""
    if sigma < 0.05:
        return img
    r = int(np.ceil(3 * sigma))
    kernel = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    kernel /= kernel.sum()
    for axis in (0, 1):
        padded = np.pad(img, [(r, r) if a == axis else (0, 0) for a in range(img.ndim)], mode="edge")
        size = img.shape[axis]
        img = sum(wk * np.take(padded, np.arange(i, i + size), axis=axis) for i, wk in enumerate(kernel))
    return img


def expose(cam: Camera, radiance: Array, sensor: Sensor, rng: np.random.Generator, bayer: bool) -> NDArray[np.uint8]:
    """Radiance to an 8-bit frame: white balance, vignetting, lens blur, then (Bayer mosaic,) noise, clipping, gamma.

    The Bayer mosaic (RGGB) samples the noiseless colours, so each raw sample gets its own noise like a real sensor.
    """
    img = radiance * sensor.white_balance
    v, u = np.mgrid[0 : cam.height, 0 : cam.width]
    r2 = ((u - cam.cx) ** 2 + (v - cam.cy) ** 2) / (cam.cx**2 + cam.cy**2)
    img = _blur(img * (1 - sensor.vignetting * r2)[..., None], sensor.blur_px)
    if bayer:
        raw = np.empty(img.shape[:2])
        raw[0::2, 0::2] = img[0::2, 0::2, 0]
        raw[0::2, 1::2] = img[0::2, 1::2, 1]
        raw[1::2, 0::2] = img[1::2, 0::2, 1]
        raw[1::2, 1::2] = img[1::2, 1::2, 2]
        img = raw
    sigma = np.sqrt(sensor.read_noise**2 + sensor.shot_noise**2 * np.clip(img, 0, None))
    img = np.clip(img + rng.standard_normal(img.shape) * sigma, 0, 255)
    return np.round(255 * (img / 255) ** sensor.gamma).astype(np.uint8)
