"""The angle of a cone (:mod:`shapeverify.characteristics.cone_sizes`; issue 28 item 3, NIST
CTC 04 ``Size_Angular``): the CAD's closed-form cone and the scan's fitted cone against an
independent brute-force least-squares fit in another parametrisation."""
from __future__ import annotations

import numpy as np
import pytest

from shapeverify.characteristics.cone_sizes import (cone_fit_angle, cone_from_normals,
                                                    half_angle_sd)


def _countersink(rng, n, psi, apex, axis, h0=2.0, h1=10.0, arc=np.pi):
    """Points and outward unit normals on a cone (half angle ``psi``, apex, axis towards the
    opening) between axial heights h0 and h1 over an ``arc`` of its revolution."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    e1 = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    h = rng.uniform(h0, h1, n)
    t = rng.uniform(0.0, arc, n)
    radial = np.outer(np.cos(t), e1) + np.outer(np.sin(t), e2)
    X = np.asarray(apex, float) + np.outer(h, a) + (h * np.tan(psi))[:, None] * radial
    N = np.cos(psi) * radial - np.sin(psi) * a
    return X, N


def _brute_force_half_angle(P, apex0, axis0, psi0):
    """Least squares over (apex 3, axis as polar angles 2, half angle): orthogonal distance
    ``|q| sin(angle(q, a) - psi)`` of each point, by scipy's trust-region solver."""
    from scipy.optimize import least_squares

    def axis_of(th, ph):
        return np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])

    def res(x):
        q = P - x[:3]
        a = axis_of(x[3], x[4])
        ang = np.arctan2(np.linalg.norm(np.cross(q, a), axis=1), q @ a)
        return np.linalg.norm(q, axis=1) * np.sin(ang - x[5])

    a0 = np.asarray(axis0, float)
    x0 = np.r_[apex0, np.arccos(a0[2]), np.arctan2(a0[1], a0[0]), psi0]
    r = least_squares(res, x0, xtol=1e-15, ftol=1e-15, gtol=1e-15, method="lm")
    return float(r.x[5])


def test_cad_cone_from_normals_is_the_countersinks_exact_cone():
    rng = np.random.default_rng(1)
    apex, axis = np.array([-110.0, 20.0, 20.0]), np.array([0.2, -0.1, 1.0])
    X, N = _countersink(rng, 200, np.radians(45.0), apex, axis)
    A, a, psi, err = cone_from_normals(X, N)
    assert np.allclose(A, apex, atol=1e-9)
    assert np.allclose(a, axis / np.linalg.norm(axis), atol=1e-12)
    assert abs(np.degrees(psi) - 45.0) < 1e-9 and err < 1e-9


@pytest.mark.parametrize("psi_deg,arc", [(45.0, np.pi), (41.0, 2 * np.pi), (30.0, np.pi)])
def test_fitted_half_angle_is_the_brute_force_least_squares_cone(psi_deg, arc):
    rng = np.random.default_rng(int(psi_deg))
    apex, axis = np.array([5.0, -3.0, 20.0]), np.array([0.0, 0.1, 1.0])
    X, N = _countersink(rng, 400, np.radians(psi_deg), apex, axis, arc=arc)
    P = X + rng.normal(0.0, 0.02, len(X))[:, None] * N
    f, psi = cone_fit_angle(P, axis / np.linalg.norm(axis), loss="l2")
    ref = _brute_force_half_angle(P, apex, axis / np.linalg.norm(axis), np.radians(psi_deg))
    assert abs(np.degrees(psi) - np.degrees(ref)) < 1e-6
    assert abs(psi - np.radians(psi_deg)) < 4 * half_angle_sd(P, f)


def test_half_angle_uncertainty_is_the_spread_of_repeated_scans():
    """The sandwich standard uncertainty against the standard deviation of 60 fits of
    independent noise draws on the same half countersink (agree within 30 %)."""
    rng = np.random.default_rng(5)
    apex, axis = np.zeros(3), np.array([0.0, 0.0, 1.0])
    X, N = _countersink(rng, 300, np.radians(45.0), apex, axis)
    got, sds = [], []
    for _ in range(60):
        P = X + rng.normal(0.0, 0.02, len(X))[:, None] * N
        f, psi = cone_fit_angle(P, axis, loss="l2")
        got.append(psi)
        sds.append(half_angle_sd(P, f))
    assert 0.7 < np.mean(sds) / np.std(got) < 1.3
