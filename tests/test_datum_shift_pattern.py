"""Datum feature shift of a pattern or common datum at MMB (NIST FTC 08's GT16 ``D|G(M)``, a
pattern of two holes, and GT22 ``D|H(M)-J(M)``, a common datum of two holes of different
sizes), issue 28: the pattern's simulator is rigid, each hole's pin at its MMB diameter at its
basic place, so the whole pattern may move (translate and turn) as far as every hole's
departure from its pin allows; the profile is met if it is met in some such pose.

Against brute force: the linear programme of :func:`.datum_shift.best_profile_shift` (discs as
4096-gons) against SLSQP with the exact disc constraints ``|offset_k + motion(end)| <= r_k``
on the same first-order deviations, to 1e-6 mm; the shift limits of a hole against its
construction (radius, axis offset).
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from shapeverify.characteristics.datum_shift import (Infeasible, best_profile_shift,
                                                     pattern_shift_limits)


class _Size:
    def __init__(self, nominal, lower, upper):
        self.nominal, self.lower, self.upper = nominal, lower, upper


def _hole(rng, centre, radius, k=600, depth=10.0, noise=0.0):
    phi = rng.uniform(0, 2 * np.pi, k)
    z = rng.uniform(-depth, 0.0, k)
    r = radius + rng.normal(0, noise, k)
    return np.column_stack([centre[0] + r * np.cos(phi), centre[1] + r * np.sin(phi), z])


def test_pattern_shift_limits_are_each_holes_departure_and_axis_offset():
    rng = np.random.default_rng(1)
    noms = [np.array([-30.0, 0.0, 0.0]), np.array([30.0, 0.0, 0.0])]
    offs = [np.array([0.02, -0.01, 0.0]), np.array([-0.015, 0.005, 0.0])]
    radii = [3.2, 3.25]
    groups = [(p, [0, 0, 1.0], _hole(rng, p + o, r), True)
              for p, o, r in zip(noms, offs, radii)]
    # the direction is fixed by a primary plane z: the motions free before the pattern
    N = np.zeros((6, 3))
    N[3, 0] = N[4, 1] = N[2, 2] = 1.0
    datums, det = pattern_shift_limits(groups, [_Size(6.35, -0.0254, 0.1524)] * 2, "M", N)
    for (ends, a, r, o), rad, off in zip(datums, radii, offs):
        # hole radius less the MMB pin's (the smallest hole: 6.35 - 0.0254)
        assert r == pytest.approx(rad - (6.35 - 0.0254) / 2, abs=1e-6)
        assert o == pytest.approx(np.array([off, off]), abs=1e-6)    # at both ends
        assert abs(a[2]) == pytest.approx(1.0, abs=1e-12)
    assert [d["offset"] for d in det] == pytest.approx(
        [np.linalg.norm(o) for o in offs], abs=1e-6)


def _profile(rng, k=300):
    """Points of a 60 x 40 outline (normals in the xy plane) with deviations that a
    translation (0.09, -0.05) and a small turn would mostly remove."""
    t = rng.uniform(0, 1, k)
    side = rng.integers(0, 4, k)
    X = np.zeros((k, 3))
    N = np.zeros((k, 3))
    for s, (p, q, n) in enumerate([((-30, -20), (30, -20), (0, -1)), ((30, -20), (30, 20), (1, 0)),
                                   ((30, 20), (-30, 20), (0, 1)), ((-30, 20), (-30, -20), (-1, 0))]):
        m = side == s
        X[m, :2] = np.outer(1 - t[m], p) + np.outer(t[m], q)
        N[m, :2] = n
    X[:, 2] = rng.uniform(-8, -1, k)
    d = N @ np.array([0.09, -0.05, 0.0]) + 0.0015 * (X[:, 0] * N[:, 1] - X[:, 1] * N[:, 0]) \
        + rng.normal(0, 0.005, k)
    return X, N, d


def _brute(X, N, d, S, datums):
    G = np.hstack([np.cross(X, N), N]) @ S
    m = S.shape[1]

    def skew(e):
        return np.hstack([np.array([[0, e[2], -e[1]], [-e[2], 0, e[0]], [e[1], -e[0], 0]]),
                          np.eye(3)])

    cons = [{"type": "ineq", "fun": lambda z: z[m] - (d + G @ z[:m])},
            {"type": "ineq", "fun": lambda z: z[m] + (d + G @ z[:m])}]
    for ends, a, r, offs in datums:
        a = np.asarray(a) / np.linalg.norm(a)
        for e, o in zip(ends, offs):
            J = skew(e) @ S

            def disc(z, J=J, o=o, a=a, r=r):
                v = o + J @ z[:m]
                v = v - (v @ a) * a
                return r ** 2 - v @ v
            cons.append({"type": "ineq", "fun": disc})
    x0 = np.r_[np.zeros(m), np.abs(d).max()]
    res = minimize(lambda z: z[m], x0, constraints=cons, method="SLSQP",
                   options={"ftol": 1e-15, "maxiter": 1000})
    assert res.success, res.message
    return float(res.x[m]), res.x[:m]


def test_pattern_shift_lp_equals_the_exact_disc_optimum():
    rng = np.random.default_rng(2)
    X, N, d = _profile(rng)
    S = np.zeros((6, 3))
    S[3, 0] = S[4, 1] = S[2, 2] = 1.0               # tx, ty, rz: what the pattern fixes
    z0 = np.array([[0, 0, 0.0], [0, 0, -10.0]])
    datums = [(z0 + [-30, 0, 0], [0, 0, 1.0], 0.06, np.array([[0.01, -0.02, 0], [0.01, -0.02, 0]])),
              (z0 + [30, 0, 0], [0, 0, 1.0], 0.04, np.array([[-0.005, 0.01, 0], [-0.005, 0.01, 0]]))]
    lin, xi, y = best_profile_shift(X, N, d, S, datums, polygon=4096)
    ref, y_ref = _brute(X, N, d, S, datums)
    assert lin == pytest.approx(ref, abs=1e-6)
    assert lin < np.abs(d).max() - 0.03                # the shift helps
    # the LP's pose keeps every hole on its pin (exact discs, to the polygon's 3e-7 r)
    for ends, a, r, offs in datums:
        for e, o in zip(ends, offs):
            v = o + np.cross(xi[:3], e) + xi[3:]
            assert np.hypot(v[0], v[1]) <= r + 1e-7     # (HiGHS feasibility tolerance)
    # with the offsets ignored (a single datum axis's code path) the answer differs
    lin0, _, _ = best_profile_shift(X, N, d, S, [x[:3] for x in datums], polygon=4096)
    assert abs(lin0 - lin) > 1e-4


def test_a_pattern_that_cannot_fit_its_simulator_is_reported():
    rng = np.random.default_rng(3)
    X, N, d = _profile(rng)
    S = np.zeros((6, 3))
    S[3, 0] = S[4, 1] = S[2, 2] = 1.0
    z0 = np.array([[0, 0, 0.0], [0, 0, -10.0]])
    # the two holes 0.2 apart more than the pattern, each allowing 0.05: no pose fits
    datums = [(z0 + [-30, 0, 0], [0, 0, 1.0], 0.05, np.array([[-0.1, 0, 0], [-0.1, 0, 0]])),
              (z0 + [30, 0, 0], [0, 0, 1.0], 0.05, np.array([[0.1, 0, 0], [0.1, 0, 0]]))]
    with pytest.raises(Infeasible, match="no pose of the part fits"):
        best_profile_shift(X, N, d, S, datums)
