"""Position in two parallel planes (a slot's centre plane) and in a sphere (a ball's centre),
issue 28 item 3 / NIST CTC 01, FTC 06: against brute force (linear programming for the mating
envelope, scipy's geometric least squares for the sphere) and on a part built with OCP."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares, linprog

from shapeverify.characteristics.position_zones import sphere_centre, width_centre


@pytest.mark.parametrize("slot", [True, False], ids=["slot", "tab"])
def test_width_centre_is_the_mating_envelope_of_linear_programming(slot):
    rng = np.random.default_rng(1)
    u = np.array([0.3, -0.4, 0.866])
    u /= np.linalg.norm(u)
    A = rng.normal(0, 5, (400, 3))
    A -= np.outer(A @ u, u) + np.outer(rng.normal(0, 0.05, 400), u)
    B = rng.normal(0, 5, (300, 3))
    B -= np.outer(B @ u - 12.0 - rng.normal(0, 0.05, 300), u)
    a, b = A @ u, B @ u
    # envelope planes p (side A) and q (side B): a slot's gap as wide as the points allow
    # (max q - p with p >= a_i, q <= b_j), a tab's band as narrow (min q - p, p <= a_i, q >= b_j)
    sgn = 1.0 if slot else -1.0
    A_ub = np.vstack([np.tile([-sgn, 0.0], (len(a), 1)), np.tile([0.0, sgn], (len(b), 1))])
    b_ub = np.r_[-sgn * a, sgn * b]
    res = linprog([sgn, -sgn], A_ub=A_ub, b_ub=b_ub, bounds=[(None, None)] * 2, method="highs")
    assert res.status == 0
    p, q = res.x
    assert width_centre(A, B, u, slot) == pytest.approx(0.5 * (p + q), abs=1e-9)


def test_sphere_centre_is_the_geometric_least_squares_centre():
    rng = np.random.default_rng(2)
    d = rng.normal(size=(500, 3))
    d[:, 2] = np.abs(d[:, 2])                               # a half sphere, as a ball's top
    d /= np.linalg.norm(d, axis=1)[:, None]
    c0 = np.array([12.0, -3.0, 40.0])
    X = c0 + (15.875 + rng.normal(0, 0.02, 500))[:, None] * d
    ref = least_squares(lambda p: np.linalg.norm(X - p[:3], axis=1) - p[3],
                        np.r_[X.mean(axis=0), 10.0], xtol=1e-15, ftol=1e-15, gtol=1e-15)
    c, r = sphere_centre(X)
    assert np.abs(c - ref.x[:3]).max() < 1e-6 and abs(r - ref.x[3]) < 1e-6


# ------------------------------------------------------------------------- a part built with OCP
@pytest.fixture(scope="module")
def slot_ball(tmp_path_factory):
    """60 x 40 x 20 block, a slot x in [25, 35] (z 10..20, through in y), a ball of radius 6
    centred on the top face at (12, 20, 20)."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut, BRepAlgoAPI_Fuse
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeSphere
    from OCP.gp import gp_Pnt
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer

    import shapeverify as sv
    from shapeverify.characteristics.features import model_features

    box = BRepPrimAPI_MakeBox(60.0, 40.0, 20.0).Shape()
    slot = BRepPrimAPI_MakeBox(gp_Pnt(25.0, -1.0, 10.0), 10.0, 42.0, 11.0).Shape()
    part = BRepAlgoAPI_Fuse(BRepAlgoAPI_Cut(box, slot).Shape(),
                            BRepPrimAPI_MakeSphere(gp_Pnt(12.0, 20.0, 20.0), 6.0).Shape()).Shape()
    path = tmp_path_factory.mktemp("slot") / "slot_ball.step"
    w = STEPControl_Writer()
    w.Transfer(part, STEPControl_AsIs)
    w.Write(str(path))
    model = sv.load_model(path)
    m = getattr(model, "model", model)
    feats = model_features(m)
    sides = [f.face for f in feats if f.kind == "plane" and abs(abs(f.axis[0]) - 1) < 1e-9
             and 24.0 < f.center[0] < 36.0]
    from shapeverify.characteristics.position_zones import sphere_of_faces
    ball = []
    for i in range(len(m.faces)):
        try:
            sphere_of_faces(m, [i])
            ball.append(i)
        except (ValueError, np.linalg.LinAlgError):
            pass
    prep = sv.prepare(model, spacing=1.0)
    pts = prep.model.sample(0.6, rng=np.random.default_rng(3))
    return prep, feats, sorted(sides), ball, pts


def _plan(sides, ball, tol=0.2):
    return {"alignment": {"type": "best_fit"}, "characteristics": [
        {"name": "SLOT", "type": "position_zone", "faces": [f"face:{f}" for f in sides],
         "tol": tol, "zone": "planes"},
        {"name": "BALL", "type": "position_zone", "faces": [f"face:{f}" for f in ball],
         "tol": tol, "zone": "sphere"}]}


def test_perfect_part_passes_slot_and_ball_positions(slot_ball):
    from shapeverify.characteristics import evaluate_plan

    prep, feats, sides, ball, pts = slot_ball
    assert len(sides) == 2 and ball
    P, N = np.asarray(pts.points), np.asarray(pts.normals)
    X = P + np.random.default_rng(4).normal(0, 0.005, len(P))[:, None] * N
    res = evaluate_plan(prep, X, _plan(sides, ball))
    for name in ("SLOT", "BALL"):
        assert res[name].verdict == "pass", res[name]
        assert res[name].measured < 0.05
    assert res["SLOT"].details["feature"] == "slot"
    assert res["SLOT"].details["cad_width"] == pytest.approx(10.0)


def test_slot_side_moved_and_ball_moved_fail_their_positions_by_the_shift(slot_ball):
    from shapeverify.characteristics import evaluate_plan

    prep, feats, sides, ball, pts = slot_ball
    P, N, F = np.asarray(pts.points), np.asarray(pts.normals), np.asarray(pts.face)
    X = P + np.random.default_rng(5).normal(0, 0.005, len(P))[:, None] * N
    hi = max(sides, key=lambda f: feats[f].center[0])           # the x = 35 side
    X[F == hi, 0] += 0.4                                        # slot 0.4 wider: centre +0.2
    X[np.isin(F, ball), 1] += 0.3                               # ball 0.3 along y
    res = evaluate_plan(prep, X, _plan(sides, ball))
    s, b = res["SLOT"], res["BALL"]
    assert s.verdict == "fail" and b.verdict == "fail"
    assert s.measured == pytest.approx(0.4, abs=0.03)           # 2 x 0.2
    assert b.measured == pytest.approx(0.6, abs=0.03)           # 2 x 0.3
    assert abs(s.details["centre_offset"]) == pytest.approx(0.2, abs=0.015)


def test_ball_size_passes_perfect_and_fails_grown_by_0_3_in_radius(slot_ball):
    """feature_size (FTC 06 Size_SphericalDiameter) on the same part: SØ12 ±0.2."""
    from shapeverify.characteristics import evaluate_plan

    prep, feats, sides, ball, pts = slot_ball
    P, N, F = np.asarray(pts.points), np.asarray(pts.normals), np.asarray(pts.face)
    plan = {"alignment": {"type": "best_fit"}, "characteristics": [
        {"name": "SD", "type": "feature_size", "faces": [f"face:{f}" for f in ball],
         "shape": "sphere", "size": "diameter", "lower": -0.2, "upper": 0.2}]}
    rng = np.random.default_rng(6)
    X = P + rng.normal(0, 0.005, len(P))[:, None] * N
    ok = evaluate_plan(prep, X, plan)["SD"]
    assert ok.verdict == "pass" and ok.nominal == pytest.approx(12.0, abs=1e-6)
    assert abs(ok.deviation) < 0.01
    c = np.array([12.0, 20.0, 20.0])
    on = np.isin(F, ball)
    X[on] += 0.3 * (X[on] - c) / np.linalg.norm(X[on] - c, axis=1)[:, None]
    bad = evaluate_plan(prep, X, plan)["SD"]
    assert bad.verdict == "fail" and bad.deviation == pytest.approx(0.6, abs=0.02)
