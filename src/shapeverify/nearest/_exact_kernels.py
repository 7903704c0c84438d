"""numba driver of the exact closest point on trimmed CAD faces (private).

Its pieces live beside it: the surface evaluation from patch tables (``_surface_kernels``),
the point inversion on a face and on its boundary (``_inversion_kernels``), the trim test
(:mod:`shapeverify.cad._trim_kernels`) and, for mesh models, ``_triangle_kernels``.

CAD faces
---------
Surfaces come as tables of polynomial patches (``tab``, :func:`shapeverify.nearest.exact.
power_tables`), evaluated by :func:`_eval`.  Trimming loops are flat segment arrays (see
:mod:`shapeverify.nearest.exact`): per face ``f`` the segments ``seg_off[f]:seg_off[f+1]``
with end points ``(x0, y0) -> (x1, y1)`` in (u, v), their 3D end points ``a3``, ``b3`` and a
``free`` flag, and the packed trims (:class:`shapeverify.cad.trim.PackedTrims`) for the
even-odd test.

Meshes
------
Triangles ``tri`` (T, 3) into ``verts`` (V, 3), unit normals ``tri_n``, and the triangles
around each vertex (CSR ``vt_ptr``, ``vt_idx``).

All kernels trust their input and allocate scratch space once per call, not per point.

Speed notes (:func:`refine_cad`, a few hundred ns per point): the per-point path (Newton on a
face, the trim test, the normal) is inlined into one function, since a call that passes a
dozen arrays costs about as much as a surface evaluation, and works on views of the arrays
without reference counting (:func:`_borrow`; every array passed into a callee otherwise costs
two atomic operations per call).  The surface derivatives travel as tuples of floats, not in
a scratch array.  The model point records of the next queries are prefetched.

References
----------
Piegl & Tiller, The NURBS Book, 2nd ed., §6.1 (point inversion and projection by Newton).
Ericson, Real-Time Collision Detection (2005), §5.1.5 (closest point on a triangle).
Bærentzen & Aanæs, "Signed distance computation using the angle weighted pseudonormal",
IEEE TVCG 11 (2005) 243-253.
"""

import numpy as np
from numba import njit

from shapeverify.cad._trim_kernels import inside
from shapeverify.cad.trim import PackedTrims

from . import _patch_kernels
from ._borrow import _borrow
from ._inversion_kernels import (  # noqa: F401  (the kernels stay importable from here)
    _chord_d2, _dist2, _normal, _wrap, newton_face, newton_segment, two_closest_chords)
from ._kernels import prefetch
from ._surface_kernels import _eval, _eval_call, _span, _span_near, eval_many  # noqa: F401
from ._triangle_kernels import _corner_angle, closest_on_triangle, refine_mesh  # noqa: F401

_PREFETCH = 4  # queries ahead whose model point records are prefetched


@njit(cache=True, nogil=True)
def refine_cad(Q, idx, rf, nbr, aux, pt_face, pt_uv, rh, rs, spacing, tab, domains, closed,
               rev,
               seg_off, x0, y0, x1, y1, a3, b3, sag, free, ch_off, ch_seg, ch_c, ch_r,
               trims,
               p_face, p_inner, p_centre, p_axes, p_half, p_uv, n_lo, n_hi, n_child, n_first, n_count,
               out_foot, out_normal, out_dist, out_face, out_uv, out_onb):
    """Exact closest point on the trimmed faces around each query's nearest model point.

    Candidate faces: the face of model point ``idx[i]`` (the nearest model point), and those
    of its graph neighbours and of ``aux[idx[i]]`` (its nearest model point on another face
    within a few spacings, -1 if none).  Each face starts from the (u, v) of
    its candidate point closest to the query.  On each face: point inversion
    (:func:`newton_face`); if the foot lies outside the trims (or on the edge of the surface
    domain, where the unconstrained minimum lies outside), the closest point on the face's
    boundary instead (the two closest chords of the trimming polyline refined with
    :func:`newton_segment`), flagged ``on_boundary`` when that segment is a free edge.

    The nearest point's face is always solved.  The other faces are solved when that foot
    ended on the boundary (the closest point may be across a shared edge), or when their
    candidate point is at most ``spacing`` farther from the query than the nearest model
    point (concave corners, and the rare query whose nearest model point the tree missed).
    Then every patch of every face (:mod:`shapeverify.nearest.patches`) whose oriented
    bounding box is closer than the best foot so far is tried too (unless a foot already
    found on that face lies in the patch's parameter box): Newton from the patch's centre,
    kept in its parameter box, then the trim test (none for patches wholly inside the trims)
    and the face's boundary if outside.  The seeds only make the search fast, the bounds
    make it complete.
    The closest candidate wins; its distance is signed by the face's outward normal.
    """
    n = pt_face.shape[0]
    K = nbr.shape[1]
    multi = domains.shape[0] > 1
    # the arguments outlive the call: views without reference counting for the callees
    tab = (_borrow(tab[0]), _borrow(tab[1]), _borrow(tab[2]), _borrow(tab[3]),
           _borrow(tab[4]), _borrow(tab[5]), _borrow(tab[6]), _borrow(tab[7]),
           _borrow(tab[8]), _borrow(tab[9]), _borrow(tab[10]))
    domains = _borrow(domains)
    closed = _borrow(closed)
    rh = _borrow(rh)
    rs = _borrow(rs)
    x0 = _borrow(x0)
    y0 = _borrow(y0)
    x1 = _borrow(x1)
    y1 = _borrow(y1)
    a3 = _borrow(a3)
    b3 = _borrow(b3)
    ch_off = _borrow(ch_off)
    ch_seg = _borrow(ch_seg)
    ch_c = _borrow(ch_c)
    ch_r = _borrow(ch_r)
    trims = PackedTrims(_borrow(trims.lo), _borrow(trims.hi), _borrow(trims.inv),
                        _borrow(trims.bin_off), _borrow(trims.bin_start), _borrow(trims.bin_xy))
    # flat element strides of the per-point rows, for prefetching
    rf_row = rf.strides[0] // rf.itemsize
    uv_row = pt_uv.strides[0] // pt_uv.itemsize
    cf = np.empty(K + 2, dtype=np.int64)
    cj = np.empty(K + 2, dtype=np.int64)
    cd = np.empty(K + 2)
    n_patch = p_face.shape[0]
    walk = n_patch > 0
    pk = np.empty(K + 2 + n_patch, dtype=np.int64)
    pd = np.empty(K + 2 + n_patch)
    sf = np.empty(K + 2 + n_patch, dtype=np.int64)
    su = np.empty(K + 2 + n_patch)
    sv = np.empty(K + 2 + n_patch)
    stack = np.empty(_patch_kernels.STACK, dtype=np.int64)
    searched = np.full(domains.shape[0], -1, dtype=np.int64)
    dom_s = domains.copy()  # row f is a patch's box while that patch is solved
    cl_s = closed.copy()
    p_centre = _borrow(p_centre)
    p_axes = _borrow(p_axes)
    p_half = _borrow(p_half)
    p_uv = _borrow(p_uv)
    n_lo = _borrow(n_lo)
    n_hi = _borrow(n_hi)
    n_child = _borrow(n_child)
    n_first = _borrow(n_first)
    n_count = _borrow(n_count)
    max_ch = 1
    for f in range(ch_off.shape[0] - 1):
        max_ch = max(max_ch, ch_off[f + 1] - ch_off[f])
    lb = np.empty(max_ch)
    m = Q.shape[0]
    for i in range(m):
        # the model point data of the queries ahead (their records are read at random)
        if i + _PREFETCH < m:
            bb = idx[i + _PREFETCH]
            prefetch(rf, bb * rf_row)
            prefetch(pt_face, bb)
            prefetch(pt_uv, bb * uv_row)
            prefetch(aux, bb)
        q0 = Q[i, 0]
        q1 = Q[i, 1]
        q2 = Q[i, 2]
        b = idx[i]
        nc = 1
        cf[0] = pt_face[b]
        cj[0] = b
        cd[0] = (rf[b, 0] - q0) ** 2 + (rf[b, 1] - q1) ** 2 + (rf[b, 2] - q2) ** 2
        # faces of the neighbours and of the other-face point of b (none on a one-face model)
        for k in range(K + 1 if multi else 0):
            j = nbr[b, k] if k < K else aux[b]
            if j < 0 or j >= n:
                continue
            fj = pt_face[j]
            if fj == cf[0]:
                continue
            dj = (rf[j, 0] - q0) ** 2 + (rf[j, 1] - q1) ** 2 + (rf[j, 2] - q2) ** 2
            new = True
            for c in range(1, nc):
                if cf[c] == fj:
                    new = False
                    if dj < cd[c]:
                        cj[c] = j
                        cd[c] = dj
                    break
            if new:
                cf[nc] = fj
                cj[nc] = j
                cd[nc] = dj
                nc += 1
        near = (np.sqrt(cd[0]) + spacing) ** 2
        best = np.inf
        primary_on_edge = False
        ns = 0
        nt = nc
        walked = not walk
        c = -1
        while True:
            c += 1
            if c == nt:
                if walked:
                    break
                # the patches that can still hold a closer foot
                walked = True
                nt = _patch_kernels.candidates(q0, q1, q2, best, p_centre, p_axes, p_half,
                                               n_lo, n_hi, n_child, n_first, n_count, stack,
                                               pk, pd, nc)
                c -= 1
                continue
            if c < nc:
                f = cf[c]
                if c > 0 and not primary_on_edge and cd[c] > near:
                    continue
                us = np.float64(pt_uv[cj[c], 0])
                vs = np.float64(pt_uv[cj[c], 1])
            else:
                k = pk[c]
                if not pd[c] < best:
                    continue
                f = p_face[k]
                seen = False
                for r in range(ns):
                    if (sf[r] == f and p_uv[k, 0] <= su[r] <= p_uv[k, 1]
                            and p_uv[k, 2] <= sv[r] <= p_uv[k, 3]):
                        seen = True
                        break
                if seen:
                    continue
                us = 0.5 * (p_uv[k, 0] + p_uv[k, 1])
                vs = 0.5 * (p_uv[k, 2] + p_uv[k, 3])
            on_patch = c >= nc
            if on_patch:  # solve on the patch's parameter box only
                dom_s[f, 0, 0] = p_uv[k, 0]
                dom_s[f, 0, 1] = p_uv[k, 1]
                dom_s[f, 1, 0] = p_uv[k, 2]
                dom_s[f, 1, 1] = p_uv[k, 3]
                cl_s[f, 0] = False
                cl_s[f, 1] = False
            u, v, d2, edge, D = newton_face(tab, dom_s, cl_s, f, us, vs, q0, q1, q2)
            onb = False
            if not edge:  # a local minimum (not stopped by a box): its patch needs no retry
                sf[ns] = f
                su[ns] = u
                sv[ns] = v
                ns += 1
            if on_patch:
                for r in range(2):
                    dom_s[f, r, 0] = domains[f, r, 0]
                    dom_s[f, r, 1] = domains[f, r, 1]
                    cl_s[f, r] = closed[f, r]
                # a patch wholly inside the trims needs no trim test; its foot, even on the
                # patch's border, is a point of the face (a closer one lies on another
                # patch).  On an edge of the face's domain the trims may run: search them.
                trim = ((not closed[f, 0] and (u <= domains[f, 0, 0] or u >= domains[f, 0, 1]))
                        or (not closed[f, 1] and (v <= domains[f, 1, 0]
                                                  or v >= domains[f, 1, 1]))
                        or (not p_inner[k] and not inside(trims, f, u, v)))
            else:
                trim = edge or not inside(trims, f, u, v)
            if trim:
                if searched[f] == i:
                    continue  # this face's boundary was searched for this query already
                searched[f] = i
                # the two closest chords of the face's trimming polylines
                s1, t1, e1, s2, t2, e2 = two_closest_chords(q0, q1, q2, f, a3, b3, ch_off,
                                                            ch_seg, ch_c, ch_r, lb)
                # a segment's curve lies within sag[s] of its chord: refine only chords
                # that can still beat the best foot found so far
                d2 = np.inf
                if s1 >= 0 and np.sqrt(e1) - sag[s1] < np.sqrt(best):
                    _, u, v, d2 = newton_segment(tab, domains, f, s1, t1, x0, y0, x1, y1,
                                                 q0, q1, q2)
                    onb = free[s1]
                if s2 >= 0 and np.sqrt(e2) - sag[s2] < np.sqrt(min(best, d2)):
                    _, ub, vb, db = newton_segment(tab, domains, f, s2, t2, x0, y0, x1, y1,
                                                   q0, q1, q2)
                    if db < d2:
                        u = ub
                        v = vb
                        d2 = db
                        onb = free[s2]
                if not d2 < best:
                    continue
                D = _eval_call(tab, f, u, v, np.int64(1))  # int64: one compiled _eval_call
                if c == 0:
                    primary_on_edge = True
            # a patch's foot must beat the seeds' clearly: a tie (the same point, found
            # again) keeps the first answer and its flags
            if d2 < (best if c < nc else best * (1.0 - 1e-12)):
                best = d2
                p0 = D[0]
                p1 = D[1]
                p2 = D[2]
                n0, n1, n2 = _normal(D, rev[f], b, rh, rs)
                out_foot[i, 0] = p0
                out_foot[i, 1] = p1
                out_foot[i, 2] = p2
                out_normal[i, 0] = n0
                out_normal[i, 1] = n1
                out_normal[i, 2] = n2
                d = np.sqrt(d2)
                if (q0 - p0) * n0 + (q1 - p1) * n1 + (q2 - p2) * n2 < 0.0:
                    d = -d
                out_dist[i] = d
                out_face[i] = f
                out_uv[i, 0] = u
                out_uv[i, 1] = v
                out_onb[i] = onb
