"""The torus fit (:mod:`shapeverify.fitting.torus`) that measures a fillet's radius (NIST FTC
11 DIM5, issue 28): against its definition solved independently (scipy's least squares on
the orthogonal distance ``sqrt((rho - R)^2 + h^2) - r`` in another parametrisation), and the
torus of a NURBS surface."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.optimize

from shapeverify.fitting.torus import fit_torus, torus_of_surface


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def _frame(a):
    u = _unit(np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0]))
    return u, np.cross(a, u)


def _fillet(rng, n, c, a, R, r, tube=(0.0, np.pi / 2)):
    """n points on a band of the tube (a fillet's quarter by default), all the way round."""
    u, v = _frame(a)
    t = rng.uniform(0, 2 * np.pi, n)
    p = rng.uniform(*tube, n)
    radial = np.cos(t)[:, None] * u + np.sin(t)[:, None] * v
    return c + (R + r * np.cos(p))[:, None] * radial + (r * np.sin(p))[:, None] * a


def _distance(z, x):
    """Orthogonal distance, parametrised as centre (3), axis (x, y, 1), R, r."""
    a = _unit([z[3], z[4], 1.0])
    q = x - z[:3]
    h = q @ a
    rho = np.linalg.norm(q - np.outer(h, a), axis=1)
    return np.hypot(rho - z[5], h) - z[6]


def test_fit_torus_exact_points_give_the_torus():
    rng = np.random.default_rng(1)
    c, a = np.array([3.0, -2.0, 5.0]), _unit([0.2, -0.1, 1.0])
    x = _fillet(rng, 400, c, a, 30.0, 1.5)
    f = fit_torus(x, start=(c + 0.3, _unit(a + [0.01, 0.0, 0.0]), 29.5, 1.7))
    assert f.converged and f.rms < 1e-10
    np.testing.assert_allclose(f.center, c, atol=1e-8)
    assert 1 - abs(f.axis @ a) < 1e-14
    assert abs(f.major_radius - 30.0) < 1e-9 and abs(f.minor_radius - 1.5) < 1e-9


def test_fit_torus_noisy_fillet_agrees_with_scipy_to_1e_6():
    rng = np.random.default_rng(2)
    c, a = np.array([0.0, 0.0, 1.5]), _unit([0.0, 0.05, 1.0])
    x = _fillet(rng, 2000, c, a, 30.0, 1.5, tube=(-0.2, 2.2))
    x = x + rng.normal(0.0, 0.02, x.shape)
    f = fit_torus(x, start=(c, a, 30.0, 1.5))
    a0 = f.axis / f.axis[2]
    ref = scipy.optimize.least_squares(_distance, np.r_[f.center + 0.01, a0[0] + 1e-3, a0[1],
                                                        f.major_radius - 0.01,
                                                        f.minor_radius + 0.01],
                                       args=(x,), xtol=1e-15, ftol=1e-15, gtol=1e-15)
    assert np.sum(f.residuals ** 2) <= 2 * ref.cost * (1 + 1e-9)
    np.testing.assert_allclose(f.center, ref.x[:3], atol=1e-6)
    assert abs(f.major_radius - ref.x[5]) < 1e-6 and abs(f.minor_radius - ref.x[6]) < 1e-6
    assert abs(f.minor_radius - 1.5) < 0.01
    # signed: a point outside the tube reads positive
    out = c + 33.0 * _frame(a)[0]
    assert fit_torus(np.vstack([x, out]), start=f).residuals[-1] > 0


def test_fit_torus_rejects_a_start_that_is_no_torus():
    x = _fillet(np.random.default_rng(3), 50, np.zeros(3), np.array([0, 0, 1.0]), 10.0, 1.0)
    with pytest.raises(ValueError, match="start must be"):
        fit_torus(x, start=(np.zeros(3), np.array([0, 0, 1.0]), 10.0, -1.0))


def test_torus_of_a_nurbs_surface_of_revolution_is_its_torus_and_none_for_a_cylinder():
    """A rational NURBS torus (the tube's circle swept about the axis, exact) read back by
    its iso-parameter circles; a cylinder's straight rulings are not a torus."""
    from shapeverify.cad.nurbs import NurbsSurface

    w = np.sqrt(0.5)
    knots = np.array([0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1.0])
    circ = np.array([[1, 0], [1, 1], [0, 1], [-1, 1], [-1, 0], [-1, -1], [0, -1], [1, -1],
                     [1, 0.0]])
    cw = np.array([1, w, 1, w, 1, w, 1, w, 1.0])
    R, r = 30.0, 1.5
    P, W = np.empty((9, 9, 3)), np.empty((9, 9))
    for i in range(9):              # about the axis (u)
        for j in range(9):          # round the tube (v)
            rad = R + r * circ[j, 0]
            P[i, j] = [rad * circ[i, 0], rad * circ[i, 1], r * circ[j, 1]]
            W[i, j] = cw[i] * cw[j]
    surf = NurbsSurface(2, 2, knots, knots, P, W)
    t = torus_of_surface(surf, ((0.0, 1.0), (0.3, 0.7)))
    assert t is not None
    assert abs(t.minor_radius - r) < 1e-9 and abs(t.major_radius - R) < 1e-9
    assert np.linalg.norm(t.center) < 1e-9 and abs(abs(t.axis[2]) - 1) < 1e-12
    cyl = NurbsSurface(2, 1, knots, np.array([0, 0, 1, 1.0]),
                       np.stack([P[:, 4] * [1, 1, 0] + [0, 0, z] for z in (0.0, 5.0)], 1),
                       np.stack([cw, cw], 1))
    assert torus_of_surface(cyl, ((0.0, 1.0), (0.0, 1.0))) is None
