"""GD&T characteristics (issue 28 items 2-3): minimum zones, datum reference frames, evaluators,
the characteristic registry.

Every zone is checked against an independent brute-force computation of its definition to
1e-6 mm: enumeration of the candidate centres that the minimum-zone conditions allow (circles),
a dense scan of the free angle refined by a bounded scalar minimiser (planes whose normal turns
about one axis), or SLSQP on the exact (not linearised) distances (cylinders).
"""
from __future__ import annotations

import dataclasses
import itertools

import numpy as np

from shapeverify.characteristics.zone_noise import corrected_value
import pytest
from scipy.optimize import minimize, minimize_scalar

from shapeverify.characteristics import registry
from shapeverify.characteristics.drf import DatumFeature, fit_drf, rigid_exp
from shapeverify.characteristics.gdt_zones import (circles_zone, cylinders_zone, planes_zone,
                                                   width_planes)
from shapeverify.characteristics.plan import PlanError, parse_plan

TOL = 1e-6


# ------------------------------------------------------------------------------ brute force
def _brute_one_turn(width_of, lo=-0.05, hi=0.05):
    """Minimum of width_of(angle) over [lo, hi]: a dense scan, then a bounded minimiser in the
    best cell."""
    ts = np.linspace(lo, hi, 40001)
    w = np.array([width_of(t) for t in ts])
    i = int(np.argmin(w))
    a, b = ts[max(i - 1, 0)], ts[min(i + 1, len(ts) - 1)]
    r = minimize_scalar(width_of, bounds=(a, b), method="bounded", options={"xatol": 1e-13})
    return min(float(r.fun), float(w[i]))


def _circumcentre(a, b, c):
    A = np.array([b - a, c - a])
    return np.linalg.solve(A, 0.5 * np.array([b @ b - a @ a, c @ c - a @ a]))


def _candidate_centres(Q):
    """Every centre the minimum-zone / inscribed / circumscribed conditions allow: circumcentres
    of point triples, midpoints of pairs, intersections of two perpendicular bisectors."""
    n = len(Q)
    out = []
    for i, j, k in itertools.combinations(range(n), 3):
        try:
            out.append(_circumcentre(Q[i], Q[j], Q[k]))
        except np.linalg.LinAlgError:
            pass
    for i, j in itertools.combinations(range(n), 2):
        out.append(0.5 * (Q[i] + Q[j]))
    pairs = list(itertools.combinations(range(n), 2))
    for (i, j), (k, l) in itertools.combinations(pairs, 2):
        A = np.array([Q[j] - Q[i], Q[l] - Q[k]])
        b = 0.5 * np.array([Q[j] @ Q[j] - Q[i] @ Q[i], Q[l] @ Q[l] - Q[k] @ Q[k]])
        try:
            out.append(np.linalg.solve(A, b))
        except np.linalg.LinAlgError:
            pass
    return np.array(out)


def _ring(rng, n, r=5.0, noise=0.03, centre=(0.3, -0.2)):
    t = np.sort(rng.uniform(0, 2 * np.pi, n))
    R = r + noise * rng.standard_normal(n)
    return np.column_stack([R * np.cos(t) + centre[0], R * np.sin(t) + centre[1]])


# ------------------------------------------------------------------------------ zones
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_circularity_minimum_zone_equals_enumeration_of_candidate_centres(seed):
    Q = _ring(np.random.default_rng(seed), 11)
    value, c, _ = circles_zone(Q, [0.0, 0.0])
    C = _candidate_centres(Q)
    r = np.linalg.norm(Q[None, :, :] - C[:, None, :], axis=2)
    brute = float((r.max(axis=1) - r.min(axis=1)).min())
    assert value == pytest.approx(brute, abs=TOL)


@pytest.mark.parametrize("seed", [4, 5])
def test_inscribed_and_circumscribed_circles_equal_enumeration(seed):
    Q = _ring(np.random.default_rng(seed), 16, noise=0.05)
    C = _candidate_centres(Q)
    r = np.linalg.norm(Q[None, :, :] - C[:, None, :], axis=2)
    inside = np.linalg.norm(C - Q.mean(0), axis=1) < 1.5     # centres well inside the ring
    rin, _, _ = circles_zone(Q, [0.0, 0.0], "inscribed")
    rout, _, _ = circles_zone(Q, [0.0, 0.0], "circumscribed")
    assert rin == pytest.approx(float(r.min(axis=1)[inside].max()), abs=TOL)
    assert rout == pytest.approx(float(r.max(axis=1).min()), abs=TOL)


@pytest.mark.parametrize("seed", [6, 7])
def test_planes_zone_turning_about_one_axis_equals_a_scan_of_the_angle(seed):
    """Perpendicularity to a datum plane z: the zone's normal (1, 0, 0) may turn about z."""
    rng = np.random.default_rng(seed)
    P = np.column_stack([0.004 * rng.uniform(0, 40, 80), rng.uniform(0, 40, 80),
                         rng.uniform(0, 30, 80)])
    P[:, 0] += 0.02 * rng.standard_normal(80)
    w, n, _ = planes_zone(P, [1.0, 0.0, 0.0], turn=[[0.0, 1.0, 0.0]])
    brute = _brute_one_turn(lambda t: np.ptp(P @ np.array([np.cos(t), np.sin(t), 0.0])))
    assert w == pytest.approx(brute, abs=TOL)
    assert abs(n[2]) < 1e-12                     # it turned about z only
    # no turn (parallelism): the range along the fixed normal
    w0, _, _ = planes_zone(P, [1.0, 0.0, 0.0])
    assert w0 == pytest.approx(np.ptp(P[:, 0]), abs=1e-12)


def test_planes_zone_free_normal_equals_the_minimum_width_over_candidate_directions():
    rng = np.random.default_rng(8)
    P = np.column_stack([rng.uniform(0, 30, 9), rng.uniform(0, 20, 9),
                         0.05 * rng.standard_normal(9)])
    w, _, _ = planes_zone(P, [0, 0, 1], turn=[[1, 0, 0], [0, 1, 0]])
    dirs = [np.cross(P[j] - P[i], P[k] - P[i]) for i, j, k in itertools.combinations(range(9), 3)]
    D = [np.cross(P[j] - P[i], P[l] - P[k]) for (i, j), (k, l)
         in itertools.combinations(list(itertools.combinations(range(9), 2)), 2)]
    widths = [np.ptp(P @ (d / np.linalg.norm(d))) for d in dirs + D if np.linalg.norm(d) > 1e-9]
    assert w == pytest.approx(min(widths), abs=TOL)


def test_width_mating_planes_of_a_tab_equal_a_scan_of_the_angle():
    rng = np.random.default_rng(9)
    P1 = np.column_stack([10 + 0.03 * rng.standard_normal(40), rng.uniform(0, 30, 40),
                          rng.uniform(0, 5, 40)])
    P2 = np.column_stack([0.002 * P1[:, 1] + 0.03 * rng.standard_normal(40),
                          rng.uniform(0, 30, 40), rng.uniform(0, 5, 40)])
    size, n, (h1, h2), mid = width_planes(P1, P2, [1, 0, 0], turn=[[0, 1, 0]])

    def sep(t):
        v = np.array([np.cos(t), np.sin(t), 0.0])
        return (P1 @ v).max() + (-(P2 @ v)).max()

    assert size == pytest.approx(_brute_one_turn(sep), abs=TOL)
    assert mid == pytest.approx(0.5 * (h1 - h2))


def _cyl_points(rng, n=150, r=4.0, noise=0.01):
    h = rng.uniform(-10, 10, n)
    th = rng.uniform(0, 2 * np.pi, n)
    rr = r + noise * rng.standard_normal(n)
    X = np.column_stack([rr * np.cos(th), rr * np.sin(th), h])
    R = rigid_exp([0.3, -0.2, 0.1, 1.0, 2.0, 3.0])
    return X @ R[:3, :3].T + R[:3, 3], R


def _slsqp_cylinder(X, p0, a0, kind):
    """The definition on exact distances: axis (point p, direction a), radii by SLSQP."""
    e = np.linalg.svd(np.eye(3) - np.outer(a0, a0))[0][:, :2]

    def line(z):
        p = p0 + e @ z[:2]
        a = a0 + e @ z[2:4]
        a = a / np.linalg.norm(a)
        q = X - p
        return np.linalg.norm(q - np.outer(q @ a, a), axis=1)

    if kind == "zone":
        f, x0 = (lambda z: z[5] - z[4]), np.r_[0, 0, 0, 0, 3.9, 4.1]
        cons = [{"type": "ineq", "fun": lambda z: line(z) - z[4]},
                {"type": "ineq", "fun": lambda z: z[5] - line(z)}]
    else:
        f, x0 = (lambda z: z[4]), np.r_[0, 0, 0, 0, 4.1]
        cons = [{"type": "ineq", "fun": lambda z: z[4] - line(z)}]
    r = minimize(f, x0, constraints=cons, method="SLSQP",
                 options={"ftol": 1e-15, "maxiter": 2000})
    return float(r.fun)


@pytest.mark.parametrize("kind", ["zone", "circumscribed"])
def test_cylindricity_and_circumscribed_cylinder_equal_slsqp_on_exact_distances(kind):
    X, R = _cyl_points(np.random.default_rng(10), n=60)
    a0 = R[:3, 2]
    value, p, a, (lo, hi) = cylinders_zone(X, R[:3, 3] + [0.02, 0, 0], a0 + [0.003, 0, 0], kind)
    brute = _slsqp_cylinder(X, R[:3, 3], a0, kind)
    assert value == pytest.approx(brute, abs=TOL)


# ------------------------------------------------------------------------------ DRF
def _block(rng):
    """A: bottom z = 0 (outward -z); B: hole at (30, 20), d 10, axis z; C: side x = 0 (-x)."""
    A = np.column_stack([rng.uniform(0, 60, 400), rng.uniform(0, 40, 400), np.zeros(400)])
    A[:, 2] += 0.01 * rng.random(400)           # bumps into the material only
    th = rng.uniform(0, 2 * np.pi, 300)
    H = np.column_stack([30 + 5 * np.cos(th), 20 + 5 * np.sin(th), rng.uniform(0, 10, 300)])
    C = np.column_stack([np.zeros(300), rng.uniform(0, 40, 300), rng.uniform(0, 10, 300)])
    return A, H, C


def test_drf_a_b_c_takes_out_a_known_rigid_motion_and_leaves_nothing_free():
    A, H, C = _block(np.random.default_rng(0))
    M = rigid_exp([0.002, -0.003, 0.004, 0.1, -0.2, 0.05])
    tr = lambda X: X @ M[:3, :3].T + M[:3, 3]  # noqa: E731
    fs = [DatumFeature("A", "plane", np.zeros(3), np.array([0, 0, -1.0]), tr(A)),
          DatumFeature("B", "axis", np.array([30, 20, 0.0]), np.array([0, 0, 1.0]), tr(H)),
          DatumFeature("C", "plane", np.zeros(3), np.array([-1.0, 0, 0]), tr(C))]
    drf = fit_drf(fs, size=60)
    assert drf.free == []
    # the tangent plane of A rests on its lowest points (the bumps go into the material)
    Ac = drf.apply(tr(A))
    assert Ac[:, 2].min() == pytest.approx(0.0, abs=1e-9)
    # B's axis and C fix the rest: the motion is undone except for A's flatness tilt
    assert np.abs(drf.T @ M - np.eye(4)).max() < 1e-3
    assert drf.datums[0].fit.startswith("tangent plane")


def test_drf_reports_its_free_directions():
    A, H, C = _block(np.random.default_rng(1))
    a = DatumFeature("A", "plane", np.zeros(3), np.array([0, 0, -1.0]), A)
    b = DatumFeature("B", "axis", np.array([30, 20, 0.0]), np.array([0, 0, 1.0]), H)
    c = DatumFeature("C", "plane", np.zeros(3), np.array([-1.0, 0, 0]), C)
    assert len(fit_drf([a], 60).free) == 3
    free_ab = fit_drf([a, b], 60).free
    assert len(free_ab) == 1 and free_ab[0].startswith("rotation about")
    assert "(30.000, 20.000" in free_ab[0]
    free_ac = fit_drf([a, c], 60).free
    assert free_ac == ["translation along (+0.000, -1.000, +0.000)"] or \
        free_ac == ["translation along (+0.000, +1.000, +0.000)"]


def test_secondary_plane_of_a_drf_turns_only_about_the_primary_normal():
    """The secondary plane is the tangent plane perpendicular to the primary: its fitted
    normal has no component along the primary's normal, and its form is the minimum zone
    with that one turn, checked against a scan of the angle."""
    rng = np.random.default_rng(2)
    A, H, C = _block(rng)
    C = C.copy()
    C[:, 0] += 0.002 * C[:, 2] + 0.01 * rng.random(300)    # leans in z: not perpendicular
    a = DatumFeature("A", "plane", np.zeros(3), np.array([0, 0, -1.0]), A)
    c = DatumFeature("C", "plane", np.zeros(3), np.array([-1.0, 0, 0]), C)
    drf = fit_drf([a, c], 60)
    fc = drf.datums[1]
    assert abs(fc.direction[2]) < 1e-9
    Cc = drf.apply(C)
    brute = _brute_one_turn(lambda t: np.ptp(Cc @ np.array([np.cos(t), np.sin(t), 0.0])))
    assert fc.form == pytest.approx(brute, abs=TOL)


# ------------------------------------------------------------------------------ registry
def test_registry_drives_the_plan_schema_dispatch_and_spc():
    from shapeverify.characteristics import spc
    from shapeverify.characteristics.plan import _TAGS

    for t in registry.TYPES:
        assert t.schema.model_fields["type"].annotation.__args__ == (t.name,)
        assert callable(registry.evaluator(t.name))
        assert t.name in _TAGS
    assert set(registry.one_sided_types()) <= set(spc._ONE_SIDED)
    for old in ("hole", "surface_profile", "flatness", "cylinder", "check_point"):
        assert registry.label(old) == old          # the existing five print as before
    with pytest.raises(KeyError, match="registered"):
        registry.by_name("roundness")


def test_plan_refuses_a_characteristic_whose_datum_is_not_in_the_datums_table():
    text = ("datums: {A: {faces: [face:0]}}\ncharacteristics:\n"
            "  - {name: P, type: perpendicularity, faces: [face:1], tol: 0.1, datums: [A, B]}\n")
    with pytest.raises(PlanError, match="'B'"):
        parse_plan(text)
    with pytest.raises(PlanError, match="size"):
        parse_plan("characteristics:\n  - {name: P, type: position, features: [face:3], "
                   "tol: 0.1, material: M}\n")


# ------------------------------------------------------------------------------ evaluators
# (slow: the bracket fixture is four virtual scans and a plan evaluation, about 30 s of CPU)
_GDT_PLAN = """units: mm
alignment: {type: best_fit}
datums: {A: {faces: [face:0]}, B: {faces: [face:1]}, C: {faces: [face:2]}, D: {faces: [face:3]}}
characteristics:
  - {name: PERP_B, type: perpendicularity, faces: [face:1], tol: 0.4, datums: [A]}
  - {name: PERP_BOSS, type: perpendicularity, faces: [face:3], tol: 0.3, zone: diameter,
     datums: [A]}
  - {name: POS_BOSS, type: position, features: [face:3], tol: 0.5, datums: [A, B, C]}
  - {name: POS_BOSS_M, type: position, features: [face:3], tol: 0.4, datums: [A, B, C],
     material: M, size: {lower: -0.2, upper: 0.2}}
  - {name: CYL, type: cylindricity, faces: [face:3], tol: 0.3}
  - {name: CIRC, type: circularity, faces: [face:3], tol: 0.3}
  - {name: RUN, type: total_runout, faces: [face:3], tol: 0.4, datums: [D]}
  - {name: PROF_B, type: surface_profile, faces: [face:1], tol: 0.6, datums: [A, B, C]}
  - {name: STRAIGHT, type: straightness, faces: [face:0], tol: 0.3}
"""


@pytest.fixture(scope="module")
def bracket_prep():
    from shapeverify.characteristics.parts import bracket
    from shapeverify.nearest import prepare

    return prepare(bracket(), spacing=1.0)


def _scan_of(part_prep, rng):
    """Four views of the part (the boss seen all around), merged, then one rigid motion."""
    from shapeverify.registration.rigid import apply_transform
    from shapeverify.simulate import virtual_scan

    views = ([1.0, 1.0, 1.6], [-1.0, 1.0, 1.6], [1.0, -1.0, 1.6], [-1.0, -1.0, 1.6])
    P = np.vstack([virtual_scan(part_prep, view=v, pixel=1.0, noise=0.02, rng=rng + i).scan
                   for i, v in enumerate(views)])
    return apply_transform(rigid_exp([0.02, -0.03, 0.01, 1.5, -2.0, 1.0]), P)


@pytest.fixture(scope="module")
def gdt_clean(bracket_prep):
    from shapeverify.characteristics import evaluate_plan

    return evaluate_plan(bracket_prep, _scan_of(bracket_prep, 13), _GDT_PLAN)


@pytest.mark.slow
def test_gdt_characteristics_of_a_perfect_bracket_pass(gdt_clean):
    bad = {c.name: (c.verdict, c.measured, c.upper, c.details.get("reason"))
           for c in gdt_clean.characteristics if c.verdict != "pass"}
    assert not bad
    for c in gdt_clean.characteristics:
        assert c.uncertainty > 0 and np.isfinite(c.measured)
    assert gdt_clean["POS_BOSS"].details["drf"]["free"] == []
    assert len(gdt_clean["PERP_B"].details["drf"]["free"]) == 3


@pytest.fixture(scope="module")
def gdt_ctx(bracket_prep, gdt_clean):
    """The evaluation context of gdt_clean (same pose, same kept points)."""
    from shapeverify.characteristics.evaluate import EvalContext, evaluate_characteristics
    from shapeverify.characteristics.features import model_features
    from shapeverify.characteristics.plan import load_plan

    plan = load_plan(_GDT_PLAN)
    P = gdt_clean.points      # model frame already: evaluate at the identity

    al = dataclasses.replace(gdt_clean.alignment, T_model_scan=np.eye(4))
    chars, S, _ = evaluate_characteristics(bracket_prep, P, plan, al)
    return EvalContext(S, model_features(bracket_prep.model), al, 2.0, bracket_prep, P,
                       float("nan"), plan), {c.name: c for c in chars}


@pytest.mark.slow
def test_perpendicularity_of_the_bracket_wall_equals_brute_force_on_its_points(gdt_ctx):
    """The evaluator's value = the narrowest slab about a normal turning about the datum A's
    normal (z), on the same points in the same DRF frame: a scan of the angle."""
    from shapeverify.characteristics.gdt import _on

    ctx, res = gdt_ctx
    r = res["PERP_B"]
    T = np.asarray(r.details["drf"]["T"])
    X = ctx.S.X[_on(ctx, [1])] @ T[:3, :3].T + T[:3, 3]
    assert X.shape[0] == r.details["n"]
    brute = _brute_one_turn(lambda t: np.ptp(X @ np.array([np.cos(t), np.sin(t), 0.0])),
                            -0.02, 0.02)
    assert r.details["zone_of_points"] == pytest.approx(brute, abs=TOL)
    # the value is the points' zone less the noise's expected part (zone_noise.py)
    assert 0 < r.details["noise_bias"] < r.details["zone_of_points"]
    assert r.measured == pytest.approx(
        corrected_value(brute, r.details["noise_bias"], r.details["fitted_zone"]), abs=TOL)


@pytest.mark.slow
def test_cylindricity_of_the_boss_equals_slsqp_on_its_points(gdt_ctx):
    from shapeverify.characteristics.gdt import _cylinder_points, _on

    ctx, res = gdt_ctx
    X, _ = _cylinder_points(ctx.S.X[_on(ctx, [3])], ctx.feats[3])
    assert X.shape[0] == res["CYL"].details["n"]
    d = res["CYL"].details
    assert d["zone_of_points"] == pytest.approx(
        _slsqp_cylinder_at(X, np.array([75.0, 58.0, 10.0]), np.array([0, 0, 1.0]), 8.0),
        abs=TOL)
    # the value is the points' zone less the noise's expected part (zone_noise.py)
    assert res["CYL"].measured == pytest.approx(
        corrected_value(d["zone_of_points"], d["noise_bias"], d["fitted_zone"]), abs=1e-12)


@pytest.mark.slow
def test_circularity_of_the_boss_equals_enumeration_in_its_sections(gdt_ctx):
    """Each section's value against the candidate-centre enumeration (on 12 of its points
    spread around, so that the enumeration stays small, compared with the LP on the same)."""
    from shapeverify.characteristics.gdt import _cylinder_points, _on, _sections
    from shapeverify.characteristics.gdt_zones import tangent_basis

    ctx, res = gdt_ctx
    f = ctx.feats[3]
    X, _ = _cylinder_points(ctx.S.X[_on(ctx, [3])], f)
    h = (X - f.center) @ f.axis
    B = tangent_basis(f.axis)
    vals = [circles_zone((X[i] - f.center) @ B.T, np.zeros(2))[0] for i in _sections(h)
            if i.size >= 6]
    d = res["CIRC"].details
    assert d["zone_of_points"] == pytest.approx(max(vals), abs=1e-12)
    assert d["sections"] == pytest.approx(vals, abs=1e-12)
    # the value: the largest section's zone less its noise's expected part (zone_noise.py)
    j = d["section"]
    assert res["CIRC"].measured == pytest.approx(
        corrected_value(vals[j], d["noise_bias"], d["fitted_zone"]), abs=1e-12)
    assert res["CIRC"].measured == pytest.approx(max(d["sections_corrected"]), abs=1e-12)
    idx = _sections(h)[4]
    Q = ((X[idx] - f.center) @ B.T)
    Q = Q[np.argsort(np.arctan2(Q[:, 1], Q[:, 0]))][:: max(1, idx.size // 12)][:12]
    C = _candidate_centres(Q)
    r = np.linalg.norm(Q[None] - C[:, None], axis=2)
    assert circles_zone(Q, np.zeros(2))[0] == pytest.approx(
        float((r.max(1) - r.min(1)).min()), abs=TOL)


def _slsqp_cylinder_at(X, p0, a0, r0):
    e = np.linalg.svd(np.eye(3) - np.outer(a0, a0))[0][:, :2]

    def dist(z):
        p = p0 + e @ z[:2]
        a = a0 + e @ z[2:4]
        a = a / np.linalg.norm(a)
        q = X - p
        return np.linalg.norm(q - np.outer(q @ a, a), axis=1)

    cons = [{"type": "ineq", "fun": lambda z: dist(z) - z[4]},
            {"type": "ineq", "fun": lambda z: z[5] - dist(z)}]
    res = minimize(lambda z: z[5] - z[4], np.r_[0, 0, 0, 0, r0 - 0.1, r0 + 0.1],
                   constraints=cons, method="SLSQP", options={"ftol": 1e-15, "maxiter": 3000})
    return float(res.fun)


@pytest.mark.slow
def test_a_boss_moved_0p5_mm_fails_its_position_and_nothing_else(bracket_prep):
    """The scanned part's boss is 0.5 mm off (x): position (tol 0.5, about 1.0 measured)
    fails; with the MMC bonus (tol 0.4 + at most 0.2) it fails too (the boss is at its nominal
    size); the form and the orientations still pass.  (0.5 mm, not 0.3: the tangent datum
    planes of a scan with 0.02 mm noise make U about 0.2 mm.)"""
    from shapeverify.characteristics import evaluate_plan
    from shapeverify.characteristics.parts import BRACKET_BOSS, bracket
    from shapeverify.nearest import prepare

    bx, by, br, bh = BRACKET_BOSS
    moved = prepare(bracket(boss=(bx + 0.5, by, br, bh)), spacing=1.0)
    res = evaluate_plan(bracket_prep, _scan_of(moved, 17), _GDT_PLAN)
    assert res["POS_BOSS"].verdict == "fail"
    assert res["POS_BOSS"].measured == pytest.approx(1.0, abs=0.15)
    assert res["POS_BOSS_M"].verdict == "fail"
    bonus = res["POS_BOSS_M"].details["features"][0]["bonus"]
    assert 0.0 <= bonus < 0.2          # MMC size 16.2 less the mating size (16 + noise)
    for name in ("PERP_B", "PERP_BOSS", "CYL", "CIRC", "STRAIGHT"):
        assert res[name].verdict == "pass", (name, res[name].measured)


@pytest.mark.slow
def test_straightness_of_the_base_line_elements_equals_a_scan_of_the_angle(gdt_ctx):
    """Each line element (band across the direction) against the narrowest slab whose normal
    turns only along the band (in the plane of z and the direction): a scan of the angle."""
    from shapeverify.characteristics.gdt import _on, _sections

    ctx, res = gdt_ctx
    r = res["STRAIGHT"]
    X = ctx.S.X[_on(ctx, [0])]
    u = np.asarray(r.details["direction"])
    v = np.cross([0.0, 0.0, 1.0], u)
    vals = []
    for idx in _sections(X @ v):
        if idx.size >= 3:
            Y = X[idx]
            vals.append(_brute_one_turn(
                lambda t: np.ptp(Y @ (np.cos(t) * np.array([0, 0, 1.0]) + np.sin(t) * u)),
                -0.01, 0.01))
    assert r.details["zone_of_points"] == pytest.approx(max(vals), abs=TOL)
    assert r.details["lines"] == pytest.approx(vals, abs=TOL)
    # the value: the largest line's zone less its noise's expected part (zone_noise.py)
    j = r.details["line"]
    assert r.measured == pytest.approx(
        corrected_value(r.details["lines"][j], r.details["noise_bias"],
                        r.details["fitted_zone"]), abs=1e-12)


@pytest.mark.slow
def test_angularity_and_parallelism_use_the_cad_orientation_in_the_drf(gdt_ctx):
    """Angularity of wall B to A (the CAD's 90 degrees) is perpendicularity's value; its
    parallelism to itself as a datum (B|A: all rotations fixed by B then A about ...) is the
    plain range along B's normal after the DRF."""
    from shapeverify.characteristics.evaluate import evaluate_characteristics
    from shapeverify.characteristics.gdt import _on
    from shapeverify.characteristics.plan import load_plan

    ctx, res = gdt_ctx
    extra = load_plan(_GDT_PLAN.replace(
        "characteristics:\n",
        "characteristics:\n"
        "  - {name: ANG_B, type: angularity, faces: [face:1], tol: 0.4, datums: [A]}\n"
        "  - {name: PAR_B, type: parallelism, faces: [face:1], tol: 0.4, datums: [B, A]}\n"))
    chars, _, _ = evaluate_characteristics(ctx.prep, ctx.scan, extra, ctx.al)
    got = {c.name: c for c in chars}
    assert got["ANG_B"].measured == pytest.approx(res["PERP_B"].measured, abs=1e-12)
    T = np.asarray(got["PAR_B"].details["drf"]["T"])
    X = ctx.S.X[_on(ctx, [1])] @ T[:3, :3].T + T[:3, 3]
    assert got["PAR_B"].details["zone_of_points"] == pytest.approx(np.ptp(X[:, 0]), abs=TOL)


@pytest.mark.slow  # 6-7 s each (measured at a load of 3): out of `make test-fast` (issue 32)
@pytest.mark.parametrize("n", [20, 56])
def test_position_u_of_a_mating_circle_covers_a_monte_carlo_of_its_value(n):
    """FTC 08's hole moved 0.3 mm read 'undecided' (0.622 against 0.508, U 0.121 = 2 z_n sigma):
    the centre of a mating circle does not move by its extremes' common shift.  A Monte Carlo
    of the largest inscribed circle of n noisy points (offset 0.3 mm, value 0.6): the U of
    :func:`mating_centre_u` covers >= 95 % of the value's errors and is at most 1.5 x their
    95.45 % quantile (not the 2.5-3 x of 2 z_n sigma)."""
    from shapeverify.characteristics.gdt import mating_centre_u
    from shapeverify.characteristics.support import extreme_quantile

    rng = np.random.default_rng(n)
    err = []
    for _ in range(400):
        t = rng.uniform(0, 2 * np.pi, n)
        r = 2.9 + rng.normal(0, 0.02, n)
        xy = np.column_stack([r * np.cos(t) + 0.3, r * np.sin(t)])
        _, c, _ = circles_zone(xy, np.zeros(2), "inscribed")
        err.append(2 * np.linalg.norm(c) - 0.6)
    q = float(np.quantile(np.abs(err), 0.9545))
    U = mating_centre_u(n, 0.02, 2.0)
    assert np.mean(np.abs(err) <= U) >= 0.95
    assert U <= 1.5 * q < 2 * extreme_quantile(n, 2.0) * 0.02
