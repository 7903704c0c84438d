"""CAD features from the topology: holes (circular inner trim loops), planes, cylinders."""
from __future__ import annotations

import json

import numpy as np
import pytest

from shapeverify.cad.model import Face, Model
from shapeverify.cad.nurbs import NurbsSurface
from shapeverify.characteristics.features import features_table, find_feature, model_features
from shapeverify.characteristics.parts import BRACKET_BOSS, BRACKET_HOLES, bracket

N_LOOP = 512
# a polygon of N_LOOP vertices inscribed in the circle: the fitted radius lies between the
# apothem r cos(pi / N) and r
POLY = 1.0 - np.cos(np.pi / N_LOOP)


def _curved_sheet(hole=(40.0, 30.0, 7.0)):
    """A bicubic Bezier sheet over [0, 100] x [0, 80] with x = 100 u, y = 80 v exactly (equally
    spaced control points: linear precision) and a curved height, with a round hole along z."""
    xs, ys = np.linspace(0, 100, 4), np.linspace(0, 80, 4)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    Z = 8.0 * np.sin(X / 40.0) + 0.002 * (Y - 40) ** 2
    surf = NurbsSurface(3, 3, [0] * 4 + [1] * 4, [0] * 4 + [1] * 4, np.stack([X, Y, Z], -1))
    x0, y0, r = hole
    t = -np.linspace(0, 2 * np.pi, N_LOOP, endpoint=False)
    inner = np.column_stack([(x0 + r * np.cos(t)) / 100.0, (y0 + r * np.sin(t)) / 80.0])
    outer = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    return Model((Face(surf, (outer, inner), (np.ones(4, bool), np.ones(N_LOOP, bool))),)), surf


def test_bracket_faces_are_classified_and_its_holes_found_at_their_cad_positions():
    feats = model_features(bracket())
    kinds = {f.id: f.kind for f in feats}
    assert kinds == {"face:0": "plane", "face:1": "plane", "face:2": "plane",
                     "face:3": "cylinder", "hole:0": "hole", "hole:1": "hole"}
    normals = {f.id: f.axis for f in feats if f.kind == "plane"}
    np.testing.assert_allclose(normals["face:0"], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(normals["face:1"], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(normals["face:2"], [0, 1, 0], atol=1e-12)
    boss = find_feature(feats, "face:3")
    assert boss.diameter == pytest.approx(2 * BRACKET_BOSS[2], abs=1e-9)
    np.testing.assert_allclose(np.abs(boss.axis), [0, 0, 1], atol=1e-9)
    np.testing.assert_allclose(boss.center[:2], BRACKET_BOSS[:2], atol=1e-9)
    holes = [f for f in feats if f.kind == "hole"]
    for f, (x, y, r) in zip(holes, BRACKET_HOLES):
        np.testing.assert_allclose(f.center, [x, y, 0.0], atol=1e-9)
        np.testing.assert_allclose(f.axis, [0, 0, 1], atol=1e-12)   # the face's outward side
        assert 2 * r * (1 - POLY) - 1e-9 <= f.diameter <= 2 * r + 1e-9
        assert f.face == 0 and f.form_error < 1e-3


def test_hole_through_a_curved_sheet_lies_on_a_cylinder_and_its_centre_on_the_surface():
    model, surf = _curved_sheet()
    feats = model_features(model)
    assert [f.id for f in feats] == ["face:0", "hole:0"]
    assert feats[0].kind == "freeform"
    h = feats[1]
    # the loop is not planar (the sheet curves), so this came from the cylinder fit
    np.testing.assert_allclose(h.axis, [0, 0, 1], atol=1e-6)
    assert 14 * (1 - POLY) - 1e-6 <= h.diameter <= 14 + 1e-6
    z = surf.evaluate(np.array([0.4]), np.array([30 / 80]))[0]   # S(u, v) at the hole's centre
    np.testing.assert_allclose(h.center, z, atol=1e-6)


def test_near_picks_the_closest_feature_of_the_type_and_unknown_ids_list_what_exists():
    feats = model_features(bracket())
    assert find_feature(feats, near=[60, 25, 0], kind="hole").id == "hole:1"
    assert find_feature(feats, near=[33, 41, 5], kind="hole").id == "hole:0"
    assert find_feature(feats, near=[70, 60, 10], kind="cylinder").id == "face:3"
    with pytest.raises(ValueError, match=r"no feature 'hole:7'.*hole:0, hole:1"):
        find_feature(feats, "hole:7", kind="hole")
    with pytest.raises(ValueError, match="no cylinder"):
        find_feature(model_features(bracket(boss=None)), near=[0, 0, 0], kind="cylinder")


def test_features_table_is_json_ready_and_ids_are_stable():
    rows = features_table(bracket())
    text = json.dumps(rows)
    assert json.loads(text) == rows
    assert [r["id"] for r in rows] == [r["id"] for r in features_table(bracket())]
    assert {"id", "kind", "face", "name", "center", "axis", "diameter"} <= set(rows[0])


def test_mesh_models_have_no_features():
    mesh = Model(kind="mesh", vertices=np.eye(3), triangles=np.array([[0, 1, 2]]))
    with pytest.raises(ValueError, match="CAD model"):
        model_features(mesh)
