"""numba kernels: exact nearest points of several lattice points at once (private; used by
:mod:`._build_kernels`).

A refined cell's children need the exact nearest model point of the parent's 27 lattice points
(their vertices), a failed cell that of its 7 extra samples, all found by brute force in the
cell's candidate list.  The points lie on a 3 x 3 x 3 lattice, so their squared distances to a
candidate p are sums ``(x_i - p_x)^2 + (y_j - p_y)^2 + (z_k - p_z)^2`` of 9 squares: one pass
over the list computes the 9 squares of each candidate and adds them up for every lattice
point, instead of one pass (3 subtractions, 3 products) per lattice point.  The sums are
formed in the same order as a single search does (``(e0 e0 + e1 e1) + e2 e2``, the coordinates
``q = origin + size * integer``), so the distances, and the nearest points (lowest index on
ties), are bit for bit those of one search per point.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, inline="always")
def _squares(pts, j, qx, qy, qz, sq):
    """sq[0:3], sq[3:6], sq[6:9]: (p_x - qx[i])^2, (p_y - qy[i])^2, (p_z - qz[i])^2 of
    model point j."""
    x = pts[j, 0]
    y = pts[j, 1]
    z = pts[j, 2]
    for i in range(3):
        e = x - qx[i]
        sq[i] = e * e
        e = y - qy[i]
        sq[3 + i] = e * e
        e = z - qz[i]
        sq[6 + i] = e * e


@njit(cache=True, nogil=True)
def nn_lattice(qx, qy, qz, pts, lst, a, b, sq, out_i, out_d):
    """Exact nearest point among ``lst[a:b]`` (lowest index on ties, as a linear scan) of each
    of the 27 points ``(qx[t % 3], qy[t // 3 % 3], qz[t // 9])``: into ``out_i`` (27,) int64
    (-1 for an empty list) and ``out_d`` (27,) (distance).  ``sq`` (9,) scratch."""
    for t in range(27):
        out_i[t] = -1
        out_d[t] = np.inf
    for s in range(a, b):
        j = lst[s]
        _squares(pts, j, qx, qy, qz, sq)
        for k in range(3):
            ck = sq[6 + k]
            for jj in range(3):
                bj = sq[3 + jj]
                for i in range(3):
                    t = i + 3 * jj + 9 * k
                    d = (sq[i] + bj) + ck
                    bt = out_d[t]
                    if d <= bt:
                        if d < bt or j < out_i[t]:
                            out_d[t] = d
                            out_i[t] = j
    for t in range(27):
        out_d[t] = np.sqrt(out_d[t])


@njit(cache=True, nogil=True)
def nn_extra(qx, qy, qz, extra, pts, lst, a, b, sq, out_i, out_d):
    """:func:`nn_lattice` for the points ``(qx[e0], qy[e1], qz[e2])`` of the rows of ``extra``
    (E, 3) int64 (a failed cell's extra samples), into ``out_i``, ``out_d`` (E,)."""
    ne = extra.shape[0]
    for e in range(ne):
        out_i[e] = -1
        out_d[e] = np.inf
    for s in range(a, b):
        j = lst[s]
        _squares(pts, j, qx, qy, qz, sq)
        for e in range(ne):
            d = (sq[extra[e, 0]] + sq[3 + extra[e, 1]]) + sq[6 + extra[e, 2]]
            bt = out_d[e]
            if d <= bt:
                if d < bt or j < out_i[e]:
                    out_d[e] = d
                    out_i[e] = j
    for e in range(ne):
        out_d[e] = np.sqrt(out_d[e])


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
