"""A point target's neighbourhood on a randomly sampled scan (issue 28, NIST CTC 02 end to end
from a random pose): datum A is three point targets on one face, each taking the scan points
within max(2 mm, 2.5 median spacings).  On a scan sampled uniformly at random the median
nearest-neighbour spacing is about half the mean distance between points, so the disc stayed
2 mm; at 1.5 mm spacing one of the three targets held fewer than the 3 points a plane needs in
23 % of scans, and every tolerance on A|B|C came out undecided ("2 scan points near the datum
target").  The neighbourhood now takes at least the 8 nearest points of the face."""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from shapeverify.characteristics.datum_targets import (POINT_MIN, POINT_RADIUS,
                                                       point_contact, point_neighbours)


def _random_face(rng, spacing, size=60.0):
    n = int(size * size / spacing**2)
    feet = np.column_stack([rng.uniform(0, size, n), rng.uniform(0, size, n), np.zeros(n)])
    d, _ = cKDTree(feet).query(feet, k=2)
    return feet, float(np.median(d[:, 1]))


def test_point_target_on_random_scan_always_has_a_plane_of_points():
    rng = np.random.default_rng(3)
    targets = np.array([[15.0, 15, 0], [45.0, 20, 0], [30.0, 45, 0]])
    short_before = short_now = 0
    for _ in range(150):
        feet, sp = _random_face(rng, 1.5)
        on = np.ones(len(feet), bool)
        # the old rule: the disc alone
        counts = [int((np.linalg.norm(feet - t, axis=1) <= max(POINT_RADIUS, 2.5 * sp)).sum())
                  for t in targets]
        short_before += min(counts) < 3
        sel = [point_neighbours(feet, on, t, sp) for t in targets]
        short_now += min(int(s.sum()) for s in sel) < POINT_MIN
        for t, s, c in zip(targets, sel, counts):
            d = np.linalg.norm(feet - t, axis=1)
            if c >= POINT_MIN:                      # a full disc is taken as it is
                assert np.array_equal(s, d <= max(POINT_RADIUS, 2.5 * sp))
            else:                                   # else the nearest POINT_MIN
                assert s.sum() == POINT_MIN and d[s].max() <= d[~s].min()
    assert short_before >= 15, short_before         # the bug: 10-30 % of scans
    assert short_now == 0


def test_point_contact_from_the_wider_neighbourhood_is_on_the_surface():
    """The contact of a target on a tilted plane (z = 0.01 x + 0.3) from its nearest points,
    against the plane's own height at the target: within the noise's share."""
    rng = np.random.default_rng(5)
    errs = []
    for _ in range(100):
        feet, sp = _random_face(rng, 1.5)
        t = np.array([30.0, 30.0, 0.0])
        sel = point_neighbours(feet, np.ones(len(feet), bool), t, sp)
        X = feet[sel].copy()
        X[:, 2] = 0.01 * X[:, 0] + 0.3 + rng.normal(0, 0.02, len(X))
        errs.append(point_contact(X, t, np.array([0.0, 0, 1])) - (0.01 * 30 + 0.3))
    errs = np.abs(errs)
    assert np.percentile(errs, 95) < 0.06 and errs.max() < 0.1, (errs.mean(), errs.max())
