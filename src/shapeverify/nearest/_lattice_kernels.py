"""numba kernels: exact nearest points of several lattice points at once (private; used by
:mod:`._build_kernels`).

A refined cell's children need the exact nearest model point of the parent's 27 lattice points
(their vertices), a failed cell that of its 7 extra samples, all found by brute force in the
cell's candidate list.  One pass over the list offers each candidate to all the points at once,
in vector registers (:func:`._intrinsics.nearest_update32`: 32 lanes for the 27 lattice
points, 8 for the 7 samples).  The squared distances are formed in the order a single search
forms them (``(e0 e0 + e1 e1) + e2 e2``, the coordinates ``q = origin + size * integer``), so
the distances, and the nearest points (lowest index on ties, in any candidate order), are bit
for bit those of one search per point.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._intrinsics import nearest_update8, nearest_update32

LANES = 32          # the 27 lattice points, padded to a vector width
SCRATCH = 5 * LANES  # scratch a search needs (:func:`._intrinsics.nearest_update32`)


@njit(cache=True, nogil=True)
def nn_lattice(qx, qy, qz, pts, lst, a, b, st, out_i, out_d):
    """Exact nearest point among ``lst[a:b]`` (lowest index on ties, as a linear scan) of each
    of the 27 points ``(qx[t % 3], qy[t // 3 % 3], qz[t // 9])``: into ``out_i`` (27,) int64
    (-1 for an empty list) and ``out_d`` (27,) (distance).  ``st`` (SCRATCH,) float64
    scratch."""
    for t in range(LANES):
        u = min(t, 26)  # padding lanes: copies of the last point
        st[t] = qx[u % 3]
        st[LANES + t] = qy[u // 3 % 3]
        st[2 * LANES + t] = qz[u // 9]
        st[3 * LANES + t] = np.inf
        st[4 * LANES + t] = -1.0
    for s in range(a, b):
        j = lst[s]
        nearest_update32(st, pts[j, 0], pts[j, 1], pts[j, 2], np.float64(j))
    for t in range(27):
        out_i[t] = np.int64(st[4 * LANES + t])
        out_d[t] = np.sqrt(st[3 * LANES + t])


@njit(cache=True, nogil=True)
def nn_extra(qx, qy, qz, extra, pts, lst, a, b, st, out_i, out_d):
    """:func:`nn_lattice` for the points ``(qx[e0], qy[e1], qz[e2])`` of the rows of ``extra``
    (E, 3) int64, E <= 8 (a failed cell's extra samples), into ``out_i``, ``out_d`` (E,);
    ``st`` (SCRATCH,) float64 scratch."""
    ne = extra.shape[0]
    for e in range(8):
        u = min(e, ne - 1)
        st[e] = qx[extra[u, 0]]
        st[8 + e] = qy[extra[u, 1]]
        st[16 + e] = qz[extra[u, 2]]
        st[24 + e] = np.inf
        st[32 + e] = -1.0
    for s in range(a, b):
        j = lst[s]
        nearest_update8(st, pts[j, 0], pts[j, 1], pts[j, 2], np.float64(j))
    for e in range(ne):
        out_i[e] = np.int64(st[32 + e])
        out_d[e] = np.sqrt(st[24 + e])


@njit(cache=True, nogil=True)
def nn_one(q0, q1, q2, pts, lst, a, b):
    """Exact nearest point of one point q among ``lst[a:b]`` (lowest index on ties):
    (index, distance).  The search the functions above do for several points at once (the
    tests' reference)."""
    best = -1
    bd = np.inf
    for s in range(a, b):
        j = lst[s]
        e0 = pts[j, 0] - q0
        e1 = pts[j, 1] - q1
        e2 = pts[j, 2] - q2
        d = e0 * e0 + e1 * e1 + e2 * e2
        if d < bd or (d == bd and j < best):
            bd = d
            best = j
    return best, np.sqrt(bd)
