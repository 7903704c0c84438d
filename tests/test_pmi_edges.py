"""PMI attached to edges (issue 28; NIST CTC 02: the position, perpendicularity and diameters
of holes point at a hole's rim circle, not its wall): the edge is mapped to the feature it
bounds by OpenCASCADE topology, checked here on shapes built with OCP whose faces are known."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from shapeverify.cad import occ_import as oi
from shapeverify.cad.pmi import _FaceIndex
from shapeverify.cad.pmi_edges import edge_feature, edge_record


def _faces(shape):
    return oi._shape_faces(Path("t.stp"), "step", shape)


def _block_with_hole(split: bool):
    """A 40 x 30 x 20 block with a through hole of radius 5 along z at (20, 15); ``split``: the
    block is two 10 mm slabs glued, so the hole's wall is two faces."""
    from OCP.BOPAlgo import BOPAlgo_Builder
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCylinder
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt

    cyl = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(20, 15, -5), gp_Dir(0, 0, 1)), 5.0, 30.0).Shape()
    if not split:
        return BRepAlgoAPI_Cut(BRepPrimAPI_MakeBox(40.0, 30.0, 20.0).Shape(), cyl).Shape()
    slabs = [BRepAlgoAPI_Cut(BRepPrimAPI_MakeBox(gp_Pnt(0, 0, z), 40.0, 30.0, 10.0).Shape(),
                             cyl).Shape() for z in (0.0, 10.0)]
    b = BOPAlgo_Builder()
    for s in slabs:
        b.AddArgument(s)
    b.Perform()
    return b.Shape()


def _edges(shape):
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer

    out, exp = [], TopExp_Explorer(shape, TopAbs_EDGE)
    while exp.More():
        out.append(exp.Current())
        exp.Next()
    return out


def _cyl_faces(faces):
    from shapeverify.cad.pmi_edges import _surface_kind

    return [i for i, f in enumerate(faces) if _surface_kind(f)[0] == "Cylinder"]


def _setup(split):
    from shapeverify.cad._occ_loops import _edge_face_map

    oi._init_ocp()
    shape = _block_with_hole(split)
    faces = _faces(shape)
    return shape, faces, _FaceIndex(faces), _edge_face_map(shape)


@pytest.mark.parametrize("split", [False, True], ids=["one_wall_face", "wall_in_two_faces"])
def test_rim_circle_of_a_hole_maps_to_the_whole_hole_wall(split):
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.GeomAbs import GeomAbs_Circle
    from OCP.TopoDS import TopoDS

    shape, faces, index, emap = _setup(split)
    walls = _cyl_faces(faces)
    assert len(walls) == (2 if split else 1)
    top = [e for e in _edges(shape)
           if BRepAdaptor_Curve(TopoDS.Edge(e)).GetType() == GeomAbs_Circle
           and abs(BRepAdaptor_Curve(TopoDS.Edge(e)).Circle().Location().Z() - 20.0) < 1e-9]
    assert top
    rec = edge_record(top[0], index, emap, faces)
    assert rec["curve"] == "Circle" and rec["radius"] == pytest.approx(5.0)
    assert np.allclose(rec["centre"][:2], [20.0, 15.0])
    assert sorted(rec["kinds"]) == ["Cylinder", "Plane"]
    got, how, why = edge_feature([rec], faces, emap, index)
    assert why == "" and how == "circular edge (\u230010) of the cylinder it bounds"
    assert got == sorted(walls)     # both halves of a split wall: one hole


def test_straight_edge_between_two_planes_is_not_mapped_and_says_between_which_faces():
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.GeomAbs import GeomAbs_Line
    from OCP.TopoDS import TopoDS

    shape, faces, index, emap = _setup(False)
    line = next(e for e in _edges(shape)
                if BRepAdaptor_Curve(TopoDS.Edge(e)).GetType() == GeomAbs_Line)
    rec = edge_record(line, index, emap, faces)
    got, how, why = edge_feature([rec], faces, emap, index)
    assert got == [] and how == ""
    assert f"face {rec['faces'][0]} (Plane) and face {rec['faces'][1]} (Plane)" in why


def test_line_drawn_on_a_face_names_the_face_it_lies_on():
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge
    from OCP.gp import gp_Pnt

    shape, faces, index, emap = _setup(False)
    # a line across the top face (z = 20), clear of the hole: bounds no face of the block
    e = BRepBuilderAPI_MakeEdge(gp_Pnt(2.0, 2.0, 20.0), gp_Pnt(2.0, 28.0, 20.0)).Edge()
    from OCP.BRepAdaptor import BRepAdaptor_Surface

    rec = edge_record(e, index, emap, faces)
    assert rec["faces"] == []
    assert len(rec["on_faces"]) == 1
    top = BRepAdaptor_Surface(faces[rec["on_faces"][0]]).Plane().Location().Z()
    assert top == pytest.approx(20.0)
    _, _, why = edge_feature([rec], faces, emap, index)
    assert f"drawn on face {rec['on_faces'][0]}" in why


def _block_with_hole_cut_aslant(deg: float):
    """The block with its hole (one wall face), its top cut by a plane tilted ``deg`` about x
    through (20, 15, 18): the hole's top rim is not a circle (an ellipse, or a B-spline in a
    CAD export: NIST FTC 07 DIM15)."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
    from OCP.gp import gp_Ax1, gp_Dir, gp_Pnt, gp_Trsf
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Transform

    big = BRepPrimAPI_MakeBox(gp_Pnt(-50, -50, 18.0), 140.0, 130.0, 50.0).Shape()
    t = gp_Trsf()
    t.SetRotation(gp_Ax1(gp_Pnt(20, 15, 18.0), gp_Dir(1, 0, 0)), np.radians(deg))
    big = BRepBuilderAPI_Transform(big, t, True).Shape()
    return BRepAlgoAPI_Cut(_block_with_hole(False), big).Shape()


def test_rim_of_a_hole_cut_aslant_by_a_plane_maps_to_the_hole_wall():
    """FTC 07 DIM15 (⌀22.225 on a B-spline edge between its cylinder and a plane) was "not
    the rim of a cylinder": an edge around a cylinder where a plane cuts it is its rim; a
    straight edge between that plane and a side face is still not mapped."""
    from shapeverify.cad._occ_loops import _edge_face_map

    oi._init_ocp()
    shape = _block_with_hole_cut_aslant(1.0)
    faces = _faces(shape)
    index, emap = _FaceIndex(faces), _edge_face_map(shape)
    walls = _cyl_faces(faces)
    recs = [edge_record(e, index, emap, faces) for e in _edges(shape)]
    rims = [r for r in recs if sorted(r["kinds"]) == ["Cylinder", "Plane"]
            and r["curve"] not in ("Circle", "Line")
            and min(p[2] for p in r["points"]) > 17.0]
    assert rims and all(r["curve"] != "Circle" for r in rims)
    for r in rims:
        P = np.asarray(r["points"])
        assert np.ptp(P[:, 2]) > 0.05                    # not in a plane square to the axis
        got, how, why = edge_feature([r], faces, emap, index)
        assert why == "" and got == walls
        assert how.startswith(f"edge ({r['curve']}) around the \u230010 cylinder")
    line = next(r for r in recs if r["curve"] == "Line" and "Cylinder" not in r["kinds"])
    assert edge_feature([line], faces, emap, index)[0] == []
