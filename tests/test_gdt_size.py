"""Dimensions between two planar faces (issue 28 item 3, size; :mod:`shapeverify.characteristics.gdt_size`):
``distance`` (``Location_LinearDistance`` of AP242 PMI) and ``angle`` (``Location_Angular``).

Each is checked against an independent computation of its definition on the same points:
each face's least-squares plane by scipy's ``least_squares`` on the orthogonal distances
(normal in spherical angles, offset), then the mean one-sided distances / the angle between the
fitted normals, to 1e-6 (mm, degrees).  The part: a 50 x 40 x 10 mm plate (faces 0 bottom, 1
top, 2 the x = 0 side, 3 the y = 0 side) and a face at 60 degrees to the top (4), sampled
directly on its faces with 0.02 mm noise.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.optimize import least_squares

TOL = 1e-6
L, W, H = 50.0, 40.0, 10.0
C60, S60 = np.cos(np.radians(60.0)), np.sin(np.radians(60.0))
#: (p00, p10, p01) of each face: normal (p10 - p00) x (p01 - p00), outward
FACES = [
    ([0, 0, 0], [0, W, 0], [L, 0, 0]),                    # bottom, -z
    ([0, 0, H], [L, 0, H], [0, W, H]),                    # top, +z
    ([0, 0, 0], [0, 0, H], [0, W, 0]),                    # x = 0 side, -x
    ([0, 0, 0], [L, 0, 0], [0, 0, H]),                    # y = 0 side, -y
    ([70, 0, 0], [70, W, 0], [70 - 10 * C60, 0, 10 * S60]),  # normal (sin 60, 0, cos 60)
]


def _model():
    from shapeverify.cad.model import Face, Model
    from shapeverify.characteristics.parts import _bilinear

    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    faces = []
    for p00, p10, p01 in FACES:
        p00, p10, p01 = map(np.asarray, (p00, p10, p01))
        faces.append(Face(_bilinear(p00, p10, p01, p10 + p01 - p00), (square,),
                          (np.ones(4, bool),)))
    return Model(tuple(faces), source="plate with a 60 degree face (test_gdt_size)")


def _scan(rng, top_shift=0.0, tilt_deg=0.0):
    """Points uniform on each face (1 per mm^2), 0.02 mm noise along the normal; the top
    moved ``top_shift`` along z, face 4 turned ``tilt_deg`` about its lower edge (y axis)."""
    out = []
    for k, (p00, p10, p01) in enumerate(FACES):
        p00, p10, p01 = map(np.asarray, (p00, p10, p01))
        a, b = p10 - p00, p01 - p00
        n = np.cross(a, b)
        area = np.linalg.norm(n)
        n /= area
        m = int(area)
        uv = rng.random((m, 2))
        P = p00 + uv[:, :1] * a + uv[:, 1:] * b + rng.normal(0, 0.02, (m, 1)) * n
        if k == 1:
            P[:, 2] += top_shift
        if k == 4 and tilt_deg:
            t = np.radians(tilt_deg)
            R = np.array([[np.cos(t), 0, np.sin(t)], [0, 1, 0], [-np.sin(t), 0, np.cos(t)]])
            P = (P - p00) @ R.T + p00
        out.append(P)
    return np.vstack(out)


PLAN = {"alignment": {"type": "best_fit"}, "characteristics": [
    {"name": "THICK", "type": "distance", "faces": ["face:1", "face:0"], "lower": -0.2,
     "upper": 0.2, "nominal": 10.0},
    {"name": "ANG", "type": "angle", "faces": ["face:1", "face:4"], "lower": -0.5,
     "upper": 0.5, "nominal": 60.0},
    {"name": "ANG_SUP", "type": "angle", "faces": ["face:4", "face:1"], "lower": -0.5,
     "upper": 0.5, "nominal": 120.0}]}


@pytest.fixture(scope="module")
def prep():
    from shapeverify.nearest import prepare

    return prepare(_model(), spacing=1.0)


def _evaluate(prep, P):
    from shapeverify.characteristics import evaluate_plan
    from shapeverify.characteristics.evaluate import EvalContext, evaluate_characteristics
    from shapeverify.characteristics.features import model_features
    from shapeverify.characteristics.plan import load_plan

    res = evaluate_plan(prep, P, PLAN, init=np.eye(4))
    plan = load_plan(PLAN)
    al = dataclasses.replace(res.alignment, T_model_scan=np.eye(4))
    _, S, _ = evaluate_characteristics(prep, res.points, plan, al)
    ctx = EvalContext(S, model_features(prep.model), al, 2.0, prep, res.points,
                      float("nan"), plan)
    return {c.name: c for c in res.characteristics}, ctx


@pytest.fixture(scope="module")
def perfect(prep):
    return _evaluate(prep, _scan(np.random.default_rng(3)))


def _scipy_plane(P, n0):
    """(unit normal, offset) of the orthogonal least-squares plane, by scipy least_squares."""
    th0 = np.arccos(np.clip(n0[2], -1, 1))
    ph0 = np.arctan2(n0[1], n0[0])

    def normal(x):
        return np.array([np.sin(x[0]) * np.cos(x[1]), np.sin(x[0]) * np.sin(x[1]),
                         np.cos(x[0])])

    r = least_squares(lambda x: P @ normal(x) - x[2], [th0, ph0, float(np.mean(P @ n0))],
                      xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return normal(r.x), r.x[2]


def _points(ctx, face):
    from shapeverify.characteristics.gdt import _on

    return ctx.S.X[_on(ctx, [face])]


def test_lsq_plane_distance_and_angle_equal_scipy_orthogonal_fits():
    from shapeverify.characteristics.gdt_size import plane_angle, plane_distance

    rng = np.random.default_rng(7)
    P1 = np.column_stack([rng.uniform(0, 30, 200), rng.uniform(0, 20, 200),
                          rng.normal(0, 0.05, 200)])
    P2 = P1[:150] * [1, 1, 0] + [0, 0, 5.0] + rng.normal(0, 0.05, (150, 3)) * [0, 0, 1]
    P2[:, 2] += 0.002 * P2[:, 0]                  # slightly tilted
    n1, d1 = _scipy_plane(P1, np.array([0, 0, 1.0]))
    n2, d2 = _scipy_plane(P2, np.array([0, 0, 1.0]))
    brute = 0.5 * (abs(np.mean(P2 @ n1 - d1)) + abs(np.mean(P1 @ n2 - d2)))
    assert plane_distance(P1, P2) == pytest.approx(brute, abs=TOL)
    ang = np.degrees(np.arccos(n1 @ n2))
    assert plane_angle(P1, P2, [0, 0, 1], [0, 0, 1]) == pytest.approx(ang, abs=TOL)


@pytest.mark.slow
def test_distance_and_angle_of_a_perfect_plate_equal_scipy_fits_and_pass(perfect):
    res, ctx = perfect
    top, bottom, slope = (_points(ctx, f) for f in (1, 0, 4))
    n1, d1 = _scipy_plane(top, np.array([0, 0, 1.0]))
    n0, d0 = _scipy_plane(bottom, np.array([0, 0, 1.0]))
    brute = 0.5 * (abs(np.mean(bottom @ n1 - d1)) + abs(np.mean(top @ n0 - d0)))
    assert res["THICK"].measured == pytest.approx(brute, abs=TOL)
    assert res["THICK"].measured == pytest.approx(10.0, abs=0.01)
    n4, _ = _scipy_plane(slope, np.array([S60, 0, C60]))
    ang = np.degrees(np.arccos(abs(n1 @ n4)))
    assert res["ANG"].measured == pytest.approx(ang, abs=TOL)
    assert res["ANG_SUP"].measured == pytest.approx(180.0 - ang, abs=TOL)
    assert res["ANG"].details["supplement"] is False and res["ANG_SUP"].details["supplement"]
    for c in res.values():
        assert c.verdict == "pass", (c.name, c.measured, c.uncertainty)
        # a sanity bound (the angle's U is 0.055 deg since the edge band covers whole edges)
        assert 0 < c.uncertainty < 0.1


@pytest.mark.slow
def test_plate_0p3_mm_thicker_fails_its_distance_and_a_face_turned_1_degree_its_angle(prep):
    res, _ = _evaluate(prep, _scan(np.random.default_rng(4), top_shift=0.3, tilt_deg=1.0))
    assert res["THICK"].verdict == "fail" and res["THICK"].deviation == pytest.approx(0.3, abs=0.02)
    assert res["ANG"].verdict == "fail" and abs(res["ANG"].deviation) == pytest.approx(1.0, abs=0.05)
    assert res["ANG_SUP"].verdict == "fail"


@pytest.mark.slow
def test_distance_between_faces_that_are_not_parallel_is_an_error_naming_them(perfect):
    from shapeverify.characteristics.gdt_size import eval_distance
    from shapeverify.characteristics.schema import Distance

    _, ctx = perfect
    c = Distance(name="BAD", type="distance", faces=["face:1", "face:4"], lower=-1, upper=1)
    with pytest.raises(ValueError, match="not parallel"):
        eval_distance(c, ctx)
