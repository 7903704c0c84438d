"""A linear distance whose sides are straight edges between two planar faces (NIST CTC 05
DIM24: 127 ±0.2032 between the top face's edges with its two side faces, x = ±63.5): each
side becomes the face of its edge that, with the other side, makes two parallel planes the
nominal apart (:func:`shapeverify.characteristics.pmi_dimensions._edge_sides`)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from shapeverify.characteristics.pmi_dimensions import between_entries


def _plane(c, n):
    return SimpleNamespace(kind="plane", center=np.asarray(c, float), axis=np.asarray(n, float))


def _ctx():
    feats = {0: _plane([0, 9, 279.4], [0, 0, 1]), 74: _plane([63.5, 23, 200], [1, 0, 0]),
             77: _plane([-63.5, 23, 206], [-1, 0, 0]), 5: _plane([0, 0, 0], [0, 0, -1])}
    return SimpleNamespace(fmap={k: k for k in feats}, feats=feats, size=300.0,
                           model=SimpleNamespace(size=300.0))


def _item(nominal, e1=(0, 77), e2=(0, 74)):
    def edge(f):
        return [{"curve": "Line", "faces": list(f), "kinds": ["Plane", "Plane"]}]

    return {"id": "DIM24", "type": "Location_LinearDistance", "nominal": nominal,
            "lower": -0.2032, "upper": 0.2032, "modifiers": [], "faces": [], "faces2": [],
            "other": ["edge", "edge"], "edges": edge(e1), "edges2": edge(e2),
            "edge_reason": "it is attached to an edge (Line) between face 0 (Plane) and face 77"}


def test_distance_between_two_straight_edges_is_between_their_parallel_faces_nominal_apart():
    got, why = between_entries(_item(127.0), _ctx(), {"id": "DIM24"}, lambda n: n)
    assert why == "" and len(got) == 1
    e = got[0]
    assert e["type"] == "distance" and e["faces"] == ["face:77", "face:74"]
    assert (e["nominal"], e["lower"], e["upper"]) == (127.0, -0.2032, 0.2032)
    assert e["pmi"]["attached"] == "the parallel planar faces of its straight edges"


def test_edges_whose_faces_are_not_the_nominal_apart_keep_the_edge_reason():
    got, why = between_entries(_item(120.0), _ctx(), {"id": "DIM24"}, lambda n: n)
    assert got == [] and why.startswith("it is not between two faces (its first side: it is "
                                        "attached to an edge (Line)")
    # the top face (on both edges) and face 5 under it are parallel too, 279.4 apart: a
    # nominal of 279.4 with the edge [0, 77] against [5, 74] is one choice only
    got, why = between_entries(_item(279.4, e2=(5, 74)), _ctx(), {"id": "X"}, lambda n: n)
    assert why == "" and got[0]["faces"] == ["face:0", "face:5"]


def test_side_at_the_circle_where_a_hole_meets_its_drill_point_is_a_depth_to_that_circle():
    """FTC 06 DIM49 (12.7 ±1.27 from face 125 to where the ⌀6.35 hole's wall, face 20, meets
    its drill point, face 18) said "not the rim of a cylinder", then "no characteristic for a
    distance to such a circle yet"; it is now a ``distance`` whose second side is
    ``{cylinder, cone}``.  A plane not square to the hole's axis, or a nominal off the CAD's
    depth by more than the limits, keeps it unsupported with that reason; an edge that is not
    square to the cylinder's axis keeps the reader's reason."""
    t = np.linspace(0.0, np.pi, 9)
    ring = np.column_stack([76.2 + 3.175 * np.cos(t), np.full(9, 72.39),
                            -158.75 + 3.175 * np.sin(t)])
    rec = {"curve": "BSplineCurve", "faces": [18, 20], "kinds": ["Cone", "Cylinder"],
           "cylinders": {20: [[76.2, 85.09, -158.75], [0.0, -1.0, 0.0], 3.175]},
           "points": ring.tolist()}
    ctx = _ctx()
    ctx.feats[125] = _plane([70.0, 85.09, -150.0], [0, 1, 0])
    ctx.fmap.update({125: 125, 18: 18, 20: 20, 265: 265, 19: 19})
    item = {"id": "DIM49", "type": "Location_LinearDistance", "nominal": 12.7, "lower": -1.27,
            "upper": 1.27, "modifiers": [], "faces": [125], "faces2": [], "other": ["edge"],
            "edges2": [rec], "edge_reason2": "the reader's reason"}
    src = {"kind": "dimension", "type": "Location_LinearDistance", "id": "DIM49"}
    got, why = between_entries(item, ctx, src, lambda n: n)
    assert why == "" and len(got) == 1, why
    e = got[0]
    assert e["type"] == "distance" and e["name"] == "DIM49_distance"
    assert e["faces"] == ["face:125", {"cylinder": "face:20", "cone": "face:18"}]
    assert (e["nominal"], e["lower"], e["upper"]) == (12.7, -1.27, 1.27)
    assert "cad_distance" not in e["pmi"]              # 85.09 - 72.39 = 12.7 exactly
    from shapeverify.characteristics.plan import load_plan

    plan = load_plan({"characteristics": got})          # the schema takes the circle side
    assert plan.characteristics[0].faces[1].cone == "face:18"
    # FTC 10 DIM16: the circle in two halves (two cone faces) and edges of thread faces on it
    other = {"curve": "BSplineCurve", "faces": [265], "kinds": ["Cylinder"],
             "cylinders": {265: [[76.2, 85.09, -158.75], [0.0, 1.0, 0.0], 3.175]},
             "points": ring[::-1].tolist()}
    half = {**rec, "faces": [19, 20], "points": (ring * [1, 1, -1] + [0, 0, -317.5]).tolist()}
    got2, _ = between_entries({**item, "edges2": [other, rec, half]}, ctx, {}, lambda n: n)
    assert got2[0]["faces"][1] == {"cylinder": "face:20", "cone": ["face:18", "face:19"]}
    # the nominal off the CAD's depth by more than the limits; a tilted plane
    got, why = between_entries({**item, "nominal": 15.0}, ctx, {}, lambda n: n)
    assert got == [] and "the nominal depth 15 differs from the CAD's 12.7000 mm" in why
    ctx.feats[125] = _plane([70.0, 85.09, -150.0], [0, np.cos(0.01), np.sin(0.01)])
    got, why = between_entries(item, ctx, {}, lambda n: n)
    assert got == [] and "the plane is 0.573 deg from square to the hole's axis" in why
    ring[:, 1] += 0.2 * np.sin(t)                       # not in a plane square to the axis
    rec["points"] = ring.tolist()
    got, why = between_entries(item, ctx, {"id": "DIM49"}, lambda n: n)
    assert why == "it is not between two faces (its second side: the reader's reason)"
