"""Two dents side by side (issue 29 item 1, ``benchmarks/check_defect_shapes.py`` ``pairG``):
one region or two by the in-tolerance gap between their out-of-tolerance discs, in spacings,
the same at every spacing.  The rule (``regions``): core points (neighbourhood median beyond
the limit) closer than ``LINK_FACTOR`` = 2.5 spacings are one region.  Measured on a plane
(4 seeds; random, lattice, rows 3 x apart both ways; 1/5 and 1/15 of the dent's radius): a gap
of 2.5 spacings or more is two regions in every scan, 0.5 spacing one (but where the rows,
1.7 spacings apart, run along the gap), between 1 and 2 spacings either, by where the points
fall.  Each region then carries its own dent's out-of-tolerance area.
"""
from __future__ import annotations

import numpy as np
import pytest

from shapeverify.inspection.regions import find_regions

R, DEPTH, TOL, NOISE = 15.0, -0.5, 0.2, 0.02
R_OUT = np.arccos(np.sqrt(TOL / abs(DEPTH))) * 2 * R / np.pi


def _regions(kind, s, gap, seed):
    rng = np.random.default_rng(seed)
    half = R_OUT + gap * s / 2                      # each disc's centre from the middle
    hx, hy = half + 1.5 * R, 1.5 * R
    if kind == "random":
        n = rng.poisson(4 * hx * hy / s ** 2)
        P2 = np.column_stack([rng.uniform(-hx, hx, n), rng.uniform(-hy, hy, n)])
    else:
        X, Y = np.meshgrid(np.arange(-hx, hx, s) + rng.random() * s,
                           np.arange(-hy, hy, s) + rng.random() * s)
        P2 = np.column_stack([X.ravel(), Y.ravel()])
    r = np.min([np.hypot(P2[:, 0] - sx * half, P2[:, 1]) for sx in (-1, 1)], axis=0)
    d = np.where(r < R, DEPTH * np.cos(np.pi * r / (2 * R)) ** 2, 0.0) + rng.normal(0, NOISE, len(r))
    n = len(d)
    regions, _, _ = find_regions(np.column_stack([P2, np.zeros(n)]), d, np.ones(n, bool),
                                 np.abs(d) <= TOL, np.zeros(n, int), np.tile([0.0, 0.0, 1.0], (n, 1)),
                                 limits=(np.full(n, -TOL), np.full(n, TOL)))
    return regions


@pytest.mark.parametrize("kind", ["random", "grid"])
@pytest.mark.parametrize("ratio", [1 / 5, 1 / 15])
def test_two_dents_three_spacings_apart_are_two_regions_each_its_own_area(kind, ratio):
    s = ratio * R
    for seed in range(3):
        regions = _regions(kind, s, 3.0, seed)
        assert len(regions) == 2, (seed, len(regions))
        for g in regions:
            assert abs(g.area / (np.pi * R_OUT ** 2) - 1) < 0.15, (seed, g.area)
            assert abs(g.extreme / DEPTH - 1) < 0.10, (seed, g.extreme)
        assert sorted(np.sign(g.centroid[0]) for g in regions) == [-1, 1]


@pytest.mark.parametrize("kind", ["random", "grid"])
@pytest.mark.parametrize("ratio", [1 / 5, 1 / 15])
def test_two_dents_half_a_spacing_apart_are_one_region(kind, ratio):
    s = ratio * R
    for seed in range(3):
        regions = _regions(kind, s, 0.5, seed)
        assert len(regions) == 1, (seed, len(regions))
        assert abs(regions[0].area / (2 * np.pi * R_OUT ** 2) - 1) < 0.15, (seed, regions[0].area)
