"""Sizes of radii and spheres (issue 28 item 3: NIST FTC 06 Size_Radius, Size_SphericalDiameter):
the least-squares size against an exact shape and scipy's geometric fit, its uncertainty
against Monte Carlo, and on a part built with OCP (tests/test_position_zones.py's ball)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from shapeverify.characteristics.size_features import _fit, radius_uncertainty


def _cap(rng, n, r, noise, c=(3.0, -2.0, 7.0)):
    d = rng.normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.3
    d /= np.linalg.norm(d, axis=1)[:, None]
    return np.asarray(c) + (r + rng.normal(0, noise, n))[:, None] * d


def _arc(rng, n, r, noise, span=np.pi):
    t = rng.uniform(0, span, n)
    z = rng.uniform(0, 20, n)
    rr = r + rng.normal(0, noise, n)
    return np.column_stack([1.0 + rr * np.cos(t), 2.0 + rr * np.sin(t), z])


@pytest.mark.parametrize("shape", ["sphere", "cylinder"])
def test_size_of_an_exact_shape_is_its_radius(shape):
    rng = np.random.default_rng(0)
    P = _cap(rng, 400, 15.875, 0.0) if shape == "sphere" else _arc(rng, 400, 12.7, 0.0)
    axis = None if shape == "sphere" else np.array([0.0, 0.0, 1.0])
    _, _, _, r = _fit(P, shape, axis)
    assert r == pytest.approx(15.875 if shape == "sphere" else 12.7, abs=1e-9)


def test_sphere_size_matches_scipy_geometric_least_squares_on_gaussian_noise():
    rng = np.random.default_rng(1)
    P = _cap(rng, 2000, 15.875, 0.01)
    ref = least_squares(lambda p: np.linalg.norm(P - p[:3], axis=1) - p[3],
                        np.r_[P.mean(axis=0), 10.0], xtol=1e-15, ftol=1e-15, gtol=1e-15)
    _, c, _, r = _fit(P, "sphere")
    # Tukey weights on clean Gaussian residuals stay near 1: the fit is the L2 fit closely
    assert abs(r - ref.x[3]) < 2e-4 and np.abs(c - ref.x[:3]).max() < 5e-4


@pytest.mark.parametrize("shape", ["sphere", "cylinder"])
def test_radius_uncertainty_is_the_monte_carlo_spread(shape):
    rng = np.random.default_rng(2)
    axis0 = None if shape == "sphere" else np.array([0.0, 0.0, 1.0])
    rs, us = [], []
    for _ in range(60):
        P = _cap(rng, 300, 15.875, 0.02) if shape == "sphere" else _arc(rng, 300, 12.7, 0.02)
        f, c, a, r = _fit(P, shape, axis0)
        rs.append(r)
        us.append(radius_uncertainty(P, c, a, f.residuals, f.weights))
    assert np.median(us) == pytest.approx(np.std(rs), rel=0.3)
