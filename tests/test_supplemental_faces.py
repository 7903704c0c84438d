"""Supplemental geometry is not the part (NIST FTC 10, CTC 04).

NIST FTC 10 holds, after its solid's 264 faces, 18 faces in open shells (thread cylinders and
planes, up to 1.25 mm off the solid); CTC 04 an open shell 'Fill.1' (face 483).  They keep
their numbers (PMI is tied to them) but a scan of the manufactured part never holds them: no
model point may lie on them, and a dent of the solid under one must be measured against the
solid, not against the supplemental surface beside it (where it read 0.25 mm instead of 1 mm).

The oracles are OpenCASCADE's: which faces belong to a solid (``TopExp_Explorer`` over the
solid), the distance of a point to the solid (``BRepExtrema_DistShapeShape``), and a scan drawn
on ``BRepMesh_IncrementalMesh``'s tessellation of the solid alone (``independent_scans``).
"""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("OCP")

from independent_scans import bump, random_points, read_shape, scan, tessellate  # noqa: E402
from model_cache import cached_model, cached_prepared  # noqa: E402

DATA = Path(__file__).parent / "data" / "nist_extra"


@pytest.fixture(scope="module")
def ftc10(tmp_path_factory):
    p = tmp_path_factory.mktemp("ftc10") / "nist_ftc_10_asme1_ap242-e2.stp"
    with gzip.open(DATA / "nist_ftc_10_asme1_ap242-e2.stp.gz", "rb") as src:
        p.write_bytes(src.read())
    return p


def _occ_faces(shape):
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    out, e = [], TopExp_Explorer(shape, TopAbs_FACE)
    while e.More():
        out.append(TopoDS.Face(e.Current()))
        e.Next()
    return out


def _solid(shape):
    from OCP.TopAbs import TopAbs_SOLID
    from OCP.TopExp import TopExp_Explorer

    e = TopExp_Explorer(shape, TopAbs_SOLID)
    solid = e.Current()
    e.Next()
    assert not e.More(), "FTC 10 holds one solid"
    return solid


def _dist(p, shape) -> float:
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape
    from OCP.gp import gp_Pnt

    d = BRepExtrema_DistShapeShape(BRepBuilderAPI_MakeVertex(gp_Pnt(*map(float, p))).Vertex(),
                                   shape)
    d.Perform()
    return d.Value()


def _face_grid(face, n=5):
    """n x n points of an OCC face's parameter box (its surface, trims ignored)."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface

    ad = BRepAdaptor_Surface(face)
    u = np.linspace(ad.FirstUParameter(), ad.LastUParameter(), n + 2)[1:-1]
    v = np.linspace(ad.FirstVParameter(), ad.LastVParameter(), n + 2)[1:-1]
    return np.array([ad.Value(a, b).Coord() for a in u for b in v])


def test_ftc10_supplemental_faces_keep_their_numbers_outside_the_solid(ftc10):
    model = cached_model(ftc10)
    shape = read_shape(ftc10)
    faces = _occ_faces(shape)
    in_solid = _occ_faces(_solid(shape))
    outside = [i for i, f in enumerate(faces) if not any(f.IsSame(g) for g in in_solid)]
    assert len(faces) == 282 and len(outside) == 18
    assert len(model.faces) == len(faces)              # numbering unchanged: one per OCC face
    assert list(model.supplemental) == outside == list(range(264, 282))
    assert model.part_faces() == tuple(range(264))
    # face i of the model is OpenCASCADE's face i: a point inside it lies on that face
    for i in (0, 100, 263, 264, 270, 281):
        f = model.faces[i]
        (a0, a1), (b0, b1) = f.uv_bounds
        g = np.stack(np.meshgrid(np.linspace(a0, a1, 15), np.linspace(b0, b1, 15)), -1)
        g = g.reshape(-1, 2)
        uv = g[f.contains(g)][:1]
        assert len(uv), i
        assert _dist(f.evaluate(uv)[0], faces[i]) < 1e-6 * model.size, i


def test_ctc04_fill_shell_is_supplemental(tmp_path):
    """CTC 04's open shell 'Fill.1' (face 483, after the solid's 483 faces)."""
    p = tmp_path / "nist_ctc_04_asme1_ap242-e1.stp"
    with gzip.open(DATA / "nist_ctc_04_asme1_ap242-e1.stp.gz", "rb") as src:
        p.write_bytes(src.read())
    model = cached_model(p)
    shape = read_shape(p)
    faces = _occ_faces(shape)
    in_solid = _occ_faces(_solid(shape))
    outside = [i for i, f in enumerate(faces) if not any(f.IsSame(g) for g in in_solid)]
    assert len(model.faces) == len(faces) == 484
    assert list(model.supplemental) == outside == [483]


@pytest.mark.slow
def test_ftc10_model_points_all_lie_on_the_solid(ftc10):
    prep = cached_prepared(ftc10, spacing=1.0)
    model = prep.model
    P, F = np.asarray(prep.points.points), np.asarray(prep.points.face)
    assert not np.isin(F, model.supplemental).any()
    shape = read_shape(ftc10)
    solid = _solid(shape)
    faces = _occ_faces(shape)
    # the model points nearest to the supplemental faces (where a point on them would be), and
    # a random few elsewhere: every one on the solid, by OpenCASCADE
    from scipy.spatial import cKDTree

    S = np.vstack([_face_grid(faces[i]) for i in model.supplemental])
    near = np.unique(cKDTree(P).query(S, k=2)[1].ravel())
    pick = np.union1d(near, np.random.default_rng(3).choice(len(P), 100, replace=False))
    d = np.array([_dist(P[i], solid) for i in pick])
    assert d.max() <= 1e-6 * model.size, (d.max(), P[pick[np.argmax(d)]])
    # and the structure never answers with a supplemental face, even for points on them
    near_sup = prep.closest(S)
    assert not np.isin(near_sup.face, model.supplemental).any()


@pytest.mark.slow  # 4.3 s of CPU with numba's cache warm (quick tests: under ~3 s)
def test_ftc10_dent_under_a_supplemental_thread_face_is_found(ftc10):
    """A 1 mm dent of the tapped hole's wall towards face 265 (a thread cylinder 1.25 mm away,
    inside the material): measured against the supplemental face it read about 0.25 mm."""
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.TopAbs import TopAbs_IN
    from OCP.gp import gp_Pnt

    import shapeverify as sv

    shape = read_shape(ftc10)
    solid = _solid(shape)
    faces = _occ_faces(shape)
    # the point of face 265 farthest from the solid among a grid, and the solid's point under it
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape

    best = None
    for p in _face_grid(faces[265], 3):
        d = BRepExtrema_DistShapeShape(BRepBuilderAPI_MakeVertex(gp_Pnt(*p)).Vertex(), solid)
        d.Perform()
        if best is None or d.Value() > best[0]:
            best = (d.Value(), p, np.array(d.PointOnShape2(1).Coord()))
    gap, sup_pt, centre = best
    assert 1.2 < gap < 1.3
    cls = BRepClass3d_SolidClassifier(solid, gp_Pnt(*sup_pt), 1e-7)
    inside = cls.State() == TopAbs_IN            # the thread's major cylinder is in the material
    depth = -1.0 if inside else 1.0              # towards the supplemental surface

    V, T, _ = tessellate(solid, 0.005)
    rng = np.random.default_rng(7)
    X = scan(V, T, "random", 0.5, rng, noise=0.005, dents=[(centre, depth, 1.5)])
    prep = cached_prepared(ftc10, spacing=1.0)
    res = sv.inspect(prep, X, tolerance=0.2)
    T_ms = res.registration.T_model_scan
    assert np.abs(T_ms[:3, :3] - np.eye(3)).max() < 1e-3 and np.abs(T_ms[:3, 3]).max() < 0.01
    # the points of the dent's core (bump over 0.85 mm), measured: their bump, to 0.05 mm
    # (against the supplemental face they read 1.25 mm less)
    P, _ = random_points(V, T, 0.5, np.random.default_rng(7))  # the scan's points, undented
    assert len(P) == len(X)
    core = np.flatnonzero(np.linalg.norm(P - centre, axis=1) < 0.25 * 1.5)
    assert core.size >= 3
    want = bump(P[core], centre, depth, 1.5)
    vals = res.deviations.values[core]
    assert np.all(np.abs(vals - want) < 0.05), (vals, want)
    assert res.verdict == "fail"
    dents = [r for r in res.regions if np.linalg.norm(r.centroid - centre) < 1.5]
    # the region's extreme (its peak as the region measures estimate it, 0.91 here) is the
    # dent's depth, not the 0.25 mm left to the supplemental surface
    assert dents and 0.85 < dents[0].extreme / depth < 1.05, res.regions[:3]


def _plane_face(z, size=10.0):
    from shapeverify.cad.model import Face
    from shapeverify.cad.nurbs import NurbsSurface

    ctrl = np.array([[[0, 0, z], [0, size, z]], [[size, 0, z], [size, size, z]]], float)
    surf = NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1], ctrl)
    return Face(surf, (np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float),),
                (np.ones(4, bool),))


def test_supplemental_face_is_numbered_but_never_sampled_nor_answered(tmp_path):
    """A plate z = 0 (the part) and a supplemental plate z = 1 above it: every model point on
    z = 0, points on the upper plate are 1 mm from the part, the face keeps number 1 through a
    save and load, and `faces=` refuses it."""
    import shapeverify as sv
    from shapeverify.cad.model import Model
    from shapeverify.cad.summary import summarize

    m = Model((_plane_face(0.0), _plane_face(1.0)), source="plates", supplemental=(1,))
    assert m.part_faces() == (0,) and "supplemental=1" in repr(m)
    np.testing.assert_allclose(m.bounds, [[0, 0, 0], [10, 10, 0]], atol=1e-12)
    mp = m.sample(0.5)
    assert len(mp) > 300 and np.all(mp.face == 0) and np.all(mp.points[:, 2] == 0.0)
    prep = sv.prepare(m, spacing=0.5)
    q = np.column_stack([np.random.default_rng(1).uniform(1, 9, (50, 2)), np.full(50, 1.0)])
    near = prep.closest(q)
    assert np.all(near.face == 0)
    np.testing.assert_allclose(near.distances, 1.0, atol=1e-9)
    m.save(tmp_path / "plates.svmodel")
    back = sv.load_model(tmp_path / "plates.svmodel")
    assert back.supplemental == (1,) and len(back.faces) == 2
    assert summarize(back).supplemental == (1,)
    from rich.console import Console

    from shapeverify.cli import model_summary_table

    con = Console(width=200, record=True)
    con.print(model_summary_table(back, "plates"))
    text = con.export_text()
    assert "supplemental faces" in text and "1 (faces 1: outside the solid" in text
    with pytest.raises(ValueError, match="supplemental"):
        sv.inspect(prep, q - [0, 0, 1.0], tolerance=0.1, faces=[1])
    with pytest.raises(ValueError, match="supplemental"):
        Model((_plane_face(0.0),), source="x", supplemental=(0,))
    with pytest.raises(ValueError, match="supplemental"):
        Model((_plane_face(0.0),), source="x", supplemental=(3,))


@pytest.mark.parametrize("name", ["wavy-cube.stp", "hammer.iges"])
def test_a_surface_model_has_no_supplemental_faces(shared_data, name):
    """Files of faces without a solid: every face is the part, as before."""
    p = shared_data / "cad" / name
    if not p.exists():
        pytest.skip(f"{name} not in the shared data")
    m = cached_model(p)
    assert m.supplemental == () and len(m.part_faces()) == len(m.faces)
