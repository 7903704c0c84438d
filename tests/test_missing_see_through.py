"""Issue 33 row 3, by default: a hole the CAD does not have is a ``missing`` region when the scan
sees through it (scan points behind the CAD surface, inside its footprint); surface that was only
not seen (the back of a one-sided scan, random dropouts) is no ``missing`` region.

The part is made with OpenCASCADE (a 120 x 80 x 10 mm plate, two through holes, Ø12 and Ø16
mm) and the scans are drawn on OpenCASCADE's tessellation of the *holed* plate by
``tests/independent_scans`` (uniform by area), independently of the project's sampling and
simulator; the CAD the scans are inspected against is the plate without the holes.  The hole
areas are the analytic ``pi r^2``.
"""

import numpy as np
import pytest

import shapeverify as sv

pytest.importorskip("OCP")

from independent_scans import random_points, tessellate  # noqa: E402

HOLES = ((40.0, 40.0, 6.0), (85.0, 35.0, 8.0))          # x, y, radius
SPACING = 0.8
TOL = 0.1


@pytest.fixture(scope="module")
def plates(tmp_path_factory):
    """(prepared plate without holes, tessellation (V, T) of the plate with the holes, of the
    plate without)."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCylinder
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer

    d = tmp_path_factory.mktemp("plate")
    box = BRepPrimAPI_MakeBox(120.0, 80.0, 10.0).Shape()
    w = STEPControl_Writer()
    w.Transfer(box, STEPControl_AsIs)
    w.Write(str(d / "plate.step"))
    holed = box
    for x, y, r in HOLES:
        cyl = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(x, y, -1), gp_Dir(0, 0, 1)), r, 12.0).Shape()
        holed = BRepAlgoAPI_Cut(holed, cyl).Shape()
    prep = sv.prepare(sv.load_model(d / "plate.step"), spacing=1.0)
    Vh, Th, _ = tessellate(holed, 0.005)
    Vb, Tb, _ = tessellate(BRepPrimAPI_MakeBox(120.0, 80.0, 10.0).Shape(), 0.005)
    return prep, (Vh, Th), (Vb, Tb)


def _scan(VT, seed, up_only=False):
    V, T = VT
    rng = np.random.default_rng(seed)
    tris = None
    if up_only:   # one side only: the triangles facing up or sideways, never the back face
        a, b, c = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
        nz = np.cross(b - a, c - a)
        nz = nz[:, 2] / np.maximum(np.linalg.norm(nz, axis=1), 1e-300)
        tris = np.flatnonzero(nz > -0.5)
    P, N = random_points(V, T, SPACING, rng, tris=tris)
    P = P + N * rng.normal(0.0, 0.02, (len(P), 1))
    return P[rng.permutation(len(P))]


def _missing(res):
    return [r for r in res.regions if r.kind == "missing"]


def test_holes_the_cad_does_not_have_are_missing_regions_by_default(plates):
    prep, holed, _ = plates
    res = sv.inspect(prep, _scan(holed, 1), tolerance=TOL, init=np.eye(4))
    assert str(res.verdict) == "fail" and res.rule == "regions"
    miss = _missing(res)
    for x, y, r in HOLES:
        for z in (0.0, 10.0):          # the through hole is seen through on both faces
            at = [m for m in miss if np.hypot(m.centroid[0] - x, m.centroid[1] - y) < 1.0
                  and abs(m.centroid[2] - z) < 1.0]
            assert len(at) == 1, ([(m.centroid, m.area) for m in miss], x, y, z)
            hole_area = np.pi * r * r
            assert abs(at[0].area - hole_area) <= 0.2 * hole_area, (at[0].area, hole_area)
    assert len(miss) == 2 * len(HOLES)
    assert any("sees" in s and "through" in s for s in res.reasons)


def test_back_face_never_seen_is_not_missing(plates):
    prep, _, box = plates
    res = sv.inspect(prep, _scan(box, 2, up_only=True), tolerance=TOL, init=np.eye(4))
    assert not _missing(res)
    assert str(res.verdict) in ("pass", "incomplete"), res.reasons
    assert res.coverage.fraction < 0.75          # the back face (40 % of the area) was not seen


def test_random_dropouts_of_a_good_part_are_not_missing(plates):
    prep, _, box = plates
    P = _scan(box, 3)
    rng = np.random.default_rng(4)
    keep = np.ones(len(P), bool)
    top = np.flatnonzero(np.abs(P[:, 2] - 10.0) < 0.2)
    for c in P[rng.choice(top, 25, replace=False)]:   # 25 dropouts of 1.5-3 mm radius on top
        keep &= np.linalg.norm(P - c, axis=1) > rng.uniform(1.5, 3.0)
    res = sv.inspect(prep, P[keep], tolerance=TOL, init=np.eye(4))
    assert not _missing(res)
    assert str(res.verdict) == "pass", res.reasons


def test_holed_plate_scanned_from_one_side_is_missing_on_the_seen_face(plates):
    prep, holed, _ = plates
    res = sv.inspect(prep, _scan(holed, 5, up_only=True), tolerance=TOL, init=np.eye(4))
    miss = _missing(res)
    assert str(res.verdict) == "fail"
    for x, y, r in HOLES:
        at = [m for m in miss if np.hypot(m.centroid[0] - x, m.centroid[1] - y) < 1.0
              and abs(m.centroid[2] - 10.0) < 1.0]
        assert len(at) == 1 and abs(at[0].area - np.pi * r * r) <= 0.2 * np.pi * r * r
    assert all(abs(m.centroid[2] - 10.0) < 1.0 for m in miss)   # the unseen back: no region
