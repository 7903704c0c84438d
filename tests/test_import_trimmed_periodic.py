"""A face on a Geom_RectangularTrimmedSurface over a U-periodic B-spline, trimmed from a hair
before the period's start (u = -1.8e-15), made ``BRepBuilderAPI_NurbsConvert`` raise
``Standard_OutOfRange: NCollection_Array1::at``: NIST CTC 02 lost faces 35 and 361 (0.4 % of
its area each) and ``prepare`` refused the file.  The import now takes the trimmed surface's
B-spline basis (same parametrisation, so the face's own pcurves stay valid)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from shapeverify.cad import occ_import as oi


def _hair_trimmed_cylinder(u0: float = -1.7763568394002505e-15):
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
    from OCP.Geom import Geom_CylindricalSurface, Geom_RectangularTrimmedSurface
    from OCP.GeomConvert import GeomConvert
    from OCP.gp import gp_Ax3, gp_Dir, gp_Pnt

    cyl = Geom_CylindricalSurface(gp_Ax3(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), 10.0)
    bs = GeomConvert.SurfaceToBSplineSurface_s(
        Geom_RectangularTrimmedSurface(cyl, 0, 2 * np.pi, 0, 1))
    assert bs.IsUPeriodic()
    surf = Geom_RectangularTrimmedSurface(bs, u0, 2 * np.pi, 0.0, 1.0)
    return BRepBuilderAPI_MakeFace(surf, 1e-7).Face(), surf


def test_face_trimmed_a_hair_before_a_periodic_bspline_start_is_imported_exactly():
    oi._init_ocp()
    face, gsurf = _hair_trimmed_cylinder()
    work, surface, conv = oi._face_surface(face, 0, Path("hair.stp"))
    rng = np.random.default_rng(1)
    u, v = rng.uniform(0, 2 * np.pi, 300), rng.uniform(0, 1, 300)
    ours = surface.evaluate(u, v)
    occ = np.array([gsurf.Value(a, b).Coord() for a, b in zip(u, v)])
    assert np.abs(ours - occ).max() < 1e-9
    uv, xyz, _, _, _ = oi._face_loops(work, face, conv, surface, None, 0.002, 0, Path("h.stp"))
    P = np.concatenate(xyz)
    # the loop runs round the whole cylinder (radius 10, z 0..1) on the surface
    assert np.abs(np.linalg.norm(P[:, :2], axis=1) - 10.0).max() < 1e-9
    assert np.ptp(np.concatenate(uv)[:, 0]) == pytest.approx(2 * np.pi, abs=1e-9)
    assert P[:, 2].min() == pytest.approx(0.0, abs=1e-12)
    assert P[:, 2].max() == pytest.approx(1.0, abs=1e-12)


def test_trimmed_bspline_basis_cuts_a_non_periodic_direction_to_the_trim():
    from OCP.Geom import Geom_RectangularTrimmedSurface

    oi._init_ocp()
    _, gsurf = _hair_trimmed_cylinder()
    part = Geom_RectangularTrimmedSurface(gsurf.BasisSurface(), 0.0, 2 * np.pi, 0.25, 0.75)
    basis = oi._trimmed_bspline_basis(part)
    u0, u1, v0, v1 = basis.Bounds()
    assert (v0, v1) == pytest.approx((0.25, 0.75))
    assert (u0, u1) == pytest.approx((0.0, 2 * np.pi))
    for a, b in [(0.3, 0.3), (4.0, 0.7)]:
        assert np.allclose(basis.Value(a, b).Coord(), part.Value(a, b).Coord(), atol=1e-12)


@pytest.mark.slow
@pytest.mark.shared
def test_ctc02_imports_all_487_faces_with_faces_35_and_361_sampled_by_their_area(shared_data):
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    from model_cache import cached_model

    path = shared_data / "cad/nist/nist_ctc_02_asme1_ap242-e1.stp"
    # load_model's import, built once per suite run for every CTC 02 module (tests/model_cache.py)
    model = cached_model(path)
    assert len(model.faces) == model.n_faces_in_file == 487
    assert model.skipped_faces == ()
    shape = oi._read_shape_named(path, "step")[0]
    faces = oi._shape_faces(path, "step", shape)
    pts = model.sample(1.0, rng=np.random.default_rng(0))
    count = np.bincount(np.asarray(pts.face), minlength=len(faces))
    for i in (35, 361):
        g = GProp_GProps()
        BRepGProp.SurfaceProperties_s(faces[i], g)
        assert g.Mass() == pytest.approx(10078.17, rel=1e-4)
        # 1 mm spacing: about one point per mm^2 (the whole part: median 0.99)
        assert 0.9 < count[i] / g.Mass() < 1.1
