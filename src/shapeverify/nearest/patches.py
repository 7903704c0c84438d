"""Bounds of every trimmed CAD face, small patch by small patch, for the exact closest point.

The exact mode (:mod:`shapeverify.nearest.exact`) starts from the faces met around the
nearest model point; those seeds are almost always right, but a face whose model points are
not among them (thinned away at a seam, or just beyond the seed's reach) could still hold a
closer point.  :class:`PatchBounds` makes the search complete: every face is cut into small
patches with a *rigorous* bound, and after the seeded faces have given a best distance, every
patch whose bound can still beat it is tried (:func:`shapeverify.nearest._patch_kernels.
candidates`).

How a patch is bounded
----------------------
Each non-empty knot span of a face's NURBS surface is one rational polynomial patch (the
power tables of :func:`shapeverify.nearest.exact.power_tables`).  It is clipped to the
parameter box of the face's outer trimming loop and cut into sub-boxes whose control
polygons are at most ``size`` (mm) long; on each sub-box the polynomial is converted to its
Bernstein (Bézier) form.  With positive weights, the patch lies in the convex hull of its
Bézier control points (Piegl & Tiller §3.4, §4.4), hence in their oriented bounding box (axes:
the net's mean u and v directions and their normal), inflated by a rounding margin.  A trimmed
face is a subset of its surface, so the bound holds for it too.  Sub-boxes that lie wholly
outside the trims (no trimming segment crosses them and their centre is outside) are dropped.

The patches are ordered in a bounding-volume hierarchy (median splits, axis-aligned node
boxes) that the query walks with the best squared distance found so far.

References
----------
Piegl & Tiller, The NURBS Book, 2nd ed. (1997), §3.4 and §4.4 (convex hull property),
eq. (5.38)-(5.41) (power basis and Bernstein form).
"""

from __future__ import annotations

import logging
from math import comb

import numpy as np

from . import _patch_kernels

logger = logging.getLogger(__name__)

__all__ = ["PatchBounds"]

_MAX_SUB = 64       # sub-boxes per knot span and direction
_LEAF = 4           # patches per hierarchy leaf


def _binom(n: int) -> np.ndarray:
    return np.array([[comb(a, k) for k in range(n + 1)] for a in range(n + 1)], dtype=float)


def _bernstein_matrices(p: int, s0: np.ndarray, ds: np.ndarray) -> np.ndarray:
    """(m, p+1, p+1): Bernstein coefficients on [s0, s0 + ds] of the power-basis polynomial
    ``sum_a c_a s^a`` are ``M @ c``."""
    C = _binom(p)
    a = np.arange(p + 1)
    e = a[None, :] - a[:, None]                     # (k, a): power of s0
    ok = e >= 0
    Ck = np.where(ok, C.T, 0.0)                     # C(a, k) at [k, a]
    A = (Ck[None] * np.where(ok[None], s0[:, None, None] ** np.maximum(e, 0)[None], 0.0)
         * ds[:, None, None] ** a[None, :, None])
    Bm = np.where(a[None, :] <= a[:, None], C / C[p][None, :], 0.0)  # [m, k] = C(m,k)/C(p,k)
    return np.einsum("mk,xka->xma", Bm, A)


def _to_bernstein(Mu, Mv, C):
    """Bézier nets (X, Y, p+1, q+1, 4) of the polynomials C (X, Y, p+1, q+1, 4) (power basis,
    homogeneous) on sub-boxes: ``sum_ab Mu[x, m, a] Mv[y, l, b] C[x, y, a, b, w]``, one index
    contracted at a time (one einsum over both loops over every (a, b) pair of every output:
    3-4x the CPU, 0.07 s of an inspection's first exact query on the example panel)."""
    half = np.einsum("ylb,xyabw->xyalw", Mv, C)
    return np.einsum("xma,xyalw->xymlw", Mu, half)


def _nets(Cs, p, q, us, vs):
    """Bézier nets of one span's polynomial Cs (p+1, q+1, 4) on the sub-intervals
    us (X, 2), vs (Y, 2) of its local parameters: (X, Y, p+1, q+1, 4) homogeneous."""
    Mu = _bernstein_matrices(p, us[:, 0], us[:, 1] - us[:, 0])
    Mv = _bernstein_matrices(q, vs[:, 0], vs[:, 1] - vs[:, 0])
    return np.einsum("xma,ylb,abw->xymlw", Mu, Mv, Cs)


def _obb(P: np.ndarray, margin: float):
    """Oriented boxes of control nets P (M, p+1, q+1, 3): (centre (M, 3), axes (M, 3, 3) rows,
    half extents (M, 3))."""
    m = P.shape[0]
    eu = P[:, -1, 0] + P[:, -1, -1] - P[:, 0, 0] - P[:, 0, -1]
    ev = P[:, 0, -1] + P[:, -1, -1] - P[:, 0, 0] - P[:, -1, 0]
    axes = np.zeros((m, 3, 3))
    lu = np.linalg.norm(eu, axis=1)
    a1 = np.where(lu[:, None] > 0, eu / np.where(lu > 0, lu, 1.0)[:, None], 0.0)
    n = np.cross(a1, ev)
    ln = np.linalg.norm(n, axis=1)
    a3 = np.where(ln[:, None] > 0, n / np.where(ln > 0, ln, 1.0)[:, None], 0.0)
    a2 = np.cross(a3, a1)
    good = (lu > 0) & (ln > 1e-12 * (lu * np.linalg.norm(ev, axis=1) + 1e-300))
    axes[:, 0] = np.where(good[:, None], a1, [1.0, 0.0, 0.0])
    axes[:, 1] = np.where(good[:, None], a2, [0.0, 1.0, 0.0])
    axes[:, 2] = np.where(good[:, None], a3, [0.0, 0.0, 1.0])
    pts = P.reshape(m, -1, 3)
    ref = pts[:, 0]
    loc = np.einsum("mkc,mac->mka", pts - ref[:, None], axes)
    lo = loc.min(axis=1)
    hi = loc.max(axis=1)
    mid = 0.5 * (lo + hi)
    centre = ref + np.einsum("ma,mac->mc", mid, axes)
    half = 0.5 * (hi - lo) * (1.0 + 1e-9) + margin
    return centre, axes, half


class PatchBounds:
    """Small patches of every CAD face with oriented bounding boxes, in a hierarchy.

    Parameters
    ----------
    faces : sequence of Face
    tab : power tables of the faces' surfaces (:func:`~shapeverify.nearest.exact.power_tables`)
    seg : (seg_off (F+1,), x0, y0, x1, y1) trimming segments per face in (u, v)
    size : float
        Longest control-polygon edge of a patch (mm); about 4 model point spacings.
    skip : iterable of int
        Faces left out (supplemental geometry, ``Model.supplemental``): the search never
        returns a foot on them.

    Attributes (patch k, in hierarchy order)
    ----------------------------------------
    face (K,) int32, inner (K,) bool (no trimming segment crosses the patch: wholly inside
    the trims), centre (K, 3), axes (K, 3, 3) (rows: unit axes), half (K, 3),
    uvbox (K, 4) (u0, u1, v0, v1); hierarchy nodes ``node_lo``/``node_hi`` (M, 3),
    ``node_child`` (M,) (first child, -1 for a leaf), ``node_first``/``node_count`` (M,).
    """

    def __init__(self, faces, tab, seg, size: float, skip=()):
        deg, bu, bu_off, mu, mu_off, bv, bv_off, mv, mv_off, coef, c_off = tab
        seg_off, x0, y0, x1, y1 = seg
        ctrl = np.concatenate([f.surface.control.reshape(-1, 3) for f in faces])
        extent = float(np.abs(ctrl).max()) + 1.0
        margin = 1e-9 * extent
        size = float(size)
        F, Cn, Ax, Hf, UV = [], [], [], [], []
        n_bad = 0
        skip = set(skip)
        for fi, face in enumerate(faces):
            if fi in skip:      # supplemental geometry (Model.supplemental): not the part
                continue
            p, q = int(deg[fi, 0]), int(deg[fi, 1])
            b_u = bu[bu_off[fi]:bu_off[fi + 1]]
            b_v = bv[bv_off[fi]:bv_off[fi + 1]]
            m_u = mu[mu_off[fi]:mu_off[fi + 1]]
            m_v = mv[mv_off[fi]:mv_off[fi + 1]]
            nsu, nsv = b_u.shape[0] - 1, b_v.shape[0] - 1
            C = coef[c_off[fi]:c_off[fi + 1]].reshape(nsu, nsv, p + 1, q + 1, 4)
            (ua, ub), (va, vb) = face.surface.domain
            if len(face.loops) and len(face.loops[0]):
                lo_l = face.loops[0].min(axis=0)
                hi_l = face.loops[0].max(axis=0)
                ua, ub = max(ua, lo_l[0]), min(ub, hi_l[0])
                va, vb = max(va, lo_l[1]), min(vb, hi_l[1])
            # the knot spans that meet the outer loop's box, clipped to it
            iu = np.flatnonzero((np.minimum(b_u[1:], ub) > np.maximum(b_u[:-1], ua))
                                | ((nsu == 1) & (ub >= ua)))
            jv = np.flatnonzero((np.minimum(b_v[1:], vb) > np.maximum(b_v[:-1], va))
                                | ((nsv == 1) & (vb >= va)))
            if iu.size == 0 or jv.size == 0:
                continue
            u_lo, u_hi = np.maximum(b_u[iu], ua), np.minimum(b_u[iu + 1], ub)
            v_lo, v_hi = np.maximum(b_v[jv], va), np.minimum(b_v[jv + 1], vb)
            # one net per span: control polygon lengths -> sub-boxes per span row / column
            N1 = _to_bernstein(_bernstein_matrices(p, u_lo - m_u[iu], u_hi - u_lo),
                               _bernstein_matrices(q, v_lo - m_v[jv], v_hi - v_lo),
                               C[np.ix_(iu, jv)])
            w1 = N1[..., 3]
            P1 = N1[..., :3] / np.where(w1 > 0, w1, 1.0)[..., None]
            lu = np.linalg.norm(np.diff(P1, axis=2), axis=-1).sum(axis=2).max(axis=2)
            lv = np.linalg.norm(np.diff(P1, axis=3), axis=-1).sum(axis=3).max(axis=2)
            ku = np.clip(np.ceil(lu.max(axis=1) / size), 1, _MAX_SUB).astype(np.int64)
            kv = np.clip(np.ceil(lv.max(axis=0) / size), 1, _MAX_SUB).astype(np.int64)

            def pieces(lo, hi, k):
                span = np.repeat(np.arange(lo.size), k)
                t = np.arange(span.size) - np.repeat(np.cumsum(k) - k, k)
                step = (hi - lo) / k
                a0 = lo[span] + t * step[span]
                a1 = np.where(t + 1 == k[span], hi[span], lo[span] + (t + 1) * step[span])
                return span, np.column_stack([a0, a1])

            su, us = pieces(u_lo, u_hi, ku)
            sv, vs = pieces(v_lo, v_hi, kv)
            Mu = _bernstein_matrices(p, us[:, 0] - m_u[iu[su]], us[:, 1] - us[:, 0])
            Mv = _bernstein_matrices(q, vs[:, 0] - m_v[jv[sv]], vs[:, 1] - vs[:, 0])
            X, Y = us.shape[0], vs.shape[0]
            step = max(1, 20_000 // Y)
            for x0_ in range(0, X, step):
                xs = slice(x0_, min(X, x0_ + step))
                Cx = C[iu[su[xs]]][:, jv[sv]]             # (x, Y, p+1, q+1, 4)
                nets = _to_bernstein(Mu[xs], Mv, Cx)
                nx = nets.shape[0]
                nets = nets.reshape(nx * Y, p + 1, q + 1, 4)
                w = nets[..., 3]
                P = nets[..., :3] / np.where(w > 0, w, 1.0)[..., None]
                c, a_, h = _obb(P, margin)
                # a non-positive weight voids the convex hull property: never prune it
                bad = ~np.all(w.reshape(w.shape[0], -1) > 0, axis=1)
                h[bad] = np.inf
                n_bad += int(bad.sum())
                Cn.append(c)
                Ax.append(a_)
                Hf.append(h)
                UV.append(np.column_stack([np.repeat(us[xs], Y, axis=0),
                                           np.tile(vs, (nx, 1))]))
                F.append(np.full(nx * Y, fi, dtype=np.int32))
        if n_bad:
            logger.warning("%d patches with non-positive weights are never pruned (slower "
                           "exact queries)", n_bad)
        face_id = np.concatenate(F)
        centre = np.concatenate(Cn)
        axes = np.concatenate(Ax)
        half = np.concatenate(Hf)
        uvbox = np.ascontiguousarray(np.concatenate(UV)[:, [0, 1, 2, 3]])
        # drop sub-boxes wholly outside the trims
        keep = np.ones(face_id.shape[0], dtype=np.bool_)
        centres_uv = np.column_stack([0.5 * (uvbox[:, 0] + uvbox[:, 1]),
                                      0.5 * (uvbox[:, 2] + uvbox[:, 3])])
        crossed = np.zeros(face_id.shape[0], dtype=np.bool_)
        _patch_kernels.crossed_by_trims(face_id, uvbox, seg_off, x0, y0, x1, y1, crossed)
        for fi, face in enumerate(faces):
            sel = np.flatnonzero((face_id == fi) & ~crossed)
            if sel.size and len(face.loops):
                keep[sel] = np.asarray(face.contains(centres_uv[sel]), dtype=bool)
        n_all = face_id.shape[0]
        face_id, centre, axes, half, uvbox, crossed = (
            a[keep] for a in (face_id, centre, axes, half, uvbox, crossed))
        # hierarchy
        ext = np.abs(axes).transpose(0, 2, 1) @ half[:, :, None]   # AABB half extents
        ext = np.where(np.isfinite(half).all(axis=1)[:, None], ext[:, :, 0], np.inf)
        box_lo = np.ascontiguousarray(centre - ext)
        box_hi = np.ascontiguousarray(centre + ext)
        m = face_id.shape[0]
        cap = 2 * m + 1  # leaves hold >= 2 patches (halves of > _LEAF), so <= m leaves
        order = np.arange(m, dtype=np.int64)
        nlo = np.empty((cap, 3))
        nhi = np.empty((cap, 3))
        child = np.empty(cap, dtype=np.int64)
        first = np.empty(cap, dtype=np.int64)
        count = np.empty(cap, dtype=np.int64)
        n_nodes = _patch_kernels.build_bvh(np.ascontiguousarray(centre), box_lo, box_hi,
                                           order, _LEAF, nlo, nhi, child, first, count)
        self.face = np.ascontiguousarray(face_id[order])
        self.inner = np.ascontiguousarray(~crossed[order])
        self.centre = np.ascontiguousarray(centre[order])
        self.axes = np.ascontiguousarray(axes[order])
        self.half = np.ascontiguousarray(half[order])
        self.uvbox = np.ascontiguousarray(uvbox[order])
        self.node_lo = nlo[:n_nodes].copy()
        self.node_hi = nhi[:n_nodes].copy()
        self.node_child = child[:n_nodes].copy()
        self.node_first = first[:n_nodes].copy()
        self.node_count = count[:n_nodes].copy()
        logger.debug("patch bounds: %d patches (%d outside the trims dropped), %d nodes, "
                     "size %.4g mm", m, n_all - m, n_nodes, size)

    #: what a ``.svm`` file stores (:meth:`to_arrays`), in :meth:`arrays` order
    FIELDS = ("face", "inner", "centre", "axes", "half", "uvbox", "node_lo", "node_hi",
              "node_child", "node_first", "node_count")
    #: the rules the bounds were made by (:data:`_MAX_SUB`, :data:`_LEAF`, the hull and the
    #: margin): stored with them; stored bounds of another rule are made again
    RULE = 1

    def to_arrays(self) -> dict:
        """The arrays by name (:data:`FIELDS`), for a prepared-model file."""
        return dict(zip(self.FIELDS, self.arrays()))

    @classmethod
    def from_arrays(cls, arrays, n_faces: int) -> "PatchBounds":
        """The bounds :meth:`to_arrays` gave, checked (:func:`check_arrays`) so that the
        kernels, which index them without bounds checks, stay inside them.

        Raises
        ------
        ValueError
            What is wrong with them.
        """
        problem = check_arrays(arrays, n_faces)
        if problem is not None:
            raise ValueError(problem)
        self = cls.__new__(cls)
        for name in cls.FIELDS:
            setattr(self, name, arrays[name])
        return self

    def __len__(self) -> int:
        return int(self.face.shape[0])

    def arrays(self) -> tuple:
        """The arrays the kernels read, in their argument order."""
        return (self.face, self.inner, self.centre, self.axes, self.half, self.uvbox, self.node_lo,
                self.node_hi, self.node_child, self.node_first, self.node_count)

    @property
    def nbytes(self) -> int:
        return int(sum(a.nbytes for a in self.arrays()))

    def lower_bounds(self, q) -> np.ndarray:
        """(N, K) lower bounds of the distance (mm) from each query to each patch (tests)."""
        q = np.asarray(q, dtype=np.float64).reshape(-1, 3)
        d = q[:, None, :] - self.centre[None]
        loc = np.abs(np.einsum("nkc,kac->nka", d, self.axes)) - self.half[None]
        return np.sqrt((np.maximum(loc, 0.0) ** 2).sum(axis=2))


_KINDS = {"face": (np.int32, 1), "inner": (np.bool_, 1), "centre": (np.float64, 2),
          "axes": (np.float64, 3), "half": (np.float64, 2), "uvbox": (np.float64, 2),
          "node_lo": (np.float64, 2), "node_hi": (np.float64, 2), "node_child": (np.int64, 1),
          "node_first": (np.int64, 1), "node_count": (np.int64, 1)}


def check_arrays(arrays, n_faces: int) -> str | None:
    """What is wrong with stored patch bounds (None: nothing), in time linear in their size:
    dtypes and shapes; faces in range; finite boxes (a half extent may be inf: a patch that is
    never pruned); a hierarchy whose root is node 0, whose inner nodes name a pair of later
    nodes that no other node names (a tree: every walk ends, no node is met twice) and whose
    leaves list patches in range, at most as many in all as there are patches (the kernel's
    candidate buffer holds that many)."""
    a = {}
    for name, (dtype, ndim) in _KINDS.items():
        v = arrays.get(name)
        if v is None:
            return f"the patch bounds lack {name}"
        v = np.asarray(v)
        if v.dtype != dtype or v.ndim != ndim:
            return f"the patch bounds' {name} is {v.dtype} with {v.ndim} dimensions"
        a[name] = np.ascontiguousarray(v)
    k, m = a["face"].shape[0], a["node_child"].shape[0]
    shapes = {"inner": (k,), "centre": (k, 3), "axes": (k, 3, 3), "half": (k, 3),
              "uvbox": (k, 4), "node_lo": (m, 3), "node_hi": (m, 3), "node_first": (m,),
              "node_count": (m,)}
    for name, shape in shapes.items():
        if a[name].shape != shape:
            return f"the patch bounds' {name} is {a[name].shape}, not {shape}"
    if k and (a["face"].min() < 0 or a["face"].max() >= n_faces):
        return "a patch names a face out of range"
    if not (np.isfinite(a["centre"]).all() and np.isfinite(a["axes"]).all()
            and np.isfinite(a["uvbox"]).all() and not np.isnan(a["half"]).any()
            and not np.isnan(a["node_lo"]).any() and not np.isnan(a["node_hi"]).any()):
        return "the patch bounds hold NaN or infinite boxes"
    if k and m == 0:
        return "the patch bounds have patches but no hierarchy"
    child, first, count = a["node_child"], a["node_first"], a["node_count"]
    inner = np.flatnonzero(child >= 0)
    if np.any((child < 0) & (child != -1)):
        return "a hierarchy node's child index is out of range"
    if inner.size:
        c = child[inner]
        if np.any(c <= inner) or c.max() + 1 >= m:
            return "a hierarchy node's child index is out of range"
        if np.bincount(c, minlength=m).max() > 1 or np.intersect1d(c, c + 1).size:
            return "the patch hierarchy is not a tree"
    leaf = child < 0
    f, n = first[leaf], count[leaf]
    if (np.any(f < 0) or np.any(n < 0) or np.any(f > k) or np.any(n > k)
            or np.any(f + n > k) or int(n.sum()) > k):
        return "a hierarchy leaf lists patches out of range"
    return None
