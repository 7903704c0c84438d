"""Position of axes with datums referenced at MMB (ASME Y14.5-2009 4.11, 7: the datum feature
simulator at MMB; the frame may shift by the datum feature's departure from MMB, and the
tolerance is met if some shift within it brings every axis into its zone).  NIST CTC 03 GT5
(position 1.27 (M) to A|B(M)|C(M)) was unsupported: "datum modifiers ... are not applied".

:func:`best_position_shift` (a linear programme on regular polygons inscribed in the zone
circles and the shift discs) against brute force of the same definition: every vertex of the
LP's feasible set (three active constraints in (tx, ty, s)) enumerated, the least s of the
feasible ones, to 1e-6 mm; and against the exact circles (a dense grid of the shift refined
by Nelder-Mead) within the polygon's 0.12 % of the radius.
"""
from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.optimize import minimize

from shapeverify.characteristics.datum_shift import best_position_shift

Z = np.array([0.0, 0.0, 1.0])
S_T = np.array([[0, 0], [0, 0], [0, 0], [1, 0], [0, 1], [0, 0]], float)   # tx, ty


def _case(seed):
    rng = np.random.default_rng(seed)
    cs = [np.array([30.0, 0.0, 0.0]), np.array([-20.0, 25.0, 0.0]), np.array([5.0, -40.0, 0.0])]
    axes = []
    for c in cs:
        off = rng.uniform(-0.6, 0.6, 2)
        e = c + np.array([off[0], off[1], 0.0])
        axes.append((np.array([e, e + [0, 0, 10.0]]), c, Z, float(rng.uniform(0.5, 1.2))))
    dat = [(np.array([[0, 0, 0.0], [0, 0, 10.0]]), Z, float(rng.uniform(0.05, 0.4)))]
    return axes, dat


def _vertex_enumeration(axes, dat, polygon):
    ang = 2 * np.pi * (np.arange(polygon) + 0.5) / polygon
    U = np.column_stack([np.cos(ang), np.sin(ang)])
    cp = np.cos(np.pi / polygon)
    A, b = [], []
    for ends, c0, _, z in axes:
        q = ends[0, :2] - c0[:2]
        for u in U:           # u.(q + t) <= cp (z/2 + s)
            A.append([u[0], u[1], -cp])
            b.append(cp * z / 2 - u @ q)
    for _, _, r in dat:
        for u in U:           # u.t <= cp r
            A.append([u[0], u[1], 0.0])
            b.append(cp * r)
    A, b = np.array(A), np.array(b)
    best = np.inf
    for i, j, k in itertools.combinations(range(len(A)), 3):
        M = A[[i, j, k]]
        if abs(np.linalg.det(M)) < 1e-12:
            continue
        x = np.linalg.solve(M, b[[i, j, k]])
        if np.all(A @ x <= b + 1e-9):
            best = min(best, x[2])
    return best


@pytest.mark.parametrize("seed", [1, 2])
def test_position_shift_lp_equals_enumeration_of_its_vertices(seed):
    axes, dat = _case(seed)
    lin, xi, _ = best_position_shift(axes, S_T, dat, polygon=12)
    assert lin == pytest.approx(_vertex_enumeration(axes, dat, 12), abs=1e-6)
    assert np.allclose(xi[[0, 1, 2, 5]], 0.0)          # translations across the axes only


@pytest.mark.parametrize("seed", [3, 4])
def test_position_shift_agrees_with_the_exact_circles_within_the_polygon(seed):
    """The exact problem: min over |t| <= r of max_j (|q_j + t| - z_j / 2)."""
    axes, dat = _case(seed)
    r = dat[0][2]
    Q = [(ends[0, :2] - c0[:2], z) for ends, c0, _, z in axes]

    def f(t):
        pen = max(np.linalg.norm(t) - r, 0.0) * 1e3
        return max(np.linalg.norm(q + t) - z / 2 for q, z in Q) + pen

    g = np.linspace(-r, r, 81)
    T = [np.array([x, y]) for x in g for y in g if x * x + y * y <= r * r]
    t0 = min(T, key=f)
    best = minimize(f, t0, method="Nelder-Mead", options={"xatol": 1e-10, "fatol": 1e-12}).fun
    best = min(best, f(t0))
    lin, xi, _ = best_position_shift(axes, S_T, dat)          # 64-gons
    rmax = max(z / 2 + abs(best) for _, z in Q) + r
    assert lin == pytest.approx(best, abs=(1 - np.cos(np.pi / 64)) * rmax * 2 + 1e-9)
    assert lin >= best - 1e-9 - (1 - np.cos(np.pi / 64)) * rmax * 2


def test_two_holes_off_by_0p4_come_back_by_the_datum_shift():
    """Both holes 0.4 mm off along x with a zone of 0.5: 0.15 mm over; the datum's departure
    from MMB allows 0.45: the shift brings both back to their true positions."""
    axes = [(np.array([[x + 0.4, y, 0.0], [x + 0.4, y, 10.0]]), np.array([x, y, 0.0]), Z, 0.5)
            for x, y in ((20.0, 0.0), (-20.0, 10.0))]
    dat = [(np.array([[0, 0, 0.0], [0, 0, 10.0]]), Z, 0.45)]
    lin, xi, _ = best_position_shift(axes, S_T, dat)
    assert lin == pytest.approx(-0.25, abs=1e-9)
    assert xi[3] == pytest.approx(-0.4, abs=1e-9)
    # a datum allowing only 0.1: 0.3 off remains, 0.05 over the zone's radius
    lin, _, _ = best_position_shift(axes, S_T, [(dat[0][0], Z, 0.1)])
    assert lin == pytest.approx(0.3 - 0.25, abs=0.1 * (1 - np.cos(np.pi / 64)) + 1e-9)
