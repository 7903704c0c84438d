"""Features the CAD splits into several faces, and separate features under one frame (issue 28;
NIST FTC 10: bosses of two half-cylinder faces, "3X" / "4X" cylindricity of split holes).

A part built with OpenCASCADE here: a 60 x 30 x 10 block with three pins (diameter 8, 12 mm
tall), each pin fused from two half-cylinders, so each is two cylinder faces (and its top two
half discs).  The scan is independent of the project: OpenCASCADE's tessellation sampled by
area, and the pins' walls drawn on the exact cylinders (in their interior, away from the
seams and rims, so that every wall point is one the evaluation keeps).

* A boss of two faces was refused ("a boss of 2 faces; the plan's cylinder is one face"):
  ``type: cylinder`` with ``faces`` fits one cylinder to both faces' points.
* A cylindricity on three pins was refused ("Cylindricity of 3 cylinders under one
  tolerance"); fitted as one cylinder it would be nonsense.  ``features`` evaluates each pin
  on its own (ASME Y14.5: each individually).
"""
from __future__ import annotations

import numpy as np

from shapeverify.characteristics.zone_noise import corrected_value
import pytest

#: pins off the block's centre lines: no rigid motion maps the part onto itself (a symmetric
#: part lets the best fit land on a turned copy)
R, X_PINS, Y0, Z0, Z1 = 4.0, (10.0, 26.0, 44.0), 12.0, 10.0, 22.0


def _pins_step(path):
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Fuse
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCylinder
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt

    from test_cad_import import write_step

    shape = BRepPrimAPI_MakeBox(gp_Pnt(0, 0, 0), 60.0, 30.0, Z0).Shape()
    for x in X_PINS:
        for xd in (1, -1):        # two half-cylinders: the pin's wall is two faces
            half = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(x, Y0, Z0), gp_Dir(0, 0, 1),
                                                   gp_Dir(xd, 0, 0)), R, Z1 - Z0, np.pi)
            shape = BRepAlgoAPI_Fuse(shape, half.Shape()).Shape()
    write_step(shape, path)
    return shape


@pytest.fixture(scope="module")
def part(tmp_path_factory):
    import shapeverify as sv
    from independent_scans import random_points, tessellate
    from shapeverify.characteristics.features import model_features

    path = tmp_path_factory.mktemp("pins") / "pins.step"
    shape = _pins_step(path)
    model = sv.load_model(path)
    feats = model_features(model)
    walls = {x: sorted(f.face for f in feats if f.kind == "cylinder"
                       and abs(f.center[0] - x) < 1e-6) for x in X_PINS}
    assert all(len(w) == 2 for w in walls.values()), walls
    rng = np.random.default_rng(11)
    V, T, F = tessellate(shape, 0.002)
    # the tessellation's faces are the model's (no face skipped): its wall triangles lie on
    # the walls found by the features
    assert len(model.faces) == F.max() + 1
    rest = np.flatnonzero(~np.isin(F, [f for w in walls.values() for f in w]))
    P, N = random_points(V, T, 0.5, rng, tris=rest)
    return model, sv.prepare(model, spacing=0.5), walls, P, N


def _wall(x, rng, n=700, ovality=0.0, grow=0.0, noise=0.005):
    """Points on the pin at x: its wall 1.5 mm from the rims and from the two seams (in the
    x-z plane), radius ``R + grow + ovality cos 2(theta - 45 deg)`` plus radial noise."""
    gap = 2 * np.arcsin(0.75 / R)
    th = rng.uniform(gap, np.pi - gap, n) + np.pi * rng.integers(0, 2, n)
    z = rng.uniform(Z0 + 1.5, Z1 - 1.5, n)
    r = R + grow + ovality * np.cos(2 * (th - np.pi / 4)) + rng.normal(0.0, noise, n)
    return np.column_stack([x + r * np.cos(th), Y0 + r * np.sin(th), z])


def _lsq_cylinder(P):
    """Least-squares cylinder (scipy): (axis point, axis, radius), started at the pin's."""
    from scipy.optimize import least_squares

    c0 = P.mean(axis=0)

    def res(v):
        a = np.array([v[2], v[3], 1.0]) / np.linalg.norm([v[2], v[3], 1.0])
        q = P - np.array([v[0], v[1], c0[2]])
        return np.linalg.norm(q - np.outer(q @ a, a), axis=1) - v[4]

    s = least_squares(res, [c0[0], c0[1], 0.0, 0.0, R], xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return s.x[4]


def _minimum_zone_cylinder(P):
    """Minimum zone (coaxial cylinders, the difference of radii) of P by SLSQP on the axis
    (point in the plane z = mean, direction) and the two radii, every point between them."""
    from scipy.optimize import minimize

    c0 = P.mean(axis=0)

    def radii(v):
        a = np.array([v[2], v[3], 1.0]) / np.linalg.norm([v[2], v[3], 1.0])
        q = P - np.array([v[0], v[1], c0[2]])
        return np.linalg.norm(q - np.outer(q @ a, a), axis=1)

    best = np.inf
    for start in ([c0[0], c0[1], 0.0, 0.0],
                  [c0[0] + 0.01, c0[1] - 0.01, 1e-3, -1e-3]):
        r = radii(start)
        x0 = np.array(start + [r.min(), r.max()])
        s = minimize(lambda x: x[5] - x[4], x0, method="SLSQP",
                     constraints=[{"type": "ineq", "fun": lambda x: radii(x[:4]) - x[4]},
                                  {"type": "ineq", "fun": lambda x: x[5] - radii(x[:4])}],
                     options={"ftol": 1e-15, "maxiter": 500})
        r = radii(s.x[:4])
        best = min(best, float(r.max() - r.min()))
    return best


def _evaluate(part, walls_points, chars):
    import yaml

    from shapeverify.characteristics import evaluate_plan

    model, prep, walls, P, N = part
    rng = np.random.default_rng(5)
    X = P + rng.normal(0.0, 0.005, len(P))[:, None] * N
    X = np.vstack([X] + walls_points)
    plan = {"alignment": {"type": "best_fit"}, "characteristics": chars}
    return evaluate_plan(prep, X, yaml.safe_dump(plan), init=np.eye(4)).characteristics


def test_boss_of_two_half_cylinder_faces_is_measured_as_one_cylinder(part):
    """The first pin (x = 10) grown by 0.04 mm in radius: its diameter over both faces is the
    least-squares cylinder (scipy) of both faces' points, 8.08 (fails +-0.05)."""
    _, _, walls, _, _ = part
    rng = np.random.default_rng(1)
    pins = [_wall(x, rng, grow=0.04 if x == X_PINS[0] else 0.0) for x in X_PINS]
    faces = [f"face:{f}" for f in walls[X_PINS[0]]]
    (c,) = _evaluate(part, pins, [{"name": "D", "type": "cylinder", "faces": faces,
                                   "diameter": {"tol": 0.05}}])
    truth = 2 * _lsq_cylinder(pins[0])
    assert truth == pytest.approx(8.08, abs=0.002)
    assert c.details["faces"] == walls[X_PINS[0]] and c.details["n"] == len(pins[0])
    assert c.measured == pytest.approx(truth, abs=2e-4), (c.measured, truth)
    assert c.verdict == "fail" and c.nominal == pytest.approx(8.0, abs=1e-9)


@pytest.mark.slow  # 3.4 s of CPU with numba's cache warm (quick tests: under ~3 s)
def test_3x_cylindricity_of_three_pins_is_each_pins_own_minimum_zone(part):
    """One tolerance on three pins, the middle one oval by +-0.05 mm: each pin's value is the
    minimum zone of its own points (SLSQP), the result the worst (the oval pin, 0.1 plus the
    noise's zone).  Within 0.2 all pass; within 0.05 the oval pin fails, and so the result."""
    _, _, walls, _, _ = part
    rng = np.random.default_rng(2)
    pins = [_wall(x, rng, ovality=0.05 if x == X_PINS[1] else 0.0) for x in X_PINS]
    feats = [[f"face:{f}" for f in walls[x]] for x in X_PINS]
    (c,) = _evaluate(part, pins, [{"name": "CYL", "type": "cylindricity", "tol": 0.2,
                                   "faces": [f for g in feats for f in g],
                                   "features": feats}])
    truth = [_minimum_zone_cylinder(P) for P in pins]
    rows = c.details["features"]
    assert [r["faces"] for r in rows] == feats
    assert [r["n"] for r in rows] == [len(P) for P in pins]
    # the points' zone is the minimum zone; the value is it less the noise's expected part
    # (zone_noise.py)
    for r, t in zip(rows, truth):
        assert r["zone_of_points"] == pytest.approx(t, abs=1e-6), (r, t)
        assert r["value"] == pytest.approx(
            corrected_value(t, r["noise_bias"], r["fitted_zone"]), abs=1e-6), (r, t)
    assert truth[1] > 0.1 > 0.05 > max(truth[0], truth[2])
    assert c.details["zone_of_points"] == pytest.approx(truth[1], abs=1e-6)
    assert c.details["worst_feature"] == feats[1]
    assert c.verdict == "pass" and c.upper == 0.2, c
    # the oval pin over a 0.05 tolerance fails (the others are within it, maybe undecided)
    (c2,) = _evaluate(part, pins, [{"name": "CYL", "type": "cylindricity", "tol": 0.05,
                                    "faces": [f for g in feats for f in g],
                                    "features": feats}])
    v = [r["verdict"] for r in c2.details["features"]]
    assert v[1] == "fail" and "fail" not in (v[0], v[2]), c2.details["features"]
    assert c2.verdict == "fail" and c2.measured == pytest.approx(rows[1]["value"], abs=1e-6)


def test_features_must_split_the_faces():
    from shapeverify.characteristics.plan import PlanError, load_plan

    with pytest.raises(PlanError, match="must split faces"):
        load_plan({"characteristics": [{"name": "C", "type": "cylindricity", "tol": 0.1,
                                        "faces": ["face:1", "face:2"],
                                        "features": [["face:1"], ["face:3"]]}]})


def test_face_groups_are_the_built_cylinders_and_planes(part):
    """Grouped by :func:`features_of`: the three pins (two faces each, on the axes they were
    built on), the six half discs of the pins' tops (one plane z = 22), and each of the
    block's six sides alone -- as the construction made them (each face's own OpenCASCADE
    sample point decides where it lies)."""
    from shapeverify.characteristics.face_groups import features_of
    from shapeverify.characteristics.features import model_features

    model, _, walls, _, _ = part
    groups, other = features_of(model_features(model), list(range(len(model.faces))),
                                float(model.size))
    assert other == []
    cyl = sorted(sorted(g) for k, g in groups if k == "cylinder")
    assert cyl == sorted(walls.values())
    planes = sorted(sorted(g) for k, g in groups if k == "plane")
    # the truth of each face: a point of it (its trimmed domain's centre, evaluated)
    mid = {}
    for i, f in enumerate(model.faces):
        (a0, a1), (b0, b1) = f.uv_bounds
        mid[i] = f.evaluate(np.array([[0.5 * (a0 + a1), 0.5 * (b0 + b1)]]))[0]
    tops = sorted(i for i in range(len(model.faces)) if abs(mid[i][2] - Z1) < 1e-9)
    assert len(tops) == 6 and tops in planes
    assert len(planes) == 7 and all(len(g) == 1 for g in planes if g != tops)
