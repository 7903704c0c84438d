"""The inspection's shortcuts give exactly what the plain computations give (issue 9's CPU cost).

Each shortcut skips work whose answer is not looked at or is already known; pinned here against
the computation it replaces, on inputs where that computation is written out in full.
"""

from __future__ import annotations

import numpy as np

from shapeverify.inspection import per_face_statistics, statistics
from shapeverify.inspection.deviations import (EVALUATED, ON_BOUNDARY, TOO_FAR, Deviations)
from shapeverify.inspection.material import MAX_NORMAL_SHARE, beside_surface


def _random_deviations(rng, n=4000):
    """Deviations of a wavy sheet z = f(x, y) with every reason and some points without a foot."""
    q = np.column_stack([rng.uniform(0, 100, n), rng.uniform(0, 60, n), rng.normal(0, 1.5, n)])
    foot = q.copy()
    foot[:, 2] = 0.0
    edge = rng.random(n) < 0.2                  # feet on an edge: offsets along the surface
    foot[edge, 0] += rng.uniform(-3, 3, edge.sum())
    normals = np.tile([0.0, 0.0, 1.0], (n, 1))
    d = np.linalg.norm(q - foot, axis=1) * np.sign(q[:, 2])
    reason = np.where(np.abs(d) > 1.0, TOO_FAR, EVALUATED).astype(np.int8)
    reason[rng.random(n) < 0.05] = ON_BOUNDARY
    lost = rng.random(n) < 0.02                 # no foot point found
    foot[lost] = np.nan
    normals[lost] = np.nan
    reason[lost] = TOO_FAR
    ev = reason == EVALUATED
    return Deviations(np.where(ev, d, np.nan), ev, reason, np.zeros(n, np.int32), foot, normals,
                      q, 1.0)


def test_beside_surface_of_the_too_far_points_equals_the_full_computation():
    rng = np.random.default_rng(4)
    dev = _random_deviations(rng)
    beside, dist = beside_surface(dev)
    delta = dev.points_model - dev.foot_points            # the computation on every point
    with np.errstate(invalid="ignore"):
        full_dist = np.linalg.norm(delta, axis=1)
        full = np.isfinite(full_dist) & (np.abs(np.einsum("ij,ij->i", delta, dev.normals))
                                         <= MAX_NORMAL_SHARE * full_dist)
    far = dev.reason == TOO_FAR
    assert 100 < far.sum() < len(far) and 0 < (far & full).sum() < far.sum()
    np.testing.assert_array_equal(beside[far], full[far])
    np.testing.assert_array_equal(dist[far], full_dist[far])      # bit for bit, NaN included
    assert not beside[~far].any() and np.isnan(dist[~far]).all()


def test_per_face_statistics_of_one_face_equal_the_sorted_computation():
    rng = np.random.default_rng(5)
    v = rng.normal(0, 0.1, 5001)
    within = np.abs(v) <= 0.2
    for f in (0, 7):
        face = np.full(v.size, f, np.int32)
        got = per_face_statistics(v, face, within, v > 0)
        assert list(got) == [f]
        # what the general path computes: the face's points in sorted order
        order = np.argsort(face, kind="stable")
        assert got[f] == statistics(v[order], within[order], (v > 0)[order]) == statistics(v, within, v > 0)
    two = np.where(np.arange(v.size) % 3 == 0, 2, 1).astype(np.int32)
    got = per_face_statistics(v, two, within, v > 0)
    assert got[2] == statistics(v[two == 2], within[two == 2], (v > 0)[two == 2])
    assert got[1].n + got[2].n == v.size
    assert per_face_statistics(v[:0], two[:0], within[:0], v[:0] > 0) == {}


def test_regions_from_the_neighbourhood_tree_equal_those_from_the_whole_tree():
    """find_regions without a tree builds one of the evaluated points near the out-of-tolerance
    ones only; the regions, outliers and spacing are those the whole tree gives."""
    from scipy.spatial import cKDTree

    from shapeverify.inspection.regions import RegionSearch, find_regions

    rng = np.random.default_rng(8)
    x, y = np.meshgrid(np.arange(0, 120, 0.7), np.arange(0, 80, 0.7))
    x = x.ravel() + rng.uniform(-0.2, 0.2, x.size)
    y = y.ravel() + rng.uniform(-0.2, 0.2, y.size)
    v = rng.normal(0, 0.03, x.size)
    for cx, cy, depth in ((30, 30, -0.5), (90, 50, 0.4), (60, 10, -0.3)):
        v += depth * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * 4.0 ** 2))
    spikes = rng.choice(x.size, 80, replace=False)
    v[spikes] += rng.choice([-1, 1], 80) * 0.6
    pts = np.column_stack([x, y, np.zeros_like(x)])
    normals = np.tile([0.0, 0.0, 1.0], (x.size, 1))
    ev = rng.random(x.size) > 0.03
    vals = np.where(ev, v, np.nan)
    within = np.abs(vals) <= 0.2
    face = (x > 60).astype(np.int32)
    limits = (np.full(x.size, -0.2), np.full(x.size, 0.2))
    whole = cKDTree(pts[ev])
    for spacing in (None, 0.7):
        a = find_regions(pts, vals, ev, within, face, normals, limits=limits,
                         search=RegionSearch(spacing=spacing))
        b = find_regions(pts, vals, ev, within, face, normals, limits=limits,
                         search=RegionSearch(spacing=spacing, tree=whole))
        assert len(a[0]) == len(b[0]) == 3 and a[2] == b[2]
        np.testing.assert_array_equal(a[1].indices, b[1].indices)
        for ra, rb in zip(a[0], b[0]):
            np.testing.assert_array_equal(ra.indices, rb.indices)
            assert (ra.n, ra.area, ra.severity, ra.extreme_raw, ra.faces, ra.side) == \
                   (rb.n, rb.area, rb.severity, rb.extreme_raw, rb.faces, rb.side)
            # the quadratic fit sums its neighbours in another order: the last bits may differ
            assert abs(ra.extreme - rb.extreme) < 1e-12
            np.testing.assert_allclose(ra.extreme_point, rb.extreme_point, rtol=0, atol=1e-9)


def test_linked_components_label_like_scipy_connected_components():
    """Union-find labels: the same numbering as scipy's (components by their lowest index)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from shapeverify.inspection.regions import linked_components

    rng = np.random.default_rng(9)
    for _ in range(200):
        n = int(rng.integers(1, 300))
        pairs = rng.integers(0, n, (int(rng.integers(0, 2 * n)), 2))
        g = coo_matrix((np.ones(len(pairs), np.int8), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
        count, labels = connected_components(g, directed=False)
        got = linked_components(n, pairs)
        assert got[0] == count
        np.testing.assert_array_equal(got[1], labels)
    assert linked_components(3, np.zeros((0, 2), np.int64))[1].tolist() == [0, 1, 2]


def test_row_medians_equal_numpy_nanmedian_bit_for_bit():
    import warnings

    from shapeverify.inspection.regions import _nanmedian_rows

    rng = np.random.default_rng(11)
    for t in range(100):
        a = rng.normal(0, 1, (int(rng.integers(1, 300)), int(rng.integers(1, 12))))
        if t % 3 == 0:
            a = np.round(a, 1)                                  # ties
        a[rng.random(a.shape) < rng.uniform(0, 0.9)] = np.nan  # all-NaN rows too
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            np.testing.assert_array_equal(_nanmedian_rows(a), np.nanmedian(a, axis=1))


def test_an_inspection_gives_what_the_plain_tree_computations_give():
    """End to end on a simulated scan (dent, blob, outliers): the spacing, the coverage and the
    regions of ``inspect`` are those of the k-d tree computations they replaced."""
    from scipy.spatial import cKDTree

    import shapeverify as sv
    from shapeverify.cad.examples import wavy_panel
    from shapeverify.inspection.regions import RegionSearch, find_regions
    from shapeverify.inspection.regions import median_spacing, surface_spacing
    from shapeverify.simulate import ScanEffects, virtual_scan

    prep = sv.prepare(wavy_panel(), spacing=2.0)
    sim = virtual_scan(prep, pixel=1.2, noise=0.02,
                       effects=ScanEffects(outlier_fraction=0.03, blobs=1,
                                           dents=[(0.5, 12.0)]), motion=(2.0, 3.0), rng=4)
    res = sv.inspect(prep, sim.scan, tolerance=0.2)
    dev, ev = res.deviations, res.deviations.evaluated
    feet = dev.foot_points[ev]
    tree = cKDTree(feet)
    d, _ = tree.query(feet[:: max(1, feet.shape[0] // 1500)], k=2)
    d = d[:, 1]
    # the grid search's nearest distances are the tree's; the inspection's spacing is the area
    # per point (surface_spacing), within a few % of the nearest distance on this pixel grid
    assert median_spacing(None, feet) == float(np.median(d[np.isfinite(d) & (d > 0)]))
    assert res.spacing == surface_spacing(feet)
    assert abs(res.spacing / float(np.median(d)) - 1) < 0.15
    cov = res.coverage
    near, _ = tree.query(cov.points, k=1, distance_upper_bound=cov.radius)
    np.testing.assert_array_equal(cov.covered, np.isfinite(near))
    assert cov.fraction == float(np.isfinite(near).mean()) > 0.5
    within = res.tolerance.within(dev.values, dev.face)
    regions, outliers, _ = find_regions(dev.foot_points, dev.values, ev, within, dev.face,
                                        dev.normals, res.registration.weights,
                                        limits=res.tolerance.limits(dev.face),
                                        search=RegionSearch(spacing=res.spacing, tree=tree))
    mine = [r for r in res.regions if r.kind == "deviation"]
    assert res.verdict == "fail" and len(mine) == len(regions) >= 1
    for a, b in zip(mine, regions):
        np.testing.assert_array_equal(a.indices, b.indices)
        assert (a.area, a.severity, a.extreme_raw) == (b.area, b.severity, b.extreme_raw)
        assert abs(a.extreme - b.extreme) < 1e-12 and abs(a.extreme + 0.5) < 0.05
    np.testing.assert_array_equal(res.outliers.indices, outliers.indices)
