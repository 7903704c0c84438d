"""numba kernels of the Distance Varying Grid tree's build: the classification of one level's
cells (private).

A cell is FAR, a single-seed leaf, a multi-seed leaf or refined (see the tree layout in
:mod:`shapeverify.nearest._kernels`); :func:`classify` decides the first three from walks
from the nearest model point of the cell's centre, :func:`classify_multi` the multi-seed
leaves of the cells it failed.  :mod:`shapeverify.nearest._build_kernels` feeds them the exact
nearest points of the cells' vertices.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import walk_inline as walk

# the 7 extra samples of a cell in half-cell units: centre, then the 6 face centres
EXTRA = np.array([[1, 1, 1], [0, 1, 1], [2, 1, 1], [1, 0, 1], [1, 2, 1], [1, 1, 0], [1, 1, 2]],
                 dtype=np.int64)


@njit(cache=True, nogil=True)
def classify(cells, origin, size, samples, nn_idx, nn_d, rf, ri, rh, rs, max_distance,
             max_moves, out_kind, out_seed):
    """First pass over the cells of one level: FAR (0), single-seed leaf (1) or failed (2).

    cells : (M, 3) int64 integer cell coordinates at this level (cell size ``size``).
    samples : (M, 8) int64 row of each cell's 8 vertices (octant order) in ``nn_idx`` /
        ``nn_d`` (exact nearest model point and distance; inf beyond the query bound).

    A cell is FAR when every vertex is farther than ``max_distance + r`` (r = half diagonal):
    every point of the cell is within r of a vertex, so none is within ``max_distance``.  The
    seed is the end of a walk towards the centre from the nearest point of the closest vertex.
    The cell is a single-seed leaf when the walk from the seed reaches the exact nearest point
    of every vertex within ``max_moves`` moves; else it has failed (see :func:`classify_multi`).
    """
    r = 0.5 * np.sqrt(3.0) * size
    tol = 1e-12 * size
    for m in range(cells.shape[0]):
        dmin = np.inf
        vmin = 0
        for o in range(8):
            d = nn_d[samples[m, o]]
            if d < dmin:
                dmin = d
                vmin = o
        out_seed[m] = -1
        if not (dmin <= max_distance + r):
            out_kind[m] = 0
            continue
        c0 = origin[0] + size * (cells[m, 0] + 0.5)
        c1 = origin[1] + size * (cells[m, 1] + 0.5)
        c2 = origin[2] + size * (cells[m, 2] + 0.5)
        seed, _, _ = walk(c0, c1, c2, nn_idx[samples[m, vmin]], rf, ri, rh, rs, 64)
        out_seed[m] = seed
        out_kind[m] = 1
        for o in range(8):
            q0 = origin[0] + size * (cells[m, 0] + (o & 1))
            q1 = origin[1] + size * (cells[m, 1] + ((o >> 1) & 1))
            q2 = origin[2] + size * (cells[m, 2] + ((o >> 2) & 1))
            _, d2, mv = walk(q0, q1, q2, seed, rf, ri, rh, rs, max_moves + 1)
            if mv > max_moves or np.sqrt(d2) > nn_d[samples[m, o]] * (1.0 + 1e-12) + tol:
                out_kind[m] = 2
                break


@njit(cache=True, nogil=True, inline="always")
def _seeded_ok(q0, q1, q2, seeds, cnt, rf, ri, rh, rs, max_moves, d_exact, tol):
    """Whether the query procedure (a walk from each seed) finds the exact nearest point."""
    bd = np.inf
    mv = 0
    for s in range(cnt):
        _, d2, k = walk(q0, q1, q2, seeds[s], rf, ri, rh, rs, max_moves + 1)
        mv = max(mv, k)
        bd = min(bd, d2)
    return mv <= max_moves and np.sqrt(bd) <= d_exact * (1.0 + 1e-12) + tol


@njit(cache=True, nogil=True)
def classify_multi(cells, origin, size, samples, nn_idx, nn_d, extra, xn_idx, xn_d, first_seed,
                   rf, ri, rh, rs, max_moves, max_seeds, last_level, out_kind, out_seeds,
                   out_nseeds):
    """Second pass over the cells that failed :func:`classify`: multi-seed leaf (1) or refine (2).

    Seeds: the cell's seed plus the exact nearest point of each vertex that the query
    procedure (a walk of at most ``max_moves`` from each seed) still gets wrong.  The leaf
    is accepted when it has at most ``max_seeds`` seeds and the procedure is right at all 8
    vertices and at the 7 extra samples (centre and face centres, ``extra`` (M, 7) rows into
    ``xn_idx`` / ``xn_d``).  On the last level the cell is always a leaf; it keeps the
    nearest points of failing extra samples as further seeds (out_seeds has 16 columns).
    """
    tol = 1e-12 * size
    h = 0.5 * size
    cap = out_seeds.shape[1]
    for m in range(cells.shape[0]):
        seeds = out_seeds[m]
        seeds[0] = first_seed[m]
        cnt = 1
        ok = True
        for rnd in range(2):
            for o in range(8):
                q0 = origin[0] + size * (cells[m, 0] + (o & 1))
                q1 = origin[1] + size * (cells[m, 1] + ((o >> 1) & 1))
                q2 = origin[2] + size * (cells[m, 2] + ((o >> 2) & 1))
                iv = samples[m, o]
                if not _seeded_ok(q0, q1, q2, seeds, cnt, rf, ri, rh, rs, max_moves, nn_d[iv],
                                  tol):
                    if rnd == 0 and cnt < cap:
                        seeds[cnt] = nn_idx[iv]
                        cnt += 1
                    else:
                        ok = False
        for e in range(7):
            q0 = origin[0] + h * (2 * cells[m, 0] + EXTRA[e, 0])
            q1 = origin[1] + h * (2 * cells[m, 1] + EXTRA[e, 1])
            q2 = origin[2] + h * (2 * cells[m, 2] + EXTRA[e, 2])
            ix = extra[m, e]
            if not _seeded_ok(q0, q1, q2, seeds, cnt, rf, ri, rh, rs, max_moves, xn_d[ix], tol):
                ok = False
                if last_level and cnt < cap:
                    seeds[cnt] = xn_idx[ix]
                    cnt += 1
        out_nseeds[m] = cnt
        out_kind[m] = 1 if (ok and cnt <= max_seeds) or last_level else 2
