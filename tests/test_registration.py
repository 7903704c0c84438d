"""Robust ICP registration (registration/): rigid steps, losses, IRLS-ICP against the truth of
the virtual scanner (the Cramér-Rao check of issue 4), bad input, degeneracy, real bunny scans."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import integrate, stats
from scipy.spatial.transform import Rotation

from shapeverify.cad.model import Face, Model
from shapeverify.cad.nurbs import NurbsSurface, cylinder
from shapeverify.errors import RegistrationError, ScanError
from shapeverify.registration import (
    DegenerateGeometryWarning, LOSSES, get_loss, principal_axes_alignment, register, robust_scale,
)
from shapeverify.registration.rigid import (
    compose_step, fisher_information, make_transform, point_to_plane_system, pose_covariance,
    pose_error, rodrigues, rotation_vector, solve_step, weighted_rigid_fit,
)
from shapeverify.simulate import BLOB, INLIER, OUTLIER, ScanEffects, random_motion, virtual_scan

from shapeverify.nearest import prepare

UNIT = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


# ------------------------------------------------------------------------------ fixtures
def _prepare(model, spacing=None):
    return prepare(model, spacing=spacing)


@pytest.fixture(scope="module")
def panel(example_step):
    from shapeverify.cad.load import load_model

    return load_model(example_step)


@pytest.fixture(scope="module")
def panel_prep(panel):
    return _prepare(panel, spacing=1.0)


def _issue_scan(model, seed):
    """The scan of issue 4 "How good": ~14 % outliers incl. a blob, a 0.4 mm dent, a shadow,
    depth noise 0.02 mm, start 6 deg and 12 mm off."""
    effects = ScanEffects(shadows=1, blobs=1, blob_radius=20.0, outlier_fraction=0.11,
                          dents=[(0.4, 12.0)])
    return virtual_scan(model, pixel=1.4, noise=0.02, effects=effects, motion=(6.0, 12.0),
                        rng=seed)


def _plain_face(ctrl, deg=(1, 1)):
    ku = [0] * (deg[0] + 1) + [1] * (deg[0] + 1)
    kv = [0] * (deg[1] + 1) + [1] * (deg[1] + 1)
    s = NurbsSurface(deg[0], deg[1], ku, kv, np.asarray(ctrl, float))
    return Face(s, (UNIT,), (np.ones(4, bool),))


# ------------------------------------------------------------------------------ losses
@pytest.mark.parametrize("name", sorted(LOSSES))
def test_weight_is_rho_prime_over_r(name):
    loss = get_loss(name)
    sigma = 0.7
    r = np.linspace(-8, 8, 321)
    r = r[np.abs(r) > 1e-3]
    h = 1e-6
    drho = (loss.rho(r + h, sigma) - loss.rho(r - h, sigma)) / (2 * h)
    np.testing.assert_allclose(loss.weight(r, sigma), drho / r, atol=1e-6)
    assert loss.weight(np.array([0.0]), sigma)[0] == pytest.approx(1.0)  # w(0) = rho''(0)
    assert np.all(loss.rho(r, sigma) >= 0) and loss.rho(np.array([0.0]), sigma)[0] == 0


@pytest.mark.parametrize("name", ["huber", "tukey", "cauchy", "welsch"])
def test_tuning_constants_give_95_percent_gaussian_efficiency(name):
    """Asymptotic efficiency (E psi')^2 / E psi^2 at the standard normal is 0.95."""
    loss = get_loss(name)
    psi = lambda r: loss.weight(np.array([r]), 1.0)[0] * r  # noqa: E731
    h = 1e-5
    dpsi = lambda r: (psi(r + h) - psi(r - h)) / (2 * h)  # noqa: E731
    pts = [-loss.c, loss.c]
    e_dpsi = integrate.quad(lambda r: dpsi(r) * stats.norm.pdf(r), -12, 12, points=pts)[0]
    e_psi2 = integrate.quad(lambda r: psi(r) ** 2 * stats.norm.pdf(r), -12, 12, points=pts)[0]
    assert e_dpsi ** 2 / e_psi2 == pytest.approx(0.95, abs=0.002)


def test_tukey_rejects_beyond_k_and_bad_names():
    t = get_loss("tukey")
    assert np.all(t.weight(np.array([4.686, -10.0]), 1.0) == 0)
    assert get_loss("biweight") is t
    with pytest.raises(ValueError, match="unknown loss"):
        get_loss("l3")


def test_robust_scale_of_gaussian_with_outliers():
    rng = np.random.default_rng(0)
    r = rng.normal(0, 0.02, 200_000)
    assert robust_scale(r) == pytest.approx(0.02, rel=0.01)
    r[:20_000] = rng.uniform(-5, 5, 20_000)  # 10 % gross errors inflate it only mildly
    assert 0.02 < robust_scale(r) < 0.0235
    assert robust_scale(np.zeros(10), floor=1e-9) == 1e-9


# ------------------------------------------------------------------------------ rigid steps
def test_rodrigues_and_rotation_vector_against_scipy():
    rng = np.random.default_rng(1)
    for w in [*rng.normal(size=(20, 3)), np.array([1e-9, 0, 0]), np.array([0, 0, np.pi - 1e-7]),
              np.array([0.0, 0.0, 0.0])]:
        R = rodrigues(w)
        np.testing.assert_allclose(R, Rotation.from_rotvec(w).as_matrix(), atol=1e-13)
        np.testing.assert_allclose(rotation_vector(R), Rotation.from_matrix(R).as_rotvec(),
                                   atol=1e-7)


def test_weighted_rigid_fit_matches_scipy_and_keeps_det_one():
    rng = np.random.default_rng(2)
    P = rng.normal(size=(50, 3)) * [30, 20, 5]
    R0 = Rotation.random(random_state=3).as_matrix()
    Y = P @ R0.T + [5, -2, 7] + rng.normal(0, 0.1, (50, 3))
    w = rng.uniform(0.1, 1.0, 50)
    R, t = weighted_rigid_fit(P, Y, w)
    mp, my = w @ P / w.sum(), w @ Y / w.sum()
    Rs, _ = Rotation.align_vectors(Y - my, P - mp, weights=w)
    np.testing.assert_allclose(R, Rs.as_matrix(), atol=1e-10)
    np.testing.assert_allclose(t, my - R @ mp, atol=1e-12)
    # exact data: exact answer
    R, t = weighted_rigid_fit(P, P @ R0.T + [1, 2, 3])
    np.testing.assert_allclose(R, R0, atol=1e-12)
    # a mirror image: the unconstrained SVD solution is a reflection; eq. 10 gives a rotation
    M = np.diag([1.0, 1.0, -1.0])
    R, _ = weighted_rigid_fit(P, P @ M)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    Rs, _ = Rotation.align_vectors(P @ M - (P @ M).mean(0), P - P.mean(0))
    np.testing.assert_allclose(R, Rs.as_matrix(), atol=1e-9)


def test_point_to_plane_steps_converge_on_a_box_corner():
    """Three planes: the linearised step (eq. 12-13) composed exactly converges to the truth."""
    rng = np.random.default_rng(4)
    pts, nrm = [], []
    for k in range(3):
        p = rng.uniform(0, 50, (200, 3))
        p[:, k] = 0.0
        n = np.zeros(3)
        n[k] = 1.0
        pts.append(p)
        nrm.append(np.tile(n, (200, 1)))
    Y, N = np.vstack(pts), np.vstack(nrm)
    Tt = random_motion(8.0, 5.0, center=(25, 25, 25), rng=5)   # model <- scan truth
    S = Y @ np.linalg.inv(Tt)[:3, :3].T + np.linalg.inv(Tt)[:3, 3]
    R, t = np.eye(3), np.zeros(3)
    for _ in range(12):
        X = S @ R.T + t
        # closest points on the (infinite) planes of each point's own face
        d = np.einsum("ij,ij->i", X, N)   # each point's own plane passes through the origin
        foot = X - d[:, None] * N
        H, g, r = point_to_plane_system(X, foot, N, np.ones(len(X)), X.mean(0))
        theta, undet = solve_step(H, g, 30.0)
        assert undet.shape == (0, 6)
        R, t = compose_step(R, t, theta, X.mean(0))
    np.testing.assert_allclose(R, Tt[:3, :3], atol=1e-12)
    np.testing.assert_allclose(t, Tt[:3, 3], atol=1e-10)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-14)


def test_covariance_is_sigma2_inverse_information_for_least_squares():
    rng = np.random.default_rng(6)
    X = rng.uniform(-50, 50, (20000, 3))
    N = rng.normal(size=(20000, 3))
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    r = rng.normal(0, 0.02, 20000)
    C = pose_covariance(X, N, r, np.ones(20000), np.array([10.0, 0, 0]), 30.0)
    J = np.hstack([np.cross(X, N), N])
    C0 = 0.02 ** 2 * np.linalg.inv(J.T @ J)
    np.testing.assert_allclose(np.sqrt(np.diag(C)), np.sqrt(np.diag(C0)), rtol=0.05)


# ------------------------------------------------------------------------------ IRLS-ICP
@pytest.mark.parametrize("seed", [0, 1])
def test_issue_scenario_reaches_the_cramer_rao_bound(panel, panel_prep, seed):
    """Issue 4 'How good': default settings, sqrt(e^T F e) <= 6, normal error <= 1 um RMS."""
    vs = _issue_scan(panel, seed)
    c = vs.counts()
    assert 0.12 < (c["outlier"] + c["blob"]) / len(vs) < 0.16 and c["dent"] > 100
    reg = register(vs.scan, panel_prep, rng=seed)
    acc = vs.accuracy(reg.T_model_scan)
    assert reg.converged, reg.message
    assert acc.crb <= 6.0, acc
    assert acc.normal_rms <= 1e-3, acc
    R = reg.R
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    # the result's bookkeeping
    n = len(vs)
    assert reg.weights.shape == (n,) and np.all((reg.weights >= 0) & (reg.weights <= 1))
    assert np.mean(reg.weights[vs.labels == BLOB] == 0) > 0.99
    assert np.mean(reg.weights[vs.labels == OUTLIER] == 0) > 0.9
    assert np.mean(reg.weights[vs.labels == INLIER] > 0) > 0.98
    assert 0.8 < reg.inlier_fraction < 0.9
    assert reg.scale == pytest.approx(0.02, rel=0.25) and reg.rms < 0.025
    assert reg.undetermined_directions.shape == (0, 6)
    assert [h.stage for h in reg.history][0] == "coarse"
    assert [h.stage for h in reg.history][-1] == "final"
    steps = [h for h in reg.history if h.step_translation > 0 or h.step_rotation > 0]
    assert len(steps) == reg.iterations and reg.history[-1].step_sigma == 0
    assert reg.history[-1].step_sigma == 0 and 0 < reg.history[-1].scale < 0.03
    # the covariance is the Cramér-Rao bound within a small factor: the noise is 0.02 mm along
    # the rays, less along the normals (ratio < 1), and the M-estimator loses a little (> 1)
    Finv = np.linalg.inv(vs.fisher())
    ratio = np.diag(reg.covariance) / np.diag(Finv)
    assert np.all((ratio > 0.5) & (ratio < 2.0)), ratio
    assert "Registration(" in repr(reg) and len(repr(reg)) < 400


@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rotvec=st.tuples(*[st.floats(-1, 1)] * 3), angle=st.floats(0.0, 10.0),
       trans=st.tuples(*[st.floats(-20, 20)] * 3), seed=st.integers(0, 2 ** 16))
def test_random_rigid_transforms_are_recovered(panel, panel_prep, rotvec, angle, trans, seed):
    """Rotation up to 10 deg about any axis, translation up to 10 % of the part's size."""
    axis = np.asarray(rotvec)
    if np.linalg.norm(axis) < 1e-3:
        axis = np.array([0.0, 0.0, 1.0])
    axis /= np.linalg.norm(axis)
    c = np.array([150.0, 100.0, 8.0])
    R = rodrigues(np.radians(angle) * axis)
    M = make_transform(R, c - R @ c + np.asarray(trans))  # model -> scan
    vs = virtual_scan(panel, pixel=4.0, noise=0.01,
                      effects=ScanEffects(outlier_fraction=0.05), motion=M, rng=seed)
    reg = register(vs.scan, panel_prep, rng=seed)
    acc = vs.accuracy(reg.T_model_scan)
    assert np.linalg.det(reg.R) == pytest.approx(1.0, abs=1e-12)
    assert reg.converged
    assert acc.crb < 6.0 and acc.normal_rms < 2e-3, acc


@pytest.mark.parametrize("fraction", [0.0, 0.1, 0.2, 0.3, 0.4])
def test_outlier_fractions(panel, panel_prep, fraction):
    vs = virtual_scan(panel, pixel=2.5, noise=0.02,
                      effects=ScanEffects(outlier_fraction=fraction), motion=(6.0, 12.0),
                      rng=11)
    reg = register(vs.scan, panel_prep, rng=0)
    acc = vs.accuracy(reg.T_model_scan)
    assert reg.converged and acc.crb < 6.0 and acc.normal_rms < 2e-3, acc
    assert reg.inlier_fraction == pytest.approx(1 - fraction, abs=0.03)


def test_partial_overlap_scan_covers_part_of_the_model(panel, panel_prep):
    vs = virtual_scan(panel, pixel=1.5, noise=0.02,
                      effects=ScanEffects(outlier_fraction=0.05), motion=(5.0, 10.0),
                      rng=12)
    keep = np.linalg.norm(vs.points[:, :2] - [90.0, 70.0], axis=1) < 70.0   # ~25 % of the panel
    assert 0.15 < keep.mean() < 0.35
    reg = register(vs.scan[keep], panel_prep, rng=0)
    e = pose_error(reg.T_model_scan, vs.T_model_scan)
    m = keep & vs.inliers
    F = fisher_information(vs.points[m], vs.normals[m], 0.02)
    assert reg.converged and np.sqrt(e @ F @ e) < 6.0


@pytest.mark.slow
def test_scan_running_past_the_cad_edge_gets_zero_weight(panel):
    """The model is the middle of the panel; scan points past its free edge must not pull."""
    f = panel.faces[0]
    (u0, u1), (v0, v1) = f.uv_bounds
    sub = np.array([[u0 + 0.2 * (u1 - u0), v0 + 0.2 * (v1 - v0)],
                    [u0 + 0.8 * (u1 - u0), v0 + 0.2 * (v1 - v0)],
                    [u0 + 0.8 * (u1 - u0), v0 + 0.8 * (v1 - v0)],
                    [u0 + 0.2 * (u1 - u0), v0 + 0.8 * (v1 - v0)]])
    small = Model(faces=(Face(f.surface, (sub,), (np.ones(4, bool),), f.reversed),),
                  source="middle of the panel")
    prep = _prepare(small, spacing=1.0)
    vs = virtual_scan(panel, pixel=2.0, noise=0.02, motion=(4.0, 8.0), rng=13)
    reg = register(vs.scan, prep, rng=0)
    inside = small.faces[0].contains(vs.uv)
    acc = vs.accuracy(reg.T_model_scan)
    assert reg.converged and acc.normal_rms < 2e-3, acc
    # far outside the small model (> 3 mm past its edge): no weight
    from scipy.spatial import cKDTree

    margin = cKDTree(small.sample(1.0).points).query(vs.points)[0] > 3.0
    assert margin.sum() > 1000
    assert np.all(reg.weights[~inside & margin] == 0)
    assert reg.inlier_fraction < 0.5


@pytest.fixture(scope="module")
def wavy():
    """A doubly curved 300 x 200 mm bicubic panel (waves 8 mm high): point-to-point ICP, which
    converges linearly at a rate set by the curvature, converges on it in ~100 iterations."""
    nu, nv = 9, 7
    X, Y = np.meshgrid(np.linspace(0, 300, nu), np.linspace(0, 200, nv), indexing="ij")
    Z = 8.0 * (np.sin(2 * np.pi * X / 300 * 1.3) * np.cos(2 * np.pi * Y / 200 * 0.9)
               + 0.3 * np.cos(2 * np.pi * (X + Y) / 250))
    ku = np.r_[[0] * 4, np.linspace(0, 1, nu - 2)[1:-1], [1] * 4]
    kv = np.r_[[0] * 4, np.linspace(0, 1, nv - 2)[1:-1], [1] * 4]
    s = NurbsSurface(3, 3, ku, kv, np.stack([X - 150, Y - 100, Z], axis=-1))
    model = Model(faces=(Face(s, (UNIT,), (np.ones(4, bool),)),), source="wavy panel")
    return model, _prepare(model, spacing=1.0)


@pytest.mark.parametrize("method", ["point-to-plane", "point-to-point", "point-then-plane"])
@pytest.mark.parametrize("loss", sorted(LOSSES))
def test_every_method_and_loss(wavy, method, loss):
    model, prep = wavy
    of = 0.0 if loss == "l2" else 0.08
    vs = virtual_scan(model, pixel=4.0, noise=0.02,
                      effects=ScanEffects(outlier_fraction=of), motion=(3.0, 5.0),
                      rng=14)
    reg = register(vs.scan, prep, method=method, loss=loss, rng=0, max_iterations=300)
    acc = vs.accuracy(reg.T_model_scan)
    assert reg.method == method and reg.loss == loss
    assert np.linalg.det(reg.R) == pytest.approx(1.0, abs=1e-12)
    assert reg.converged, reg.message
    assert acc.crb < 6.0 and acc.normal_rms < 2e-3, acc


def test_point_then_plane_strategy_of_section_522(wavy):
    """Thesis Section 5.2.2: point-to-point steps far from the solution, point-to-plane near it --
    as accurate as point-to-plane throughout, in a handful of final iterations."""
    model, prep = wavy
    vs = virtual_scan(model, pixel=4.0, noise=0.02,
                      effects=ScanEffects(outlier_fraction=0.05), motion=(6.0, 12.0),
                      rng=3)
    both = register(vs.scan, prep, method="point-then-plane", rng=0)
    plane = register(vs.scan, prep, method="point-to-plane", rng=0)
    assert both.converged and both.method == "point-then-plane"
    a, b = vs.accuracy(both.T_model_scan), vs.accuracy(plane.T_model_scan)
    assert a.normal_rms < 2e-3 and abs(a.normal_rms - b.normal_rms) < 5e-4
    with pytest.raises(ValueError, match="point-then-plane"):
        register(vs.scan, prep, method="point-to-curve")


def test_point_to_point_is_honest_where_it_crawls(panel, panel_prep):
    """On the nearly cylindrical example panel, point-to-point slides towards the optimum at a
    rate ~1 - 1e-4 per iteration: it must say so instead of claiming convergence."""
    vs = virtual_scan(panel, pixel=4.0, noise=0.02, motion=(3.0, 5.0), rng=14)
    for budget in (3, 30):
        reg = register(vs.scan, panel_prep, method="point-to-point", max_iterations=budget,
                       rng=0)
        acc = vs.accuracy(reg.T_model_scan)
        assert acc.crb < 6.0 or not reg.converged, (budget, acc, reg)
        if not reg.converged:
            assert f"max_iterations={budget}" in reg.message
    assert not register(vs.scan, panel_prep, method="point-to-point", max_iterations=3,
                        rng=0).converged


def test_fixed_scale_and_convergence_honesty(panel, panel_prep):
    vs = virtual_scan(panel, pixel=4.0, noise=0.02,
                      effects=ScanEffects(outlier_fraction=0.1), motion=(6.0, 12.0),
                      rng=15)
    reg = register(vs.scan, panel_prep, scale=0.02, rng=0)
    assert reg.scale == 0.02 and reg.converged
    assert vs.accuracy(reg.T_model_scan).crb < 6.0
    short = register(vs.scan, panel_prep, max_iterations=2, rng=0)
    assert not short.converged and "max_iterations=2" in short.message


# ------------------------------------------------------------------------------ bad input
def test_bad_input_gets_clear_errors(panel, panel_prep):
    good = virtual_scan(panel, pixel=8.0, noise=0.0, rng=16).scan
    with pytest.raises(ScanError, match=r"shape \(N, 3\)"):
        register(good[:, :2], panel_prep)
    with pytest.raises(ScanError, match="at least 6"):
        register(good[:5], panel_prep)
    bad = good.copy()
    bad[7, 1] = np.nan
    with pytest.raises(ScanError, match="NaN"):
        register(bad, panel_prep)
    with pytest.raises(ValueError):
        register(good[:, :2], panel_prep)  # ScanError is a ValueError
    with pytest.raises(RegistrationError, match="reach"):   # no global search asked
        register(good + [0.0, 0.0, 1e5], panel_prep, init="identity")
    with pytest.raises(ValueError, match="method"):
        register(good, panel_prep, method="point-to-line")
    with pytest.raises(ValueError, match="loss"):
        register(good, panel_prep, loss="bogus")
    with pytest.raises(ValueError, match="rigid"):
        register(good, panel_prep, init=np.diag([1.0, 1.0, -1.0, 1.0]))
    with pytest.raises(ValueError, match="init"):
        register(good, panel_prep, init=np.eye(3))
    with pytest.raises(ValueError, match="scale"):
        register(good, panel_prep, scale=-1.0)
    with pytest.raises(ValueError, match="max_iterations"):
        register(good, panel_prep, max_iterations=0)
    with pytest.raises(ValueError, match="prep"):
        register(good, object())


# ------------------------------------------------------------------------------ degeneracy
def test_flat_scan_reports_three_undetermined_directions():
    plate = Model(faces=(_plain_face([[[-100, -50, 0], [-100, 50, 0]],
                                      [[100, -50, 0], [100, 50, 0]]]),), source="plate")
    prep = _prepare(plate, spacing=1.0)
    vs = virtual_scan(plate, view=(0.1, 0.2, 1.0), pixel=3.0, noise=0.02,
                      motion=make_transform(rodrigues([0.01, -0.02, 0.005]), [1.0, 2.0, 3.0]),
                      rng=17)
    with pytest.warns(DegenerateGeometryWarning, match="3 pose direction"):
        reg = register(vs.scan, prep, rng=0)
    assert reg.converged, reg.message
    assert reg.undetermined_directions.shape == (3, 6)
    # what is determined is right: the plate's plane (tilt and height)
    X = vs.scan @ reg.R.T + reg.t
    assert np.sqrt(np.mean(X[vs.inliers][:, 2] ** 2)) < 0.03
    # undetermined: x/y sliding and rotation about z (no tilt, no z translation)
    np.testing.assert_allclose(reg.undetermined_directions[:, [0, 1, 5]], 0.0, atol=1e-6)
    assert "undetermined" in reg.message
    assert np.max(np.diag(reg.covariance)) > 1e6


def test_cylindrical_scan_reports_two_undetermined_directions():
    # the trimming loop as a polyline (its circles are long curved segments otherwise); the
    # seam u = 0 / u = 1 is not a free edge, the two end circles are
    s = np.linspace(0, 1, 64, endpoint=False)
    loop = np.concatenate([np.c_[s, 0 * s], np.c_[1 + 0 * s, s], np.c_[1 - s, 1 + 0 * s],
                           np.c_[0 * s, 1 - s]])
    free = np.repeat([True, False, True, False], 64)
    cyl = Model(faces=(Face(cylinder(40.0, 200.0), (loop,), (free,)),), source="cylinder")
    prep = _prepare(cyl, spacing=1.0)
    vs = virtual_scan(cyl, view=(1.0, 0.3, 0.0), pixel=2.0, noise=0.02,
                      motion=make_transform(rodrigues([0.0, 0.0, 0.02]), [0.5, -0.5, 2.0]),
                      rng=18)
    with pytest.warns(DegenerateGeometryWarning, match="2 pose direction"):
        reg = register(vs.scan, prep, rng=0)
    assert reg.converged, reg.message
    assert reg.undetermined_directions.shape == (2, 6)
    # spanned by the rotation about the axis (z through the origin) and sliding along it
    np.testing.assert_allclose(reg.undetermined_directions[:, [0, 1, 3, 4]], 0.0, atol=1e-4)
    assert "undetermined" in reg.message
    X = vs.scan[vs.inliers] @ reg.R.T + reg.t
    assert np.std(np.hypot(X[:, 0], X[:, 1]) - 40.0) < 0.03


# ------------------------------------------------------------------------------ init
@pytest.mark.slow
def test_principal_axes_alignment_from_any_orientation(panel, panel_prep):
    vs = virtual_scan(panel, pixel=4.0, noise=0.02,
                      effects=ScanEffects(outlier_fraction=0.05), motion=(150.0, 200.0),
                      rng=19)
    ia = principal_axes_alignment(vs.scan, panel_prep, rng=0)
    coarse = vs.accuracy(ia.T_model_scan)
    assert coarse.rotation_deg < 5.0 and coarse.translation < 20.0, coarse
    reg = register(vs.scan, panel_prep, init="principal-axes", rng=0)
    acc = vs.accuracy(reg.T_model_scan)
    assert reg.converged and acc.crb < 6.0, acc


# ------------------------------------------------------------------------------ real data
def _bun_pose(conf, name):
    for line in conf.read_text().splitlines():
        f = line.split()
        if len(f) == 9 and f[0] == "bmesh" and f[1] == name:
            t = np.array(f[2:5], float)
            R = Rotation.from_quat(np.array(f[5:9], float)).as_matrix()
            # row vectors: common = X @ R + t, i.e. common = R^T x + t
            return make_transform(R.T, t)
    raise KeyError(name)


@pytest.mark.slow
def test_bunny_045_to_000(shared_data):
    """Real partial-overlap scans: bun045 onto bun000 (point-cloud reference), from the
    bun.conf pose perturbed by 5 deg and 5 mm, matches bun.conf within 0.3 deg and 0.5 mm."""
    import dataclasses

    from shapeverify.cad.load import load_model
    from shapeverify.io.points import read_points

    d = shared_data / "scans" / "bunny"
    ref = load_model(d / "bun000.ply")
    ref = dataclasses.replace(ref, vertices=ref.vertices * 1000.0)  # metres -> mm
    scan = read_points(d / "bun045.ply") * 1000.0
    T0 = _bun_pose(d / "bun.conf", "bun000.ply")
    T45 = _bun_pose(d / "bun.conf", "bun045.ply")
    T0[:3, 3] *= 1000.0
    T45[:3, 3] *= 1000.0
    T_true = np.linalg.inv(T0) @ T45            # bun000 frame <- bun045 frame
    c = scan.mean(axis=0)
    P = random_motion(5.0, 5.0, center=T_true[:3, :3] @ c + T_true[:3, 3], rng=20)
    prep = _prepare(ref, spacing=1.0)   # the scans' own spacing is 0.5-1 mm
    reg = register(scan, prep, init=P @ T_true, rng=0)
    assert reg.converged, reg.message
    dT = reg.T_model_scan @ np.linalg.inv(T_true)
    ang = np.degrees(np.linalg.norm(rotation_vector(dT[:3, :3])))
    cm = T_true[:3, :3] @ c + T_true[:3, 3]
    trans = np.linalg.norm(dT[:3, :3] @ cm + dT[:3, 3] - cm)
    assert ang < 0.3 and trans < 0.5, (ang, trans, reg)


@pytest.mark.parametrize("name", sorted(LOSSES))
def test_fused_weights_equal_the_loss_formulas(name):
    """The one-pass numba weighting of the built-in losses equals losses.py's numpy formulas."""
    from shapeverify.registration import _irls
    from shapeverify.registration.losses import Loss

    rng = np.random.default_rng(3)
    d = rng.standard_t(3, size=4000) * 0.1
    valid = rng.random(4000) > 0.1
    d[~valid] = 0.0
    Z = np.zeros((4000, 3))
    args = (Z, Z, Z, d, valid, np.zeros(4000, np.int64), np.zeros(4000, bool))
    fused = _irls.weigh(_irls.Match(*args), LOSSES[name], None, 1e-6)
    own = LOSSES[name]
    own_loss = Loss(own.name, own.c, own.redescending, own._rho, own._w)
    plain = _irls.weigh(_irls.Match(*args), own_loss, None, 1e-6)
    assert fused.sigma == plain.sigma
    np.testing.assert_allclose(fused.w, plain.w, rtol=0, atol=1e-15)
    assert abs(fused.objective - plain.objective) <= 1e-14 * abs(plain.objective)
    assert abs(fused.rms - plain.rms) <= 1e-14
    assert np.array_equal(fused.inliers, plain.inliers)
