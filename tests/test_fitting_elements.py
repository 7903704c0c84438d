"""Least-squares geometric elements: NIST reference fits, real laser-scanner spheres, analytic shapes."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.optimize

from shapeverify import fitting
from shapeverify.fitting import elements


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def _frame(axis):
    a = _unit(axis)
    u = _unit(np.cross(a, [1.0, 0.3, 0.2]))
    return a, u, np.cross(a, u)


def _sphere_points(rng, n, center, radius, cap=np.pi):
    """Points on a spherical cap of half-angle ``cap`` around +z."""
    z = rng.uniform(np.cos(cap), 1.0, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    s = np.sqrt(1 - z * z)
    return np.asarray(center) + radius * np.column_stack([s * np.cos(phi), s * np.sin(phi), z])


def _cylinder_points(rng, n, point, axis, radius, length=4.0, arc=2 * np.pi):
    a, u, v = _frame(axis)
    h = rng.uniform(-length / 2, length / 2, n)
    phi = rng.uniform(0, arc, n)
    return (np.asarray(point) + h[:, None] * a + radius * (np.cos(phi)[:, None] * u
                                                             + np.sin(phi)[:, None] * v))


def _cone_points(rng, n, apex, axis, half_angle, h0=1.0, h1=3.0):
    a, u, v = _frame(axis)
    h = rng.uniform(h0, h1, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    rho = h * np.tan(half_angle)
    return np.asarray(apex) + h[:, None] * a + rho[:, None] * (np.cos(phi)[:, None] * u
                                                             + np.sin(phi)[:, None] * v)


def _line_distance(p, a, q):
    """Distance of point q from the line p + s a (a unit)."""
    d = q - p
    return np.linalg.norm(d - (d @ a) * a)


# ------------------------------------------------------------------------------- NIST reference
def _nist(shared_data, kind, name):
    folder = shared_data / "fitting" / "nist" / kind
    pts = np.loadtxt(folder / f"{name}.ds", skiprows=1)
    ref = np.loadtxt(folder / f"{name}.fit")
    return pts, ref


def test_nist_sph5(shared_data):
    pts, ref = _nist(shared_data, "Sphere", "sph5")
    fit = fitting.fit_sphere(pts)
    assert fit.converged
    np.testing.assert_allclose(fit.center, ref[:3], rtol=0, atol=1e-9)
    assert abs(2 * fit.radius - ref[3]) < 1e-9


def test_nist_cyl21(shared_data):
    pts, ref = _nist(shared_data, "Cylinder", "cyl21")
    fit = fitting.fit_cylinder(pts)
    assert fit.converged
    a_ref = _unit(ref[3:6])
    assert 1 - abs(fit.axis @ a_ref) < 1e-15          # direction up to sign (angle < 1e-7 rad ...)
    assert np.linalg.norm(np.cross(fit.axis, a_ref)) < 1e-9
    assert _line_distance(ref[:3], a_ref, fit.point) < 1e-9   # same axis line
    assert abs(2 * fit.radius - ref[6]) < 1e-9
    # the reported point is the axis point closest to the centroid
    c = pts.mean(axis=0)
    assert abs((c - fit.point) @ fit.axis) < 1e-9


# ------------------------------------------------------------------ real laser-scanner spheres
def test_nist_tls_spheres_robust(shared_data):
    files = sorted((shared_data / "scans" / "nist_tls_spheres").glob("*.xyz"))
    assert len(files) == 11
    for f in files:
        pts = np.loadtxt(f)                       # metres, nominal radius 0.050 m
        l2 = fitting.fit_sphere(pts)
        rob = fitting.fit_sphere(pts, loss="tukey")
        # stray points outside the sphere bias least squares by more than 10 mm ...
        assert l2.radius > 0.060, (f.name, l2.radius)
        # ... the robust fit finds the 50 mm sphere (the data show 48.9 - 50.3 mm)
        assert abs(rob.radius - 0.050) < 0.0015, (f.name, rob.radius)
        assert rob.converged
        inliers = rob.weights > 0
        assert 0.5 < inliers.mean() < 0.9
        assert np.sqrt(np.mean(rob.residuals[inliers] ** 2)) < 0.002


# -------------------------------------------------------------------------- analytic shapes
def test_sphere_exact_noise_outliers():
    rng = np.random.default_rng(1)
    c, R = np.array([3.0, -2.0, 10.0]), 25.0
    x = _sphere_points(rng, 400, c, R, cap=1.0)           # partial cap: hard for algebraic fits
    fit = fitting.fit_sphere(x)
    np.testing.assert_allclose(fit.center, c, atol=1e-9)
    assert abs(fit.radius - R) < 1e-9 and fit.rms < 1e-10
    sigma = 0.01
    xn = x + rng.normal(scale=sigma, size=x.shape)
    fit = fitting.fit_sphere(xn)
    assert abs(fit.radius - R) < 0.05 and abs(fit.rms - sigma) < 0.2 * sigma
    # residuals are the signed orthogonal distances
    np.testing.assert_allclose(fit.residuals, np.linalg.norm(xn - fit.center, axis=1) - fit.radius)
    # 20 % outliers on one side
    xo = xn.copy()
    k = rng.choice(len(xo), 80, replace=False)
    xo[k] += (x[k] - c) / R * rng.uniform(2, 6, 80)[:, None]
    def error(f):
        return np.linalg.norm(f.center - c) + abs(f.radius - R)
    l2 = fitting.fit_sphere(xo)
    assert error(l2) > 0.3
    for loss in ("tukey", "welsch"):
        rob = fitting.fit_sphere(xo, loss=loss)
        assert error(rob) < 0.01, loss
        assert rob.weights[k].max() < 0.05
    assert error(fitting.fit_sphere(xo, loss="huber")) < error(l2)


def test_circle_2d_and_3d():
    rng = np.random.default_rng(2)
    t = rng.uniform(0, 1.5, 200)                    # an 86 degree arc
    c2, R = np.array([5.0, -1.0]), 7.0
    x2 = c2 + R * np.column_stack([np.cos(t), np.sin(t)])
    fit = fitting.fit_circle(x2)
    assert fit.normal is None
    np.testing.assert_allclose(fit.center, c2, atol=1e-9)
    assert abs(fit.radius - R) < 1e-9
    a, u, v = _frame([1.0, 2.0, 0.5])
    c3 = np.array([1.0, 2.0, 3.0])
    x3 = c3 + R * (np.cos(t)[:, None] * u + np.sin(t)[:, None] * v)
    fit = fitting.fit_circle(x3)
    np.testing.assert_allclose(fit.center, c3, atol=1e-8)
    assert abs(fit.radius - R) < 1e-9
    assert 1 - abs(fit.normal @ a) < 1e-12
    # noisy 3-D: residuals are distances to the circle (brute force on a dense polyline)
    xn = x3 + rng.normal(scale=0.02, size=x3.shape)
    fit = fitting.fit_circle(xn)
    _, fu, fv = _frame(fit.normal)
    s = np.linspace(0, 2 * np.pi, 200001)
    ring = fit.center + fit.radius * (np.cos(s)[:, None] * fu + np.sin(s)[:, None] * fv)
    brute = np.array([np.min(np.linalg.norm(ring - p, axis=1)) for p in xn[:20]])
    np.testing.assert_allclose(fit.residuals[:20], brute, atol=1e-6)
    assert abs(fit.radius - R) < 0.02


def test_line_and_plane():
    rng = np.random.default_rng(3)
    p0, a = np.array([1.0, 2.0, 3.0]), _unit([1.0, -2.0, 0.5])
    s = rng.uniform(-10, 10, 300)
    x = p0 + s[:, None] * a + rng.normal(scale=0.01, size=(300, 3))
    fit = fitting.fit_line(x)
    assert 1 - abs(fit.direction @ a) < 1e-6
    assert _line_distance(p0, a, fit.point) < 0.01
    # outliers: robust line ignores them
    xo = x.copy()
    xo[:30] += rng.uniform(2, 5, (30, 3))
    assert 1 - abs(fitting.fit_line(xo, loss="tukey").direction @ a) < 1e-5
    n = _unit([0.2, 0.3, 1.0])
    _, u, v = _frame(n)
    y = p0 + rng.uniform(-5, 5, (300, 1)) * u + rng.uniform(-5, 5, (300, 1)) * v
    fit = fitting.fit_plane(y)
    np.testing.assert_allclose(fit.normal, n, atol=1e-12)
    assert np.max(np.abs(fit.residuals)) < 1e-12
    yo = y + rng.normal(scale=0.01, size=y.shape) * n
    yo[:40] += 3.0 * n
    assert 1 - fitting.fit_plane(yo).normal @ n > 1e-4         # least squares is tilted ...
    rob = fitting.fit_plane(yo, loss="tukey")
    assert 1 - rob.normal @ n < 1e-6                            # ... the robust fit is not
    assert rob.weights[:40].max() == 0.0


@pytest.mark.parametrize("arc", [2 * np.pi, 2.0])
def test_cylinder_exact_and_noisy(arc):
    rng = np.random.default_rng(4)
    p, a, R = np.array([10.0, -5.0, 2.0]), _unit([0.3, 1.0, 0.2]), 3.0
    x = _cylinder_points(rng, 500, p, a, R, length=20.0, arc=arc)
    fit = fitting.fit_cylinder(x)
    assert 1 - abs(fit.axis @ a) < 1e-14
    assert _line_distance(p, a, fit.point) < 1e-8
    assert abs(fit.radius - R) < 1e-9
    xn = x + rng.normal(scale=0.01, size=x.shape)
    fit = fitting.fit_cylinder(xn)
    assert abs(fit.radius - R) < 0.01 and abs(fit.rms - 0.01) < 0.002
    # same optimum as a generic least-squares solver on an independent parametrisation
    def dist(z):
        ax = _unit([z[3], z[4], 1.0])
        d = xn - z[:3]
        return np.linalg.norm(d - np.outer(d @ ax, ax), axis=1) - z[5]
    a0 = fit.axis / fit.axis[2]
    ref = scipy.optimize.least_squares(dist, np.r_[fit.point + 0.01, a0[0] + 1e-3, a0[1], fit.radius * 1.01],
                                       xtol=1e-15, ftol=1e-15, gtol=1e-15)
    assert np.sum(fit.residuals ** 2) <= 2 * ref.cost * (1 + 1e-9)
    assert abs(fit.radius - ref.x[5]) < 1e-7


def test_cylinder_robust_outliers():
    rng = np.random.default_rng(5)
    p, a, R = np.zeros(3), _unit([0.0, 0.2, 1.0]), 5.0
    x = _cylinder_points(rng, 600, p, a, R, length=30.0) + rng.normal(scale=0.01, size=(600, 3))
    x[:60] += rng.normal(scale=2.0, size=(60, 3))
    l2 = fitting.fit_cylinder(x)
    rob = fitting.fit_cylinder(x, loss="tukey")
    assert abs(rob.radius - R) < 0.005 < abs(l2.radius - R)
    assert 1 - abs(rob.axis @ a) < 1e-6


def test_cone_exact_noisy_and_against_scipy():
    rng = np.random.default_rng(6)
    apex, a, psi = np.array([1.0, 2.0, -3.0]), _unit([0.5, -0.2, 1.0]), np.radians(25.0)
    x = _cone_points(rng, 500, apex, a, psi, h0=2.0, h1=8.0)
    fit = fitting.fit_cone(x)
    assert fit.converged
    assert 1 - fit.axis @ a < 1e-13                 # opens towards +axis
    assert abs(fit.half_angle - psi) < 1e-10
    np.testing.assert_allclose(fit.apex, apex, atol=1e-8)
    assert fit.rms < 1e-10
    xn = x + rng.normal(scale=0.01, size=x.shape)
    fit = fitting.fit_cone(xn)
    assert abs(np.degrees(fit.half_angle - psi)) < 0.2

    def dist(z):                                    # apex, axis (x, y, 1), half-angle
        ax = _unit([z[3], z[4], 1.0])
        d = xn - z[:3]
        h = d @ ax
        rho = np.linalg.norm(d - np.outer(h, ax), axis=1)
        return rho * np.cos(z[5]) - h * np.sin(z[5])
    a0 = fit.axis / fit.axis[2]
    ref = scipy.optimize.least_squares(dist, np.r_[fit.apex + 0.02, a0[0], a0[1] + 1e-3, fit.half_angle],
                                       xtol=1e-15, ftol=1e-15, gtol=1e-15)
    assert np.sum(fit.residuals ** 2) <= 2 * ref.cost * (1 + 1e-9)
    np.testing.assert_allclose(fit.apex, ref.x[:3], atol=1e-6)
    # residuals are signed orthogonal distances: positive outside
    out = fit.apex + 5.0 * fit.axis + 10.0 * _frame(fit.axis)[1]
    assert fitting.fit_cone(np.vstack([xn, out])).residuals[-1] > 0


# ------------------------------------------------------------------------ robust weights, API
def test_robust_weights_shapes():
    r = np.linspace(-10, 10, 201)
    for loss, c in elements.LOSSES.items():
        w = fitting.robust_weights(r, loss, 1.0)
        assert w.shape == r.shape and w.max() <= 1.0 and w[100] == 1.0
        assert np.all(np.diff(w[100:]) <= 1e-15)       # non-increasing in |r|
        if c is not None:
            assert np.all(w[100:] < 1.0 + 1e-15)
    w = fitting.robust_weights(r, "tukey", 1.0)
    assert np.all(w[np.abs(r) >= 4.685] == 0)
    assert fitting.robust_weights([1.345], "huber", 1.0)[0] == 1.0


def test_results_repr_and_frozen():
    rng = np.random.default_rng(7)
    fit = fitting.fit_sphere(_sphere_points(rng, 100, [0, 0, 0], 1.0))
    text = repr(fit)
    assert text.startswith("SphereFit(center=") and "array (100,)" in text and "\n" not in text
    with pytest.raises(AttributeError):
        fit.radius = 2.0


@pytest.mark.parametrize("func, pts, match", [
    (fitting.fit_sphere, np.zeros((3, 3)), "at least 4"),
    (fitting.fit_sphere, np.zeros((10, 2)), r"shape \(N, 3\)"),
    (fitting.fit_cylinder, np.full((10, 3), np.nan), "NaN"),
    (fitting.fit_circle, np.zeros((5, 4)), r"\(N, 2\) or \(N, 3\)"),
    (fitting.fit_plane, np.zeros((2, 3)), "at least 3"),
    (fitting.fit_line, np.zeros(6), "shape"),
    (fitting.fit_cone, np.ones((5, 3)), "at least 6"),
])
def test_bad_input(func, pts, match):
    with pytest.raises(ValueError, match=match):
        func(pts)


def test_bad_loss_and_degenerate():
    rng = np.random.default_rng(8)
    x = _sphere_points(rng, 50, [0, 0, 0], 1.0)
    with pytest.raises(ValueError, match="unknown loss"):
        fitting.fit_sphere(x, loss="l1")
    with pytest.raises(ValueError, match="scale"):
        fitting.fit_sphere(x, loss="tukey", scale=-1.0)
    flat = np.column_stack([rng.normal(size=(50, 2)), np.zeros(50)])
    with pytest.raises(ValueError, match="plane|coplanar|radius"):
        fitting.fit_sphere(flat)
