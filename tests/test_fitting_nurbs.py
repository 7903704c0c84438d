"""NURBS curve and surface fitting: exact recovery, ODR vs fixed parameters, ODR == VarPro,
rational circle, orthogonality, the eliminated step == the dense Gauss-Newton step, export."""

from __future__ import annotations

import json

import numpy as np
import pytest

from shapeverify import fitting
from shapeverify.cad.nurbs import NurbsCurve, NurbsSurface
from shapeverify.fitting import FitSolver, _odr, curves, surfaces


def _known_curve():
    U = np.r_[0, 0, 0, 0, 0.2, 0.45, 0.7, 1, 1, 1, 1]
    P = np.column_stack([np.arange(7) * 2.0, [0, 1.5, -1, 0.5, 2, -0.5, 0], [0, 0.3, 0.8, 0.2, -0.4, 0, 0.5]])
    return NurbsCurve(3, U, P)


def _known_surface():
    U = np.r_[0, 0, 0, 0, 0.5, 1, 1, 1, 1]
    V = np.r_[0, 0, 0, 0.5, 1, 1, 1]
    u, v = np.meshgrid(np.linspace(0, 1, 5), np.linspace(0, 1, 4), indexing="ij")
    P = np.stack([u * 10, v * 8, 2 * np.sin(3 * u) * np.cos(2 * v)], axis=-1)
    return NurbsSurface(3, 2, U, V, P)


# ----------------------------------------------------------------------------- exact recovery
@pytest.mark.parametrize("method", ["odr", "varpro"])
def test_curve_exact_recovery(method):
    c = _known_curve()
    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(0, 1, 300))
    fit = fitting.fit_curve(c.evaluate(t), degree=3, n_ctrl=7, knots=c.knots, method=method)
    assert fit.converged
    assert fit.max_error < 1e-10
    np.testing.assert_allclose(fit.curve.control, c.control, atol=1e-9)
    np.testing.assert_allclose(fit.params, t, atol=1e-9)


@pytest.mark.slow  # over 4 s of CPU: out of `make test-fast` (issue 32)
def test_surface_exact_recovery_grid():
    s = _known_surface()
    ug, vg = np.meshgrid(np.linspace(0, 1, 25), np.linspace(0, 1, 20), indexing="ij")
    grid = s.evaluate(ug.ravel(), vg.ravel()).reshape(25, 20, 3)
    fixed = fitting.fit_surface(grid, degrees=(3, 2), n_ctrl=(5, 4), knots=(s.knots_u, s.knots_v),
                                method="fixed")
    assert fixed.max_error > 1e-3           # chord-length parameters are not the true ones ...
    fit = fitting.fit_surface(grid, degrees=(3, 2), n_ctrl=(5, 4), knots=(s.knots_u, s.knots_v),
                              method="odr")
    assert fit.converged and fit.max_error < 1e-10      # ... the orthogonal fit passes through all
    # (the net itself is not unique: the surface may extend beyond the grid's border)


@pytest.mark.slow  # 3.8 s of CPU with numba's cache warm (quick tests: under ~3 s)
def test_surface_scattered_noise_level():
    s = _known_surface()
    rng = np.random.default_rng(1)
    uv = rng.uniform(0, 1, (800, 2))
    x = s.evaluate(uv[:, 0], uv[:, 1])
    sigma = 0.01
    xn = x + sigma * s.normal(uv[:, 0], uv[:, 1]) * rng.normal(size=(800, 1))
    fixed = fitting.fit_surface(xn, degrees=(3, 2), n_ctrl=(5, 4), method="fixed")
    odr = fitting.fit_surface(xn, degrees=(3, 2), n_ctrl=(5, 4), method="odr",
                              solver=FitSolver(max_iterations=40))
    assert odr.rms < fixed.rms
    assert odr.rms < 1.05 * sigma                   # at the noise level (n = 20 of 800 dof)
    # the signed residuals are the added normal noise (up to the orientation of the fitted surface)
    noise = np.einsum("ij,ij->i", xn - x, s.normal(uv[:, 0], uv[:, 1]))
    assert abs(np.corrcoef(odr.residuals, noise)[0, 1]) > 0.95


# -------------------------------------------------------------------- ODR vs fixed, ODR == VarPro
def _noisy_curve(n=400, sigma=0.01, seed=2):
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0, 1, n))
    x = np.column_stack([np.cos(4 * t) * (1 + t), np.sin(4 * t) * (1 + t), 0.3 * t])
    return x + rng.normal(scale=sigma, size=x.shape)


def test_odr_beats_fixed_and_varpro_agrees():
    x = _noisy_curve()
    fixed = fitting.fit_curve(x, n_ctrl=10, method="fixed")
    odr = fitting.fit_curve(x, n_ctrl=10, method="odr",
                            solver=FitSolver(rtol=1e-13, max_iterations=300))
    vp = fitting.fit_curve(x, n_ctrl=10, method="varpro",
                           solver=FitSolver(rtol=1e-13, max_iterations=300))
    assert odr.converged and vp.converged
    assert odr.rms < 0.97 * fixed.rms
    # same objective, same optimum
    assert abs(odr.history[-1] - vp.history[-1]) < 1e-9 * odr.history[-1]
    np.testing.assert_allclose(odr.curve.control, vp.curve.control, atol=1e-5)
    assert abs(odr.rms - vp.rms) < 1e-9
    # the reported rms is the orthogonal one: brute force over a dense sampling of the curve
    dense = odr.curve.evaluate(np.linspace(0, 1, 200001))
    brute = np.array([np.min(np.linalg.norm(dense - p, axis=1)) for p in x[::20]])
    np.testing.assert_allclose(odr.residuals[::20], brute, atol=1e-6)


@pytest.mark.parametrize("second_order", [True, False])
def test_orthogonal_residuals_at_convergence(second_order):
    x = _noisy_curve(300, 0.02, seed=3)
    fit = fitting.fit_curve(x, n_ctrl=8, method="odr",
                            solver=FitSolver(second_order=second_order, rtol=1e-14,
                                             max_iterations=400))
    assert fit.converged
    d = fit.curve.derivatives(fit.params, 1)
    r = x - d[:, 0]
    inner = (fit.params > 1e-9) & (fit.params < 1 - 1e-9)
    cosang = np.abs(np.einsum("ij,ij->i", r, d[:, 1])) / (np.linalg.norm(r, axis=1)
                                                          * np.linalg.norm(d[:, 1], axis=1))
    assert inner.sum() > 280
    assert np.max(cosang[inner]) < 1e-6


def test_rational_circle_fit():
    rng = np.random.default_rng(4)
    th = np.sort(rng.uniform(0, 2 * np.pi / 3, 150))         # a 120 degree arc
    c, R = np.array([1.0, -1.0]), 2.0
    x = c + R * np.column_stack([np.cos(th), np.sin(th)])
    poly = fitting.fit_curve(x, degree=2, n_ctrl=3, method="odr")
    for method in ("odr", "varpro"):
        fit = fitting.fit_curve(x, degree=2, n_ctrl=3, rational=True, method=method)
        assert fit.curve.rational and fit.converged
        pts = fit.curve.evaluate(np.linspace(0, 1, 101))
        np.testing.assert_allclose(np.linalg.norm(pts - c, axis=1), R, atol=1e-10)
        assert fit.max_error < 1e-10 < poly.max_error
        # conic shape factor of a circular arc: w1 / sqrt(w0 w2) = cos(half the arc's angle)
        ends = fit.curve.evaluate([0.0, 1.0]) - c
        half = 0.5 * np.arccos(ends[0] @ ends[1] / R ** 2)
        w = fit.curve.weights
        assert abs(w[1] / np.sqrt(w[0] * w[2]) - np.cos(half)) < 1e-8


# ------------------------------------------------ the eliminated step equals the dense GN step
def _dense_jacobian(prob, ev):
    Jl = ev.Jl
    N, d, _ = Jl.shape
    q = ev.T.shape[2]
    J = np.zeros((N * d, prob.M + N * q))
    idx = prob.idx_cell[ev.cell]
    for i in range(N):
        for e in range(d):
            J[i * d + e, idx[i]] += Jl[i, e]
            J[i * d + e, prob.M + i * q:prob.M + (i + 1) * q] = ev.T[i, e]
    return J


def _step_case(kind, rational, rng):
    if kind == "curve":
        t = np.sort(rng.uniform(0, 1, 40))
        x = np.column_stack([np.cos(3 * t), np.sin(3 * t), t ** 2]) + rng.normal(scale=0.01, size=(40, 3))
        U = curves.approximation_knots(t, 6, 3)
        prob = curves._CurveProblem(x, 3, U, 6, rational, 0.0)
        P = fitting.fit_curve(x, n_ctrl=6, knots=U, params=t, method="fixed").curve.control
        params = t
    else:
        s = _known_surface()
        uv = rng.uniform(0.02, 0.98, (120, 2))
        x = s.evaluate(uv[:, 0], uv[:, 1]) + rng.normal(scale=0.01, size=(120, 3))
        prob = surfaces._SurfaceProblem(x, 3, 2, s.knots_u, s.knots_v, 5, 4, rational, 0.0)
        P = s.control.reshape(-1, 3)
        params = uv
    theta = P.ravel() + rng.normal(scale=0.01, size=P.size)
    if rational:
        theta = np.concatenate([theta, rng.uniform(0.9, 1.1, prob.n)])
    return prob, theta, params


@pytest.mark.parametrize("kind", ["curve", "surface"])
@pytest.mark.parametrize("rational", [False, True])
@pytest.mark.parametrize("lam", [1e-4, 1e-2])
def test_reduced_step_equals_dense_gauss_newton(kind, rational, lam):
    rng = np.random.default_rng(5)
    prob, theta, params = _step_case(kind, rational, rng)
    ev = _odr.evaluate(prob, theta, params, second=False)
    step = _odr.reduced_step(prob, theta, ev, lam)
    if step is None:
        pytest.fail("reduced Gauss-Newton matrix reported indefinite")
    dtheta, dt, _ = step
    J = _dense_jacobian(prob, ev)
    keep = np.ones(J.shape[1], bool)
    keep[prob.fixed] = False
    Jk = J[:, keep]
    A = Jk.T @ Jk
    A += lam * np.diag(np.diag(A))                       # Marquardt damping, as in the solver
    dense = np.zeros(J.shape[1])
    dense[keep] = np.linalg.solve(A, -Jk.T @ ev.r.ravel())
    scale = np.abs(dense).max()
    np.testing.assert_allclose(dtheta, dense[:prob.M], rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(dt.ravel(), dense[prob.M:], rtol=0, atol=1e-10 * scale)


# ------------------------------------------------------------------- helpers, smoothing, errors
def test_knot_helpers():
    t = np.sort(np.random.default_rng(6).uniform(0, 1, 200))
    t[0], t[-1] = 0.0, 1.0
    U = fitting.approximation_knots(t, 12, 3)
    assert U.shape == (16,) and np.all(np.diff(U) >= 0)
    assert np.all(U[:4] == 0) and np.all(U[-4:] == 1)
    counts = np.histogram(t, bins=U[3:-3])[0]
    assert counts.min() >= 10                       # every span holds data (eqs. 9.68-9.69)
    np.testing.assert_allclose(fitting.uniform_knots(5, 2), [0, 0, 0, 1 / 3, 2 / 3, 1, 1, 1])
    p = fitting.chord_length_params([[0, 0], [3, 4], [3, 5]])
    np.testing.assert_allclose(p, [0, 5 / 6, 1])
    pc = fitting.chord_length_params([[0, 0], [3, 4], [3, 5]], centripetal=True)
    np.testing.assert_allclose(pc, [0, np.sqrt(5) / (np.sqrt(5) + 1), 1])


def test_smoothing_reduces_roughness():
    x = _noisy_curve(300, 0.03, seed=7)
    rough = fitting.fit_curve(x, n_ctrl=30, method="fixed")
    smooth = fitting.fit_curve(x, n_ctrl=30, method="fixed", smoothing=1.0)

    def roughness(c):
        return np.sum(np.diff(c.control, 2, axis=0) ** 2)
    assert roughness(smooth.curve) < 0.5 * roughness(rough.curve)
    # smoothing makes an under-determined net solvable
    few, U, t = x[:40], fitting.uniform_knots(40, 3), np.linspace(0, 1, 40) ** 3
    with pytest.raises(ValueError, match="control point"):
        fitting.fit_curve(few, n_ctrl=40, method="fixed", knots=U, params=t)
    fit = fitting.fit_curve(few, n_ctrl=40, method="fixed", knots=U, params=t, smoothing=1e-3)
    assert fit.rms < 0.03


@pytest.mark.parametrize("kwargs, match", [
    (dict(points=np.zeros((3, 3)), degree=3), "at least 4 points"),
    (dict(points=np.full((20, 3), np.nan)), "NaN"),
    (dict(points=np.zeros((20, 4))), r"shape \(N, 2\) or \(N, 3\)"),
    (dict(points=np.random.default_rng(0).normal(size=(20, 3)), n_ctrl=25), "exceeds the number"),
    (dict(points=np.random.default_rng(0).normal(size=(20, 3)), n_ctrl=3, degree=3), "n_ctrl must"),
    (dict(points=np.random.default_rng(0).normal(size=(20, 3)), method="lsq"), "unknown method"),
    (dict(points=np.random.default_rng(0).normal(size=(20, 3)), n_ctrl=5, knots=[0, 1]), "knots"),
])
def test_curve_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        fitting.fit_curve(**kwargs)


@pytest.mark.parametrize("kwargs, match", [
    (dict(points=np.zeros((10, 2))), r"\(N, 3\) or \(ku, kv, 3\)"),
    (dict(points=np.zeros((30, 3)), n_ctrl=(8, 8)), "cannot determine"),
    (dict(points=np.full((100, 3), np.inf)), "NaN or inf"),
    (dict(points=np.random.default_rng(0).normal(size=(100, 3)), n_ctrl=(3, 5), degrees=3), "exceed"),
])
def test_surface_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        fitting.fit_surface(**kwargs)


def test_surface_empty_region_needs_smoothing():
    rng = np.random.default_rng(8)
    xy = rng.uniform(-1, 1, (3000, 2))
    xy = xy[np.linalg.norm(xy, axis=1) < 1]                  # a disc: the corners hold no data
    x = np.column_stack([xy, 0.1 * xy[:, 0] ** 2])
    with pytest.raises(ValueError, match="smoothing"):
        fitting.fit_surface(x, n_ctrl=(12, 12), method="fixed")
    fit = fitting.fit_surface(x, n_ctrl=(12, 12), method="fixed", smoothing=1e-3)
    assert fit.rms < 1e-3


# --------------------------------------------------------------------------------- export
def _occ_read(path):
    from OCP.BRep import BRep_Tool
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.IGESControl import IGESControl_Reader
    from OCP.STEPControl import STEPControl_Reader
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    reader = STEPControl_Reader() if path.suffix == ".step" else IGESControl_Reader()
    assert reader.ReadFile(str(path)) == IFSelect_RetDone
    reader.TransferRoots()
    shape = reader.OneShape()
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    if exp.More():
        return "surface", BRep_Tool.Surface_s(TopoDS.Face(exp.Current()))
    exp = TopExp_Explorer(shape, TopAbs_EDGE)
    assert exp.More()
    edge = TopoDS.Edge(exp.Current())
    curve, t0, t1 = BRep_Tool.Curve_s(edge, 0.0, 0.0), *BRep_Tool.Range_s(edge)
    return "curve", curve


@pytest.mark.parametrize("suffix", [".step", ".igs"])
def test_export_round_trip(tmp_path, suffix):
    from shapeverify.cad.occ_write import write_nurbs

    s = _known_surface()
    w = np.linspace(0.7, 1.4, 20).reshape(5, 4)
    rs = NurbsSurface(s.degree_u, s.degree_v, s.knots_u, s.knots_v, s.control, w)
    c = _known_curve()
    rc = NurbsCurve(c.degree, c.knots, c.control, np.linspace(0.8, 1.3, 7))
    u = np.array([0.0, 0.13, 0.5, 0.77, 1.0])
    v = np.array([0.0, 0.61, 0.25, 0.9, 1.0])
    for shape in (s, rs, c, rc):
        path = tmp_path / f"shape{suffix}"
        write_nurbs(shape, path)
        kind, geom = _occ_read(path)
        if isinstance(shape, NurbsSurface):
            assert kind == "surface"
            ours = shape.evaluate(u, v)
            theirs = np.array([[geom.Value(a, b).X(), geom.Value(a, b).Y(), geom.Value(a, b).Z()]
                               for a, b in zip(u, v)])
        else:
            assert kind == "curve"
            ours = shape.evaluate(u)
            theirs = np.array([[geom.Value(a).X(), geom.Value(a).Y(), geom.Value(a).Z()] for a in u])
        np.testing.assert_allclose(theirs, ours, atol=1e-9)


def test_fit_points_file_json_and_step(tmp_path):
    s = _known_surface()
    rng = np.random.default_rng(9)
    uv = rng.uniform(0, 1, (600, 2))
    pts = s.evaluate(uv[:, 0], uv[:, 1]) + rng.normal(scale=0.005, size=(600, 3))
    src = tmp_path / "region.xyz"
    np.savetxt(src, pts)
    out = tmp_path / "region.json"
    summary = fitting.fit_points_file(src, out, surface=True, ctrl=(5, 4), degree=2, method="fixed")
    assert summary["kind"] == "surface" and summary["points"] == 600 and summary["ctrl"] == [5, 4]
    data = json.loads(out.read_text())
    surf = fitting.nurbs_from_dict(data["nurbs"])
    assert surf.control.shape == (5, 4, 3) and data["fit"]["rms"] == summary["rms"]
    uvf, d = fitting.project_to_surface(surf, pts, fitting.surface_params(pts))
    assert np.sqrt(np.mean(d ** 2)) == pytest.approx(summary["rms"], rel=1e-6)
    step = tmp_path / "region.step"
    fitting.fit_points_file(src, step, surface=True, ctrl=5, degree=2, method="fixed")
    kind, geom = _occ_read(step)
    assert kind == "surface" and geom.NbUPoles() == 5 and geom.NbVPoles() == 5
    curve_src = tmp_path / "curve.xyz"
    np.savetxt(curve_src, _noisy_curve(200, 0.001))
    res = fitting.fit_points_file(curve_src, tmp_path / "curve.igs", ctrl=8)
    assert res["kind"] == "curve" and res["ctrl"] == 8 and res["rms"] < 0.01
    with pytest.raises(ValueError, match="use one of"):
        fitting.fit_points_file(curve_src, tmp_path / "curve.stl")


def test_knots_on_another_domain():
    c = _known_curve()
    t = np.sort(np.random.default_rng(10).uniform(0, 1, 200))
    x = c.evaluate(t)
    a = fitting.fit_curve(x, n_ctrl=7, knots=c.knots, method="fixed")
    b = fitting.fit_curve(x, n_ctrl=7, knots=10.0 * c.knots - 3.0, method="fixed")
    assert b.curve.domain == (-3.0, 7.0)
    np.testing.assert_allclose(b.curve.control, a.curve.control, atol=1e-12)
    np.testing.assert_allclose(b.params, 10.0 * a.params - 3.0, atol=1e-7)


# ------------------------------------------------------------------------- the sliding prior
def _spiral_truth_distance(curve):
    tt = np.linspace(0, 1, 400001)
    from scipy.spatial import cKDTree
    kd = cKDTree(np.column_stack([np.cos(4 * tt) * (1 + tt), np.sin(4 * tt) * (1 + tt), 0.3 * tt]))
    return float(np.sqrt(np.mean(kd.query(curve.evaluate(np.linspace(0, 1, 20001)))[0] ** 2)))


@pytest.mark.slow  # over 4 s of CPU: out of `make test-fast` (issue 32)
def test_slide_prior_converges_fast_and_stays_on_the_true_shape():
    """Plain ODR on noisy data creeps: control points slide together and the curve folds to
    follow the noise (lower RMS, farther from the truth).  The default prior converges in a few
    iterations and is at least as close to the true curve as the fixed-parameter fit."""
    x = _noisy_curve(n=3000, sigma=0.01, seed=5)
    fixed = fitting.fit_curve(x, n_ctrl=30, method="fixed")
    fit = fitting.fit_curve(x, n_ctrl=30)
    plain = fitting.fit_curve(x, n_ctrl=30,
                              solver=FitSolver(slide_stiffness=0.0, max_iterations=150))
    assert fit.converged and fit.iterations <= 15
    assert fit.rms <= fixed.rms
    e_fixed, e_fit, e_plain = (_spiral_truth_distance(f.curve) for f in (fixed, fit, plain))
    assert e_fit <= 1.05 * e_fixed                 # 0.00144 vs 0.00146
    assert plain.rms < fit.rms and e_plain > 20 * e_fit   # plain: 0.18
    # without the prior control points bunch up (relative smallest gap of the control polygon)
    gaps = lambda c: np.linalg.norm(np.diff(c.control, axis=0), axis=1)  # noqa: E731
    rel = [gaps(f.curve).min() / np.median(gaps(f.curve)) for f in (fixed, fit, plain)]
    assert rel[2] < rel[0] <= rel[1]


def test_slide_prior_is_part_of_the_objective():
    """odr and varpro reach the same optimum of distances + prior; the prior's gradient balances
    the data's (a perturbation of the control points raises the objective)."""
    x = _noisy_curve(n=800, sigma=0.02, seed=6)
    odr = fitting.fit_curve(x, n_ctrl=12, solver=FitSolver(rtol=1e-14, max_iterations=200))
    vp = fitting.fit_curve(x, n_ctrl=12, method="varpro",
                           solver=FitSolver(rtol=1e-14, max_iterations=200))
    assert odr.converged and vp.converged
    assert abs(odr.history[-1] - vp.history[-1]) < 1e-8 * odr.history[-1]
    np.testing.assert_allclose(odr.curve.control, vp.curve.control, atol=1e-6)


def test_slide_stiffness_validated():
    with pytest.raises(ValueError, match="slide_stiffness"):
        fitting.fit_curve(_noisy_curve(100), n_ctrl=6, solver=FitSolver(slide_stiffness=-1.0))
    with pytest.raises(ValueError, match="slide_stiffness"):
        fitting.fit_surface(np.random.default_rng(0).uniform(size=(200, 3)), n_ctrl=(4, 4),
                            solver=FitSolver(slide_stiffness=float("nan")))
