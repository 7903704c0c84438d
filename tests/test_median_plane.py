"""The derived median plane of a width (ASME Y14.5-2009 1.3.23) and an orientation zone of it
(NIST FTC 06 GT15: perpendicularity of the width B's median plane to datum A was unsupported).

Checked against brute force: median points as the exact midpoints of opposed points (sides
whose interpolation is exact: planes at random sample positions; curved sides sampled at the
same positions), the zone against a dense scan of the free angle refined by a bounded scalar
minimiser (as tests/test_gdt.py checks planes zones), to 1e-6 mm.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from shapeverify.characteristics.gdt_zones import planes_zone
from shapeverify.characteristics.median_plane import median_points

TOL = 1e-6


def _brute_one_turn(width_of, lo=-0.05, hi=0.05):
    ts = np.linspace(lo, hi, 40001)
    w = np.array([width_of(t) for t in ts])
    i = int(np.argmin(w))
    a, b = ts[max(i - 1, 0)], ts[min(i + 1, len(ts) - 1)]
    r = minimize_scalar(width_of, bounds=(a, b), method="bounded", options={"xatol": 1e-13})
    return min(float(r.fun), float(w[i]))


def test_median_points_of_two_tilted_planar_sides_are_their_exact_midpoints():
    """Side 1 x = 5 + 0.003 y - 0.002 z, side 2 x = -5 + 0.001 y + 0.004 z, sampled at
    different random (y, z): each median point lies at the mean of the two sides' x at its
    (y, z) (linear interpolation is exact on planes); points beyond the other side's hull
    are left out."""
    rng = np.random.default_rng(1)
    yz1 = rng.uniform([0, 0], [40, 20], (300, 2))
    yz2 = rng.uniform([-1, -1], [41, 21], (280, 2))
    s1 = lambda yz: 5 + 0.003 * yz[:, 0] - 0.002 * yz[:, 1]
    s2 = lambda yz: -5 + 0.001 * yz[:, 0] + 0.004 * yz[:, 1]
    X1 = np.column_stack([s1(yz1), yz1])
    X2 = np.column_stack([s2(yz2), yz2])
    M = median_points(X1, X2, [1.0, 0.0, 0.0])
    yz = M[:, 1:]
    np.testing.assert_allclose(M[:, 0], 0.5 * (s1(yz) + s2(yz)), atol=1e-9)
    # side 2 is sampled over a wider box: its hull holds (nearly) all of side 1
    assert len(M) >= 300


@pytest.mark.parametrize("seed", [2, 3])
def test_median_plane_perpendicularity_zone_equals_an_angle_scan_of_the_exact_midpoints(seed):
    """A tab 10 mm wide (sides along +-x) with wavy, tilted sides and 0.02 mm noise, both sides
    sampled at the same (y, z): the median points are the exact midpoints; their
    perpendicularity zone to a datum plane z (the zone's normal turning about z) equals the
    narrowest slab over a dense scan of the angle."""
    rng = np.random.default_rng(seed)
    yz = rng.uniform([0, 0], [40, 20], (250, 2))
    y, z = yz.T
    x1 = 5 + 0.004 * z + 0.03 * np.sin(y / 5) + 0.02 * rng.standard_normal(250)
    x2 = -5 + 0.001 * y + 0.01 * np.cos(z / 3) + 0.02 * rng.standard_normal(250)
    X1 = np.column_stack([x1, y, z])
    X2 = np.column_stack([x2, y, z])
    M = median_points(X1, X2, [1.0, 0.0, 0.0])
    mid = np.column_stack([0.5 * (x1 + x2), y, z])
    # every median point is an exact midpoint (each appears once per side)
    key = lambda A: A[np.lexsort(A.T[::-1])]
    np.testing.assert_allclose(key(M), key(np.vstack([mid, mid])), atol=1e-9)
    w, n, _ = planes_zone(M, [1.0, 0.0, 0.0], turn=[[0.0, 1.0, 0.0]])
    brute = _brute_one_turn(lambda t: np.ptp(mid @ np.array([np.cos(t), np.sin(t), 0.0])))
    assert w == pytest.approx(brute, abs=TOL)
    assert abs(n[2]) < 1e-12
    # the sides' own zones are wider than the median plane's: the zone is of the median
    assert w < planes_zone(X1, [1.0, 0.0, 0.0], turn=[[0.0, 1.0, 0.0]])[0] + \
        planes_zone(X2, [1.0, 0.0, 0.0], turn=[[0.0, 1.0, 0.0]])[0]


def test_median_points_reject_a_side_of_fewer_than_three_points():
    with pytest.raises(ValueError, match="n >= 3"):
        median_points(np.zeros((2, 3)), np.ones((5, 3)), [1, 0, 0])
