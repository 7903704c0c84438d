"""STEP/IGES import (cad/occ_import.py) checked against OpenCASCADE itself as the oracle.

Files come from two places: parts the tests build and write with OCP (always run), and the real
files in ../shared/data/cad (skipped when that folder is absent).
"""

from __future__ import annotations

import logging
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from shapeverify.cad.examples import PANEL_HOLE, PANEL_SIZE, example_part_step, panel_shape
from shapeverify.cad.model import Model
from shapeverify.cad.occ_import import read_cad
from shapeverify.errors import (CADImportError, EmptyModelError, ShapeVerifyError,
                                UnsupportedFormatError)

OCP = pytest.importorskip("OCP")
from OCP.BRep import BRep_Tool  # noqa: E402
from OCP.BRepBuilderAPI import (BRepBuilderAPI_MakeFace, BRepBuilderAPI_MakePolygon,  # noqa: E402
                                BRepBuilderAPI_MakeVertex, BRepBuilderAPI_NurbsConvert)
from OCP.BRepClass3d import BRepClass3d_SolidClassifier  # noqa: E402
from OCP.BRepPrimAPI import (BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCone,  # noqa: E402
                             BRepPrimAPI_MakeCylinder, BRepPrimAPI_MakeRevol,
                             BRepPrimAPI_MakeSphere, BRepPrimAPI_MakeTorus)
from OCP.BRepTools import BRepTools  # noqa: E402
from OCP.Geom import Geom_BSplineSurface, Geom_CylindricalSurface  # noqa: E402
from OCP.gp import gp_Ax1, gp_Ax3, gp_Dir, gp_Pnt, gp_Pnt2d, gp_Vec  # noqa: E402
from OCP.IFSelect import IFSelect_RetDone  # noqa: E402
from OCP.IGESControl import IGESControl_Reader, IGESControl_Writer  # noqa: E402
from OCP.Interface import Interface_Static  # noqa: E402
from OCP.IntTools import IntTools_FClass2d  # noqa: E402
from OCP.Message import Message, Message_PrinterOStream  # noqa: E402
from OCP.STEPControl import STEPControl_AsIs, STEPControl_Reader, STEPControl_Writer  # noqa: E402
from OCP.TopAbs import TopAbs_FACE, TopAbs_IN, TopAbs_ON, TopAbs_OUT  # noqa: E402
from OCP.TopExp import TopExp_Explorer  # noqa: E402
from OCP.TopoDS import TopoDS, TopoDS_Compound  # noqa: E402
from OCP.BRep import BRep_Builder  # noqa: E402

Message.DefaultMessenger_s().RemovePrinters(Message_PrinterOStream.get_type_descriptor_s())

SHARED_FILES = {"impeller.igs": 277, "hammer.iges": 45, "wavy-cube.stp": 6}
# the 4 MB impeller (277 faces) takes a few seconds per test: marked slow
SHARED_NAMES = [pytest.param(n, marks=pytest.mark.slow) if n == "impeller.igs" else n
                for n in sorted(SHARED_FILES)]
CHORD_TOL = 0.002  # read_cad's default


# ------------------------------------------------------------------------------- OCP helpers
def write_step(shape, path, unit="MM"):
    Interface_Static.SetCVal_s("write.step.unit", unit)
    try:
        w = STEPControl_Writer()
        w.Transfer(shape, STEPControl_AsIs)
        assert w.Write(str(path)) == IFSelect_RetDone
    finally:
        Interface_Static.SetCVal_s("write.step.unit", "MM")
    return Path(path)


def write_iges(shape, path, unit="MM", mode=0):
    w = IGESControl_Writer(unit, mode)
    w.AddShape(shape)
    w.ComputeModel()
    assert w.Write(str(path))
    return Path(path)


def occ_read(path):
    path = str(path)
    r = STEPControl_Reader() if path.lower().endswith((".stp", ".step")) else IGESControl_Reader()
    assert r.ReadFile(path) == IFSelect_RetDone
    r.TransferRoots()
    return r.OneShape()


def occ_faces(shape, nurbs=True):
    """Faces in TopExp_Explorer order; with nurbs=True non-B-spline faces are NurbsConverted
    (the parameter space read_cad's loops live in)."""
    out = []
    e = TopExp_Explorer(shape, TopAbs_FACE)
    while e.More():
        f = TopoDS.Face(e.Current())
        if nurbs and not isinstance(BRep_Tool.Surface_s(f), Geom_BSplineSurface):
            f = TopoDS.Face(BRepBuilderAPI_NurbsConvert(f, True).Shape())
        out.append(f)
        e.Next()
    return out


def compound(shapes):
    c = TopoDS_Compound()
    b = BRep_Builder()
    b.MakeCompound(c)
    for s in shapes:
        b.Add(c, s)
    return c


def samples_on_face(face, n, rng):
    """Random (u, v) on a model face (inside its trims), at most n."""
    (a0, a1), (b0, b1) = face.uv_bounds
    (u0, u1), (v0, v1) = face.surface.domain
    uv = np.column_stack([rng.uniform(max(a0, u0), min(a1, u1), 8 * n),
                          rng.uniform(max(b0, v0), min(b1, v1), 8 * n)])
    return uv[face.contains(uv)][:n]


_cache: dict = {}


def load_shared(shared_data, name):
    if name not in _cache:
        _cache[name] = read_cad(shared_data / "cad" / name)
    return _cache[name]


# ------------------------------------------------------------------------ real shared files
@pytest.mark.parametrize("name", SHARED_NAMES)
def test_face_counts_match_opencascade(shared_data, name):
    model = load_shared(shared_data, name)
    n_occ = len(occ_faces(occ_read(shared_data / "cad" / name), nurbs=False))
    assert len(model.faces) == n_occ == SHARED_FILES[name]
    assert model.kind == "cad" and model.source.endswith(name)


@pytest.mark.parametrize("name, unit", [
    pytest.param("impeller.igs", "MM", marks=pytest.mark.slow), ("hammer.iges", "MM"),
    ("wavy-cube.stp", "millimetre")])
def test_units_and_bounds_of_the_shared_files(shared_data, name, unit):
    """The declared unit is reported; the bounds lie inside OCP's box (which OCP takes over each
    face's untrimmed (u, v) rectangle) and contain a dense sample of every trimmed face."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    model = load_shared(shared_data, name)
    assert (model.unit, model.scale_to_mm) == (unit, 1.0)
    box = Bnd_Box()
    BRepBndLib.AddOptimal_s(occ_read(shared_data / "cad" / name), box, False, False)
    occ = np.array([box.CornerMin().Coord(), box.CornerMax().Coord()])
    eps = 1e-9 * model.size
    slack = 1e-6 + 1e-8 * model.size  # OCP's optimal box is itself approximate
    assert np.all(model.bounds[0] >= occ[0] - slack) and np.all(model.bounds[1] <= occ[1] + slack)
    rng = np.random.default_rng(1)
    pts = np.concatenate([face.evaluate(samples_on_face(face, 400, rng)) for face in model.faces])
    assert np.all(pts >= model.bounds[0] - eps) and np.all(pts <= model.bounds[1] + eps)
    # and they are tight: no more than 1 % of the size beyond the sample
    assert np.all(pts.min(axis=0) - model.bounds[0] < 0.01 * model.size)
    assert np.all(model.bounds[1] - pts.max(axis=0) < 0.01 * model.size)


@pytest.mark.parametrize("name", SHARED_NAMES)
def test_contains_agrees_with_occ_classifier(shared_data, name):
    """>= 99.9 % agreement with IntTools_FClass2d on every face (1000 samples per face)."""
    model = load_shared(shared_data, name)
    faces = occ_faces(occ_read(shared_data / "cad" / name))
    rng = np.random.default_rng(2011)
    n = 1000
    total_bad = 0
    for i, (occ_face, face) in enumerate(zip(faces, model.faces)):
        u0, u1, v0, v1 = BRepTools.UVBounds_s(occ_face)
        uv = np.column_stack([rng.uniform(u0, u1, n), rng.uniform(v0, v1, n)])
        classifier = IntTools_FClass2d(occ_face, 1e-7)
        state = [classifier.Perform(gp_Pnt2d(float(a), float(b))) for a, b in uv]
        occ_in = np.array([s == TopAbs_IN for s in state])
        on = np.array([s == TopAbs_ON for s in state])
        bad = int(np.count_nonzero((face.contains(uv) != occ_in) & ~on))
        assert bad <= n // 1000, f"face {i}: {bad} of {n} samples disagree with OCP"
        total_bad += bad
    assert total_bad / (n * len(faces)) <= 1e-3


@pytest.mark.parametrize("name", SHARED_NAMES)
def test_nurbs_kernel_matches_occ_d2(shared_data, name):
    """Our NurbsSurface.derivatives(order=2) vs Geom_BSplineSurface.D2 on every face.

    Relative error 1e-9, relative to the size of the terms summed in the evaluation: for the
    (a, b)-th derivative max(|that order's derivatives over the face|, max|S| / (h_u^a h_v^b))
    with h the mean knot span (rational second derivatives of faces tens of metres from the
    origin lose digits to cancellation in both OCP and our kernel).
    """
    model = load_shared(shared_data, name)
    faces = occ_faces(occ_read(shared_data / "cad" / name))
    rng = np.random.default_rng(7)
    n = 40
    worst = 0.0
    p, d1u, d1v, d2u, d2v, d2uv = gp_Pnt(), gp_Vec(), gp_Vec(), gp_Vec(), gp_Vec(), gp_Vec()
    for occ_face, face in zip(faces, model.faces):
        srf = BRep_Tool.Surface_s(occ_face)
        s = face.surface
        (u0, u1), (v0, v1) = s.domain
        u, v = rng.uniform(u0, u1, n), rng.uniform(v0, v1, n)
        ours = s.derivatives(u, v, order=2)
        occ = np.empty((n, 6, 3))
        for k in range(n):
            srf.D2(float(u[k]), float(v[k]), p, d1u, d1v, d2u, d2v, d2uv)
            occ[k] = [p.Coord(), d1u.Coord(), d1v.Coord(), d2u.Coord(), d2v.Coord(), d2uv.Coord()]
        idx = [(0, 0), (1, 0), (0, 1), (2, 0), (0, 2), (1, 1)]
        mine = np.stack([ours[:, a, b] for a, b in idx], axis=1)
        err = np.linalg.norm(mine - occ, axis=2)
        mag = np.linalg.norm(occ, axis=2)
        hu = (u1 - u0) / max(1, np.unique(s.knots_u[s.degree_u:s.control.shape[0] + 1]).size - 1)
        hv = (v1 - v0) / max(1, np.unique(s.knots_v[s.degree_v:s.control.shape[1] + 1]).size - 1)
        smax = mag[:, 0].max()
        den = np.array([max(smax, mag[:, [q for q, (a2, b2) in enumerate(idx)
                                          if a2 + b2 == a + b]].max(), smax / (hu ** a * hv ** b))
                        if a + b else smax for a, b in idx])
        worst = max(worst, float((err / den).max()))
    assert worst <= 1e-9, worst


@pytest.mark.slow
def test_free_edges_of_shared_files(shared_data):
    # wavy-cube is a closed STEP solid: no free edge
    cube = load_shared(shared_data, "wavy-cube.stp")
    assert sum(int(f.sum()) for face in cube.faces for f in face.loop_free) == 0
    # the impeller is a closed part exported as unsewn IGES faces: its edges are all "free" in
    # the file's topology, but (nearly) every one touches a neighbouring face
    imp = load_shared(shared_data, "impeller.igs")
    flags = np.concatenate([f for face in imp.faces for f in face.loop_free])
    assert flags.mean() < 2e-3


# ------------------------------------------------------------------ parts the tests write
def _check_panel_holes(model, holes, rng, n=20_000, margin=0.05):
    """contains() is False inside the holes, True elsewhere on the panel (by 3D position)."""
    assert len(model.faces) == 1
    face = model.faces[0]
    assert len(face.loops) == 1 + len(holes)
    (u0, u1), (v0, v1) = face.surface.domain
    uv = np.column_stack([rng.uniform(u0, u1, n), rng.uniform(v0, v1, n)])
    xyz = face.evaluate(uv)
    L, W = PANEL_SIZE
    in_hole = np.zeros(n, bool)
    clear = (np.minimum(xyz[:, 0], L - xyz[:, 0]) > margin) & \
            (np.minimum(xyz[:, 1], W - xyz[:, 1]) > margin)
    for x, y, r in holes:
        d = np.hypot(xyz[:, 0] - x, xyz[:, 1] - y)
        in_hole |= d < r
        clear &= np.abs(d - r) > margin
    got = face.contains(uv)
    assert in_hole[clear].sum() > 100 and (~in_hole[clear]).sum() > 1000
    np.testing.assert_array_equal(got[clear], ~in_hole[clear])
    assert all(f.all() for f in face.loop_free)  # a single sheet: every edge is free


@pytest.mark.parametrize("fmt", ["step", "iges"])
def test_two_hole_patch_round_trip(tmp_path, fmt):
    holes = [(80.0, 70.0, 20.0), (215.0, 125.0, 30.0)]
    shape = panel_shape(holes)
    path = (write_step(shape, tmp_path / "two_holes.step") if fmt == "step"
            else write_iges(shape, tmp_path / "two_holes.igs"))
    model = read_cad(path)
    _check_panel_holes(model, holes, np.random.default_rng(3))
    # and the OCP classifier agrees on the file as read back
    occ_face = occ_faces(occ_read(path))[0]
    face = model.faces[0]
    u0, u1, v0, v1 = BRepTools.UVBounds_s(occ_face)
    rng = np.random.default_rng(4)
    uv = np.column_stack([rng.uniform(u0, u1, 3000), rng.uniform(v0, v1, 3000)])
    cl = IntTools_FClass2d(occ_face, 1e-7)
    st = [cl.Perform(gp_Pnt2d(float(a), float(b))) for a, b in uv]
    occ_in = np.array([s == TopAbs_IN for s in st])
    on = np.array([s == TopAbs_ON for s in st])
    assert np.mean((face.contains(uv) == occ_in) | on) >= 0.999


def test_example_part(example_step, tmp_path):
    model = read_cad(example_step)
    assert (model.unit, model.scale_to_mm) == ("millimetre", 1.0)
    _check_panel_holes(model, [PANEL_HOLE], np.random.default_rng(5))
    lo, hi = model.bounds
    np.testing.assert_allclose([lo[0], lo[1], hi[0], hi[1]], [0, 0, *PANEL_SIZE], atol=1e-6)
    assert 5.0 < hi[2] - lo[2] < 40.0  # gentle waves
    again = example_part_step(tmp_path / "again.step")
    assert again.read_bytes() == Path(example_step).read_bytes()  # deterministic


def _revolved_spline():
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeWire
    from OCP.collections import Array1_gp_Pnt
    from OCP.GeomAPI import GeomAPI_PointsToBSpline

    pts = Array1_gp_Pnt(1, 5)
    for i, (x, z) in enumerate([(10, 0), (14, 5), (11, 10), (15, 15), (12, 20)]):
        pts.SetValue(i + 1, gp_Pnt(x, 0, z))
    curve = GeomAPI_PointsToBSpline(pts).Curve()
    e1 = BRepBuilderAPI_MakeEdge(curve).Edge()
    e2 = BRepBuilderAPI_MakeEdge(gp_Pnt(12, 0, 20), gp_Pnt(0, 0, 20)).Edge()
    e3 = BRepBuilderAPI_MakeEdge(gp_Pnt(0, 0, 20), gp_Pnt(0, 0, 0)).Edge()
    e4 = BRepBuilderAPI_MakeEdge(gp_Pnt(0, 0, 0), gp_Pnt(10, 0, 0)).Edge()
    wire = BRepBuilderAPI_MakeWire(e1, e2, e3, e4).Wire()
    face = BRepBuilderAPI_MakeFace(wire).Face()
    return BRepPrimAPI_MakeRevol(face, gp_Ax1(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1))).Shape()


SOLIDS = {
    "box": lambda: BRepPrimAPI_MakeBox(30.0, 20.0, 10.0).Shape(),
    "cylinder": lambda: BRepPrimAPI_MakeCylinder(10.0, 20.0).Shape(),
    "sphere": lambda: BRepPrimAPI_MakeSphere(12.0).Shape(),
    "cone": lambda: BRepPrimAPI_MakeCone(10.0, 4.0, 15.0).Shape(),
    "torus": lambda: BRepPrimAPI_MakeTorus(20.0, 6.0).Shape(),
    "revolution": _revolved_spline,
}


@pytest.mark.parametrize("fmt", ["step", "iges"])
@pytest.mark.parametrize("name", sorted(SOLIDS))
def test_analytic_faces_become_nurbs_on_the_solid_and_outward(tmp_path, name, fmt):
    """Every face (planes, cylinders, cones, spheres, tori, surfaces of revolution) is converted;
    model points lie on the solid's boundary and normals point out of it."""
    solid = SOLIDS[name]()
    path = (write_step(solid, tmp_path / f"{name}.step") if fmt == "step"
            else write_iges(solid, tmp_path / f"{name}.igs"))
    model = read_cad(path)
    assert len(model.faces) == len(occ_faces(occ_read(path), nurbs=False))
    classifier = BRepClass3d_SolidClassifier(solid)
    rng = np.random.default_rng(6)
    for i, face in enumerate(model.faces):
        uv = samples_on_face(face, 12, rng)
        assert uv.shape[0] >= 6, f"face {i}: too few samples inside its trims"
        pts, nrm = face.evaluate(uv), face.normal(uv)
        for x, n in zip(pts, nrm):
            states = []
            for off in (0.0, 1e-3, -1e-3):
                q = x + off * n
                classifier.Perform(gp_Pnt(*map(float, q)), 1e-6)
                states.append(classifier.State())
            assert states == [TopAbs_ON, TopAbs_OUT, TopAbs_IN], (i, x, states)


def test_face_straddling_the_seam_of_a_periodic_surface(tmp_path):
    # a 2-radian strip of a cylinder centred on the seam u = 0 of its periodic parameter
    cyl = Geom_CylindricalSurface(gp_Ax3(), 10.0)
    face = BRepBuilderAPI_MakeFace(cyl, -1.0, 1.0, 0.0, 15.0, 1e-7).Face()
    model = read_cad(write_step(face, tmp_path / "strip.step"))
    f = model.faces[0]
    rng = np.random.default_rng(8)
    (u0, u1), (v0, v1) = f.surface.domain
    uv = np.column_stack([rng.uniform(u0, u1, 4000), rng.uniform(v0, v1, 4000)])
    xyz = f.evaluate(uv)
    np.testing.assert_allclose(np.hypot(xyz[:, 0], xyz[:, 1]), 10.0, atol=1e-9)
    ang = np.arctan2(xyz[:, 1], xyz[:, 0])
    inside = f.contains(uv)
    clear = (np.abs(np.abs(ang) - 1.0) > 1e-4) & (np.abs(xyz[:, 2] - 7.5) < 7.5 - 1e-4)
    np.testing.assert_array_equal(inside[clear], (np.abs(ang) < 1.0)[clear])
    assert inside.sum() > 500


@pytest.mark.parametrize("a0", [0.0, np.pi / 2, 2.0])
def test_full_cylinder_with_its_seam_anywhere(tmp_path, a0):
    """A full cylinder face with u in [a0, a0 + 2 pi] and two holes: the trims match the geometry.
    (NurbsConvert leaves the outer wire of such a face offset from the converted domain when
    a0 != 0; read_cad moves it back.)"""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
    from OCP.gp import gp_Ax2

    face = BRepBuilderAPI_MakeFace(Geom_CylindricalSurface(gp_Ax3(), 10.0), a0,
                                   a0 + 2 * np.pi, 0.0, 15.0, 1e-7).Face()
    tool = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(-20, 0, 7.5), gp_Dir(1, 0, 0)), 3.0, 40.0)
    shape = BRepAlgoAPI_Cut(face, tool.Shape()).Shape()
    model = read_cad(write_step(shape, tmp_path / "cyl.step"))
    assert len(model.faces) == 1
    f = model.faces[0]
    (u0, u1), (v0, v1) = f.surface.domain
    rng = np.random.default_rng(10)
    uv = np.column_stack([rng.uniform(u0, u1, 20_000), rng.uniform(v0, v1, 20_000)])
    xyz = f.evaluate(uv)
    d = np.hypot(xyz[:, 1], xyz[:, 2] - 7.5)  # distance to the holes' axis
    clear = np.abs(d - 3.0) > 2.5 * CHORD_TOL  # the polygonised hole is within CHORD_TOL
    np.testing.assert_array_equal(f.contains(uv)[clear], (d >= 3.0)[clear])


@pytest.mark.parametrize("fmt", ["step", "iges"])
def test_free_edges_of_an_open_box(tmp_path, fmt):
    """An open box (5 faces, no lid): exactly the rim is free.  The IGES file's faces are not
    sewn, so there the shared edges are found geometrically."""
    box = BRepPrimAPI_MakeBox(40.0, 30.0, 20.0).Shape()
    faces = [f for f in occ_faces(box, nurbs=False) if not _is_top(f, 20.0)]
    assert len(faces) == 5
    shape = compound(faces)
    path = (write_step(shape, tmp_path / "open.step") if fmt == "step"
            else write_iges(shape, tmp_path / "open.igs"))
    model = read_cad(path)
    assert len(model.faces) == 5
    n_rim = 0
    for face in model.faces:
        for lp, free in zip(face.loops, face.loop_free):
            a = face.evaluate(lp)
            mid = 0.5 * (a + np.roll(a, -1, axis=0))
            on_rim = np.abs(mid[:, 2] - 20.0) < 1e-6
            np.testing.assert_array_equal(free, on_rim)
            n_rim += int(on_rim.sum())
    assert n_rim >= 4


def _is_top(face, z):
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.SurfaceProperties_s(face, props)
    return abs(props.CentreOfMass().Z() - z) < 1e-9


def test_trimming_loops_are_within_the_chordal_tolerance(tmp_path, example_step):
    """Every loop segment's midpoint (mapped to 3D) lies within chord_tol of the true edges."""
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape

    rng = np.random.default_rng(9)
    for path in (example_step, write_step(SOLIDS["sphere"](), tmp_path / "s.step"),
                 write_step(SOLIDS["revolution"](), tmp_path / "r.step")):
        model = read_cad(path)
        for occ_face, face in zip(occ_faces(occ_read(path)), model.faces):
            (u0, u1), (v0, v1) = face.surface.domain
            for lp in face.loops:
                pick = rng.choice(lp.shape[0], size=min(60, lp.shape[0]), replace=False)
                nxt = np.roll(lp, -1, axis=0)
                mid_uv = 0.5 * (lp[pick] + nxt[pick])
                mid_uv[:, 0] = np.clip(mid_uv[:, 0], u0, u1)
                mid_uv[:, 1] = np.clip(mid_uv[:, 1], v0, v1)
                a, b = face.evaluate(lp[pick]), face.evaluate(nxt[pick])
                edges = compound(_edges(occ_face))
                for q in np.concatenate([face.evaluate(mid_uv), 0.5 * (a + b)]):
                    v = BRepBuilderAPI_MakeVertex(gp_Pnt(*map(float, q))).Vertex()
                    dist = BRepExtrema_DistShapeShape(v, edges).Value()
                    assert dist <= 1.5 * CHORD_TOL, (path, dist)


def _edges(face):
    from OCP.TopAbs import TopAbs_EDGE

    out = []
    e = TopExp_Explorer(face, TopAbs_EDGE)
    while e.More():
        out.append(e.Current())
        e.Next()
    return out


@pytest.mark.parametrize("write_unit, unit, scale", [
    ("M", "metre", 1000.0), ("CM", "centimetre", 10.0), ("INCH", "INCH", 25.4),
    ("MM", "millimetre", 1.0)])
def test_step_units_are_read_and_converted_to_mm(tmp_path, write_unit, unit, scale):
    path = write_step(BRepPrimAPI_MakeBox(100.0, 50.0, 20.0).Shape(), tmp_path / "box.step",
                      unit=write_unit)
    model = read_cad(path)
    assert model.unit.lower() == unit.lower() and model.scale_to_mm == pytest.approx(scale)
    np.testing.assert_allclose(model.bounds, [[0, 0, 0], [100, 50, 20]], atol=1e-6)


@pytest.mark.parametrize("write_unit, unit, scale", [
    ("M", "M", 1000.0), ("IN", "INCH", 25.4), ("CM", "CM", 10.0), ("MM", "MM", 1.0)])
def test_iges_units_are_read_and_converted_to_mm(tmp_path, write_unit, unit, scale):
    path = write_iges(BRepPrimAPI_MakeBox(100.0, 50.0, 20.0).Shape(), tmp_path / "box.igs",
                      unit=write_unit)
    # the file really holds the unit's numbers: 100 mm = 0.1 m is written as 0.1
    model = read_cad(path)
    assert (model.unit, model.scale_to_mm) == (unit, pytest.approx(scale))
    np.testing.assert_allclose(model.bounds, [[0, 0, 0], [100, 50, 20]], atol=1e-6)


# -------------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("suffix, fmt", [(".step", "STEP"), (".stp", "STEP"), (".igs", "IGES"),
                                         (".iges", "IGES")])
def test_corrupt_file_raises(tmp_path, suffix, fmt):
    path = tmp_path / f"garbage{suffix}"
    path.write_bytes(np.random.default_rng(0).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    with pytest.raises(CADImportError, match=f"{path.name}: not a readable {fmt} file"):
        read_cad(path)


def test_truncated_iges_raises(tmp_path):
    full = write_iges(panel_shape(), tmp_path / "full.igs")
    data = full.read_bytes()
    path = tmp_path / "truncated.igs"
    path.write_bytes(data[: len(data) // 3])
    with pytest.raises(CADImportError, match="truncated.igs"):
        read_cad(path)


@pytest.mark.parametrize("suffix", [".step", ".iges"])
def test_empty_file_raises(tmp_path, suffix):
    path = tmp_path / f"empty{suffix}"
    path.write_bytes(b"")
    with pytest.raises(CADImportError, match=r"empty.*: the file is empty \(0 bytes\)"):
        read_cad(path)


def test_unsupported_extension_raises(tmp_path):
    path = tmp_path / "part.dwg"
    path.write_bytes(b"not a CAD format we read")
    with pytest.raises(UnsupportedFormatError, match=r"part\.dwg.*'\.dwg'.*\.iges.*\.step"):
        read_cad(path)


def test_missing_file_raises(tmp_path):
    path = tmp_path / "nowhere.step"
    with pytest.raises(FileNotFoundError, match="nowhere.step") as info:
        read_cad(path)
    assert info.value.filename == str(path)


@pytest.mark.parametrize("what", ["wire", "vertex"])
@pytest.mark.parametrize("fmt", ["step", "iges"])
def test_file_without_faces_raises(tmp_path, what, fmt):
    if what == "wire":
        poly = BRepBuilderAPI_MakePolygon(gp_Pnt(0, 0, 0), gp_Pnt(10, 0, 0), gp_Pnt(10, 10, 0),
                                          True)
        shape = poly.Wire()
    else:
        shape = BRepBuilderAPI_MakeVertex(gp_Pnt(1, 2, 3)).Vertex()
    path = (write_step(shape, tmp_path / f"{what}.step") if fmt == "step"
            else write_iges(shape, tmp_path / f"{what}.igs"))
    with pytest.raises(EmptyModelError, match=f"{what}.*holds no"):
        read_cad(path)


def test_step_without_entities_raises(tmp_path):
    path = tmp_path / "nodata.step"
    path.write_text("ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\nENDSEC;\nEND-ISO-10303-21;\n")
    with pytest.raises(EmptyModelError, match="nodata.step: the STEP file holds no shapes"):
        read_cad(path)


def test_errors_share_a_base_class_and_bad_options_are_rejected(example_step):
    for cls in (CADImportError, EmptyModelError, UnsupportedFormatError):
        assert issubclass(cls, ShapeVerifyError) and issubclass(cls, ValueError)
    with pytest.raises(ValueError, match="chord_tol"):
        read_cad(example_step, chord_tol=0.0)
    with pytest.raises(ValueError, match="gap_tol"):
        read_cad(example_step, gap_tol=float("nan"))


# ----------------------------------------------------------------------- console and logging
@pytest.mark.slow
def test_opencascade_console_output_is_silenced(tmp_path):
    good = write_iges(panel_shape(), tmp_path / "panel.igs")
    bad = tmp_path / "bad.step"
    bad.write_bytes(b"ISO-10303-21;\nHEADER;\nthis is not step\n" * 50)
    script = (
        "import sys\n"
        "from shapeverify.cad.occ_import import read_cad\n"
        f"read_cad({str(good)!r})\n"
        "try:\n"
        f"    read_cad({str(bad)!r})\n"
        "except Exception as e:\n"
        "    pass\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout == "" and out.stderr == ""


def test_import_logs_face_count_unit_and_time(example_step, caplog):
    with caplog.at_level(logging.INFO, logger="shapeverify.cad.occ_import"):
        model = read_cad(example_step)
    assert isinstance(model, Model)
    msg = " ".join(r.getMessage() for r in caplog.records)
    assert "1 faces" in msg and "millimetre" in msg and "total" in msg


# ------------------------------------- damaged files: the project's errors, never a dead process
def _without_line(src: Path, dst: Path, start: bytes) -> Path:
    lines = src.read_bytes().splitlines(keepends=True)
    keep = [ln for ln in lines if not ln.startswith(start)]
    assert len(keep) == len(lines) - 1, f"no single line starts with {start!r}"
    dst.write_bytes(b"".join(keep))
    return dst


def test_a_crash_of_opencascade_is_a_cad_import_error_and_the_importer_comes_back(
        example_step, tmp_path):
    # without the entity line of one pcurve OpenCASCADE 8.0.1 dies with SIGSEGV
    bad = _without_line(example_step, tmp_path / "no-pcurve.step", b"#682 = LINE(")
    with pytest.raises(CADImportError, match=r"no-pcurve\.step: the CAD importer crashed .*signal "
                                             r"11, SIGSEGV"):
        read_cad(bad)
    model = read_cad(example_step)  # a new importer process: the next file reads normally
    assert len(model.faces) == 1 and model.n_faces_in_file == 1


def test_exceptions_raised_by_opencascade_become_cad_import_errors(example_step, monkeypatch):
    from OCP.Standard import Standard_Failure

    import shapeverify.cad.occ_import as occ_import

    def fails(*args):
        raise Standard_Failure("BRep_API: command not done")

    monkeypatch.setattr(occ_import, "_read_cad_here", fails)
    with pytest.raises(CADImportError, match=r"panel\.step: OpenCASCADE could not read the file "
                                             r"\(Standard_Failure: BRep_API: command not done\)"):
        read_cad(example_step, isolated=False)


def test_an_import_that_does_not_finish_in_time_is_stopped(example_step):
    with pytest.raises(CADImportError, match=r"panel\.step: the CAD importer did not finish "
                                             r"within 0\.001 s"):
        read_cad(example_step, timeout=0.001)
    assert len(read_cad(example_step).faces) == 1
    with pytest.raises(ValueError, match="timeout"):
        read_cad(example_step, timeout=0)


@pytest.mark.parametrize("fmt", ["step", "iges"])
def test_undamaged_files_have_all_their_declared_faces(tmp_path, example_step, fmt):
    from shapeverify.cad.face_count import declared_faces

    box = BRepPrimAPI_MakeBox(10.0, 20.0, 30.0).Shape()
    files = ([write_step(box, tmp_path / "box.step"), example_step] if fmt == "step" else
             [write_iges(box, tmp_path / "box.igs"), write_iges(box, tmp_path / "brep.igs", mode=1),
              write_iges(panel_shape(), tmp_path / "panel.igs")])
    for path in files:
        model = read_cad(path)
        n_occ = len(occ_faces(occ_read(path), nurbs=False))
        assert declared_faces(path, fmt)[0] == n_occ == len(model.faces) == model.n_faces_in_file
        assert model.skipped_faces == () and model.n_missing_faces == 0


@pytest.mark.parametrize("name", SHARED_NAMES)
def test_shared_files_have_all_their_declared_faces(shared_data, name):
    model = load_shared(shared_data, name)
    assert model.n_faces_in_file == len(model.faces) == SHARED_FILES[name]


def test_a_dangling_face_reference_is_warned_and_counted(tmp_path, caplog):
    step = write_step(BRepPrimAPI_MakeBox(10.0, 20.0, 30.0).Shape(), tmp_path / "box.step")
    text = step.read_text()
    face = re.findall(r"#(\d+) = ADVANCED_FACE", text)[2]
    bad = _without_line(step, tmp_path / "dangling.step", f"#{face} = ADVANCED_FACE".encode())
    with caplog.at_level(logging.WARNING, logger="shapeverify"):
        model = read_cad(bad)
    assert len(model.faces) == 5 and model.n_faces_in_file == 6 and model.n_missing_faces == 1
    shell = re.search(r"#(\d+) = CLOSED_SHELL", text).group(1)
    assert model.skipped_faces == (f"#{face}: listed by CLOSED_SHELL #{shell} but not defined in "
                                   "the file",)
    warned = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert any("1 of the 6 faces in the file were not loaded" in m and f"#{face}" in m
               for m in warned), warned
    assert "of 6 in the file" in repr(model)


def test_a_face_that_fails_to_convert_is_skipped_and_named(tmp_path, monkeypatch, caplog):
    import shapeverify.cad.occ_import as occ_import

    step = write_step(BRepPrimAPI_MakeBox(10.0, 20.0, 30.0).Shape(), tmp_path / "box.step")
    real = occ_import._face_loops

    def loops(work, face, conv, surface, edge_faces, tol, index, path):
        if index == 2:
            raise CADImportError(f"{path}: face 2 has no usable trimming loop")
        return real(work, face, conv, surface, edge_faces, tol, index, path)

    monkeypatch.setattr(occ_import, "_face_loops", loops)
    with caplog.at_level(logging.WARNING, logger="shapeverify"):
        model = read_cad(step, isolated=False)
    assert len(model.faces) == 5 and model.n_faces_in_file == 6
    assert model.skipped_faces == ("face 2: face 2 has no usable trimming loop",)
    assert any("face 2" in r.getMessage() for r in caplog.records)
    monkeypatch.setattr(occ_import, "_face_loops", lambda *a: (_ for _ in ()).throw(
        CADImportError("bad")))
    with pytest.raises(CADImportError, match="none of the 6 faces could be converted"):
        read_cad(step, isolated=False)
