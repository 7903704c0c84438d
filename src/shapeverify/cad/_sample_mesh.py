"""Model points on triangle meshes: shifted square lattices per triangle, then thinning (private).

See :mod:`shapeverify.cad.sampling` (*Mesh models*).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._sample_common import _BATCH_CANDIDATES, _CAND, _RADIUS, _Parts, _check_count, _near, _thin


@njit(cache=True)
def _lattice_count_fill(A, B, C, h, off, fill, tri, bary):
    """Points of a shifted square lattice (step h) inside each triangle (count; then fill)."""
    m = 0
    for t in range(A.shape[0]):
        e = np.empty((3, 3))
        for k in range(3):
            e[0, k] = B[t, k] - A[t, k]
            e[1, k] = C[t, k] - A[t, k]
            e[2, k] = C[t, k] - B[t, k]
        # longest edge direction as the lattice's first axis
        best, lb = 0, -1.0
        for q in range(3):
            lq = e[q, 0] ** 2 + e[q, 1] ** 2 + e[q, 2] ** 2
            if lq > lb:
                best, lb = q, lq
        if lb <= 0.0:
            continue
        ax = e[best] / math.sqrt(lb)
        nrm = np.empty(3)
        nrm[0] = e[0, 1] * e[1, 2] - e[0, 2] * e[1, 1]
        nrm[1] = e[0, 2] * e[1, 0] - e[0, 0] * e[1, 2]
        nrm[2] = e[0, 0] * e[1, 1] - e[0, 1] * e[1, 0]
        ln = math.sqrt(nrm[0] ** 2 + nrm[1] ** 2 + nrm[2] ** 2)
        if ln <= 0.0:
            continue
        nrm /= ln
        ay = np.empty(3)
        ay[0] = nrm[1] * ax[2] - nrm[2] * ax[1]
        ay[1] = nrm[2] * ax[0] - nrm[0] * ax[2]
        ay[2] = nrm[0] * ax[1] - nrm[1] * ax[0]
        # 2-D coordinates of B and C relative to A
        bx = e[0, 0] * ax[0] + e[0, 1] * ax[1] + e[0, 2] * ax[2]
        by = e[0, 0] * ay[0] + e[0, 1] * ay[1] + e[0, 2] * ay[2]
        cx = e[1, 0] * ax[0] + e[1, 1] * ax[1] + e[1, 2] * ax[2]
        cy = e[1, 0] * ay[0] + e[1, 1] * ay[1] + e[1, 2] * ay[2]
        det = bx * cy - by * cx
        if det == 0.0:
            continue
        x0, x1 = min(0.0, bx, cx), max(0.0, bx, cx)
        y0, y1 = min(0.0, by, cy), max(0.0, by, cy)
        i0 = math.ceil(x0 / h - off[t, 0])
        j0 = math.ceil(y0 / h - off[t, 1])
        i1 = math.floor(x1 / h - off[t, 0])
        j1 = math.floor(y1 / h - off[t, 1])
        for i in range(i0, i1 + 1):
            x = (i + off[t, 0]) * h
            for j in range(j0, j1 + 1):
                y = (j + off[t, 1]) * h
                u = (x * cy - y * cx) / det
                v = (bx * y - by * x) / det
                if u >= 0.0 and v >= 0.0 and u + v <= 1.0:
                    if fill:
                        tri[m] = t
                        bary[m, 0] = u
                        bary[m, 1] = v
                    m += 1
    return m


def _sample_mesh(model, s, rng):
    V = np.asarray(model.vertices, dtype=np.float64)
    Tr = np.asarray(model.triangles, dtype=np.int64)
    if len(Tr) == 0:
        raise ValueError(f"mesh model {getattr(model, 'source', '')!r} has no triangles")
    A, B, C = V[Tr[:, 0]], V[Tr[:, 1]], V[Tr[:, 2]]
    cr = np.cross(B - A, C - A)
    dbl = np.linalg.norm(cr, axis=1)
    _check_count(0.5 * dbl.sum(), s)
    with np.errstate(invalid="ignore", divide="ignore"):
        tn = cr / dbl[:, None]
    h = _CAND * s
    r = _RADIUS * s
    parts = _Parts()
    # batches of triangles with about _BATCH_CANDIDATES candidates each
    est = np.cumsum(0.5 * dbl / (h * h) + 1.0)
    cuts = np.searchsorted(est, np.arange(_BATCH_CANDIDATES, est[-1], _BATCH_CANDIDATES))
    edges = np.unique(np.concatenate([[0], cuts, [len(Tr)]]))
    for start, stop in zip(edges[:-1], edges[1:]):
        sl = slice(start, stop)
        off = rng.random((stop - start, 2))
        a, b, c = (np.ascontiguousarray(X[sl]) for X in (A, B, C))
        m = _lattice_count_fill(a, b, c, h, off, False, np.empty(0, np.int64), np.empty((0, 2)))
        tri = np.empty(m, np.int64)
        bary = np.empty((m, 2))
        _lattice_count_fill(a, b, c, h, off, True, tri, bary)
        tri += start
        P = A[tri] + bary[:, :1] * (B[tri] - A[tri]) + bary[:, 1:] * (C[tri] - A[tri])
        N = tn[tri]
        idx = _thin(P, N, r)  # lattice order, triangle by triangle (coherent, regular)
        t = B[tri[idx]] - A[tri[idx]]
        t /= np.linalg.norm(t, axis=1)[:, None]
        parts.add(P[idx], N[idx], t, tri[idx].astype(np.int32), bary[idx])
    P, N, T, F, UV = parts.cat()
    idx = _thin(P, N, r)
    boundary = _mesh_free_edge_flags(V, Tr, P[idx], s)
    return P[idx], N[idx], T[idx], F[idx], UV[idx], boundary


def _mesh_free_edges(Tr):
    """Edges (E, 2) used by exactly one triangle."""
    e = np.concatenate([Tr[:, [0, 1]], Tr[:, [1, 2]], Tr[:, [2, 0]]])
    e = np.sort(e, axis=1)
    uniq, cnt = np.unique(e, axis=0, return_counts=True)
    return uniq[cnt == 1]


def _mesh_free_edge_flags(V, Tr, pts, s):
    free = _mesh_free_edges(Tr)
    if len(free) == 0:
        return np.zeros(len(pts), bool)
    A, B = V[free[:, 0]], V[free[:, 1]]
    k = np.maximum(1, np.ceil(np.linalg.norm(B - A, axis=1) / (0.25 * s))).astype(np.int64)
    seg = np.repeat(np.arange(len(A)), k)
    tt = (np.arange(k.sum()) - np.repeat(np.cumsum(k) - k, k)) / np.repeat(k, k)
    samples = np.concatenate([A[seg] + tt[:, None] * (B[seg] - A[seg]), B])
    return _near([samples], pts, s)
