"""The robust circle through rim points (trackerd/detect/circle.py): one outline, and many at once."""

from __future__ import annotations

import numpy as np
import pytest

from trackerd.detect.circle import median_of, robust_circle, robust_circles, row_medians


def test_robust_circle_ignores_a_quarter_of_wild_points() -> None:
    rng = np.random.default_rng(3)
    angles = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    points = np.column_stack([50 + 9 * np.cos(angles), 40 + 9 * np.sin(angles)]) + rng.normal(0, 0.05, (40, 2))
    # An occluder's edge: a quarter of the points 2.5 px inside the circle.
    points[:10] = np.column_stack([50 + 6.5 * np.cos(angles[:10]), 40 + 6.5 * np.sin(angles[:10])])
    circle = robust_circle(points)
    assert circle is not None
    centre, radius, weights, _ = circle
    assert np.hypot(*(centre - [50, 40])) < 0.05 and abs(radius - 9) < 0.05
    assert np.all(weights[:10] == 0) and np.all(weights[10:] > 0)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_fits_median_is_numpys_to_the_last_bit(dtype) -> None:
    rng = np.random.default_rng(11)
    for size in range(1, 60):
        values = rng.normal(3.0, 2.0, size).astype(dtype)
        values[: size // 3] = values[-1]  # ties, as residuals of rims on one lattice row have
        assert median_of(values) == float(np.median(values))


def _rim_sets(rng: np.random.Generator) -> list[np.ndarray]:
    """Rim point sets as the outline search gives them: whole and partial outlines of every size, some with
    an occluder's or a background's points among them, some too few, one on a straight edge."""
    sets = []
    for k in range(40):
        count = int(rng.integers(3, 49))
        radius = rng.uniform(3.0, 40.0)
        start = rng.uniform(0.0, 2.0 * np.pi)
        angles = start + np.linspace(0.0, rng.uniform(0.6, 2.0) * np.pi, count, endpoint=False)
        points = np.column_stack([radius * np.cos(angles), radius * np.sin(angles)]) + rng.uniform(-300, 300, 2)
        points += rng.normal(0.0, rng.uniform(0.02, 0.6), points.shape)
        wild = rng.random(count) < (0.3 if k % 3 == 0 else 0.0)
        points[wild] += rng.normal(0.0, 0.4 * radius, (int(wild.sum()), 2))
        sets.append(points)
    sets.append(np.column_stack([np.linspace(0.0, 30.0, 20), np.full(20, 5.0)]))  # a straight edge
    sets.append(np.tile([[4.0, 4.0]], (12, 1)))  # one point, repeated: every triple degenerate
    return sets


@pytest.mark.parametrize("radius_range_px", [None, (8.0, 20.0)])
def test_many_outlines_fitted_together_are_each_fitted_as_alone(radius_range_px) -> None:
    """The search fits a frame's seeds together: each set's circle must be what it gets fitted on its own,
    however many points each set has (to rounding: alone, a set's sums run over its own points, together over
    a row padded to the longest), and None where alone it is None (too few points, no circle, a radius
    outside the range). Within one outline search every set has a row of the same width, and the fits are
    the same to the last bit (tests/detect/test_ballfit.py)."""
    sets = _rim_sets(np.random.default_rng(8))
    width = 48
    points = np.zeros((len(sets), width, 2))
    counts = np.array([len(s) for s in sets])
    for k, s in enumerate(sets):
        points[k, : len(s)] = s
        points[k, len(s) :] = 1e6  # whatever lies beyond a set's count is not looked at
    together = robust_circles(points, counts, radius_range_px=radius_range_px)
    alone = [robust_circle(s, radius_range_px=radius_range_px) for s in sets]
    assert sum(c is None for c in alone) >= 3 and sum(c is not None for c in alone) >= 8
    for batched, single in zip(together, alone, strict=True):
        assert (batched is None) == (single is None)
        if single is not None:
            assert batched is not None
            assert np.allclose(batched[0], single[0], rtol=0.0, atol=1e-9)
            assert batched[1] == pytest.approx(single[1], rel=1e-12) and batched[3] == pytest.approx(
                single[3], rel=1e-12
            )
            assert np.allclose(batched[2], single[2], rtol=0.0, atol=1e-9)


def test_row_medians_are_numpys_over_each_rows_finite_values() -> None:
    rng = np.random.default_rng(2)
    values = rng.normal(0.0, 1.0, (30, 17))
    values[rng.random(values.shape) < 0.3] = np.nan
    values[4] = np.nan
    expected = [np.median(row[np.isfinite(row)]) if np.isfinite(row).any() else np.nan for row in values]
    assert np.array_equal(row_medians(values), np.array(expected), equal_nan=True)
