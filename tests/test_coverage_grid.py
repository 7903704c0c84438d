"""The inspection's fast paths give the answers of the plain computations they replace.

Coverage asks "is an evaluated foot point closer than r to this model point?"; it used to be a
nearest-neighbour query of a k-d tree and is now a grid search that stops at the first point
found (:func:`shapeverify.inspection._grid_kernels.any_within`).  Pinned here: the same booleans
as ``cKDTree.query(..., distance_upper_bound=r)`` on random clouds of every density and scale,
on exact ties (a point at exactly r is not within r), on queries far outside the cloud, and on
clouds so spread out that the grid has to widen its cells.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from shapeverify.inspection._grid_kernels import any_within, mark_within


def _tree_answer(ref, q, r):
    d, _ = cKDTree(ref).query(q, k=1, distance_upper_bound=r)
    return np.isfinite(d)


def _grid_answer(ref, q, r):
    out = np.empty(len(q), bool)
    any_within(ref, q, r, out)
    return out


@pytest.mark.parametrize("seed", range(6))
def test_any_within_equals_the_tree_query_on_random_clouds(seed):
    rng = np.random.default_rng(seed)
    for _ in range(25):
        n, m = int(rng.integers(1, 2000)), int(rng.integers(0, 1500))
        scale = 10.0 ** rng.uniform(-3, 3)
        ref = rng.uniform(-1, 1, (n, 3)) * scale * rng.uniform(0, 1, 3)   # flat and thin too
        q = rng.uniform(-1.5, 1.5, (m, 3)) * scale
        r = scale * 10.0 ** rng.uniform(-3, 0.5)
        np.testing.assert_array_equal(_grid_answer(ref, q, r), _tree_answer(ref, q, r))
        if m:                              # the other way round: q's points mark ref's
            marked = np.empty(n, bool)
            mark_within(ref, q, r, marked)
            np.testing.assert_array_equal(marked, _tree_answer(q, ref, r))


def test_any_within_a_point_at_exactly_r_is_not_within():
    ref = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]])
    q = np.array([[1.0, 0.0, 0.0], [np.nextafter(1.0, 0.0), 0.0, 0.0], [5.0, 0.0, 0.0],
                  [0.0, -1.0, 0.0], [0.0, 0.0, 0.999]])
    got = _grid_answer(ref, q, 1.0)
    assert got.tolist() == [False, True, False, False, True]
    np.testing.assert_array_equal(got, _tree_answer(ref, q, 1.0))


def test_any_within_far_queries_and_a_widened_grid():
    rng = np.random.default_rng(7)
    # 50 points spread over 1 km with r = 1 mm: a grid of r-wide cells would need 1e18 cells
    ref = rng.uniform(-500, 500, (50, 3))
    q = np.vstack([ref + rng.normal(0, 0.4, ref.shape), ref + 5.0, [[1e9, -1e9, 0.0]]])
    got = _grid_answer(ref, q, 1.0)
    np.testing.assert_array_equal(got, _tree_answer(ref, q, 1.0))
    assert got[50:].sum() == 0 and got[:50].sum() > 25


def test_any_within_surface_samples_like_the_coverage():
    """A dense scan of half a wavy sheet: samples on the seen half are covered, the rest not."""
    rng = np.random.default_rng(3)
    x, y = np.meshgrid(np.linspace(0, 300, 301), np.linspace(0, 200, 201))
    samples = np.column_stack([x.ravel(), y.ravel(), 5 * np.sin(x.ravel() / 30)])
    seen = samples[samples[:, 0] < 150] + rng.normal(0, 0.3, (np.count_nonzero(samples[:, 0] < 150), 3))
    got = _grid_answer(seen, samples, 2.0)
    np.testing.assert_array_equal(got, _tree_answer(seen, samples, 2.0))
    assert got[samples[:, 0] < 148].all() and not got[samples[:, 0] > 152].any()


def _tree_nearest_other(ref, idx):
    d, _ = cKDTree(ref).query(ref[idx], k=2)
    return d[:, 1]


@pytest.mark.parametrize("seed", range(4))
def test_nearest_distances_equal_the_tree_query_bit_for_bit(seed):
    from shapeverify.inspection.regions import nearest_distances

    rng = np.random.default_rng(10 + seed)
    for _ in range(15):
        n = int(rng.integers(2, 3000))
        scale = 10.0 ** rng.uniform(-3, 3)
        ref = rng.uniform(-1, 1, (n, 3)) * scale * rng.uniform(0, 1, 3)
        if rng.random() < 0.3:                          # isolated points far from the rest
            ref[: max(1, n // 50)] += rng.uniform(-20, 20, (max(1, n // 50), 3)) * scale
        if rng.random() < 0.3:                          # duplicates: distance 0
            ref[-3:] = ref[0]
        idx = np.arange(0, n, max(1, n // 400))
        np.testing.assert_array_equal(nearest_distances(ref, idx), _tree_nearest_other(ref, idx))


def test_nearest_distances_of_two_points_and_of_a_line():
    from shapeverify.inspection.regions import nearest_distances

    two = np.array([[0.0, 0.0, 0.0], [3.0, 4.0, 0.0]])
    assert nearest_distances(two, np.array([0, 1])).tolist() == [5.0, 5.0]
    line = np.column_stack([np.cumsum(np.arange(1.0, 40.0)), np.zeros(39), np.zeros(39)])
    np.testing.assert_array_equal(nearest_distances(line, np.arange(39)),
                                  _tree_nearest_other(line, np.arange(39)))
    same = np.zeros((5, 3))
    assert nearest_distances(same, np.arange(5)).tolist() == [0.0] * 5
