"""Runs, labels and moments of blobs, against a plain flood fill on random masks."""

from __future__ import annotations

from collections import deque

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from trackerd.detect import blobs
from trackerd.detect.blobs import blob_boxes, blob_stats, find_runs, label_runs


def flood_labels(mask: np.ndarray) -> tuple[np.ndarray, int]:
    """8-connected labels numbered in raster order of each blob's first pixel (the reference)."""
    labels = np.full(mask.shape, -1)
    n = 0
    for y, x in zip(*np.nonzero(mask), strict=True):
        if labels[y, x] >= 0:
            continue
        labels[y, x] = n
        queue = deque([(y, x)])
        while queue:
            cy, cx = queue.popleft()
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    ny, nx = cy + dy, cx + dx
                    if 0 <= ny < mask.shape[0] and 0 <= nx < mask.shape[1] and mask[ny, nx] and labels[ny, nx] < 0:
                        labels[ny, nx] = n
                        queue.append((ny, nx))
        n += 1
    return labels, n


masks = st.integers(1, 40).flatmap(lambda h: st.integers(1, 40).flatmap(lambda w: arrays(np.bool_, (h, w))))


@settings(max_examples=150, deadline=None)
@given(masks)
def test_runs_labels_and_moments_match_a_flood_fill(mask: np.ndarray) -> None:
    runs = find_runs(mask)
    rebuilt = np.zeros_like(mask)
    for row, first, last in zip(runs.rows, runs.first, runs.last, strict=True):
        assert not rebuilt[row, first : last + 1].any()
        rebuilt[row, first : last + 1] = True
    assert np.array_equal(rebuilt, mask)

    reference, n_ref = flood_labels(mask)
    labels, n = label_runs(runs)
    assert n == n_ref
    # Same partition, same numbering (blobs in order of their first pixel).
    assert np.array_equal(labels, reference[runs.rows, runs.first])
    if n == 0:
        return
    stats = blob_stats(runs, labels, n)
    count, x0, y0, x1, y1 = blob_boxes(runs, labels, n)
    elongation = stats.elongation()
    for k in range(n):
        ys, xs = np.nonzero(reference == k)
        assert stats.count[k] == xs.size == count[k]
        assert np.isclose(stats.mean_x[k], xs.mean()) and np.isclose(stats.mean_y[k], ys.mean())
        assert (stats.x0[k], stats.y0[k], stats.x1[k], stats.y1[k]) == (
            xs.min(),
            ys.min(),
            xs.max(),
            ys.max(),
        )
        assert (x0[k], y0[k], x1[k], y1[k]) == (xs.min(), ys.min(), xs.max(), ys.max())
        cov = np.cov(np.vstack([xs, ys]), bias=True) + np.eye(2) / 12.0
        low, high = np.linalg.eigvalsh(cov)
        assert np.isclose(elongation[k], np.sqrt(high / low))
        assert np.isclose(stats.fill()[k], xs.size / ((np.ptp(xs) + 1) * (np.ptp(ys) + 1)))
        assert runs.rows[stats.first_run[k]] == ys.min()


@settings(max_examples=60, deadline=None)
@given(masks)
def test_both_labelling_paths_agree(mask: np.ndarray) -> None:
    """The union-find loop (few runs) and the vectorized forest (many runs) label alike."""
    runs = find_runs(mask)
    if len(runs) < 2:
        return
    loop = blobs._label_runs_loop(runs)
    vectorized = blobs._label_runs_vectorized(runs)
    assert loop[1] == vectorized[1]
    assert np.array_equal(loop[0], vectorized[0])


def test_framed_runs_equal_padded_runs() -> None:
    rng = np.random.default_rng(3)
    mask = np.zeros((30, 50), dtype=bool)
    mask[:, 1:-1] = rng.random((30, 48)) < 0.4
    framed, padded = find_runs(mask, framed=True), find_runs(mask)
    for a, b in (
        (framed.rows, padded.rows),
        (framed.first, padded.first),
        (framed.last, padded.last),
    ):
        assert np.array_equal(a, b)


def test_a_disc_is_round_and_fills_its_box_as_a_disc_does() -> None:
    yy, xx = np.mgrid[:61, :61]
    disc = (xx - 30) ** 2 + (yy - 30) ** 2 <= 25**2
    runs = find_runs(disc)
    labels, n = label_runs(runs)
    stats = blob_stats(runs, labels, n)
    assert n == 1
    assert stats.elongation()[0] < 1.01
    assert abs(stats.fill()[0] - np.pi * 25**2 / 51**2) < 0.01
    streak = np.eye(40, dtype=bool) | np.eye(40, k=1, dtype=bool)
    runs = find_runs(streak)
    labels, n = label_runs(runs)
    stats = blob_stats(runs, labels, n)
    assert n == 1 and stats.elongation()[0] > 20 and stats.fill()[0] < 0.1
