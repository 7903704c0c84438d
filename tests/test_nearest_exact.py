"""Exact mode is exact: the global closest point on the trimmed model (issue 18 item 2).

Oracles: analytic closest points on a model built to defeat the seeded search (faces whose
model points are thinned away), a brute-force all-faces point inversion from dense samples,
and OpenCASCADE's ``BRepExtrema_DistShapeShape`` on the impeller's original faces.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from shapeverify.cad.model import Face, Model
from shapeverify.cad.nurbs import NurbsSurface, cylinder
from shapeverify.nearest import prepare
from shapeverify.nearest._exact_kernels import newton_face

RECT = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def _plane(p00, pu, pv) -> NurbsSurface:
    p00, pu, pv = (np.asarray(a, float) for a in (p00, pu, pv))
    ctrl = np.array([[p00, p00 + pv], [p00 + pu, p00 + pu + pv]])
    return NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1], ctrl)


# ---------------------------------------------------- a model that defeats the seeds
def _tabs_model():
    """A 20 x 20 mm plate (z = 0), 16 small tabs 0.3 x 0.3 mm floating 0.15 mm above it and
    4 small vertical fins, all rectangles (pu orthogonal to pv), and a cylinder post r = 1,
    z in [0, 3].  At spacing 0.5 the tabs and fins lose (almost) all their model points to the
    plate's in the cross-face thinning, so no seed reaches them."""
    rects = [([0, 0, 0], [20, 0, 0], [0, 20, 0])]
    for x in (3.0, 7.0, 11.0, 15.0):
        for y in (2.0, 6.0, 10.0, 14.0):
            rects.append(([x, y, 0.15], [0.3, 0, 0], [0, 0.3, 0]))
    for x in (5.0, 9.0, 13.0, 17.0):
        rects.append(([x, 17.0, 0.05], [0, 0.3, 0], [0, 0, 0.3]))
    faces = [Face(_plane(*r), (RECT,), (np.ones(4, bool),)) for r in rects]
    faces.append(Face(cylinder(1.0, 3.0, center=(17.0, 4.0, 0.0)), (RECT,),
                      (np.array([True, False, True, False]),)))
    return Model(faces=tuple(faces), source="plate with tabs"), rects


def _analytic(q, rects, post=((17.0, 4.0), 1.0, 3.0)):
    """Closest distance from each query to the rectangles and the post's lateral face."""
    best = np.full(q.shape[0], np.inf)
    for p00, pu, pv in rects:
        p00, pu, pv = (np.asarray(a, float) for a in (p00, pu, pv))
        u = np.clip((q - p00) @ pu / (pu @ pu), 0, 1)
        v = np.clip((q - p00) @ pv / (pv @ pv), 0, 1)
        foot = p00 + u[:, None] * pu + v[:, None] * pv
        best = np.minimum(best, np.linalg.norm(q - foot, axis=1))
    (cx, cy), r, h = post
    rho = np.hypot(q[:, 0] - cx, q[:, 1] - cy)
    dz = q[:, 2] - np.clip(q[:, 2], 0, h)
    return np.minimum(best, np.hypot(rho - r, dz))


@pytest.fixture(scope="module")
def tabs():
    model, rects = _tabs_model()
    return prepare(model, spacing=0.5, reach=2.0), rects


def _tab_queries(rng, n):
    # over the tabs and fins (and around the post), 0.02 .. 1.5 mm up
    k = rng.integers(0, 3, n)
    tab = np.column_stack([rng.choice([3.0, 7.0, 11.0, 15.0], n) + rng.uniform(-0.3, 0.6, n),
                           rng.choice([2.0, 6.0, 10.0, 14.0], n) + rng.uniform(-0.3, 0.6, n),
                           rng.uniform(0.17, 1.5, n)])
    fin = np.column_stack([rng.choice([5.0, 9.0, 13.0, 17.0], n) + rng.uniform(-0.6, 0.6, n),
                           17.0 + rng.uniform(-0.3, 0.6, n), rng.uniform(0.0, 0.6, n)])
    ang = rng.uniform(0, 2 * np.pi, n)
    rad = rng.uniform(0.3, 2.5, n)
    post = np.column_stack([17.0 + rad * np.cos(ang), 4.0 + rad * np.sin(ang),
                            rng.uniform(-0.5, 3.5, n)])
    return np.where((k == 0)[:, None], tab, np.where((k == 1)[:, None], fin, post))


def test_faces_without_seeds_are_found(tabs):
    prep, rects = tabs
    q = _tab_queries(np.random.default_rng(11), 4000)
    near = prep.closest(q, exact=True)
    expect = _analytic(q, rects)
    err = np.abs(near.distances) - expect
    assert np.abs(err).max() < 1e-9, f"{(np.abs(err) > 1e-9).sum()} queries off, max {err.max()}"
    # the answer is a point of the model: on its face's surface, inside the face
    for f in np.unique(near.face):
        sel = near.face == f
        face = prep.model.faces[f]
        np.testing.assert_allclose(face.surface.evaluate(near.uv[sel, 0], near.uv[sel, 1]),
                                   near.points[sel], atol=1e-9)


def test_seeded_search_alone_misses_those_faces(tabs):
    """The mechanism this guards: without the patch bounds the same queries are missed."""
    prep, rects = tabs
    q = _tab_queries(np.random.default_rng(11), 4000)
    prep.closest(q[:1], exact=True)
    prep._exact.complete = False
    try:
        seeded = prep.closest(q, exact=True)
    finally:
        prep._exact.complete = True
    miss = np.abs(seeded.distances) - _analytic(q, rects) > 1e-6
    assert miss.sum() > 100


def test_patch_boxes_contain_their_surface():
    """Every point of a patch's surface piece lies in the patch's box (lower bound 0)."""
    from shapeverify.cad.examples import wavy_panel

    model, _ = _tabs_model()
    for m, h in ((model, 0.5), (wavy_panel(split=True), 2.0)):
        prep = prepare(m, spacing=h, reach=4 * h)
        prep.closest(np.zeros((1, 3)), exact=True)
        pb = prep._exact.patches
        rng = np.random.default_rng(3)
        k = rng.integers(0, len(pb), 300)
        t = rng.uniform(0, 1, (300, 2))
        u = pb.uvbox[k, 0] + t[:, 0] * (pb.uvbox[k, 1] - pb.uvbox[k, 0])
        v = pb.uvbox[k, 2] + t[:, 1] * (pb.uvbox[k, 3] - pb.uvbox[k, 2])
        p = np.empty((300, 3))
        for f in np.unique(pb.face[k]):
            sel = pb.face[k] == f
            p[sel] = m.faces[f].surface.evaluate(u[sel], v[sel])
        loc = np.abs(np.einsum("kac,kc->ka", pb.axes[k], p - pb.centre[k])) - pb.half[k]
        assert loc.max() <= 1e-9
        # and the bound is tight: the boxes are thin (a patch is nearly flat at this size)
        assert np.median(pb.half[:, 2]) < 0.05 * np.median(pb.half[:, 0])


# ----------------------------------------------------- brute force over all faces
def _brute_force(model, q, n_grid=120, n_edge=4000):
    """Global closest distance by point inversion from dense samples on every face: the
    best trimmed grid sample of each face refined by Newton (kept if inside the trims), and
    dense samples of every trimming loop refined by a golden-section search on the segment."""
    best = np.full(q.shape[0], np.inf)
    for face in model.faces:
        srf = face.surface
        (u0, u1), (v0, v1) = srf.domain
        uu, vv = np.meshgrid(np.linspace(u0, u1, n_grid), np.linspace(v0, v1, n_grid),
                             indexing="ij")
        uv = np.column_stack([uu.ravel(), vv.ravel()])
        uv = uv[face.contains(uv)]
        P = srf.evaluate(uv[:, 0], uv[:, 1])
        from shapeverify.nearest.exact import power_tables
        tab = power_tables([srf])
        dom = np.array([srf.domain], dtype=float)
        closed = np.zeros((1, 2), dtype=np.bool_)
        from scipy.spatial import cKDTree
        kd = cKDTree(P)
        _, js = kd.query(q, k=min(4, len(P)))
        for i in range(q.shape[0]):
            for j in np.atleast_1d(js[i]):
                u, v, d2, _, _ = newton_face(tab, dom, closed, 0, uv[j, 0], uv[j, 1],
                                             q[i, 0], q[i, 1], q[i, 2])
                if face.contains([[u, v]])[0]:
                    best[i] = min(best[i], np.sqrt(d2))
        for loop in face.loops:
            a = loop
            b = np.roll(loop, -1, axis=0)
            t = np.linspace(0, 1, max(2, n_edge // len(loop)), endpoint=False)
            E = (a[:, None, :] + t[None, :, None] * (b - a)[:, None, :]).reshape(-1, 2)
            E = np.clip(E, [u0, v0], [u1, v1])
            X = srf.evaluate(E[:, 0], E[:, 1])
            d, j = cKDTree(X).query(q)
            for i in range(q.shape[0]):
                s = j[i] // len(t)
                lo, hi = (j[i] % len(t) - 1) / len(t), (j[i] % len(t) + 1) / len(t)
                f = lambda x: np.linalg.norm(  # noqa: E731
                    srf.evaluate(*np.clip(a[s] + np.clip(x, 0, 1) * (b[s] - a[s]),
                                          [u0, v0], [u1, v1])[:, None]) - q[i])
                g = (np.sqrt(5) - 1) / 2
                x1, x2 = hi - g * (hi - lo), lo + g * (hi - lo)
                for _ in range(60):
                    if f(x1) < f(x2):
                        hi, x2 = x2, x1
                        x1 = hi - g * (hi - lo)
                    else:
                        lo, x1 = x1, x2
                        x2 = lo + g * (hi - lo)
                best[i] = min(best[i], d[i], f(0.5 * (lo + hi)))
    return best


@pytest.mark.slow
def test_wavy_panel_against_brute_force():
    from shapeverify.cad.examples import wavy_panel

    model = wavy_panel(split=True)
    prep = prepare(model, spacing=1.0, reach=4.0)
    rng = np.random.default_rng(5)
    n = 300
    q = np.column_stack([rng.uniform(-5, 125, n), rng.uniform(-5, 95, n),
                         rng.uniform(-8, 8, n)])
    q = q[prep.closest(q).distances.__abs__() < 4.0][:150]
    near = prep.closest(q, exact=True)
    bf = _brute_force(model, q)
    assert np.all(np.abs(near.distances) <= bf + 1e-6), np.max(np.abs(near.distances) - bf)
    assert np.all(np.abs(near.distances) >= bf - 1e-6), np.min(np.abs(near.distances) - bf)


# -------------------------------------------------------------- impeller vs OCP
def _ocp_faces(path):
    from OCP.BRepBndLib import BRepBndLib
    from OCP.Bnd import Bnd_Box
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    from shapeverify.cad.occ_import import _init_ocp, _read_shape

    _init_ocp()
    shape, _, scale = _read_shape(Path(path), "iges")
    faces, lo, hi = [], [], []
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    while exp.More():
        f = TopoDS.Face(exp.Current())
        b = Bnd_Box()
        BRepBndLib.Add_s(f, b, False)
        a, c = b.CornerMin(), b.CornerMax()
        faces.append(f)
        lo.append([a.X(), a.Y(), a.Z()])
        hi.append([c.X(), c.Y(), c.Z()])
        exp.Next()
    return faces, np.array(lo) * scale, np.array(hi) * scale, scale


@pytest.fixture(scope="session")
def impeller_prep(shared_data):
    path = shared_data / "cad" / "impeller.igs"
    if not path.is_file():
        pytest.skip("impeller.igs not in ../shared/data/cad")
    from model_cache import cached_prepared

    # imported once per run and code version (tests/model_cache.py; the cache here was keyed
    # by the file's mtime alone and outlived code changes)
    prep = cached_prepared(path, spacing=0.5, reach=3.0)
    return prep, path


@pytest.mark.shared
@pytest.mark.slow
def test_impeller_scan_queries_global_against_ocp(impeller_prep):
    """0 of 2000 scan-like queries off OCP's global closest point by more than 1e-6 mm.

    OCP's candidate faces are every face whose bounding box is nearer than our answer (a
    closer point can only lie on those) plus our own face.  OCP works on the file's exact
    trims, we on polylines; a disagreement counts only when OCP's foot lies on our model.
    """
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape
    from OCP.gp import gp_Pnt

    prep, path = impeller_prep
    faces, lo, hi, _ = _ocp_faces(path)
    rng = np.random.default_rng(1)
    n = 2000
    mp = prep.points
    i = rng.integers(0, prep.n_points, n)
    side = rng.uniform(-0.5, 0.5, (n, 2)) * prep.spacing
    q = (mp.points[i] + side[:, :1] * mp.tangent_u[i] + side[:, 1:] * mp.tangent_v[i]
         + mp.normals[i] * rng.uniform(-1.5, 1.5, n)[:, None])
    near = prep.closest(q, exact=True)
    ours = np.abs(near.distances)
    d_occ = np.full(n, np.inf)
    foot = np.zeros((n, 3))
    for k in range(n):
        g = np.maximum(0.0, np.maximum(lo - q[k], q[k] - hi))
        cand = set(np.flatnonzero(np.sqrt((g * g).sum(axis=1)) < ours[k]).tolist())
        cand.add(int(near.face[k]))
        v = BRepBuilderAPI_MakeVertex(gp_Pnt(*map(float, q[k]))).Vertex()
        for f in cand:
            e = BRepExtrema_DistShapeShape(v, faces[f])
            if e.IsDone() and e.NbSolution() and e.Value() < d_occ[k]:
                d_occ[k] = e.Value()
                p = e.PointOnShape2(1)
                foot[k] = (p.X(), p.Y(), p.Z())
    on_model = np.abs(prep.closest(foot, exact=True).distances) <= 1e-7
    miss = (ours - d_occ > 1e-6) & on_model
    assert on_model.mean() > 0.95
    assert miss.sum() == 0, (f"{miss.sum()} of {n} queries farther than OCP's closest point, "
                             f"max {np.max(ours - d_occ)} mm")


# ------------------------------------------------------------------------- threads
def test_two_workers_give_identical_answers(tabs):
    from shapeverify.nearest import get_workers, set_workers

    prep, _ = tabs
    q = _tab_queries(np.random.default_rng(4), 40_000)
    before = get_workers()
    try:
        out = {}
        for w in (1, 2):
            set_workers(w)
            out[w] = (prep.closest(q), prep.closest(q, exact=True))
    finally:
        set_workers(None if before == get_workers() else before)
    for a, b in zip(out[1], out[2]):
        for name in ("points", "normals", "distances", "face", "uv", "index", "on_boundary"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    with pytest.raises(ValueError, match="whole number"):
        set_workers(0)
