"""Datum feature shift (MMB/LMB, :mod:`shapeverify.characteristics.datum_shift`): the shift
radius of a hole or boss against its analytic value, and the best pose within the shift
against a brute-force search over the allowed shift (a dense grid over the disc, and scipy's
SLSQP on the exact disc)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.optimize import minimize

from shapeverify.characteristics.datum_shift import (POLYGON, best_profile_shift,
                                                     shift_allowance)


def _ring(r, k=720, h=10.0, rng=None):
    rng = rng or np.random.default_rng(0)
    th = rng.uniform(0, 2 * np.pi, k)
    return np.column_stack([r * np.cos(th), r * np.sin(th), rng.uniform(0, h, k)])


@pytest.mark.parametrize("hole,material,radius,expected", [
    (True, "M", 5.05, 0.05),     # hole at MMB 10.0 (nominal 10, -0 / +0.2): 5.05 - 5.0
    (False, "M", 4.95, 0.15),    # boss at MMB 10.2: 5.1 - 4.95
    (True, "L", 5.05, 0.05),     # hole at LMB 10.2: 5.1 - 5.05
    (False, "L", 5.05, 0.05),    # boss at LMB 10.0: 5.05 - 5.0
])
def test_shift_radius_is_the_departure_from_the_boundary(hole, material, radius, expected):
    size = SimpleNamespace(nominal=10.0, lower=0.0, upper=0.2)
    r, det = shift_allowance(_ring(radius), [0, 0, 0], [0, 0, 1], hole, material, size)
    assert r == pytest.approx(expected, abs=1e-9)
    assert "violates_boundary" not in det


def test_a_hole_smaller_than_its_mmb_allows_no_shift_and_says_by_how_much():
    size = SimpleNamespace(nominal=10.0, lower=0.0, upper=0.2)
    r, det = shift_allowance(_ring(4.97), [0, 0, 0], [0, 0, 1], True, "M", size)
    assert r == 0.0 and det["violates_boundary"] == pytest.approx(0.03, abs=1e-9)


def _profile(rng):
    """Points of a bent strip (normals in the xy plane, varied) with deviations that a
    sideways move partly cancels."""
    k = 300
    th = rng.uniform(0, np.pi, k)
    X = np.column_stack([40 + 20 * np.cos(th), 20 * np.sin(th), rng.uniform(0, 5, k)])
    N = np.column_stack([np.cos(th), np.sin(th), np.zeros(k)])
    d = 0.08 * np.cos(th - 0.4) + rng.normal(0, 0.005, k)
    return X, N, d


@pytest.mark.parametrize("r", [0.0, 0.03, 0.2])
def test_best_pose_within_the_shift_is_the_brute_force_minimum(r):
    """A secondary hole at MMB after a primary plane z: the frame may translate in x and y
    by up to r.  The LP's value lies between the exact minimum over the disc and that plus
    what the inscribed 64-gon loses; the exact minimum from a dense grid and from SLSQP."""
    rng = np.random.default_rng(7)
    X, N, d = _profile(rng)
    S = np.zeros((6, 2))
    S[3, 0] = S[4, 1] = 1.0                       # translations x, y
    ends = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 10.0]])
    val, xi, _ = best_profile_shift(X, N, d, S, [(ends, [0, 0, 1], r)])

    def f(t):
        return np.abs(d + N[:, :2] @ t).max()

    g = np.linspace(-r, r, 301) if r else np.zeros(1)
    T = np.array([(a, b) for a in g for b in g if a * a + b * b <= r * r])
    grid = min(f(t) for t in T)
    ex = minimize(lambda v: v[2], np.r_[0.0, 0.0, f(np.zeros(2))], method="SLSQP",
                  constraints=[{"type": "ineq", "fun": lambda v: v[2] - np.abs(d + N[:, :2] @ v[:2])},
                               {"type": "ineq", "fun": lambda v: r * r - v[0] ** 2 - v[1] ** 2}],
                  options={"ftol": 1e-12, "maxiter": 500})
    exact = min(grid, ex.fun) if ex.success else grid
    # 1e-7 mm: HiGHS's feasibility tolerance
    assert exact - 1e-7 <= val <= exact + r * (1 - np.cos(np.pi / POLYGON)) + 1e-7
    assert np.hypot(*xi[3:5]) <= r + 1e-7 and np.allclose(xi[:3], 0) and xi[5] == 0
    # the value at the returned motion is what the LP says
    assert f(xi[3:5]) == pytest.approx(val, abs=1e-7)
    if r == 0.0:
        assert val == pytest.approx(np.abs(d).max(), abs=1e-12)
