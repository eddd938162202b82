"""The ray caster's column-wise arithmetic gives exactly what the plain NumPy expressions give, and its
solids are where they should be (trackerd/sim/raycast.py, trackerd/sim/lens_rays.py)."""

from __future__ import annotations

import numpy as np

from trackerd.sim.raycast import points_along, ray_cylinder, row_dots, without_axis
from trackerd.sim.render import SceneRenderer


def _unit_rows(rng: np.random.Generator, n: int) -> np.ndarray:
    rows = rng.normal(size=(n, 3))
    return rows / np.linalg.norm(rows, axis=1, keepdims=True)


def test_column_helpers_equal_the_broadcast_expressions_bit_for_bit() -> None:
    """tests/sim/test_rendered_bits.py holds whole frames; this names the helper that would break them."""
    rng = np.random.default_rng(11)
    a, b = rng.normal(size=(5000, 3)), rng.normal(size=(5000, 3))
    t, origin, axis = rng.uniform(0.1, 9.0, 5000), rng.normal(size=3), rng.normal(size=3)
    assert np.array_equal(row_dots(a, b), np.sum(a * b, axis=1))
    assert np.array_equal(np.sqrt(row_dots(a, a)), np.linalg.norm(a, axis=1))
    assert np.array_equal(points_along(origin, a, t), origin + t[:, None] * a)
    assert np.array_equal(without_axis(a, t, axis), a - t[:, None] * axis)


def test_cylinder_hits_are_on_its_side_with_outward_normals() -> None:
    rng = np.random.default_rng(5)
    start, end, radius = np.array([0.2, -0.1, 2.0]), np.array([0.5, 0.3, 2.4]), 0.03
    origin = np.zeros(3)
    # Rays at points near the axis (some on it, some past its ends, some wide of it).
    along = rng.uniform(-0.3, 1.3, 4000)
    targets = start + along[:, None] * (end - start) + rng.normal(scale=0.04, size=(4000, 3))
    dirs = targets / np.linalg.norm(targets, axis=1, keepdims=True)
    t, normal = ray_cylinder(origin, dirs, start, end, radius)
    hit = np.isfinite(t)
    assert 500 < hit.sum() < 3500
    axis = (end - start) / np.linalg.norm(end - start)
    points = dirs[hit] * t[hit, None]
    rel = points - start
    foot = rel @ axis
    across = rel - foot[:, None] * axis
    np.testing.assert_allclose(np.linalg.norm(across, axis=1), radius, rtol=1e-9)
    assert foot.min() >= 0 and foot.max() <= np.linalg.norm(end - start)
    np.testing.assert_allclose(normal[hit], across / radius, atol=1e-9)
    # Facing the camera: the first hit, not the far side.
    assert np.all(row_dots(normal[hit], dirs[hit]) <= 1e-12)
    assert not np.any(normal[~hit])


def test_whole_pixel_rays_equal_the_interpolated_ones_bit_for_bit(renderer: SceneRenderer) -> None:
    cam = renderer.cameras[0]
    rng = np.random.default_rng(8)
    xs = rng.integers(0, cam.width_px, 3000)
    ys = rng.integers(0, cam.height_px, 3000)
    xs[:4], ys[:4] = [0, cam.width_px - 1, 0, cam.width_px - 1], [0, 0, cam.height_px - 1, cam.height_px - 1]
    exact = renderer.lens.pixel_rays(0, xs, ys)
    assert np.array_equal(exact, renderer.rays(0, xs.astype(np.float64), ys.astype(np.float64)))
    np.testing.assert_allclose(np.linalg.norm(exact, axis=1), 1.0, rtol=1e-12)
