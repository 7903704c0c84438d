"""Exact closest points: refine the fast answer on the model itself.

* CAD models (:class:`ExactCAD`): Newton point inversion on the NURBS surface of the nearest
  model point's face, started from that point's (u, v) and kept inside the surface domain;
  trims respected (a foot outside the trimmed domain moves to the closest point of the face's
  boundary -- the image of the trimming polyline, refined on its segment -- and is flagged
  ``on_boundary`` when that segment is a free edge).  Faces met among the nearest model
  point's graph neighbours and its nearest point on another face are tried too when the first
  foot ends on the boundary (a shared edge) or when their model point is nearly as close
  (concave corners).  Then every patch of every face whose rigorous bound
  (:class:`~shapeverify.nearest.patches.PatchBounds`: Bézier-hull boxes in a hierarchy) is
  nearer than the best foot is solved too, so the closest foot that wins is the global one.  The surfaces are evaluated from polynomial
  patch tables (:func:`power_tables`, one tensor-product polynomial per knot span, built on
  first use), which is several times faster per evaluation than the knot-span recursion.
* Mesh models (:class:`ExactMesh`): exact point-triangle projection over every triangle that
  can be the closest one (centroid within the nearest model point's distance plus the largest
  triangle radius), signed with the angle weighted pseudonormal; a foot on an edge that only
  one triangle uses (an open mesh's outline) is ``on_boundary``.
* Point-cloud models (:class:`ExactCloud`): the closest point of a quadric fitted to the
  query's nearest cloud points (kd-tree over all cloud points), see the class.

Each ``refine(queries, index, fast, face, uv, aux)`` (``index``: nearest model points, ``fast``:
the :class:`~shapeverify.nearest.dvg.DVG`, then per model point its face, (u, v) and
other-face point) returns ``(foot, normal, distance, face, uv, on_boundary)`` arrays.
Inputs are trusted (validated by :class:`~shapeverify.nearest.Prepared`).

References
----------
Piegl & Tiller, The NURBS Book, 2nd ed., §6.1 (point inversion).
Bergström (2011), thesis §7.3 (trimmed surfaces) and Paper I §4 (exact refinement).
"""

from __future__ import annotations

import logging
from itertools import chain

import numpy as np
from numpy.polynomial import polynomial as P
from shapeverify._lazy import cKDTree

from shapeverify.cad.trim import pack_trims

from . import _exact_kernels
from .dvg import record_views, views
from ._threads import run_chunks
from .patches import PatchBounds

logger = logging.getLogger(__name__)

__all__ = ["ExactCAD", "ExactMesh", "ExactCloud", "for_model"]

_CHUNK = 16  # trimming segments per bounding sphere in the boundary search
_ALL_TRIANGLES = 256  # meshes with at most this many triangles: test them all
_PATCH = 4.0  # longest control-polygon edge of a bounded patch / model point spacing
_MAX_BINS = 4096  # trim slabs per face (about one per segment up to this)


def _closed(surface, tol: float) -> tuple[bool, bool]:
    """Whether the surface closes on itself across the u (v) domain ends."""
    (u0, u1), (v0, v1) = surface.domain
    t = np.linspace(0.0, 1.0, 7)
    us = u0 + t * (u1 - u0)
    vs = v0 + t * (v1 - v0)
    du = np.abs(surface.evaluate(np.full(7, u0), vs) - surface.evaluate(np.full(7, u1), vs))
    dv = np.abs(surface.evaluate(us, np.full(7, v0)) - surface.evaluate(us, np.full(7, v1)))
    return bool(du.max() <= tol), bool(dv.max() <= tol)


def _span_basis(p: int, U: np.ndarray):
    """Breakpoints, span centres and basis polynomials of every non-empty knot span.

    Returns (breaks (n_s + 1,), mids (n_s,), first (n_s,) index of the first non-zero basis
    function, B (n_s, p + 1, p + 1)) with ``B[i, r, a]`` the coefficient of ``(u - mid)^a`` of
    basis function ``first + r`` on span i (Cox-de Boor on polynomials; NURBS Book eq. 2.5).
    """
    n = U.shape[0] - p - 2  # last control point index
    breaks = np.unique(U[p:n + 2])
    ns = breaks.shape[0] - 1
    mids = 0.5 * (breaks[:-1] + breaks[1:])
    first = np.empty(ns, dtype=np.int64)
    B = np.zeros((ns, p + 1, p + 1))
    for i in range(ns):
        sp = int(np.searchsorted(U, breaks[i], side="right")) - 1
        sp = min(max(sp, p), n)
        m = mids[i]
        N = {sp: np.array([1.0])}
        for k in range(1, p + 1):
            nxt = {}
            for j in range(sp - k, sp + 1):
                acc = np.zeros(k + 1)
                d1 = U[j + k] - U[j]
                if j in N and d1 > 0:
                    acc += _pad(P.polymul([m - U[j], 1.0], N[j]), k + 1) / d1
                d2 = U[j + k + 1] - U[j + 1]
                if j + 1 in N and d2 > 0:
                    acc += _pad(P.polymul([U[j + k + 1] - m, -1.0], N[j + 1]), k + 1) / d2
                nxt[j] = acc
            N = nxt
        first[i] = sp - p
        for r in range(p + 1):
            B[i, r] = N[sp - p + r]
    return breaks, mids, first, B


def _pad(c, k):
    out = np.zeros(k)
    out[:len(c)] = c
    return out


def power_tables(surfaces):
    """Polynomial patch tables of NURBS surfaces for :func:`_exact_kernels._eval`.

    Each non-empty knot span (i, j) of a surface becomes a tensor-product polynomial in
    ``(u - mu_i, v - mv_j)`` with homogeneous coefficients (w x, w y, w z, w): an evaluation
    then costs two Horner passes and no knot-span recursion.
    """
    deg, bu, bu_off, mu, mu_off, bv, bv_off, mv, mv_off, coef, c_off = \
        [], [], [0], [], [0], [], [0], [], [0], [], [0]
    for srf in surfaces:
        p, q = srf.degree_u, srf.degree_v
        w = np.ones(srf.control.shape[:2]) if srf.weights is None else srf.weights
        Pw = np.concatenate([srf.control * w[..., None], w[..., None]], axis=-1)
        b_u, m_u, f_u, B_u = _span_basis(p, srf.knots_u)
        b_v, m_v, f_v, B_v = _span_basis(q, srf.knots_v)
        iu = f_u[:, None] + np.arange(p + 1)[None, :]          # (n_u, p+1)
        iv = f_v[:, None] + np.arange(q + 1)[None, :]          # (n_v, q+1)
        blocks = Pw[iu[:, None, :, None], iv[None, :, None, :]]  # (n_u, n_v, p+1, q+1, 4)
        C = np.einsum("ira,jcb,ijrcw->ijabw", B_u, B_v, blocks)
        deg.append((p, q))
        bu.append(b_u)
        bv.append(b_v)
        mu.append(m_u)
        mv.append(m_v)
        bu_off.append(bu_off[-1] + b_u.shape[0])
        bv_off.append(bv_off[-1] + b_v.shape[0])
        mu_off.append(mu_off[-1] + m_u.shape[0])
        mv_off.append(mv_off[-1] + m_v.shape[0])
        coef.append(C.reshape(-1, 4))
        c_off.append(c_off[-1] + coef[-1].shape[0])
    cat = np.concatenate
    i64 = np.int64
    return (np.array(deg, dtype=i64), cat(bu), np.array(bu_off, dtype=i64), cat(mu),
            np.array(mu_off, dtype=i64), cat(bv), np.array(bv_off, dtype=i64), cat(mv),
            np.array(mv_off, dtype=i64), np.ascontiguousarray(cat(coef)),
            np.array(c_off, dtype=i64))


def _segments(face, max_len: float):
    """Trimming segments of a face, split until each 3D image is at most ``max_len`` long.

    Returns (start (S, 2), end (S, 2), free (S,)).  A long straight segment in (u, v) can map
    to a long curve (e.g. a full rim of a cylinder, whose chord is a single point), which the
    boundary search, working on chords, would miss.
    """
    a = np.concatenate(face.loops)
    b = np.concatenate([np.roll(lp, -1, axis=0) for lp in face.loops])
    free = np.concatenate(face.loop_free).astype(np.bool_)
    (u0, u1), (v0, v1) = face.surface.domain
    t = np.linspace(0.0, 1.0, 9)
    uv = a[:, None, :] + t[None, :, None] * (b - a)[:, None, :]
    xyz = face.surface.evaluate(np.clip(uv[..., 0], u0, u1).ravel(),
                                np.clip(uv[..., 1], v0, v1).ravel()).reshape(-1, 9, 3)
    length = np.linalg.norm(np.diff(xyz, axis=1), axis=2).sum(axis=1)
    pieces = np.clip(np.ceil(length / max_len), 1, 512).astype(np.int64)
    if np.all(pieces == 1):
        return a, b, free
    seg = np.repeat(np.arange(a.shape[0]), pieces)
    k = np.arange(seg.shape[0]) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    t0 = (k / pieces[seg])[:, None]
    t1 = ((k + 1) / pieces[seg])[:, None]
    d = (b - a)[seg]
    return a[seg] + t0 * d, a[seg] + t1 * d, free[seg]


class ExactCAD:
    """Packed NURBS faces and trimming loops of a CAD model for :func:`refine_cad`.

    Parameters
    ----------
    model : shapeverify.cad.model.Model with ``kind == "cad"``
    spacing : float
        Model point spacing (mm): other faces are tried when their candidate point is at most
        this much farther than the nearest model point.
    patches : PatchBounds, optional
        The faces' patch bounds made before for this model and spacing (a prepared model's
        file stores them, :meth:`Prepared.save`): not made again.
    """

    def __init__(self, model, spacing: float, patches=None):
        self.spacing = float(spacing)
        faces = model.faces
        if not faces:
            raise ValueError("exact closest points need a CAD model with at least one face")
        self.tab = power_tables([f.surface for f in faces])
        ctrl = np.concatenate([f.surface.control.reshape(-1, 3) for f in faces])
        size = float(np.linalg.norm(ctrl.max(axis=0) - ctrl.min(axis=0))) + 1e-9
        self.domains = np.array([f.surface.domain for f in faces], dtype=np.float64)
        self.closed = np.array([_closed(f.surface, 1e-10 * size) for f in faces],
                               dtype=np.bool_)
        self.rev = np.array([f.reversed for f in faces], dtype=np.bool_)
        xs0, ys0, xs1, ys1, fr, a3, b3, sag = [], [], [], [], [], [], [], []
        seg_off = [0]
        trim_segments, trim_bins = [], []
        n_seg = 0
        max_len = 0.002 * size
        for f in faces:
            a, b, free = _segments(f, max_len)
            (u0, u1), (v0, v1) = f.surface.domain
            pa = f.surface.evaluate(np.clip(a[:, 0], u0, u1), np.clip(a[:, 1], v0, v1))
            pb = f.surface.evaluate(np.clip(b[:, 0], u0, u1), np.clip(b[:, 1], v0, v1))
            # how far each segment's curve strays from its chord (sampled at 1/4, 1/2, 3/4,
            # with a safety factor): bounds the boundary search
            dev = np.zeros(a.shape[0])
            for t in (0.25, 0.5, 0.75):
                m = a + t * (b - a)
                pm = f.surface.evaluate(np.clip(m[:, 0], u0, u1), np.clip(m[:, 1], v0, v1))
                dev = np.maximum(dev, np.linalg.norm(pm - (pa + t * (pb - pa)), axis=1))
            sag.append(2.0 * dev + 1e-9 * size)
            xs0.append(a[:, 0])
            ys0.append(a[:, 1])
            xs1.append(b[:, 0])
            ys1.append(b[:, 1])
            fr.append(free)
            a3.append(pa)
            b3.append(pb)
            k = a.shape[0]
            trim_segments.append((a, b))
            trim_bins.append(int(np.clip(k, 1, _MAX_BINS)))
            n_seg += k
            seg_off.append(n_seg)
        cat = np.concatenate
        self.seg_off = np.array(seg_off, dtype=np.int64)
        self.x0, self.y0, self.x1, self.y1 = (np.ascontiguousarray(cat(v)) for v in
                                              (xs0, ys0, xs1, ys1))
        self.free = cat(fr)
        self.a3 = np.ascontiguousarray(cat(a3))
        self.b3 = np.ascontiguousarray(cat(b3))
        self.sag = np.ascontiguousarray(cat(sag))
        # the split segments (as the boundary search sees them), one slab per segment or so
        self.trims = pack_trims(trim_segments, trim_bins)
        # chunks of consecutive segments with bounding spheres, for the boundary search
        ch_off, ch_seg, ch_c, ch_r = [0], [], [], []
        for f in range(len(faces)):
            lo_s, hi_s = seg_off[f], seg_off[f + 1]
            starts = np.arange(lo_s, hi_s, _CHUNK)
            for st in starts:
                en = min(st + _CHUNK, hi_s)
                pts = np.concatenate([self.a3[st:en], self.b3[st:en]])
                c = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
                ch_c.append(c)
                ch_r.append(float(np.linalg.norm(pts - c, axis=1).max()) * (1 + 1e-12))
                ch_seg.append(st)
            ch_off.append(ch_off[-1] + len(starts))
        ch_seg.append(n_seg)
        self.ch_off = np.array(ch_off, dtype=np.int64)
        self.ch_seg = np.array(ch_seg, dtype=np.int64)
        self.ch_c = np.array(ch_c, dtype=np.float64).reshape(-1, 3)
        self.ch_r = np.array(ch_r, dtype=np.float64)
        # bounds of every face, patch by patch: the search over them makes the answer global
        self.patches = patches if patches is not None else PatchBounds(
            faces, self.tab, (self.seg_off, self.x0, self.y0, self.x1, self.y1),
            patch_size(self.spacing), skip=getattr(model, "supplemental", ()))

    def derivatives(self, faces, uv) -> np.ndarray:
        """Derivatives (N, 3, 3, 3) from the patch tables, ``[:, k, l]`` = d^(k+l)S/du^k dv^l
        for k + l <= 2 (entries with k + l > 2 are not computed): for checking the tables.
        """
        faces = np.ascontiguousarray(faces, dtype=np.int64)
        uv = np.asarray(uv, dtype=np.float64)
        out = np.zeros((faces.shape[0], 3, 3, 3))
        _exact_kernels.eval_many(self.tab, faces, np.ascontiguousarray(uv[:, 0]),
                                 np.ascontiguousarray(uv[:, 1]), out)
        return out

    @property
    def nbytes(self) -> int:
        arrays = list(self.tab) + [self.domains, self.closed, self.rev, self.seg_off, self.x0,
                                   self.y0, self.x1, self.y1, self.a3, self.b3, self.sag,
                                   self.free, self.ch_off, self.ch_seg, self.ch_c, self.ch_r]
        return int(sum(a.nbytes for a in arrays)) + self.trims.nbytes + self.patches.nbytes

    #: False: try only the faces around the nearest model point (the search before the patch
    #: bounds; for tests and benchmarks that measure what the bounds change)
    complete = True

    def _patch_arrays(self):
        arrays = self.patches.arrays()
        return arrays if self.complete else tuple(a[:0] for a in arrays)

    def refine(self, q, idx, fast, pt_face, pt_uv, aux):
        n = q.shape[0]
        foot = np.empty((n, 3))
        normal = np.empty((n, 3))
        dist = np.empty(n)
        face = np.empty(n, dtype=np.int32)
        uv = np.empty((n, 2))
        onb = np.zeros(n, dtype=np.bool_)
        rf, ri, rh, rs = views(fast.rec)
        nbr = record_views(fast.rec)[1]
        pa = self._patch_arrays()

        def chunk(a, b):
            _exact_kernels.refine_cad(q[a:b], idx[a:b], rf, nbr, aux, pt_face, pt_uv, rh, rs,
                                      self.spacing, self.tab, self.domains, self.closed,
                                      self.rev, self.seg_off, self.x0, self.y0, self.x1,
                                      self.y1, self.a3, self.b3, self.sag, self.free,
                                      self.ch_off, self.ch_seg, self.ch_c, self.ch_r,
                                      self.trims, *pa, foot[a:b],
                                      normal[a:b], dist[a:b], face[a:b], uv[a:b], onb[a:b])

        run_chunks(chunk, n, 2048)
        return foot, normal, dist, face, uv, onb


class ExactMesh:
    """Triangles of a mesh model, their unit normals and a kd-tree of their centroids."""

    def __init__(self, model):
        V = np.ascontiguousarray(model.vertices, dtype=np.float64)
        T = np.ascontiguousarray(model.triangles, dtype=np.int64)
        if T.shape[0] == 0:
            raise ValueError("exact closest points need a mesh with at least one triangle")
        n = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
        ln = np.linalg.norm(n, axis=1)
        n[ln > 0] /= ln[ln > 0, None]
        self.verts = V
        self.tri = T
        self.tri_n = np.ascontiguousarray(n)
        centroid = V[T].mean(axis=1)
        self.radius = float(np.linalg.norm(V[T] - centroid[:, None, :], axis=2).max())
        self.kd = cKDTree(centroid)
        # edges used by one triangle only (the mesh's outline), as sorted keys lo * nV + hi
        e = np.sort(np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]), axis=1)
        keys, count = np.unique(e[:, 0] * V.shape[0] + e[:, 1], return_counts=True)
        self.free_keys = keys[count == 1]

    def _on_free_edge(self, face, uv) -> np.ndarray:
        """Feet on a free edge of the mesh (barycentric coordinate 0 on an edge used by one
        triangle): the query lies past the mesh's outline there, as a CAD foot on a free edge."""
        n = face.shape[0]
        if self.free_keys.size == 0 or n == 0:
            return np.zeros(n, dtype=np.bool_)
        tri = self.tri[face]
        u, v = uv[:, 0], uv[:, 1]
        eps = 1e-9
        nv = self.verts.shape[0]
        out = np.zeros(n, dtype=np.bool_)
        for flag, a, b in ((v <= eps, 0, 1), (u <= eps, 0, 2), (u + v >= 1.0 - eps, 1, 2)):
            lo = np.minimum(tri[:, a], tri[:, b])
            hi = np.maximum(tri[:, a], tri[:, b])
            out |= flag & np.isin(lo * nv + hi, self.free_keys)
        return out

    def refine(self, q, idx, fast, pt_face, pt_uv, aux):
        n = q.shape[0]
        T = self.tri.shape[0]
        if T <= _ALL_TRIANGLES:  # a coarse mesh: every triangle, no candidate lists
            cand = np.arange(T, dtype=np.int64)
            lo = np.zeros(n, dtype=np.int64)
            hi = np.full(n, T, dtype=np.int64)
        else:
            # every triangle closer than the nearest model point (which lies on a triangle)
            # has its centroid within that distance plus the largest triangle radius
            reach = np.linalg.norm(q - fast.points[idx], axis=1) + self.radius
            reach = reach * (1 + 1e-12) + 1e-12
            lists = self.kd.query_ball_point(q, reach) if n else np.zeros(0, dtype=object)
            counts = np.fromiter(map(len, lists), dtype=np.int64, count=n)
            ptr = np.zeros(n + 1, dtype=np.int64)
            np.cumsum(counts, out=ptr[1:])
            cand = (np.fromiter(chain.from_iterable(lists), dtype=np.int64,
                                count=int(ptr[-1])) if n else np.zeros(0, dtype=np.int64))
            lo, hi = ptr[:-1], ptr[1:]
        m = int((hi - lo).max()) if n else 0
        foot = np.empty((n, 3))
        normal = np.empty((n, 3))
        dist = np.empty(n)
        face = np.empty(n, dtype=np.int32)
        uv = np.empty((n, 2))

        def chunk(a, b):
            _exact_kernels.refine_mesh(q[a:b], lo[a:b], hi[a:b], cand, self.verts, self.tri,
                                       self.tri_n, np.empty(m), np.empty(m, dtype=np.int64),
                                       foot[a:b], normal[a:b], dist[a:b], face[a:b], uv[a:b])

        run_chunks(chunk, n, 4096)
        return foot, normal, dist, face, uv, self._on_free_edge(face, uv)


class ExactCloud:
    """A point-cloud reference measured to its local surface, not to its nearest point.

    Each query is measured to a **quadric** fitted by weighted least squares to the ``k``
    (default 20) nearest reference points of its nearest reference point (a plane where fewer
    than 10 of them lie on the query's side of a sharp edge or the system is ill-conditioned;
    the nearest reference point itself where fewer than 3 do), in the frame of the nearest model point's normal, which also
    signs the distance (+ along that normal: the same side as the fast mode and the
    registration).  The foot is the closest point of the fitted surface and the normal is its
    normal there.  Kernel and weights: :mod:`shapeverify.nearest._cloud_kernels`.

    A foot with no reference point within 2.5 local spacings (from the reference's own
    12-neighbour radius at the nearest reference point, which is larger at an edge) lies past
    the reference's edge: ``on_boundary``, as a foot on a free CAD edge (the inspection does not
    evaluate it).  On a random 1 mm cloud: none up to 1 mm past the edge (measured on the
    surface extrapolated from the edge, to 2 um), all from 4 mm past it.

    The nearest reference point alone is off by up to half the reference's spacing (a clean
    rescan against a 1 mm cloud read ±0.4 mm); the quadric's error is that of the fit: the
    reference's noise averaged over the neighbours, plus the shape's departure from a quadric
    over them (about 2.5 reference spacings).  Measured (``benchmarks/check_cloud_reference.py``,
    ``tests/test_partial_reference.py``): a gently curved sheet sampled at random 1 mm, p95
    0.15 um noise-free and 10 um with 10 um reference noise; a 2 mm bump of sigma 3 mm sampled at
    random 1 mm, up to 0.09 mm at its top (0.011 mm at 0.5 mm): the reference must resolve the
    shape to the tolerance, as a mesh's triangles must.
    """

    #: neighbours of each query in the fit
    k = 20
    #: neighbours that define a reference point's local spacing (itself included)
    k_ref = 12

    def __init__(self, model):
        from shapeverify.cad._sample_cloud import _neighbour_cov

        self.verts = np.ascontiguousarray(model.vertices, dtype=np.float64)
        m = self.verts.shape[0]
        self.kd = cKDTree(self.verts)
        k = min(max(self.k, self.k_ref), m)
        dk, nb = self.kd.query(self.verts, k=k)
        dk, nb = dk.reshape(m, k), nb.reshape(m, k)
        kr = min(self.k_ref, k)
        self.ref_rk = np.ascontiguousarray(dk[:, kr - 1])
        #: the k nearest reference points of every reference point (itself first)
        self.nbr = np.ascontiguousarray(nb[:, :min(self.k, k)], dtype=np.int32)
        if model.cloud_normals is not None:
            vn = np.asarray(model.cloud_normals, dtype=np.float64)
        else:   # PCA normals (orientation unused: the side test takes |cos|)
            cov = np.empty((m, 3, 3))
            _neighbour_cov(self.verts, np.ascontiguousarray(nb[:, :kr], dtype=np.int64), cov)
            vn = np.linalg.eigh(cov)[1][:, :, 0]
        ln = np.linalg.norm(vn, axis=1, keepdims=True)
        self.normals = np.ascontiguousarray(np.divide(vn, ln, out=np.zeros_like(vn),
                                                      where=ln > 0))

    @property
    def nbytes(self) -> int:
        return int(self.verts.nbytes + self.normals.nbytes + self.ref_rk.nbytes
                   + self.nbr.nbytes)

    def refine(self, q, idx, fast, pt_face, pt_uv, aux):
        from . import _cloud_kernels

        n = q.shape[0]
        foot = np.empty((n, 3))
        normal = np.empty((n, 3))
        dist = np.empty(n)
        onb = np.zeros(n, dtype=np.bool_)
        self.last_fit = np.zeros(n, dtype=np.int8)   # 2 quadric, 1 plane, 0 nearest point
        n0 = fast.normals(idx)

        def chunk(a, b):
            _, near = self.kd.query(q[a:b])
            _cloud_kernels.surface_distance(
                q[a:b], np.ascontiguousarray(near, dtype=np.int64), self.nbr, self.verts,
                self.normals, n0[a:b], self.ref_rk, self.k_ref, foot[a:b], normal[a:b],
                dist[a:b], onb[a:b], self.last_fit[a:b])

        run_chunks(chunk, n, 4096)
        return (foot, normal, dist, np.full(n, -1, dtype=np.int32), np.zeros((n, 2)), onb)


def patch_size(spacing: float) -> float:
    """Longest control-polygon edge (mm) of the patch bounds for a model point spacing."""
    return _PATCH * float(spacing)


def for_model(model, spacing: float, patches=None):
    """The exact refiner for a model's kind ("cad", "mesh" or "points"); ``patches``: a CAD
    model's patch bounds made before (:class:`ExactCAD`)."""
    kind = getattr(model, "kind", "cad")
    if kind == "cad":
        return ExactCAD(model, spacing, patches)
    if kind == "mesh":
        return ExactMesh(model)
    if kind == "points":
        return ExactCloud(model)
    raise ValueError(f"model.kind must be 'cad', 'mesh' or 'points', got {kind!r}")
