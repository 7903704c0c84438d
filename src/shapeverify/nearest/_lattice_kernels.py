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

The top grid's vertices, which have no candidate list yet, search the model points binned on
the top grid instead (:func:`grid_nearest`, in place of a kd-tree).
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
        bd, best = _closer(q0, q1, q2, pts, lst[s], bd, best)
    return best, np.sqrt(bd)


@njit(cache=True, nogil=True, inline="always")
def _closer(q0, q1, q2, pts, j, bd, bi):
    """(squared distance, index) of the closer of point j and the best (bd, bi) so far: j
    when strictly closer, or as close with a lower index (a linear scan's tie rule)."""
    e0 = pts[j, 0] - q0
    e1 = pts[j, 1] - q1
    e2 = pts[j, 2] - q2
    d = e0 * e0 + e1 * e1 + e2 * e2
    if d < bd or (d == bd and j < bi):
        return d, j
    return bd, bi


@njit(cache=True, nogil=True)
def grid_nearest(vx, pts, order, start, dims, origin, size, bound, out_i, out_d):
    """Exact nearest model point of grid vertices by a search of the points binned on the
    grid: what a kd-tree query bounded by ``bound`` gives (``cKDTree.query``), without it.

    vx : (V, 3) int64 vertex coordinates (vertex v at ``origin + size * vx[v]``, the corner
    of bins vx - 1 and vx); order, start : the points sorted by bin (bins of side ``size``,
    ``dims`` of them) and the start of each bin's run.  Into ``out_i`` (V,) int64 and
    ``out_d`` (V,) the nearest point (lowest index on ties, as a linear scan) and its distance
    (``sqrt((e0 e0 + e1 e1) + e2 e2)``, as the kd-tree forms it), or (0, inf) when no point is
    closer than ``bound``.  The bins are searched in shells of growing Chebyshev distance: a
    point outside the first k shells is at least k * size (less a rounding margin) away.
    """
    # a bin g bins away (per axis, integers) is at least |g| size (less a margin) away
    s2 = (size * (1.0 - 1e-9)) ** 2
    for v in range(vx.shape[0]):
        c0 = vx[v, 0]
        c1 = vx[v, 1]
        c2 = vx[v, 2]
        q0 = origin[0] + size * np.float64(c0)
        q1 = origin[1] + size * np.float64(c1)
        q2 = origin[2] + size * np.float64(c2)
        bd = np.inf
        bi = -1
        k = 0
        while True:
            lim = k * size * (1.0 - 1e-9) - 1e-9 * size
            if k > 0 and (lim > bound or lim * lim > bd):
                break  # every point not searched is farther than the bound, or the best
            x_lo = c0 - 1 - k
            x_hi = c0 + k
            y_lo = c1 - 1 - k
            y_hi = c1 + k
            z_lo = c2 - 1 - k
            z_hi = c2 + k
            if x_lo < 0 and y_lo < 0 and z_lo < 0 and x_hi >= dims[0] and y_hi >= dims[1] \
                    and z_hi >= dims[2]:
                break  # the shell is beyond the grid on every side: all searched
            for ax in range(max(x_lo, 0), min(x_hi, dims[0] - 1) + 1):
                xe = ax == x_lo or ax == x_hi
                gx = max(ax - c0, c0 - 1 - ax, 0)
                for ay in range(max(y_lo, 0), min(y_hi, dims[1] - 1) + 1):
                    gy = max(ay - c1, c1 - 1 - ay, 0)
                    gxy = gx * gx + gy * gy
                    if gxy * s2 > bd:
                        continue  # the column of bins is farther than the best
                    base = (ax * dims[1] + ay) * dims[2]
                    step = 1 if (xe or ay == y_lo or ay == y_hi) else z_hi - z_lo
                    for az in range(z_lo, z_hi + 1, step):
                        if az < 0 or az >= dims[2]:
                            continue
                        gz = max(az - c2, c2 - 1 - az, 0)
                        if (gxy + gz * gz) * s2 > bd:
                            continue  # the bin is farther than the best
                        for s in range(start[base + az], start[base + az + 1]):
                            bd, bi = _closer(q0, q1, q2, pts, order[s], bd, bi)
            k += 1
        dist = np.sqrt(bd)
        if dist < bound:
            out_i[v] = bi
            out_d[v] = dist
        else:
            out_i[v] = 0
            out_d[v] = np.inf
