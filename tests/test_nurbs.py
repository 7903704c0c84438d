"""Tests for shapeverify.cad.nurbs and its numba kernels (thesis §7.1-7.2, The NURBS Book)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numba import njit

from shapeverify.cad import _kernels as K
from shapeverify.cad.nurbs import (
    NurbsCurve,
    NurbsSurface,
    circle,
    cylinder,
    evaluate_packed,
    pack_surfaces,
    sphere,
)


# ------------------------------------------------------------------------------ helpers
def cox_de_boor(i: int, p: int, U: np.ndarray, u: float) -> float:
    """Reference: the recursive definition of N_{i,p}(u) (NURBS Book eq. 2.5), right-continuous,
    with the last non-empty span closed at the end of the domain."""
    if p == 0:
        if U[i] <= u < U[i + 1]:
            return 1.0
        # closed at u = U[-1]: the last non-empty span owns the end point
        last = np.flatnonzero(U[:-1] < U[1:])[-1]
        return 1.0 if (u == U[-1] and i == last) else 0.0
    a = 0.0 if U[i + p] == U[i] else (u - U[i]) / (U[i + p] - U[i]) * cox_de_boor(i, p - 1, U, u)
    b = 0.0
    if U[i + p + 1] != U[i + 1]:
        b = (U[i + p + 1] - u) / (U[i + p + 1] - U[i + 1]) * cox_de_boor(i + 1, p - 1, U, u)
    return a + b


def all_basis(p, U, u):
    """All n+1 basis values at u from the kernels (find_span + basis_funs)."""
    n = len(U) - p - 2
    s = K.find_span(n, p, u, U)
    N = np.zeros(p + 1)
    K.basis_funs(s, u, p, U, N, np.zeros(p + 1), np.zeros(p + 1))
    full = np.zeros(n + 1)
    full[s - p:s + 1] = N
    return full


def all_ders(p, U, u, nd):
    n = len(U) - p - 2
    s = K.find_span(n, p, u, U)
    D = np.zeros((nd + 1, p + 1))
    K.ders_basis_funs(s, u, p, nd, U, D, np.zeros((p + 1, p + 1)), np.zeros((2, p + 1)),
                      np.zeros(p + 1), np.zeros(p + 1))
    full = np.zeros((nd + 1, n + 1))
    full[:, s - p:s + 1] = D
    return full


@st.composite
def knot_vectors(draw, max_degree=5):
    """Clamped knot vectors on [a, b] with random (possibly repeated) interior knots."""
    p = draw(st.integers(1, max_degree))
    n_int = draw(st.integers(0, 8))
    a = draw(st.floats(-10, 10))
    length = draw(st.floats(0.1, 20))
    fr = sorted(draw(st.lists(st.integers(1, 19), min_size=n_int, max_size=n_int)))
    interior = []
    for f in fr:  # cap multiplicity at p so the basis stays continuous
        if interior.count(a + length * f / 20) < p:
            interior.append(a + length * f / 20)
    U = np.array([a] * (p + 1) + interior + [a + length] * (p + 1))
    return p, U


def random_surface(rng, p=3, q=3, nu=7, nv=6, rational=True, repeat=True):
    """Random surface with non-uniform knots (a double interior knot when repeat)."""
    def knots(deg, n):
        inner = np.sort(rng.uniform(0.0, 2.0, n - deg - 1))
        if repeat and n - deg - 1 >= 2 and deg >= 2:
            inner[1] = inner[0]
        return np.concatenate([[0.0] * (deg + 1), inner, [2.0] * (deg + 1)]) - 0.5
    P = rng.normal(size=(nu, nv, 3)) * 10
    W = rng.uniform(0.3, 3.0, (nu, nv)) if rational else None
    return NurbsSurface(p, q, knots(p, nu), knots(q, nv), P, W)


def interior_params(rng, knots, p, n_ctrl, N, margin=1e-3):
    """Parameters at least `margin` away from every knot."""
    lo, hi = knots[p], knots[n_ctrl]
    t = rng.uniform(lo, hi, 4 * N)
    ok = np.min(np.abs(t[:, None] - knots[None, :]), axis=1) > margin
    return t[ok][:N]


# ------------------------------------------------------------------------ basis (thesis §7.1)
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(knot_vectors(), st.floats(0, 1))
def test_basis_properties_random_knots(pU, frac):
    p, U = pU
    n = len(U) - p - 2
    lo, hi = U[p], U[n + 1]
    knots_in = U[(U >= lo) & (U <= hi)]
    for u in [lo + frac * (hi - lo), lo, hi, *knots_in]:
        N = all_basis(p, U, u)
        # 3. non-negativity, 4. partition of unity
        assert np.all(N >= 0)
        assert abs(N.sum() - 1.0) < 1e-13
        # 2. at most p+1 non-zero, consecutive
        nz = np.flatnonzero(N)
        assert len(nz) <= p + 1 and (len(nz) == 0 or nz[-1] - nz[0] <= p)
        # 1. local support and agreement with the recursive definition, for every i
        for i in range(n + 1):
            ref = cox_de_boor(i, p, U, u)
            assert abs(N[i] - ref) < 1e-13
            inside = (U[i] <= u < U[i + p + 1]) or (u == hi and U[i] < u <= U[i + p + 1])
            if not inside:
                assert N[i] == 0.0


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(knot_vectors(), st.floats(0.01, 0.99))
def test_ders_basis_vs_finite_differences(pU, frac):
    p, U = pU
    n = len(U) - p - 2
    lo, hi = U[p], U[n + 1]
    u = lo + frac * (hi - lo)
    h = 1e-6 * (hi - lo)
    if np.min(np.abs(U - u)) < 10 * h:  # stay inside one span
        return
    D = all_ders(p, U, u, p + 1)
    assert np.allclose(D[0], all_basis(p, U, u), atol=1e-14)
    assert np.all(D[p + 1] == 0)  # derivatives above the degree vanish
    for k in range(1, p + 1):
        assert abs(D[k].sum()) < 1e-8 * max(1.0, np.abs(D[k]).max())  # d^k/du^k of 1 = 0
        fd = (all_ders(p, U, u + h, k - 1)[k - 1] - all_ders(p, U, u - h, k - 1)[k - 1]) / (2 * h)
        scale = max(1.0, np.abs(D[k]).max())
        assert np.allclose(D[k], fd, atol=1e-5 * scale * max(1, k)), (k, D[k], fd)


def test_find_span_end_and_repeated_knots():
    U = np.array([0, 0, 0, 1, 2, 2, 3, 4, 4, 4], dtype=float)  # p = 2, n = 6
    p, n = 2, 6
    for u in np.concatenate([np.linspace(0, 4, 401), U]):
        s = K.find_span(n, p, u, U)
        if u < 4:
            assert U[s] <= u < U[s + 1]
        else:
            assert s == 6 and U[s] < U[s + 1]  # last non-empty span at u == u_max
    # a clamped vector whose last interior knot equals the end is skipped at u == u_max
    U2 = np.array([0, 0, 1, 1, 1], dtype=float)  # p = 1, n = 2: span 2 is empty
    assert K.find_span(2, 1, 1.0, U2) == 1


@settings(max_examples=40, deadline=None)
@given(knot_vectors(), st.lists(st.floats(0, 1), min_size=1, max_size=30))
def test_lookup_span_matches_find_span(pU, fracs):
    p, U = pU
    n = len(U) - p - 2
    table, u0, scale, last = K.span_table(p, U, n)
    lo, hi = U[p], U[n + 1]
    for u in [lo + f * (hi - lo) for f in fracs] + list(U[p:n + 2]) + [np.nextafter(hi, lo)]:
        assert K.lookup_span(u, p, U, table, u0, scale, last) == K.find_span(n, p, u, U)


# ------------------------------------------------------------------------- analytic shapes
def test_circle_radius_exact():
    c = circle(1.0)
    t = np.concatenate([np.linspace(0, 1, 10001), c.knots])
    d = c.derivatives(t, 2)
    assert np.abs(np.linalg.norm(d[:, 0], axis=1) - 1.0).max() < 1e-12
    assert np.abs(d[:, 0, 2]).max() == 0.0
    # tangent perpendicular to the radius; counter-clockwise
    assert np.abs(np.einsum("ij,ij->i", d[:, 0], d[:, 1])).max() < 1e-12 * np.abs(d[:, 1]).max()
    assert np.all(np.cross(d[:, 0], d[:, 1])[:, 2] > 0)
    c2 = circle(2.5, (1.0, -2.0))
    assert c2.dim == 2 and c2.rational
    pts = c2.evaluate(np.linspace(0, 1, 1001))
    assert np.abs(np.linalg.norm(pts - [1.0, -2.0], axis=1) - 2.5).max() < 1e-12 * 2.5


def test_sphere_exact():
    rng = np.random.default_rng(1)
    r, c = 3.7, np.array([1.0, -2.0, 0.5])
    s = sphere(r, c)
    u, v = rng.random(5000), rng.random(5000)
    P = s.evaluate(u, v)
    assert np.abs(np.linalg.norm(P - c, axis=1) - r).max() < 1e-12 * r
    vi = rng.uniform(0.02, 0.98, 5000)
    n = s.normal(u, vi)
    radial = (s.evaluate(u, vi) - c) / r
    assert np.abs(n - radial).max() < 1e-12
    # the poles: the limit normal points outwards along -z / +z
    npole = s.normal([0.1, 0.6], [0.0, 1.0])
    assert np.allclose(npole, [[0, 0, -1], [0, 0, 1]], atol=1e-12)
    # second derivatives: a great circle u = const has curvature 1/r
    d = s.derivatives(u[:100], 0.5, 2)
    assert np.allclose(np.linalg.norm(d[:, 0, 0] - c, axis=1), r, rtol=1e-12)


def test_cylinder_exact():
    rng = np.random.default_rng(2)
    r, h, c = 2.0, 5.0, np.array([0.0, 1.0, -1.0])
    s = cylinder(r, h, c)
    u, v = rng.random(5000), rng.random(5000)
    P = s.evaluate(u, v)
    rho = np.linalg.norm(P[:, :2] - c[:2], axis=1)
    assert np.abs(rho - r).max() < 1e-12 * r
    assert np.allclose(P[:, 2], c[2] + h * v, atol=1e-12)
    n = s.normal(u, v)
    radial = np.column_stack([(P[:, :2] - c[:2]) / r, np.zeros(len(u))])
    assert np.abs(n - radial).max() < 1e-12


# ------------------------------------------------------------- derivatives vs finite diffs
@pytest.mark.parametrize("rational", [True, False])
@pytest.mark.parametrize("degrees", [(3, 3), (2, 4), (1, 2), (5, 1)])
def test_surface_derivatives_vs_finite_differences(rational, degrees):
    rng = np.random.default_rng(100 * rational + 10 * degrees[0] + degrees[1])
    p, q = degrees
    s = random_surface(rng, p, q, nu=p + 4, nv=q + 3, rational=rational)
    u = interior_params(rng, s.knots_u, p, s.control.shape[0], 50)
    v = interior_params(rng, s.knots_v, q, s.control.shape[1], 50)
    h = 1e-6
    d = s.derivatives(u, v, 2)
    du = (s.derivatives(u + h, v, 1) - s.derivatives(u - h, v, 1)) / (2 * h)
    dv = (s.derivatives(u, v + h, 1) - s.derivatives(u, v - h, 1)) / (2 * h)
    scale = np.abs(d[:, 0, 0]).max()

    def close(a, b, tol):
        assert np.abs(a - b).max() <= tol * max(scale, np.abs(b).max())

    close(d[:, 1, 0], du[:, 0, 0], 1e-7)  # Su
    close(d[:, 0, 1], dv[:, 0, 0], 1e-7)  # Sv
    close(d[:, 2, 0], du[:, 1, 0], 1e-6)  # Suu
    close(d[:, 1, 1], du[:, 0, 1], 1e-6)  # Suv
    close(d[:, 1, 1], dv[:, 1, 0], 1e-6)  # Svu
    close(d[:, 0, 2], dv[:, 0, 1], 1e-6)  # Svv
    # orders are consistent and unused entries are NaN
    d1 = s.derivatives(u, v, 1)
    assert np.allclose(d1[:, :2, 0], d[:, :2, 0], rtol=0, atol=1e-12 * scale)
    assert np.isnan(d1[:, 1, 1]).all() and np.isnan(d[:, 2, 2]).all()
    assert np.allclose(s.evaluate(u, v), d[:, 0, 0], atol=1e-12 * scale)


@pytest.mark.parametrize("rational", [True, False])
@pytest.mark.parametrize("degree", [1, 2, 3, 5])
def test_curve_derivatives_vs_finite_differences(rational, degree):
    rng = np.random.default_rng(10 * degree + rational)
    n = degree + 6
    U = np.concatenate([[0.0] * (degree + 1), np.sort(rng.uniform(0, 3, n - degree - 1)),
                        [3.0] * (degree + 1)])
    c = NurbsCurve(degree, U, rng.normal(size=(n, 3)),
                   rng.uniform(0.3, 3, n) if rational else None)
    t = interior_params(rng, U, degree, n, 60)
    h = 1e-6
    order = degree + 1
    d = c.derivatives(t, order)
    fd = (c.derivatives(t + h, order - 1) - c.derivatives(t - h, order - 1)) / (2 * h)
    for k in range(1, order + 1 if rational else order):
        scale = max(1.0, np.abs(d[:, k]).max(), np.abs(d[:, k - 1]).max())
        assert np.abs(d[:, k] - fd[:, k - 1]).max() < 1e-5 * scale, k
    if not rational:  # zero up to the rounding of the unit-weight quotient
        assert np.abs(d[:, degree + 1]).max() < 1e-10 * np.abs(d[:, degree]).max()
    else:
        assert np.abs(d[:, degree + 1]).max() > 0  # rational: higher derivatives live on


# ------------------------------------------------------------------ paths agree with each other
@pytest.mark.slow  # over 4 s of CPU: out of `make test-fast` (issue 32)
@pytest.mark.parametrize("degrees", [(3, 3), (2, 1), (4, 2)])
def test_fast_path_matches_a23_packed_path(degrees):
    rng = np.random.default_rng(sum(degrees))
    surfs = [random_surface(rng, *degrees, nu=degrees[0] + 5, nv=degrees[1] + 4),
             random_surface(rng, 2, 3, nu=5, nv=6, rational=False), sphere(2.0, (1, 2, 3))]
    packed = pack_surfaces(surfs)
    assert len(packed) == 3 and packed.ctrl.shape[1] == 4
    for f, s in enumerate(surfs):
        (u0, u1), (v0, v1) = s.domain
        u = np.concatenate([rng.uniform(u0, u1, 300), s.knots_u[s.degree_u:-s.degree_u]])
        v = np.concatenate([rng.uniform(v0, v1, 300), s.knots_v[s.degree_v:-s.degree_v]])[:len(u)]
        u = u[:len(v)]
        fast = s.derivatives(u, v, 2)
        ref = evaluate_packed(packed, np.full(len(u), f), np.column_stack([u, v]), order=2)
        ok = ~np.isnan(ref)
        assert np.array_equal(ok, ~np.isnan(fast))
        scale = np.abs(ref[ok]).max()
        assert np.abs(fast[ok] - ref[ok]).max() < 1e-11 * scale



@pytest.mark.parametrize("order", [0, 1, 2])
def test_derivative_bits_do_not_depend_on_the_batch_size(order):
    """One kernel for every degree, order and batch: 25,000 points at once (which took a copy
    compiled for degree 3 before; it gave these same bits) equal the same points 1,000 at a
    time, to the last bit."""
    rng = np.random.default_rng(7)
    s = random_surface(rng, 3, 3, nu=12, nv=9)
    (u0, u1), (v0, v1) = s.domain
    u, v = rng.uniform(u0, u1, 25_000), rng.uniform(v0, v1, 25_000)
    whole = s.derivatives(u, v, order)
    parts = np.concatenate([s.derivatives(u[i:i + 1000], v[i:i + 1000], order)
                            for i in range(0, 25_000, 1000)])
    assert np.array_equal(whole, parts, equal_nan=True)


@njit(cache=True)
def _sum_points_from_njit(degrees, ko, kl, knots, co, shapes, ctrl, faces, u, v):
    """How other modules call the packed kernel from their own njit code."""
    out = np.empty((2, 2, 3))
    work = np.empty(K.surface_work_size(degrees[:, 0].max(), degrees[:, 1].max(), 1))
    res = np.empty((u.shape[0], 3))
    for i in range(u.shape[0]):
        K.surface_derivs_packed_ws(degrees, ko, kl, knots, co, shapes, ctrl, faces[i], u[i], v[i],
                                   1, out, work)
        res[i] = out[0, 0] + out[1, 0]
    K.surface_derivs_packed(degrees, ko, kl, knots, co, shapes, ctrl, faces[0], u[0], v[0],
                            1, out)
    res[0] = out[0, 0] + out[1, 0]
    return res


@pytest.mark.slow  # over 4 s of CPU: out of `make test-fast` (issue 32)
def test_packed_kernel_callable_from_njit():
    rng = np.random.default_rng(5)
    surfs = [cylinder(1.0, 2.0), random_surface(rng), sphere(3.0)]
    packed = pack_surfaces(surfs)
    faces = rng.integers(0, 3, 200)
    uv = np.column_stack([rng.random(200), rng.random(200)])
    for f, s in enumerate(surfs):  # map [0, 1]^2 into each face's domain
        (u0, u1), (v0, v1) = s.domain
        m = faces == f
        uv[m] = [u0, v0] + uv[m] * [u1 - u0, v1 - v0]
    res = _sum_points_from_njit(*packed.kernel_args, faces, uv[:, 0].copy(), uv[:, 1].copy())
    ref = evaluate_packed(packed, faces, uv, order=1)
    assert np.allclose(res, ref[:, 0, 0] + ref[:, 1, 0], rtol=1e-12, atol=1e-12)
    for f, s in enumerate(surfs):
        m = faces == f
        assert np.allclose(ref[m], s.derivatives(uv[m, 0], uv[m, 1], 1), atol=1e-11,
                           equal_nan=True)


# ----------------------------------------------------------------------------- OCP oracle
def _ocp_surface(p, q, Uk, Um, Vk, Vm, P, W):
    from OCP.collections import Array1_double, Array1_int, Array2_double, Array2_gp_Pnt
    from OCP.Geom import Geom_BSplineSurface
    from OCP.gp import gp_Pnt

    nu, nv = W.shape
    poles = Array2_gp_Pnt(1, nu, 1, nv)
    weights = Array2_double(1, nu, 1, nv)
    for i in range(nu):
        for j in range(nv):
            poles.SetValue(i + 1, j + 1, gp_Pnt(*map(float, P[i, j])))
            weights.SetValue(i + 1, j + 1, float(W[i, j]))

    def arr(vals, cls):
        a = cls(1, len(vals))
        for k, x in enumerate(vals):
            a.SetValue(k + 1, x.item())
        return a

    return Geom_BSplineSurface(poles, weights, arr(Uk, Array1_double), arr(Vk, Array1_double),
                               arr(Um, Array1_int), arr(Vm, Array1_int), p, q)


@pytest.mark.parametrize("degrees", [(3, 3), (3, 2), (5, 4), (1, 3)])
def test_agrees_with_ocp_geom_bspline_surface_d2(degrees):
    pytest.importorskip("OCP", reason="OCP (cadquery-ocp-novtk) not installed")
    from OCP.gp import gp_Pnt, gp_Vec

    rng = np.random.default_rng(100 + 10 * degrees[0] + degrees[1])
    p, q = degrees
    # distinct knots with multiplicities (ends p+1, one interior knot of multiplicity 2 if p >= 2)
    Uk = np.concatenate([[-1.0], np.sort(rng.uniform(-1, 4, 4)), [4.0]])
    Um = np.array([p + 1, 1, min(2, p), 1, 1, p + 1])
    Vk = np.concatenate([[0.5], np.sort(rng.uniform(0.5, 2, 3)), [2.0]])
    Vm = np.array([q + 1, 1, 1, min(2, q), q + 1])
    nu, nv = Um.sum() - p - 1, Vm.sum() - q - 1
    P = rng.normal(size=(nu, nv, 3)) * 20
    W = rng.uniform(0.2, 4.0, (nu, nv))
    occ = _ocp_surface(p, q, Uk, Um, Vk, Vm, P, W)
    ours = NurbsSurface(p, q, np.repeat(Uk, Um), np.repeat(Vk, Vm), P, W)

    u = np.concatenate([rng.uniform(-1, 4, 200), Uk])
    v = np.concatenate([rng.uniform(0.5, 2, 200), rng.uniform(0.5, 2, len(Uk))])
    d = ours.derivatives(u, v, 2)
    pt, vecs = gp_Pnt(), [gp_Vec() for _ in range(5)]
    for i in range(len(u)):
        occ.D2(float(u[i]), float(v[i]), pt, *vecs)
        ref = {(0, 0): (pt.X(), pt.Y(), pt.Z())}
        for key, vec in zip([(1, 0), (0, 1), (2, 0), (0, 2), (1, 1)], vecs):
            ref[key] = (vec.X(), vec.Y(), vec.Z())
        for (k, l), r in ref.items():
            r = np.array(r)
            err = np.linalg.norm(d[i, k, l] - r)
            assert err <= 1e-9 * max(np.linalg.norm(r), 1.0), (i, k, l, d[i, k, l], r)


# ------------------------------------------------------------------------------ bad input
def test_bad_input_raises():
    P = np.zeros((4, 3))
    U = np.array([0, 0, 0, 0, 1, 1, 1, 1.0])
    NurbsCurve(3, U, P)  # valid
    with pytest.raises(ValueError, match="n \\+ p \\+ 1 = 8"):
        NurbsCurve(3, U[:-1], P)
    with pytest.raises(ValueError, match="> 0"):
        NurbsCurve(3, U, P, np.array([1.0, -1.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="shape \\(4,\\)"):
        NurbsCurve(3, U, P, np.ones(5))
    with pytest.raises(ValueError, match="non-decreasing"):
        NurbsCurve(3, np.array([0, 0, 0, 0, 1, 0.5, 1, 1.0]), P)
    with pytest.raises(ValueError, match="degree"):
        NurbsCurve(0, U, P)
    with pytest.raises(ValueError, match="non-finite"):
        NurbsCurve(3, U, np.full((4, 3), np.nan))
    c = circle()
    with pytest.raises(ValueError, match="non-finite"):
        c.evaluate([0.5, np.nan])
    with pytest.raises(ValueError, match=r"domain \[0.0, 1.0\]"):
        c.evaluate(1.5)
    s = sphere(1.0)
    with pytest.raises(ValueError, match=r"v must lie in the domain \[0.0, 1.0\]"):
        s.evaluate(0.5, -0.1)
    with pytest.raises(ValueError, match="non-finite"):
        s.normal(np.nan, 0.5)
    with pytest.raises(ValueError, match="order"):
        s.derivatives(0.5, 0.5, 3)
    with pytest.raises(ValueError, match="broadcast"):
        s.evaluate([0.1, 0.2], [0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="knots_u has 11 knots"):
        NurbsSurface(2, 2, _first(s.knots_u, 11), s.knots_v, s.control, s.weights)
    with pytest.raises(ValueError, match="control must have shape"):
        NurbsSurface(2, 2, s.knots_u, s.knots_v, s.control[..., :2], s.weights)
    with pytest.raises(ValueError, match="weights must have shape"):
        NurbsSurface(2, 2, s.knots_u, s.knots_v, s.control, s.weights[:, :3])
    with pytest.raises(ValueError, match="> 0"):
        NurbsSurface(2, 2, s.knots_u, s.knots_v, s.control, -s.weights)
    packed = pack_surfaces([s])
    with pytest.raises(ValueError, match="face_ids must lie in"):
        evaluate_packed(packed, np.array([1]), np.array([[0.5, 0.5]]))
    with pytest.raises(ValueError, match="outside their face's domain"):
        evaluate_packed(packed, np.array([0]), np.array([[0.5, 1.5]]))
    with pytest.raises(ValueError, match="uv must have shape"):
        evaluate_packed(packed, np.array([0]), np.array([0.5, 0.5]))
    with pytest.raises(ValueError, match="empty list"):
        pack_surfaces([])
    with pytest.raises(ValueError, match="radius"):
        circle(-1.0)


def _first(a, n):
    return np.array(a[:n])


def test_frozen_readonly_and_repr():
    s = sphere(2.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.degree_u = 3
    with pytest.raises(ValueError):
        s.control[0, 0, 0] = 1.0  # read-only array
    r = repr(s)
    assert "degrees=(2, 2)" in r and "rational=True" in r and "[" not in r
    assert "n_control=9" in repr(circle())
    assert "PackedSurfaces(n_faces=1" in repr(pack_surfaces([s]))
    # parameters a few ulps past the end are clamped, not rejected
    assert np.isfinite(s.evaluate(np.nextafter(1.0, 2.0), 0.5)).all()
