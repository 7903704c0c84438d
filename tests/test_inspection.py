"""Inspection: deviations, tolerances, statistics, defect regions, verdict, inspect().

The first part runs on an analytic stand-in of a prepared model (a rectangle in z = 0 whose exact
closest points are known in closed form), so that the inspection logic is tested on exact
answers without the closest-point machinery.  The second part runs the real pipeline
(``shapeverify.nearest``, ``shapeverify.registration``, ``shapeverify.simulate``) on exact NURBS
geometry and simulated scans (issue 5, "How good").
"""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from shapeverify.cad.examples import wavy_panel
from shapeverify.errors import ScanError
from shapeverify.inspection import (
    EVALUATED, ON_BOUNDARY, TOO_FAR, InspectionResult, Tolerance, check_scan, decide, deviations,
    find_regions, inspect, inspect_registered, per_face_statistics, statistics,
)
from shapeverify.inspection.regions import RegionSearch


# ----------------------------------------------------------------------------- stand-ins
class PlanePrep:
    """Prepared-model stand-in: the rectangle [0, L] x [0, W] in z = 0, outward normal +z,
    split into face 0 (x < L/2) and face 1; all four edges are free (outer boundary)."""

    def __init__(self, L=100.0, W=60.0):
        self.L, self.W = L, W
        self.model = SimpleNamespace(size=float(np.hypot(L, W)))
        x, y = np.meshgrid(np.arange(0.5, L, 1.0), np.arange(0.5, W, 1.0))   # model points, 1 mm
        pts = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
        self.points = SimpleNamespace(points=pts, face=(pts[:, 0] > L / 2).astype(np.int32),
                                      spacing=1.0)
        self.spacing = 1.0
        self.n_points = len(pts)
        self.calls = []

    def closest(self, q, exact=False):
        self.calls.append(exact)
        foot = q.copy()
        foot[:, 0] = np.clip(q[:, 0], 0, self.L)
        foot[:, 1] = np.clip(q[:, 1], 0, self.W)
        foot[:, 2] = 0.0
        d = np.linalg.norm(q - foot, axis=1) * np.where(q[:, 2] >= 0, 1.0, -1.0)
        on_b = (foot[:, 0] != q[:, 0]) | (foot[:, 1] != q[:, 1])
        return SimpleNamespace(points=foot, normals=np.tile([0.0, 0.0, 1.0], (len(q), 1)),
                               distances=d, face=(foot[:, 0] > self.L / 2).astype(np.int32),
                               uv=foot[:, :2], index=np.zeros(len(q), np.int64), on_boundary=on_b)


def fake_registration(n, converged=True, inlier_fraction=0.98, weights=None, T=None):
    return SimpleNamespace(T_model_scan=np.eye(4) if T is None else T, rms=0.02, iterations=9,
                           converged=converged, inlier_fraction=inlier_fraction, message="",
                           weights=np.ones(n) if weights is None else weights)


def dented_grid(rng, spacing=0.5, depth=0.4, center=(30.0, 20.0), sigma=3.0, noise=0.02,
                n_out=60):
    """Jittered grid on the stand-in plane with a Gaussian dent, noise and isolated spikes."""
    x, y = np.meshgrid(np.arange(1, 99, spacing), np.arange(1, 59, spacing))
    x = x.ravel() + rng.uniform(-0.1, 0.1, x.size)
    y = y.ravel() + rng.uniform(-0.1, 0.1, y.size)
    r2 = (x - center[0]) ** 2 + (y - center[1]) ** 2
    z = -depth * np.exp(-r2 / (2 * sigma ** 2)) + rng.normal(0, noise, x.size)
    far_from_dent = np.flatnonzero(r2 > (4 * sigma) ** 2)
    spikes = rng.choice(far_from_dent, n_out, replace=False)
    z[spikes] += rng.choice([-1, 1], n_out) * rng.uniform(0.3, 0.9, n_out)
    return np.column_stack([x, y, z]), spikes


# ----------------------------------------------------------------------------- tolerance
def test_tolerance_symmetric_asymmetric_and_per_face():
    t = Tolerance.from_args(0.2)
    assert (t.lower, t.upper, t.is_symmetric) == (-0.2, 0.2, True)
    t = Tolerance.from_args(0.2, upper=0.3)
    assert (t.lower, t.upper, t.is_symmetric) == (-0.2, 0.3, False)
    t = Tolerance.from_args(None, lower=-0.1, upper=0.3, per_face={2: 0.05, 5: (-0.5, 0.0)})
    lo, hi = t.limits(np.array([0, 2, 5, 7]))
    np.testing.assert_array_equal(lo, [-0.1, -0.05, -0.5, -0.1])
    np.testing.assert_array_equal(hi, [0.3, 0.05, 0.0, 0.3])
    v = np.array([0.31, 0.04, -0.49, np.nan])
    np.testing.assert_array_equal(t.within(v, np.array([0, 2, 5, 0])), [False, True, True, False])
    d = t.to_dict()
    assert d["per_face"] == {"2": [-0.05, 0.05], "5": [-0.5, 0.0]} and "tolerance" not in d


@pytest.mark.parametrize("kwargs, match", [
    (dict(tolerance=None), "give a tolerance"),
    (dict(tolerance=-0.2), "must be > 0"),
    (dict(tolerance=None, lower=0.1, upper=0.3), "did you mean -0.1"),
    (dict(tolerance=None, lower=-0.1, upper=-0.05), "upper limit must be >= 0"),
    (dict(tolerance=float("nan")), "NaN"),
    (dict(tolerance="abc"), "must be a number"),
    (dict(tolerance=0.2, per_face={-1: 0.1}), "face indices"),
])
def test_tolerance_rejects_bad_limits(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Tolerance.from_args(**kwargs)


# ----------------------------------------------------------------------------- statistics
def test_statistics_match_numpy_overall_and_per_face():
    rng = np.random.default_rng(0)
    v = rng.normal(0.01, 0.05, 5000)
    face = rng.integers(0, 4, 5000)
    tol = Tolerance(-0.08, 0.1)
    within = tol.within(v, face)
    s = statistics(v, within, v > 0)
    assert s.n == 5000
    np.testing.assert_allclose([s.mean, s.std, s.rms, s.min, s.max],
                               [v.mean(), v.std(), np.sqrt(np.mean(v ** 2)), v.min(), v.max()])
    np.testing.assert_allclose([s.p05, s.p95], np.percentile(v, [5, 95]))
    assert s.in_tolerance_fraction == pytest.approx(np.mean((v >= -0.08) & (v <= 0.1)))
    assert (s.n_above, s.n_below) == (int(np.sum(v > 0.1)), int(np.sum(v < -0.08)))
    pf = per_face_statistics(v, face, within, v > 0)
    assert sorted(pf) == [0, 1, 2, 3]
    for f, st in pf.items():
        m = face == f
        assert st.n == m.sum()
        np.testing.assert_allclose([st.mean, st.max, st.p95],
                                   [v[m].mean(), v[m].max(), np.percentile(v[m], 95)])
    empty = statistics(np.zeros(0))
    assert empty.n == 0 and np.isnan(empty.mean) and empty.to_dict()["mean"] is None


# ----------------------------------------------------------------------------- deviations
def test_deviations_values_reasons_and_transform():
    prep = PlanePrep()
    pts = np.array([[10.0, 10.0, 0.15],     # evaluated, +0.15
                     [70.0, 30.0, -0.3],    # evaluated on face 1, -0.3
                     [50.0, 30.0, 2.5],     # too far (evaluation distance 1)
                     [-0.5, 30.0, 0.0],     # foot on the outer boundary
                     [10.0, 10.0, 0.0]])
    # the scan frame is the model frame shifted by (1, 2, 3) and turned 90 degrees about z
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, [1.0, 2.0, 3.0]
    scan = (pts - T[:3, 3]) @ R          # inverse transform: scan = R^T (model - t)
    dev = deviations(scan, prep, T, evaluation_distance=1.0)
    assert prep.calls == [True]                         # exact closest points
    np.testing.assert_allclose(dev.points_model, pts, atol=1e-12)
    np.testing.assert_allclose(dev.values[[0, 1, 4]], [0.15, -0.3, 0.0], atol=1e-12)
    assert np.isnan(dev.values[[2, 3]]).all()
    np.testing.assert_array_equal(dev.reason, [EVALUATED, EVALUATED, TOO_FAR, ON_BOUNDARY,
                                               EVALUATED])
    assert dev.counts() == {"evaluated": 3, "too_far": 1, "on_boundary": 1, "outside_faces": 0}
    assert dev.face.tolist()[:2] == [0, 1]
    assert "evaluated=3" in repr(dev) and len(repr(dev)) < 200
    with pytest.raises(ValueError):
        dev.values[0] = 1.0                             # results are read-only


@pytest.mark.parametrize("scan, T, md, match", [
    (np.zeros((4, 2)), None, None, r"\(N, 3\)"),
    (np.array([[0, 0, np.nan]]), None, None, "NaN"),
    (np.zeros((4, 3)), np.eye(3), None, "4x4"),
    (np.zeros((4, 3)), None, 0.0, "evaluation_distance"),
])
def test_deviations_rejects_bad_input(scan, T, md, match):
    with pytest.raises(ValueError, match=match):
        deviations(scan, PlanePrep(), T, evaluation_distance=md)


# ----------------------------------------------------------------------------- regions
def _inspect_plane(scan, **kw):
    reg_kw = {k: kw.pop(k) for k in ("weights", "converged", "inlier_fraction") if k in kw}
    return inspect_registered(PlanePrep(), scan, fake_registration(len(scan), **reg_kw), **kw)


def test_dent_is_one_region_with_its_depth_and_place_spikes_are_outliers():
    rng = np.random.default_rng(5)
    center = (62.0, 27.0)
    scan, spikes = dented_grid(rng, depth=0.4, center=center, sigma=3.0, noise=0.02)
    w = np.ones(len(scan))
    w[spikes] = 0.0
    res = _inspect_plane(scan, tolerance=0.2, weights=w)
    assert res.verdict == "fail"
    assert len(res.regions) == 1
    g = res.regions[0]
    assert abs(g.extreme - (-0.4)) < 0.03
    assert np.hypot(*(g.centroid[:2] - center)) < 2.0
    assert g.side == "below" and g.faces == (1,)
    # area where a Gaussian dent of depth 0.4 is deeper than 0.2: pi * 2 sigma^2 ln 2
    assert g.area == pytest.approx(np.pi * 2 * 9.0 * np.log(2.0), rel=0.15)
    assert res.outliers.n == len(spikes) and res.outliers.n_low_weight == len(spikes)
    assert set(res.outliers.indices.tolist()) == set(spikes.tolist())


def test_same_scan_without_dent_passes_and_reports_outliers():
    rng = np.random.default_rng(5)
    scan, spikes = dented_grid(rng, depth=0.0, noise=0.02)
    res = _inspect_plane(scan, tolerance=0.2)
    assert res.verdict == "pass" and res.regions == ()
    assert res.outliers.n == len(spikes)
    assert "measurement outliers" in res.reasons[0]


def test_small_clusters_are_outliers_and_opposite_sides_are_not_merged():
    x, y = np.meshgrid(np.arange(0, 20, 0.5), np.arange(0, 20, 0.5))
    pts = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    v = np.zeros(x.size)
    i = lambda px, py: int(np.flatnonzero((pts[:, 0] == px) & (pts[:, 1] == py))[0])  # noqa: E731
    three = [i(2, 2), i(2.5, 2), i(3, 2)]                                # 3 < min_points
    steps = (0, 0.5, 1.0, 1.5)
    block_hi = [i(10 + a, 10 + b) for a in steps for b in steps]    # 4 x 4 points above
    block_lo = [i(12 + a, 10 + b) for a in steps for b in steps]    # 4 x 4 adjacent, below
    v[three] = 0.5
    v[block_hi] = 0.5
    v[block_lo] = -0.5
    within = np.abs(v) <= 0.2
    regions, outliers, spacing = find_regions(
        pts, v, np.ones(x.size, bool), within, np.zeros(x.size, np.int32),
        np.tile([0, 0, 1.0], (x.size, 1)), weights=None, search=RegionSearch(min_points=5))
    # the spacing is the area per point (surface_spacing), a few % off on a 20 mm patch's edges
    assert spacing == pytest.approx(0.5, rel=0.05)
    assert sorted(outliers.indices.tolist()) == sorted(three)
    assert len(regions) == 2
    assert {r.side for r in regions} == {"above", "below"}
    assert sorted(sorted(r.indices.tolist()) for r in regions) == sorted(
        [sorted(block_hi), sorted(block_lo)])
    for r in regions:
        assert r.extreme_raw == pytest.approx(0.5 if r.side == "above" else -0.5)


# ----------------------------------------------------------------------------- verdict
def test_failed_registration_is_error_never_pass():
    rng = np.random.default_rng(1)
    scan, _ = dented_grid(rng, depth=0.0, n_out=0)
    assert _inspect_plane(scan, tolerance=0.2).verdict == "pass"
    r = _inspect_plane(scan, tolerance=0.2, converged=False)
    assert r.verdict == "error" and "did not converge" in r.reasons[0]
    r = _inspect_plane(scan, tolerance=0.2, inlier_fraction=0.2)
    assert r.verdict == "error" and "inlier fraction 20.0 %" in r.reasons[0]
    assert r.rule == "registration"


def test_scan_mostly_away_from_the_model_is_incomplete_and_wholly_away_is_error():
    rng = np.random.default_rng(2)
    scan, _ = dented_grid(rng, depth=0.0, n_out=0)
    scan[scan[:, 0] < 90, 2] += 5.0                 # 90 % of the part 5 mm off: not seen
    r = _inspect_plane(scan, tolerance=0.2)
    assert r.verdict == "incomplete" and r.rule == "coverage"
    assert 0.05 < r.coverage.fraction < 0.15 and "of the inspected CAD area" in r.reasons[0]
    scan[:, 2] += 5.0
    r = _inspect_plane(scan, tolerance=0.2)
    assert r.verdict == "error" and "no scan point lies within 1 mm" in r.reasons[0]


def test_decide_rules_directly():
    dev = SimpleNamespace(n=100, n_evaluated=100, n_too_far=0, n_on_boundary=0, evaluation_distance=1.0)
    ok = SimpleNamespace(converged=True, inlier_fraction=0.9, iterations=5, message="")
    region = SimpleNamespace(n=12, area=3.0, extreme=-0.31, centroid=np.array([1.0, 2, 3]),
                             faces=(4,), kind="deviation",
                             describe=lambda: "material missing: 12 points, 3.0 mm², extreme "
                                              "-0.310 mm at (1.0, 2.0, 3.0) mm on face(s) 4")
    verdict, reasons, rule = decide(ok, dev, [])
    assert (verdict, rule) == ("pass", "within_tolerance") and reasons[0].startswith("pass:")
    verdict, reasons, rule = decide(ok, dev, [region])
    assert (verdict, rule) == ("fail", "regions")
    assert "extreme -0.310 mm at (1.0, 2.0, 3.0)" in reasons[1]
    bad = SimpleNamespace(converged=False, inlier_fraction=0.9, iterations=100, message="hit max")
    assert decide(bad, dev, [region])[:3:2] == ("error", "registration")
    # a part that was not seen is never passed and never failed, even with a region in view
    unseen = SimpleNamespace(sufficient=False, fraction=0.03, covered_area=30.0, area=1000.0,
                             min_coverage=0.2, describe_gap=lambda: "the largest unseen area ...")
    verdict, reasons, rule = decide(ok, dev, [region], unseen)
    assert (verdict, rule) == ("incomplete", "coverage") and "only 3.0 %" in reasons[0]
    assert any("region 1" in r for r in reasons)


# ----------------------------------------------------------------------------- input checks
def test_scan_in_metres_against_model_in_mm_names_the_factor():
    rng = np.random.default_rng(3)
    scan, _ = dented_grid(rng, depth=0.0, n_out=0)
    with pytest.raises(ScanError, match=r"metres: multiply its coordinates by 1000"):
        check_scan(scan / 1000.0, model_size=PlanePrep().model.size)
    with pytest.raises(ScanError, match="micrometres"):
        check_scan(scan * 1000.0, model_size=PlanePrep().model.size)
    with pytest.raises(ScanError, match="metres"):
        _inspect_plane(scan / 1000.0, tolerance=0.2)
    np.testing.assert_array_equal(check_scan(scan, PlanePrep().model.size), scan)


@pytest.mark.parametrize("scan, match", [
    (np.zeros((0, 3)), "empty"),
    (np.zeros((5, 3)) + np.arange(5)[:, None], "only 5 points"),
    (np.array([[1.0, 2, 3]] * 10), "same point"),
    (np.vstack([np.eye(3)] * 3 + [[np.nan, 0, 0]]), "NaN"),
    (np.zeros((10, 2)), r"\(N, 3\)"),
])
def test_bad_scans_get_clear_messages(scan, match):
    with pytest.raises(ScanError, match=match):
        check_scan(scan, model_size=100.0)


# ----------------------------------------------------------------------------- result
def test_result_to_dict_is_json_with_the_documented_keys():
    rng = np.random.default_rng(4)
    scan, _ = dented_grid(rng)
    res = _inspect_plane(scan, tolerance=0.2)
    assert isinstance(res, InspectionResult)
    d = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    for key in ("verdict", "decision", "reasons", "inputs", "coverage", "T_model_scan",
                "registration", "deviation", "tolerance", "timings", "regions", "excluded",
                "evaluation_distance", "units"):
        assert key in d
    assert d["decision"]["rule"] == "regions" and d["regions"][0]["kind"] == "deviation"
    assert sum(d["excluded"].values()) == d["n_points"] - d["deviation"]["n"]
    assert d["units"] == "mm" and d["verdict"] == "fail"
    assert np.asarray(d["T_model_scan"]).shape == (4, 4)
    assert set(d["registration"]) >= {"rms", "iterations", "converged", "inlier_fraction"}
    assert set(d["deviation"]) >= {"n", "mean", "std", "min", "max", "p05", "p95",
                                   "in_tolerance_fraction"}
    assert d["deviation"]["n"] == len(scan) - d["outliers"]["n"]       # the evaluated inliers
    assert set(d["regions"][0]) >= {"n", "area", "extreme", "centroid", "faces", "severity"}
    assert d["tolerance"]["tolerance"] == 0.2
    assert "verdict='fail'" in repr(res) and len(repr(res)) < 300


def test_model_without_surface_points_is_rejected():
    from shapeverify.errors import EmptyModelError

    prep = PlanePrep()
    prep.points = SimpleNamespace(points=np.zeros((0, 3)))
    prep.n_points = 0
    with pytest.raises(EmptyModelError, match="no surface points"):
        inspect_registered(prep, np.eye(3).repeat(3, axis=0) + np.arange(9)[:, None],
                           fake_registration(9))


# ============================================================================ real pipeline
# Exact NURBS geometry, the real closest-point search (nearest/), registration and the
# virtual scanner (simulate/).  The panel: shapeverify.cad.examples.wavy_panel.
@pytest.fixture(scope="module")
def panel_prep():
    from shapeverify.nearest import prepare

    return prepare(wavy_panel(), spacing=1.0)


def test_noise_free_deviations_equal_the_exact_offsets(panel_prep):
    """Points offset from the exact surface along its exact normals by known amounts."""
    model = panel_prep.model
    rng = np.random.default_rng(21)
    n = 3000
    uv = rng.uniform(0.03, 0.97, (n, 2))
    face = (uv[:, 0] > 0.5).astype(int)
    truth = rng.uniform(-0.9, 0.9, n)
    base = model.faces[0].evaluate(uv)
    nrm = model.faces[0].normal(uv)
    assert np.all(nrm[:, 2] > 0)                      # outward = +z side of the panel
    pts = base + truth[:, None] * nrm
    dev = deviations(pts, panel_prep, np.eye(4), evaluation_distance=1.0)
    assert dev.evaluated.all()
    np.testing.assert_allclose(dev.values, truth, atol=1e-6)
    np.testing.assert_array_equal(dev.face, face)
    np.testing.assert_allclose(dev.foot_points, base, atol=1e-6)
    # the same points seen through a rigid transform
    from shapeverify.registration.rigid import invert_transform
    from shapeverify.simulate import random_motion

    T = random_motion(20.0, 15.0, rng=3)
    scan = pts @ invert_transform(T)[:3, :3].T + invert_transform(T)[:3, 3]
    dev2 = deviations(scan, panel_prep, T, evaluation_distance=1.0)
    np.testing.assert_allclose(dev2.values, truth, atol=1e-6)


def test_points_past_the_outer_edge_are_not_evaluated_but_the_shared_edge_is(panel_prep):
    model = panel_prep.model
    f = model.faces[0]
    # beyond the outer edge v = 0: continue the surface outwards in its own tangent direction
    uv = np.array([[0.25, 0.0], [0.75, 0.0]])
    d = f.surface.derivatives(uv[:, 0], uv[:, 1], 1)
    sv = d[:, 0, 1] / np.linalg.norm(d[:, 0, 1], axis=1)[:, None]
    outside = f.evaluate(uv) - 0.5 * sv
    # on the shared edge u = 0.5 and near it, 0.1 mm above the surface
    uv_in = np.array([[0.5, 0.5], [0.499, 0.3], [0.501, 0.7]])
    inside = f.evaluate(uv_in) + 0.1 * f.normal(uv_in)
    dev = deviations(np.vstack([outside, inside]), panel_prep, None, evaluation_distance=1.0)
    np.testing.assert_array_equal(dev.reason, [ON_BOUNDARY, ON_BOUNDARY, EVALUATED, EVALUATED,
                                               EVALUATED])
    np.testing.assert_allclose(dev.values[2:], 0.1, atol=1e-6)


def _dent_centre(vs):
    from shapeverify.simulate import DENT

    P = vs.points[vs.labels == DENT]
    return P[np.argmin(np.linalg.norm(P - P.mean(axis=0), axis=1))]


@pytest.fixture(scope="module")
def simulated(panel_prep):
    from shapeverify.simulate import ScanEffects, virtual_scan

    common = dict(pixel=0.6, noise=0.02, motion=(3.0, 2.0))
    dented = virtual_scan(panel_prep, rng=2011, **common,
                          effects=ScanEffects(outlier_fraction=0.01, blobs=1, dents=[(0.4, 10.0)]))
    clean = virtual_scan(panel_prep, rng=2011, **common,
                         effects=ScanEffects(outlier_fraction=0.01, blobs=1))
    return dented, clean


def test_simulated_dent_is_found_as_one_region(panel_prep, simulated):
    vs, _ = simulated
    res = inspect(panel_prep, vs.scan, tolerance=0.2, evaluation_distance=1.0)
    assert res.registration.converged
    assert res.verdict == "fail", res.reasons
    assert len(res.regions) == 1, res.regions
    g = res.regions[0]
    assert abs(g.extreme - (-0.4)) < 0.03, g
    assert np.linalg.norm(g.centroid - _dent_centre(vs)) < 2.0, (g.centroid, _dent_centre(vs))
    assert res.outliers.n > 0


def test_same_part_without_dent_passes(panel_prep, simulated):
    _, vs = simulated
    res = inspect(panel_prep, vs.scan, tolerance=0.2, evaluation_distance=1.0)
    assert res.verdict == "pass", res.reasons
    assert res.regions == () and res.outliers.n > 0
    s = res.statistics
    assert abs(s.mean) < 0.01 and -0.05 < s.p05 < 0 < s.p95 < 0.05     # noise 0.02 mm


def test_inspect_rejects_metres_far_and_empty_scans(panel_prep, simulated):
    vs, _ = simulated
    with pytest.raises(ScanError, match="multiply its coordinates by 1000"):
        inspect(panel_prep, vs.scan / 1000.0, tolerance=0.2)
    with pytest.raises(ScanError, match="nowhere near the model"):     # an explicit start
        inspect(panel_prep, vs.scan + [0.0, 0.0, 500.0], tolerance=0.2, init=np.eye(4))
    with pytest.raises(ScanError, match="empty"):
        inspect(panel_prep, np.zeros((0, 3)), tolerance=0.2)
