"""The two-camera closed forms in plain floats agree with the NumPy reference (trackerd/geometry/two_cameras.py)."""

from __future__ import annotations

import numpy as np
import pytest

from trackerd.errors import GeometryError
from trackerd.geometry import two_cameras
from trackerd.geometry.pointer_line import MIN_PLANE_ANGLE_SIN, estimate_pointer_line, two_plane_lines
from trackerd.geometry.rotation import world_from_camera_ypr


def _scene(rng: np.random.Generator):
    """Two cameras either side of a room and a pointer somewhere in front of them."""
    centres = np.array([[-1.3, 1.4, 3.0], [4.9, 1.4, 3.0]]) + rng.normal(0, 0.2, (2, 3))
    middle = np.array([1.8, 1.0, 1.6]) + rng.normal(0, 0.4, 3)
    axis = rng.normal(0, 1, 3)
    axis /= np.linalg.norm(axis)
    front, back = middle + 0.225 * axis, middle - 0.225 * axis
    # Rays through the ends, a little off them (centroid noise), not of unit length.
    front_dirs = (front - centres + rng.normal(0, 0.002, (2, 3))) * rng.uniform(0.5, 2.0, (2, 1))
    back_dirs = (back - centres + rng.normal(0, 0.002, (2, 3))) * rng.uniform(0.5, 2.0, (2, 1))
    return centres, front_dirs, back_dirs


def _t(v) -> tuple[float, float, float]:
    return tuple(float(x) for x in v)


def test_the_pointer_line_matches_the_numpy_reference() -> None:
    rng = np.random.default_rng(3)
    compared = fallbacks = 0
    for _ in range(400):
        centres, front_dirs, back_dirs = _scene(rng)
        reference = estimate_pointer_line(centres, front_dirs, back_dirs)
        fast = two_cameras.pointer_line(
            _t(centres[0]),
            _t(centres[1]),
            _t(front_dirs[0]),
            _t(back_dirs[0]),
            _t(front_dirs[1]),
            _t(back_dirs[1]),
            MIN_PLANE_ANGLE_SIN,
        )
        if reference.method == "points":
            assert fast is None  # the caller then takes the reference's two-point line
            fallbacks += 1
            continue
        compared += 1
        np.testing.assert_allclose(fast.front_m, reference.front_m, atol=1e-9)
        np.testing.assert_allclose(fast.back_m, reference.back_m, atol=1e-9)
        assert fast.front_gap_m == pytest.approx(reference.front_gap_m, abs=1e-12)
        assert fast.back_gap_m == pytest.approx(reference.back_gap_m, abs=1e-12)
        assert fast.plane_angle_sin == pytest.approx(reference.plane_angle_sin, abs=1e-12)
        assert fast.method == "planes"
    assert compared > 300 and fallbacks > 0, (compared, fallbacks)


def test_wall_hits_of_the_planes_line_match_the_numpy_reference() -> None:
    rng = np.random.default_rng(8)
    rotations = [world_from_camera_ypr(72.3, -16.9, 0.5).T, world_from_camera_ypr(-72.3, -16.9, -0.4).T]
    centres = np.array([[-1.3, 1.4, 3.0], [4.9576, 1.4, 3.0]])
    wall_normal, wall_offset = np.array([0.0, 0.0, 1.0]), -0.0
    variants = rng.normal(0, 0.3, (50, 2, 2, 2))  # normalised (x, y) of [camera, end]
    rays = np.concatenate([variants, np.ones((50, 2, 2, 1))], axis=3)
    world = np.einsum("bcej,cjk->bcek", rays, np.stack(rotations))
    normals = np.cross(world[:, :, 0], world[:, :, 1])
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    points, directions, _ = two_plane_lines(centres, normals)
    t = (points @ wall_normal + wall_offset) / (directions @ wall_normal)
    reference = points - t[:, None] * directions
    rows = tuple(tuple(tuple(r) for r in rotation.tolist()) for rotation in rotations)
    fast = two_cameras.plane_line_hits(
        _t(centres[0]), _t(centres[1]), rows, variants.reshape(50, 8).tolist(), _t(wall_normal), wall_offset
    )
    np.testing.assert_allclose(np.array(fast), reference, atol=1e-9)


def test_degenerate_views_are_refused_as_the_reference_refuses_them() -> None:
    c0, c1 = (0.0, 0.0, 0.0), (1.0, 0.0, 0.0)
    with pytest.raises(GeometryError, match="end-on"):
        two_cameras.pointer_line(c0, c1, (0.0, 0.0, 1.0), (0.0, 0.0, 2.0), (0.0, 0.1, 1.0), (0.1, 0.0, 1.0), 0.08)
    # Both planes the same plane (the pointer in the plane of the baseline): no line, the caller falls back.
    assert (
        two_cameras.pointer_line(c0, c1, (0.2, 0.0, 1.0), (0.4, 0.0, 1.0), (-0.2, 0.0, 1.0), (0.1, 0.0, 1.0), 0.08)
        is None
    )
    identity = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    with pytest.raises(GeometryError, match="parallel to the wall"):
        # A line along x, the wall's normal along z.
        two_cameras.plane_line_hits(
            c0,
            (0.0, 1.0, 0.0),
            (identity, identity),
            [(0.0, 0.0, 0.5, 0.0, 0.0, -1.0, 0.5, -1.0)],
            (0.0, 0.0, 1.0),
            0.0,
        )
