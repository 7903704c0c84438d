"""numba kernels of the patch bounds (:mod:`shapeverify.nearest.patches`), private.

* :func:`crossed_by_trims`: which patch parameter boxes a trimming segment's box overlaps;
* :func:`build_bvh`: the bounding-volume hierarchy over the patches (median splits);
* :func:`candidates`: the patches whose oriented box is closer to a query than a squared
  distance (inlined into :func:`shapeverify.nearest._exact_kernels.refine_cad`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

STACK = 256  # walk stack (the build, a balanced median split, is about log2(K / 4) deep)


@njit(cache=True, nogil=True)
def crossed_by_trims(face, uvbox, seg_off, x0, y0, x1, y1, out):
    """out[k] = some trimming segment of patch k's face has a (u, v) box overlapping the
    patch's parameter box (closed intervals)."""
    for k in range(face.shape[0]):
        f = face[k]
        ua = uvbox[k, 0]
        ub = uvbox[k, 1]
        va = uvbox[k, 2]
        vb = uvbox[k, 3]
        hit = False
        for s in range(seg_off[f], seg_off[f + 1]):
            if (max(x0[s], x1[s]) >= ua and min(x0[s], x1[s]) <= ub
                    and max(y0[s], y1[s]) >= va and min(y0[s], y1[s]) <= vb):
                hit = True
                break
        out[k] = hit


@njit(cache=True, nogil=True)
def build_bvh(centre, box_lo, box_hi, order, leaf, nlo, nhi, child, first, count):
    """Median-split hierarchy; reorders ``order`` in place so that every node's patches are
    ``order[first:first + count]``.  Returns the number of nodes (node 0 is the root; the
    children of an inner node are ``child`` and ``child + 1``, a leaf has ``child == -1``)."""
    m = order.shape[0]
    st_node = np.empty(256, dtype=np.int64)
    st_lo = np.empty(256, dtype=np.int64)
    st_hi = np.empty(256, dtype=np.int64)
    sp = 0
    n_nodes = 1
    st_node[0] = 0
    st_lo[0] = 0
    st_hi[0] = m
    sp = 1
    key = np.empty(m)
    while sp > 0:
        sp -= 1
        nd = st_node[sp]
        a = st_lo[sp]
        b = st_hi[sp]
        clo = np.full(3, np.inf)
        chi = np.full(3, -np.inf)
        for c in range(3):
            nlo[nd, c] = np.inf
            nhi[nd, c] = -np.inf
        for r in range(a, b):
            k = order[r]
            for c in range(3):
                nlo[nd, c] = min(nlo[nd, c], box_lo[k, c])
                nhi[nd, c] = max(nhi[nd, c], box_hi[k, c])
                clo[c] = min(clo[c], centre[k, c])
                chi[c] = max(chi[c], centre[k, c])
        first[nd] = a
        count[nd] = b - a
        if b - a <= leaf or sp + 2 > st_node.shape[0]:
            child[nd] = -1
            continue
        ax = 0
        for c in range(1, 3):
            if chi[c] - clo[c] > chi[ax] - clo[ax]:
                ax = c
        for r in range(a, b):
            key[r] = centre[order[r], ax]
        srt = np.argsort(key[a:b], kind="mergesort")
        tmp = order[a:b].copy()
        for r in range(b - a):
            order[a + r] = tmp[srt[r]]
        mid = (a + b) // 2
        child[nd] = n_nodes
        st_node[sp] = n_nodes
        st_lo[sp] = a
        st_hi[sp] = mid
        st_node[sp + 1] = n_nodes + 1
        st_lo[sp + 1] = mid
        st_hi[sp + 1] = b
        sp += 2
        n_nodes += 2
    return n_nodes


@njit(cache=True, nogil=True, inline="always")
def obb_d2(q0, q1, q2, k, centre, axes, half):
    """Squared distance from q to patch k's oriented box (a lower bound for the patch)."""
    d0 = q0 - centre[k, 0]
    d1 = q1 - centre[k, 1]
    d2 = q2 - centre[k, 2]
    acc = 0.0
    for a in range(3):
        x = abs(d0 * axes[k, a, 0] + d1 * axes[k, a, 1] + d2 * axes[k, a, 2]) - half[k, a]
        if x > 0.0:
            acc += x * x
    return acc


@njit(cache=True, nogil=True, inline="always")
def candidates(q0, q1, q2, best2, centre, axes, half, nlo, nhi, child, first, count, stack,
               out_k, out_d2, n0):
    """Append to ``out_k[n0:]`` (with their bounds in ``out_d2``) every patch whose box is
    closer to q than sqrt(best2); returns the new count."""
    n = n0
    sp = 1
    stack[0] = 0
    while sp > 0:
        sp -= 1
        nd = stack[sp]
        g = 0.0
        x = max(nlo[nd, 0] - q0, q0 - nhi[nd, 0], 0.0)
        g += x * x
        x = max(nlo[nd, 1] - q1, q1 - nhi[nd, 1], 0.0)
        g += x * x
        x = max(nlo[nd, 2] - q2, q2 - nhi[nd, 2], 0.0)
        g += x * x
        if not g < best2:
            continue
        c = child[nd]
        if c < 0:
            for r in range(first[nd], first[nd] + count[nd]):
                e = obb_d2(q0, q1, q2, r, centre, axes, half)
                if e < best2:
                    out_k[n] = r
                    out_d2[n] = e
                    n += 1
        elif sp + 2 <= stack.shape[0]:
            stack[sp] = c
            stack[sp + 1] = c + 1
            sp += 2
    return n

