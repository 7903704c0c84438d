"""Trimming loops of OCP faces: pcurves sampled to polylines in (u, v), free-edge flags (private).

Part of :func:`shapeverify.cad.occ_import.read_cad` (see there for what a loop and a free
segment are); OCP is imported inside the functions, as everywhere in ``cad/``.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from ..errors import CADImportError
from .nurbs import NurbsCurve, NurbsSurface

logger = logging.getLogger("shapeverify.cad.occ_import")

_GAP_REL = 1e-5


def _array1(a) -> np.ndarray:
    return np.array([a.Value(i) for i in range(a.Lower(), a.Upper() + 1)], dtype=np.float64)


# ---------------------------------------------------------------------------------- pcurves
class _PCurve:
    """Vectorized evaluation of an edge's 2D curve on a face over its parameter range."""

    def __init__(self, c2d, t0: float, t1: float, degenerated: bool, shift=None):
        from OCP.Geom2d import Geom2d_BSplineCurve, Geom2d_Line, Geom2d_TrimmedCurve

        self.t0, self.t1 = t0, t1
        self.shift = shift  # (2,) added to every (u, v), or None
        self.degenerated = degenerated
        self.curve = None  # NurbsCurve, when the pcurve is a B-spline
        self.line = None   # (origin, direction), when the pcurve is a line
        base = c2d
        while isinstance(base, Geom2d_TrimmedCurve):
            base = base.BasisCurve()
        self.n_init = 16
        if isinstance(base, Geom2d_Line):
            lin = base.Lin2d()
            self.line = (np.array(lin.Location().Coord()), np.array(lin.Direction().Coord()))
            self.n_init = 4
        elif isinstance(base, Geom2d_BSplineCurve) and not base.IsPeriodic():
            n = base.NbPoles()
            ctrl = np.array([base.Pole(i).Coord() for i in range(1, n + 1)], dtype=np.float64)
            w = (np.array([base.Weight(i) for i in range(1, n + 1)], dtype=np.float64)
                 if base.IsRational() else None)
            self.curve = NurbsCurve(base.Degree(), _array1(base.KnotSequence()), ctrl, w)
            knots = np.unique(self.curve.knots)
            lo, hi = min(t0, t1), max(t0, t1)
            spans = int(np.count_nonzero((knots > lo) & (knots < hi))) + 1
            self.n_init = int(np.clip(2 * spans, 8, 256))
        else:
            self._c2d = c2d

    def __call__(self, t: np.ndarray) -> np.ndarray:
        if self.line is not None:
            o, d = self.line
            uv = o + t[:, None] * d
        elif self.curve is not None:
            a, b = self.curve.domain
            uv = self.curve.evaluate(np.clip(t, a, b))
        else:
            c = self._c2d
            uv = np.array([c.Value(float(x)).Coord() for x in t], dtype=np.float64).reshape(-1, 2)
        return uv if self.shift is None else uv + self.shift


def _seam_shift(face, wire, surface: NurbsSurface):
    """(2,) shift that moves an outer wire spanning a whole period back onto the surface domain.

    ``BRepBuilderAPI_NurbsConvert`` of a periodic face whose seam is not at the start of its
    surface's period (e.g. a full cylinder with u in [pi/2, 5 pi/2]) returns a non-periodic
    B-spline on [pi/2, 5 pi/2] but leaves the outer wire's pcurves offset by a few hundredths
    of the period; a closed direction whose outer wire spans exactly the domain's width, but
    offset, is shifted back.  Returns None when nothing needs to move.
    """
    from OCP.BRepTools import BRepTools

    a0, a1, b0, b1 = BRepTools.UVBounds_s(face, wire)
    dom = surface.domain
    shift = np.zeros(2)
    for axis, (lo, hi), (a, b) in ((0, dom[0], (a0, a1)), (1, dom[1], (b0, b1))):
        width = hi - lo
        if (abs((b - a) - width) <= 1e-6 * width and 1e-9 * width < abs(a - lo) < 0.25 * width
                and _closed(surface, axis)):
            shift[axis] = lo - a
    if not shift.any():
        return None
    logger.debug("outer wire offset from its closed surface's domain by %s; shifted back", -shift)
    return shift


def _closed(surface: NurbsSurface, axis: int) -> bool:
    """Whether the surface's two domain edges across ``axis`` coincide in 3D."""
    (u0, u1), (v0, v1) = surface.domain
    t = np.linspace(0.0, 1.0, 7)
    if axis == 0:
        a = surface.evaluate(np.full(7, u0), v0 + t * (v1 - v0))
        b = surface.evaluate(np.full(7, u1), v0 + t * (v1 - v0))
    else:
        a = surface.evaluate(u0 + t * (u1 - u0), np.full(7, v0))
        b = surface.evaluate(u0 + t * (u1 - u0), np.full(7, v1))
    size = float(np.ptp(surface.control.reshape(-1, 3), axis=0).max())
    return bool(np.abs(a - b).max() <= 1e-7 * max(size, 1e-300))


def _sample_edges(pcurves: list[_PCurve], surface: NurbsSurface, tol: float,
                  max_rounds: int = 30):
    """Adaptively sample the pcurves of one face; returns per edge (params, uv (n,2), xyz (n,3))."""
    (su0, su1), (sv0, sv1) = surface.domain

    def surf(uv):
        return surface.evaluate(np.clip(uv[:, 0], su0, su1), np.clip(uv[:, 1], sv0, sv1))

    ts, uvs = [], []
    for pc in pcurves:
        n = 1 if (pc.line is not None and pc.degenerated) else pc.n_init
        t = np.linspace(pc.t0, pc.t1, n + 1)
        ts.append(t)
        uvs.append(pc(t))
    counts = [t.shape[0] for t in ts]
    xyzs = np.split(surf(np.concatenate(uvs)), np.cumsum(counts)[:-1])
    active = [i for i, pc in enumerate(pcurves) if not pc.degenerated]
    for _ in range(max_rounds):
        if not active:
            break
        tm = [0.5 * (ts[i][:-1] + ts[i][1:]) for i in active]
        uvm = [pcurves[i](t) for i, t in zip(active, tm)]
        uvc = [0.5 * (uvs[i][:-1] + uvs[i][1:]) for i in active]
        m = [t.shape[0] for t in tm]
        both = surf(np.concatenate(uvm + uvc))
        k = sum(m)
        xm = np.split(both[:k], np.cumsum(m)[:-1])
        xc = np.split(both[k:], np.cumsum(m)[:-1])
        still = []
        for j, i in enumerate(active):
            x = xyzs[i]
            dev = np.maximum(np.linalg.norm(xm[j] - 0.5 * (x[:-1] + x[1:]), axis=1),
                             np.linalg.norm(xm[j] - xc[j], axis=1))
            bad = np.flatnonzero(dev > tol)
            if bad.size == 0:
                continue
            ts[i] = np.insert(ts[i], bad + 1, tm[j][bad])
            uvs[i] = np.insert(uvs[i], bad + 1, uvm[j][bad], axis=0)
            xyzs[i] = np.insert(x, bad + 1, xm[j][bad], axis=0)
            still.append(i)
        active = still
    else:
        if active:
            logger.warning("pcurve sampling stopped after %d refinement rounds with %d edges "
                           "still above the chordal tolerance %g mm", max_rounds, len(active), tol)
    return ts, uvs, xyzs


# ------------------------------------------------------------------------------------ faces
def _edge_face_map(shape):
    from OCP.collections import (
        IndexedDataMap_TopoDS_Shape_List_TopoDS_Shape_TopTools_ShapeMapHasher as EdgeFaces)
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE
    from OCP.TopExp import TopExp

    m = EdgeFaces()
    TopExp.MapShapesAndUniqueAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, m)
    return m


def _wire_edges(wire, face):
    """Edges of a wire in connection order (falls back to storage order)."""
    from OCP.BRepTools import BRepTools_WireExplorer
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    ordered = []
    wexp = BRepTools_WireExplorer(wire, face)
    while wexp.More():
        ordered.append(wexp.Current())
        wexp.Next()
    stored = []
    exp = TopExp_Explorer(wire, TopAbs_EDGE)
    while exp.More():
        stored.append(TopoDS.Edge(exp.Current()))
        exp.Next()
    if len(ordered) == len(stored):
        return ordered
    logger.debug("wire explorer visited %d of %d edges; using storage order",
                 len(ordered), len(stored))
    return stored


def _face_wires(work_face, orig_face, conv, edge_faces, index: int, path: Path):
    """The wires of a face as pcurves, without sampling them: per wire ``(pcurves, free,
    tolerances)`` (lists, one entry per edge in wire order), outer wire first.

    ``edge_faces`` None skips the free-edge flags (all False).  Raises
    :class:`CADImportError` for a face without a boundary wire or an edge without a pcurve
    (after trying to compute one); the import then skips the face.
    """
    from OCP.BRep import BRep_Tool
    from OCP.BRepTools import BRepTools
    from OCP.ShapeFix import ShapeFix_Edge
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_REVERSED, TopAbs_WIRE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    # edges of the converted face -> edges of the original shape (for the edge -> face map)
    originals = None
    if conv is not None and edge_faces is not None:
        originals = []
        exp = TopExp_Explorer(orig_face, TopAbs_EDGE)
        while exp.More():
            e = exp.Current()
            originals.append((conv.ModifiedShape(e), e))
            exp.Next()

    def is_free(edge) -> bool:
        if edge_faces is None:
            return False
        if BRep_Tool.Degenerated_s(edge) or BRep_Tool.IsClosed_s(edge, work_face):
            return False
        key = edge
        if originals is not None:
            key = next((o for n, o in originals if n.IsSame(edge)), None)
            if key is None:
                return False
        idx = edge_faces.FindIndex(key)
        return idx > 0 and edge_faces.FindFromIndex(idx).Size() == 1

    outer = BRepTools.OuterWire_s(work_face)
    wires = [] if outer.IsNull() else [outer]
    exp = TopExp_Explorer(work_face, TopAbs_WIRE)
    while exp.More():
        w = TopoDS.Wire(exp.Current())
        if not (wires and w.IsSame(wires[0])):
            wires.append(w)
        exp.Next()
    if not wires:
        raise CADImportError(f"{path}: face {index} has no boundary wire")

    out = []
    fixer = None
    for wire in wires:
        pcurves, free, etol = [], [], []
        for edge in _wire_edges(wire, work_face):
            c2d = BRep_Tool.CurveOnSurface_s(edge, work_face, 0.0, 0.0)
            if c2d is None:
                if fixer is None:
                    fixer = ShapeFix_Edge()
                fixer.FixAddPCurve(edge, work_face, False)
                c2d = BRep_Tool.CurveOnSurface_s(edge, work_face, 0.0, 0.0)
            if c2d is None:
                raise CADImportError(f"{path}: an edge of face {index} has no curve on the "
                                     "face's surface (pcurve) and none could be computed")
            f, l = BRep_Tool.Range_s(edge, work_face)
            if edge.Orientation() == TopAbs_REVERSED:
                f, l = l, f
            pcurves.append(_PCurve(c2d, f, l, BRep_Tool.Degenerated_s(edge)))
            free.append(is_free(edge))
            etol.append(BRep_Tool.Tolerance_s(edge))
        out.append((wire, pcurves, free, etol))
    return out


def _usable_loop(pcurves) -> bool:
    """Whether :func:`_face_loops` keeps a wire of these pcurves as a loop (two or more
    segments), told without sampling: each edge gives at least ``n_init`` >= 4 segments,
    except a degenerated straight one, which gives one."""
    return sum(1 if (pc.line is not None and pc.degenerated) else pc.n_init
               for pc in pcurves) >= 2


def _face_loops(work_face, orig_face, conv, surface: NurbsSurface, edge_faces, tol: float,
                index: int, path: Path):
    """Trimming loops of a face: per loop uv (k, 2), xyz (k, 3), topologically free flags (k,),
    the tolerances (k,) of the segments' edges and the segments' edge numbers (k,) within the
    face."""
    loops_uv, loops_xyz, loops_free, loops_tol, loops_edge = [], [], [], [], []
    n_edges = 0
    wires = _face_wires(work_face, orig_face, conv, edge_faces, index, path)
    for w_index, (wire, pcurves, free, etol) in enumerate(wires):
        shift = (_seam_shift(work_face, wire, surface)
                 if w_index == 0 and conv is not None else None)
        for pc in pcurves:
            pc.shift = shift
        if not pcurves:
            continue
        _, uvs, xyzs = _sample_edges(pcurves, surface, tol)
        # drop each edge's last vertex: it (nearly) coincides with the next edge's first one,
        # and the loop is closed implicitly; vertex j starts segment j, owned by its edge
        uv = np.concatenate([a[:-1] for a in uvs])
        xyz = np.concatenate([a[:-1] for a in xyzs])
        fr = np.concatenate([np.full(a.shape[0] - 1, fl) for a, fl in zip(uvs, free)])
        tl = np.concatenate([np.full(a.shape[0] - 1, t) for a, t in zip(uvs, etol)])
        ed = np.concatenate([np.full(a.shape[0] - 1, n_edges + j) for j, a in enumerate(uvs)])
        n_edges += len(uvs)
        if uv.shape[0] < 2:
            continue
        loops_uv.append(uv)
        loops_xyz.append(xyz)
        loops_free.append(fr)
        loops_tol.append(tl)
        loops_edge.append(ed)
    if not loops_uv:
        raise CADImportError(f"{path}: face {index} has no usable trimming loop")
    return loops_uv, loops_xyz, loops_free, loops_tol, loops_edge


def _gap_to_other_edges(seg_a, seg_b, seg_edge, query, radius: np.ndarray, piece: float,
                        k: int = 16, chunk: int = 50_000) -> np.ndarray:
    """Distance from the midpoints of segments ``query`` to the nearest segment of another edge.

    seg_a, seg_b : (S, 3) segment end points (all faces' trimming loops in 3D)
    seg_edge : (S,) int, a global edge id per segment (seam copies of one edge have distinct ids)
    query : (Q,) int, segments to test;  radius : (Q,) search radius (larger gaps give inf)
    piece : float, segments are cut into pieces no longer than this for the search; the k nearest
        pieces within ``radius + piece / 2`` of a midpoint are examined exactly.
    """
    from scipy.spatial import cKDTree

    n = np.maximum(1, np.ceil(np.linalg.norm(seg_b - seg_a, axis=1) / piece).astype(np.int64))
    seg = np.repeat(np.arange(seg_a.shape[0]), n)
    nn = np.repeat(n, n)
    j = np.arange(seg.shape[0]) - np.repeat(np.cumsum(n) - n, n)
    d = (seg_b - seg_a)[seg]
    pa = seg_a[seg] + (j / nn)[:, None] * d
    pb = seg_a[seg] + ((j + 1) / nn)[:, None] * d
    owner = seg_edge[seg]
    tree = cKDTree(0.5 * (pa + pb))
    k = min(k, pa.shape[0])
    out = np.full(query.shape[0], np.inf)
    for c0 in range(0, query.shape[0], chunk):
        qi = query[c0:c0 + chunk]
        mid = 0.5 * (seg_a[qi] + seg_b[qi])
        # one query per distinct radius would be exact; the largest radius is a superset
        _, cand = tree.query(mid, k=k, distance_upper_bound=float(radius[c0:c0 + chunk].max())
                             + 0.5 * piece)
        cand = cand.reshape(qi.shape[0], k)
        found = cand < pa.shape[0]
        cand = np.where(found, cand, 0)
        ok = found & (owner[cand] != seg_edge[qi][:, None])
        rows, cols = np.nonzero(ok)
        c = cand[rows, cols]
        q = mid[rows]
        ab = pb[c] - pa[c]
        t = np.clip(np.einsum("ij,ij->i", q - pa[c], ab)
                    / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300), 0.0, 1.0)
        dist = np.linalg.norm(pa[c] + t[:, None] * ab - q, axis=1)
        best = np.full(qi.shape[0], np.inf)
        np.minimum.at(best, rows, dist)
        out[c0:c0 + chunk] = best
    return out


def _clear_touching(all_xyz, all_free, all_edge, all_tol, gap_tol: float) -> None:
    """Clear the free flag of segments that another edge (of any face) passes within the gap
    tolerance of: max(gap_tol, 1e-5 * model size, 2 * the edge's own tolerance)."""
    loops = [lp for lps in all_xyz for lp in lps]
    seg_a = np.concatenate(loops)
    seg_b = np.concatenate([np.roll(lp, -1, axis=0) for lp in loops])
    free = np.concatenate([f for fr in all_free for f in fr])
    edge = np.concatenate([e for es in all_edge for e in es])
    tol = np.concatenate([t for ts in all_tol for t in ts])
    query = np.flatnonzero(free)
    if query.size == 0:
        return
    size = float(np.linalg.norm(seg_a.max(axis=0) - seg_a.min(axis=0)))
    limit = np.maximum(max(gap_tol, _GAP_REL * size), 2.0 * tol[query])
    length = np.linalg.norm(seg_b - seg_a, axis=1)
    piece = max(2.0 * float(np.median(length)), 1e-6 * size, 1e-9)
    gap = _gap_to_other_edges(seg_a, seg_b, edge, query, limit, piece)
    free[query[gap <= limit]] = False
    pos = 0
    for fr in all_free:
        for f in fr:
            f[:] = free[pos:pos + f.shape[0]]
            pos += f.shape[0]
