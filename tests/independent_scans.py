"""Scans made without the project's simulator, for the region tests (issue 29).

The CAD file is read and tessellated by OpenCASCADE (``BRepMesh_IncrementalMesh``); the scan
points are drawn on its triangles: uniformly by area (``random``), on a regular lattice in the
plane across each triangle's dominant axis (``grid``: a scanner's pixel grid, in random order;
``scanner``: the same points in row order), or on a lattice with rows ``aniso`` times farther
apart than the points along them (``aniso``).  A dent is a smooth bump along the triangle's
outward normal, ``depth * cos^2(pi r / 2R)`` for ``r < R``; noise is Gaussian along the normal.
The true out-of-tolerance area of the dent is integrated on the tessellation by Monte Carlo.
"""

from __future__ import annotations

import numpy as np


def read_shape(path):
    """The OCC shape of a STEP or IGES file."""
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.IGESControl import IGESControl_Reader
    from OCP.STEPControl import STEPControl_Reader

    path = str(path)
    reader = IGESControl_Reader() if path.lower().endswith((".igs", ".iges")) else STEPControl_Reader()
    assert reader.ReadFile(path) == IFSelect_RetDone, path
    reader.TransferRoots()
    return reader.OneShape()


def tessellate(shape, deflection: float):
    """``(V (n, 3), T (m, 3), face (m,))``: OpenCASCADE's triangles, outward wound."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    BRepMesh_IncrementalMesh(shape, deflection, False, 0.3, True)
    V, T, F = [], [], []
    off = 0
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    k = 0
    while exp.More():
        face = TopoDS.Face(exp.Current())
        loc = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, loc)
        if tri is not None:
            tr = loc.Transformation()
            pts = []
            for i in range(1, tri.NbNodes() + 1):
                p = tri.Node(i).Transformed(tr)
                pts.append((p.X(), p.Y(), p.Z()))
            t = np.array([tri.Triangle(i).Get() for i in range(1, tri.NbTriangles() + 1)]) - 1
            if face.Orientation() == TopAbs_REVERSED:
                t = t[:, [0, 2, 1]]
            V.append(np.array(pts))
            T.append(t + off)
            F.append(np.full(len(t), k))
            off += len(pts)
        k += 1
        exp.Next()
    return np.vstack(V), np.vstack(T), np.concatenate(F)


def _file_tessellation(path, deflection: float):
    return tessellate(read_shape(path), deflection)


def file_tessellation(path, deflection: float):
    """``tessellate(read_shape(path), deflection)``, computed once per suite run and read back
    bitwise by the other tests and pytest-xdist workers (``tests/model_cache.py``; this file's
    source is part of the key)."""
    from model_cache import cached_arrays

    return cached_arrays(path, "tessellation", _file_tessellation, code=(__file__,),
                         deflection=float(deflection))


def on_surface(shape, P, N, tri_face, t):
    """``(P, N)`` moved onto the exact CAD faces: each point (drawn on triangle ``t`` of face
    ``tri_face[t]``) projected on its face's surface (``GeomAPI_ProjectPointOnSurf``), with the
    surface's normal there oriented like the triangle's (the tessellation's chord error can be
    larger than a tolerance on a large part)."""
    from OCP.BRep import BRep_Tool
    from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
    from OCP.GeomLProp import GeomLProp_SLProps
    from OCP.gp import gp_Pnt
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    faces = []
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    while exp.More():
        faces.append(BRep_Tool.Surface_s(TopoDS.Face(exp.Current())))
        exp.Next()
    P2, N2 = P.copy(), N.copy()
    fid = tri_face[t]
    for f in np.unique(fid):
        surf = faces[f]
        proj = GeomAPI_ProjectPointOnSurf()
        for i in np.flatnonzero(fid == f):
            proj.Init(gp_Pnt(*P[i]), surf)
            if proj.NbPoints() == 0:
                continue
            q = proj.NearestPoint()
            u, v = proj.LowerDistanceParameters()
            props = GeomLProp_SLProps(surf, u, v, 1, 1e-9)
            if props.IsNormalDefined():
                n = props.Normal()
                n = np.array([n.X(), n.Y(), n.Z()])
                N2[i] = n if n @ N[i] >= 0 else -n
            P2[i] = (q.X(), q.Y(), q.Z())
    return P2, N2


def _tri_geometry(V, T):
    a, b, c = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    n = np.cross(b - a, c - a)
    area2 = np.linalg.norm(n, axis=1)
    return a, b, c, n / np.maximum(area2, 1e-300)[:, None], 0.5 * area2


def random_points(V, T, spacing, rng, tris=None, with_triangles=False):
    """Uniform by area, ``1 / spacing^2`` points per unit area: ``(points, normals)`` (and
    their triangles' indices with ``with_triangles``)."""
    a, b, c, n, area = _tri_geometry(V, T)
    if tris is not None:
        a, b, c, n, area = a[tris], b[tris], c[tris], n[tris], area[tris]
    m = rng.poisson(area.sum() / spacing ** 2)
    t = rng.choice(area.size, m, p=area / area.sum())
    r1, r2 = rng.random(m), rng.random(m)
    s = np.sqrt(r1)
    P = (1 - s)[:, None] * a[t] + (s * (1 - r2))[:, None] * b[t] + (s * r2)[:, None] * c[t]
    if with_triangles:
        return P, n[t], (t if tris is None else np.asarray(tris)[t])
    return P, n[t]


def lattice_points(V, T, spacing, rng, aniso: float = 1.0, order: str = "random"):
    """A lattice of ``spacing`` (rows ``aniso x spacing`` apart) in the coordinate plane across
    each triangle's dominant normal axis, lifted onto the triangle: ``(points, normals,
    triangles)``."""
    a, b, c, n, _ = _tri_geometry(V, T)
    shift = rng.random(2)
    out, nrm, key, tri = [], [], [], []
    for ax in range(3):
        sel = np.flatnonzero(np.argmax(np.abs(n), axis=1) == ax)
        if sel.size == 0:
            continue
        u, v = [i for i in range(3) if i != ax]
        h = np.array([spacing, aniso * spacing])
        for t in sel:
            A, B, C = a[t], b[t], c[t]
            q = np.array([[A[u], A[v]], [B[u], B[v]], [C[u], C[v]]])
            lo = np.floor(q.min(axis=0) / h - shift) + shift
            hi = q.max(axis=0) / h
            gx = np.arange(lo[0], hi[0] + 1e-9) * h[0]
            gy = np.arange(lo[1], hi[1] + 1e-9) * h[1]
            if gx.size == 0 or gy.size == 0:
                continue
            X, Y = np.meshgrid(gx, gy)
            X, Y = X.ravel(), Y.ravel()
            d = (q[1, 0] - q[0, 0]) * (q[2, 1] - q[0, 1]) - (q[2, 0] - q[0, 0]) * (q[1, 1] - q[0, 1])
            if d == 0:
                continue
            l1 = ((X - q[0, 0]) * (q[2, 1] - q[0, 1]) - (q[2, 0] - q[0, 0]) * (Y - q[0, 1])) / d
            l2 = ((q[1, 0] - q[0, 0]) * (Y - q[0, 1]) - (X - q[0, 0]) * (q[1, 1] - q[0, 1])) / d
            inside = (l1 >= 0) & (l2 >= 0) & (l1 + l2 < 1)   # half-open: shared edges once
            if not inside.any():
                continue
            l1, l2 = l1[inside], l2[inside]
            P = A + l1[:, None] * (B - A) + l2[:, None] * (C - A)
            out.append(P)
            nrm.append(np.repeat(n[t][None], len(P), axis=0))
            tri.append(np.full(len(P), t))
            key.append(np.column_stack([np.full(len(P), ax), np.round(Y[inside] / h[1]),
                                        X[inside]]))
    P, N, K, t = np.vstack(out), np.vstack(nrm), np.vstack(key), np.concatenate(tri)
    if order == "scanner":
        o = np.lexsort((K[:, 2], K[:, 1], K[:, 0]))
    else:
        o = rng.permutation(len(P))
    return P[o], N[o], t[o]


def bump(P, center, depth, radius):
    """``depth * cos^2(pi r / 2R)`` for ``r = |P - center| < R``, else 0."""
    r = np.linalg.norm(P - center, axis=1)
    return np.where(r < radius, depth * np.cos(np.pi * r / (2 * radius)) ** 2, 0.0)


def true_area(V, T, center, depth, radius, tolerance, rng, n=400_000):
    """Area where ``|bump| > tolerance``, by Monte Carlo on the triangles near the dent."""
    a, b, c, _, area = _tri_geometry(V, T)
    near = np.flatnonzero(np.min([np.linalg.norm(x - center, axis=1) for x in (a, b, c)], axis=0)
                          < radius + np.sqrt(area.max()) * 3)
    A = area[near].sum()
    P, _ = random_points(V, T, np.sqrt(A / n), rng, tris=near)
    return A * np.mean(np.abs(bump(P, center, depth, radius)) > tolerance)


def dent_site(V, T, F, radius):
    """A point of the largest face at least ``1.5 radius`` from its boundary (its rim's nodes)."""
    _, _, _, _, area = _tri_geometry(V, T)
    f = np.argmax(np.bincount(F, weights=area))
    tf = T[F == f]
    e = np.sort(np.vstack([tf[:, [0, 1]], tf[:, [1, 2]], tf[:, [2, 0]]]), axis=1)
    ue, cnt = np.unique(e, axis=0, return_counts=True)
    rim_e = ue[cnt == 1]
    t = np.linspace(0.0, 1.0, 20)[:, None, None]
    rim = (V[rim_e[:, 0]][None] * (1 - t) + V[rim_e[:, 1]][None] * t).reshape(-1, 3)
    sel = np.flatnonzero(F == f)
    cand, _ = random_points(V, T, np.sqrt(area[sel].sum() / 5000), np.random.default_rng(0),
                            tris=sel)
    from scipy.spatial import cKDTree
    d, _ = cKDTree(rim).query(cand)
    i = np.argmax(d)
    assert d[i] > 1.5 * radius, f"no site {1.5 * radius:g} from the rim (best {d[i]:g})"
    return cand[i]


def box_on_part(P, prep, V, T, F, half, height, spacing, rng):
    """Scan points ``P`` with a box (``2 half`` x ``2 half`` x ``height``) standing on the part
    where :func:`dent_site` puts a dent of radius ``3 half``: the points under its footprint
    removed, its top and four walls drawn uniformly by area at ``spacing`` (Poisson counts).
    Returns (points, the footprint's centre on the CAD surface); no noise is added."""
    site = np.array(dent_site(V, T, F, 3 * half))
    cp = prep.closest(site[None], exact=True)
    c, n = cp.points[0], cp.normals[0]
    e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    off = P - c
    under = (np.abs(off @ e1) < half) & (np.abs(off @ e2) < half) & (np.abs(off @ n) < 1.0)
    faces = [(c - half * e1 - half * e2 + height * n, e1, e2, 2 * half, 2 * half)]
    faces += [(c - half * a - half * b, a, n, 2 * half, height)
              for a, b in [(e1, e2), (e2, -e1), (-e1, -e2), (-e2, e1)]]
    box = []
    for o, a, b, la, lb in faces:
        m = rng.poisson(la * lb / spacing ** 2)
        box.append(o + rng.random(m)[:, None] * la * a + rng.random(m)[:, None] * lb * b)
    return np.vstack([P[~under]] + box), c


def scan(V, T, sampler, spacing, rng, noise=0.0, dents=(), aniso=1.0, exact=None):
    """Scan points: ``sampler`` in {'random', 'grid', 'scanner', 'aniso'}; ``dents``
    ``[(center, depth, radius)]`` (depth < 0: into the part); ``exact``: ``(shape, face of each
    triangle)`` to put the points on the exact CAD surface (:func:`on_surface`) first."""
    if sampler == "random":
        P, N, t = random_points(V, T, spacing, rng, with_triangles=True)
    else:
        P, N, t = lattice_points(V, T, spacing, rng, aniso=aniso if sampler == "aniso" else 1.0,
                                 order="scanner" if sampler == "scanner" else "random")
    if exact is not None:
        P, N = on_surface(exact[0], P, N, exact[1], t)
    h = rng.normal(0.0, noise, len(P)) if noise else np.zeros(len(P))
    for c, depth, radius in dents:
        h = h + bump(P, c, depth, radius)
    return P + h[:, None] * N
