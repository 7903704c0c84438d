"""A reflection that comes within the evaluation distance of the part only at one end is judged
with the rest of its sheet beyond that distance (issue 29 items 1-2).

0.7 mm, seed 1 of the good impeller (``test_material_impeller._scan``: 2 % outliers, 4
reflection clusters): 8 points +0.28..+0.88 mm of a reflection were a 'material added' region.
They are the end of a sheet of 86 points, 62 of them beyond the evaluation distance (1 mm) over
the blades, and the face under those 8 points happened to be sparsely sampled, so no layer rule
looked at enough of the sheet: ``find_regions`` only knew the evaluated points.  Its
``RegionSearch.far`` (the signed distances of the too-far points over a face,
``material.far_over_surface``) lets the sheet run on through them; a sheet with the part's
surface measured under it is a layer (outliers), a bump taller than the evaluation distance
(the surface replaced under its top) stays one region.
"""
from __future__ import annotations

import numpy as np
import pytest

from shapeverify.inspection.regions import RegionSearch, find_regions

TOL, EV_DIST, S = 0.15, 1.0, 0.5


def _plane(rng, half=10.0, sparse_at=None):
    P2 = rng.uniform(-half, half, (rng.poisson((2 * half / S) ** 2), 2))
    if sparse_at is not None:           # the surface's own points at 0.4 of the density there
        spot = np.hypot(P2[:, 0] - sparse_at[0], P2[:, 1] - sparse_at[1]) < 2.5
        P2 = P2[~spot | (rng.random(len(P2)) < 0.4)]
    return P2


def _regions(P2, z):
    """find_regions with and without the far points' distances: ``(regions, regions_far)``."""
    n = len(z)
    pts = np.column_stack([P2, np.zeros(n)])
    ev = np.abs(z) <= EV_DIST
    values = np.where(ev, z, np.nan)
    args = (pts, values, ev, ev & (np.abs(values) <= TOL), np.zeros(n, int),
            np.tile([0.0, 0.0, 1.0], (n, 1)))
    lim = (np.full(n, -TOL), np.full(n, TOL))
    plain, _, _ = find_regions(*args, limits=lim)
    far, _, _ = find_regions(*args, limits=lim,
                             search=RegionSearch(far=np.where(ev, np.nan, z)))
    return plain, far


def _tilted_reflection(seed):
    """A plane sampled at random (0.5 mm) and a reflection over it: a disc 12 mm across tilted
    at 19 degrees, its low end 0.78 mm up over a sparsely sampled spot (noise 0.02 mm)."""
    rng = np.random.default_rng(seed)
    P2 = _plane(rng, sparse_at=(-3.0, 0.0))
    G2 = rng.uniform(-6, 6, (rng.poisson(144 / S ** 2), 2))
    G2 = G2[(np.hypot(*G2.T) < 6.0) & (G2[:, 0] > -5.0)]
    h = 0.6 + 0.35 * (G2[:, 0] + 5.5) + rng.normal(0, 0.02, len(G2))
    return np.vstack([P2, G2]), np.concatenate([rng.normal(0, 0.02, len(P2)), h]), len(P2)


def test_reflection_fragment_within_the_evaluation_distance_is_judged_with_its_far_sheet():
    """12 random scans: the reflection's evaluated end (10 or more points beyond the limit) is
    no region once its sheet beyond the evaluation distance is known (without it, seeds 2 and 4
    had a 'material added' region of 11 and 10 points, +0.94 and +0.80 mm)."""
    n_out = []
    for seed in range(12):
        P2, z, n0 = _tilted_reflection(seed)
        # the brute-force count of the reflection's points evaluated and out of tolerance
        n_out.append(int(np.count_nonzero((z[n0:] > TOL) & (z[n0:] <= EV_DIST))))
        _, with_far = _regions(P2, z)
        assert with_far == [], (seed, [(r.n, r.extreme) for r in with_far])
    assert min(n_out) >= 10                      # the fragment is large enough to be a region


@pytest.mark.parametrize("height", [1.5, 2.5])
def test_a_bump_taller_than_the_evaluation_distance_is_still_a_region(height):
    """A cos^2 bump of 4 mm radius, 1.5 and 2.5 mm tall, replaces the surface: with its top's
    too-far points known its flank is still exactly one region above (join_beyond then adds the
    top: test_tall_bump_one_region), its extreme beyond the limit up to the evaluation distance."""
    for seed in range(3):
        rng = np.random.default_rng(seed)
        P2 = _plane(rng)
        r = np.hypot(P2[:, 0] - 1.0, P2[:, 1])
        z = rng.normal(0, 0.02, len(P2)) + np.where(r < 4.0, height * np.cos(np.pi * r / 8) ** 2,
                                                   0.0)
        plain, with_far = _regions(P2, z)
        assert len(with_far) == 1 and with_far[0].side == "above", (seed, with_far)
        assert [(r.n, r.side) for r in with_far] == [(r.n, r.side) for r in plain]
        # the flank's evaluated out-of-tolerance points, counted directly
        flank = np.count_nonzero((z > TOL) & (z <= EV_DIST))
        assert with_far[0].n >= 0.9 * flank
        assert TOL < with_far[0].extreme <= EV_DIST + 0.1
