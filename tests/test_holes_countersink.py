"""A circular edge that is the rim of a countersink or a fillet is not an opening (issue 27).

On NIST FTC 06 (a 25.4 mm countersink rim, 29.2 and 38.1 mm filleted rims) the hole measurement
read such an edge from where the scan's points "stop", found the cone or the fillet still
inside the circle, and reported diameters 8-22 mm too small as measurements, with a U of
0.1-1 mm.  Such an edge now says why it cannot be measured (the plan marks it not measured); the
hole's own cylindrical wall is still measured.  The part is built with OpenCASCADE and scanned
independently of the project's sampler (its tessellation sampled uniformly by area, 0.02 mm
noise along the normal).
"""
from __future__ import annotations

import numpy as np
import pytest

from independent_scans import read_shape, random_points, tessellate


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    """80 x 40 x 10 plate: at x=20 a Ø10 hole with a 90° countersink to Ø20 at the top, at
    x=60 a Ø10 hole whose top edge is filleted with radius 3 (rim Ø16)."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
    from OCP.BRepFilletAPI import BRepFilletAPI_MakeFillet
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCone, BRepPrimAPI_MakeCylinder
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.GeomAbs import GeomAbs_Circle
    from OCP.TopoDS import TopoDS

    import shapeverify as sv
    from shapeverify.characteristics.features import model_features

    up = gp_Dir(0, 0, 1)
    s = BRepPrimAPI_MakeBox(80.0, 40.0, 10.0).Shape()
    for x in (20.0, 60.0):
        s = BRepAlgoAPI_Cut(s, BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(x, 20, -1), up), 5.0,
                                                         12.0).Shape()).Shape()
    # the countersink: a cone from Ø20 at z=10 down to Ø10 at z=5 (90° included angle)
    s = BRepAlgoAPI_Cut(s, BRepPrimAPI_MakeCone(gp_Ax2(gp_Pnt(20, 20, 5.0), up), 5.0, 10.0,
                                                5.0).Shape()).Shape()
    s = BRepAlgoAPI_Cut(s, BRepPrimAPI_MakeCone(gp_Ax2(gp_Pnt(20, 20, 10.0), up), 10.0, 11.0,
                                                1.0).Shape()).Shape()
    fil = BRepFilletAPI_MakeFillet(s)
    exp = TopExp_Explorer(s, TopAbs_EDGE)
    while exp.More():
        e = TopoDS.Edge(exp.Current())
        exp.Next()
        c = BRepAdaptor_Curve(e)
        if c.GetType() == GeomAbs_Circle:
            circ = c.Circle()
            p = circ.Location()
            if abs(circ.Radius() - 5.0) < 1e-6 and abs(p.X() - 60) < 1e-6 and abs(p.Z() - 10) < 1e-6:
                fil.Add(3.0, e)
    s = fil.Shape()
    path = tmp_path_factory.mktemp("csk") / "plate.step"
    w = STEPControl_Writer()
    w.Transfer(s, STEPControl_AsIs)
    w.Write(str(path))
    model = sv.load_model(path)
    m = getattr(model, "model", model)
    prep = sv.prepare(model, spacing=1.0)
    V, T, _ = tessellate(read_shape(path), 0.002)
    rng = np.random.default_rng(7)
    P, N = random_points(V, T, 0.5, rng)
    X = (P + rng.normal(0.0, 0.02, len(P))[:, None] * N)[rng.permutation(len(P))]
    return prep, model_features(m), X


def _hole(feats, x, dia):
    hs = [f for f in feats if f.kind == "hole" and abs(f.center[0] - x) < 1e-6
          and abs(f.diameter - dia) < 1e-6]
    assert hs, [(f.id, f.center, f.diameter) for f in feats if f.kind == "hole"]
    return hs[0]


@pytest.mark.parametrize("x, rim", [(20.0, 20.0), (60.0, 16.0)])
def test_the_rim_of_a_countersink_or_fillet_is_not_measured_as_a_hole(plate, x, rim):
    from shapeverify.characteristics.holes import measure_hole

    prep, feats, X = plate
    f = _hole(feats, x, rim)
    cl = prep.closest(X, exact=True)
    with pytest.raises(ValueError, match="countersink, chamfer or fillet"):
        measure_hole(X, f.center, f.axis, f.diameter, face=prep.model.faces[f.face],
                     deviations=cl.distances, normals=cl.normals)


@pytest.mark.parametrize("x", [20.0, 60.0])
def test_the_cylindrical_wall_under_the_rim_is_still_measured(plate, x):
    from shapeverify.characteristics.holes import measure_hole

    prep, feats, X = plate
    f = _hole(feats, x, 10.0)
    cl = prep.closest(X, exact=True)
    hm = measure_hole(X, f.center, f.axis, f.diameter, face=prep.model.faces[f.face],
                      deviations=cl.distances, normals=cl.normals)
    assert hm.method.startswith("wall")
    assert abs(hm.diameter - 10.0) <= 0.05
