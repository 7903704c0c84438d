"""numba kernels for phase unwrapping (private; they trust their input).

Pixel ``(i, j)`` of an ``(H, W)`` map has flat index ``p = i * W + j``.  Edges join 4-neighbours:
horizontal edge ``e < H*(W-1)`` joins ``(i, j)`` and ``(i, j+1)`` with ``i = e // (W-1)``,
``j = e % (W-1)``; vertical edge ``e = H*(W-1) + f`` joins flat pixels ``f`` and ``f + W``.

References
----------
M. A. Herráez, D. R. Burton, M. J. Lalor, M. A. Gdeisat, "Fast two-dimensional phase-unwrapping
algorithm based on sorting by reliability following a noncontinuous path", Appl. Opt. 41 (2002)
7437-7444 (second-difference reliability, edges sorted by reliability, groups merged).
R. E. Tarjan, union-find with path compression and union by size (offsets kept per node).
"""

from __future__ import annotations

import numpy as np
from numba import njit

TWO_PI = 2.0 * np.pi
PI = np.pi


@njit(cache=True, inline="always")
def _wrapd(x):
    """Wrap one difference into [-pi, pi) (only used on differences; exactness not needed)."""
    return x - TWO_PI * np.floor((x + PI) / TWO_PI)


@njit(cache=True)
def second_difference(psi, mask):
    """Herráez second-difference magnitude ``D`` per pixel (reliability is ``1 / D``).

    D^2 = H^2 + V^2 + D1^2 + D2^2 with H = W(p[i,j-1]-p[i,j]) - W(p[i,j]-p[i,j+1]) and V, D1, D2
    likewise along the column and both diagonals.  Terms whose pixels are masked or outside the
    image are skipped and the sum is rescaled by 4 / (terms used); a pixel with no usable term gets
    D = inf (processed last).
    """
    H, W = psi.shape
    D = np.empty((H, W))
    for i in range(H):
        for j in range(W):
            if not mask[i, j]:
                D[i, j] = np.inf
                continue
            c = psi[i, j]
            s = 0.0
            n = 0
            # (di, dj) for horizontal, vertical, diagonal, anti-diagonal
            for k in range(4):
                if k == 0:
                    di, dj = 0, 1
                elif k == 1:
                    di, dj = 1, 0
                elif k == 2:
                    di, dj = 1, 1
                else:
                    di, dj = 1, -1
                i0, j0, i1, j1 = i - di, j - dj, i + di, j + dj
                if i0 < 0 or i1 >= H or j0 < 0 or j0 >= W or j1 < 0 or j1 >= W:
                    continue
                if not (mask[i0, j0] and mask[i1, j1]):
                    continue
                t = _wrapd(psi[i0, j0] - c) - _wrapd(c - psi[i1, j1])
                s += t * t
                n += 1
            if n == 0:
                D[i, j] = np.inf
            else:
                D[i, j] = np.sqrt(s * 4.0 / n)
    return D


@njit(cache=True)
def edge_costs(rel, mask):
    """Edge cost ``1 / (rel[a] + rel[b])`` from pixel reliabilities ``rel >= 0`` (higher = better).

    Sorting by increasing cost is sorting by decreasing summed reliability (Herráez 2002).
    ``-1`` marks an edge with a masked end; two zero reliabilities give ``inf`` (processed last).
    """
    H, W = rel.shape
    nh = H * (W - 1)
    out = np.empty(nh + (H - 1) * W)
    for i in range(H):
        for j in range(W - 1):
            e = i * (W - 1) + j
            if mask[i, j] and mask[i, j + 1]:
                s = rel[i, j] + rel[i, j + 1]
                out[e] = 1.0 / s if s > 0.0 else np.inf
            else:
                out[e] = -1.0
    for i in range(H - 1):
        for j in range(W):
            e = nh + i * W + j
            if mask[i, j] and mask[i + 1, j]:
                s = rel[i, j] + rel[i + 1, j]
                out[e] = 1.0 / s if s > 0.0 else np.inf
            else:
                out[e] = -1.0
    return out


@njit(cache=True)
def bucket_order(costs, scale, nbins):
    """Indices of the valid edges (cost >= 0) sorted by increasing cost, by counting sort.

    Costs are quantised with the monotone map ``floor(nbins * c / (c + scale))`` (``inf`` goes to
    the last bin), so the order is exact up to the bin width; ties keep index order.
    """
    E = costs.shape[0]
    level = np.empty(E, np.int64)
    counts = np.zeros(nbins + 1, np.int64)
    for e in range(E):
        c = costs[e]
        if c < 0.0:
            level[e] = -1
            continue
        if np.isinf(c):
            b = nbins - 1
        else:
            b = int(nbins * (c / (c + scale)))
            if b >= nbins:
                b = nbins - 1
        level[e] = b
        counts[b + 1] += 1
    for b in range(nbins):
        counts[b + 1] += counts[b]
    n_valid = counts[nbins]
    order = np.empty(n_valid, np.int64)
    for e in range(E):
        b = level[e]
        if b >= 0:
            order[counts[b]] = e
            counts[b] += 1
    return order


@njit(cache=True)
def edge_jumps(psi, mask):
    """Per edge (a, b): ``round((psi[a] - psi[b]) / 2pi)`` as int8 (psi must lie in [-pi, pi])."""
    H, W = psi.shape
    nh = H * (W - 1)
    out = np.zeros(nh + (H - 1) * W, np.int8)
    for i in range(H):
        for j in range(W - 1):
            if mask[i, j] and mask[i, j + 1]:
                out[i * (W - 1) + j] = np.int8(np.floor((psi[i, j] - psi[i, j + 1]) / TWO_PI + 0.5))
    for i in range(H - 1):
        for j in range(W):
            if mask[i, j] and mask[i + 1, j]:
                out[nh + i * W + j] = np.int8(np.floor((psi[i, j] - psi[i + 1, j]) / TWO_PI + 0.5))
    return out


@njit(cache=True)
def _find(node, x):
    """(root, n[x] - n[root]).  node[x, 0]: parent (or -size at a root); node[x, 1]: n[x] - n[parent].

    Halves the path on the way (each visited node is re-pointed to its grandparent).
    """
    off = 0
    while node[x, 0] >= 0:
        px = node[x, 0]
        gp = node[px, 0]
        if gp >= 0:
            node[x, 1] += node[px, 1]
            node[x, 0] = gp
        off += node[x, 1]
        x = node[x, 0]
    return x, off


@njit(cache=True)
def merge_edges(jumps, order, H, W):
    """Join pixels along the sorted edges (Herráez 2002); return the integer field ``n``.

    ``jumps[e]`` (from :func:`edge_jumps`) is the required ``n[b] - n[a]`` of edge e = (a, b),
    i.e. the unwrapped difference across the edge is the wrapped one.  Groups are merged with
    union by size (weighted union-find with offsets, path halving); a group's root keeps n = 0.
    Parent and offset of a node sit side by side (one cache line per visit).
    """
    N = H * W
    node = np.empty((N, 2), np.int32)
    for p in range(N):
        node[p, 0] = -1
        node[p, 1] = 0
    nh = H * (W - 1)
    for k in range(order.shape[0]):
        e = order[k]
        if e < nh:
            i = e // (W - 1)
            a = i * W + (e - i * (W - 1))
            b = a + 1
        else:
            a = e - nh
            b = a + W
        ra, ka = _find(node, a)
        rb, kb = _find(node, b)
        if ra == rb:
            continue
        rel = jumps[e] - kb + ka               # n[rb] - n[ra]
        if node[ra, 0] <= node[rb, 0]:         # size(ra) >= size(rb): hang rb below ra
            node[ra, 0] += node[rb, 0]
            node[rb, 0] = ra
            node[rb, 1] = rel
        else:
            node[rb, 0] += node[ra, 0]
            node[ra, 0] = rb
            node[ra, 1] = -rel
    n = np.empty(N, np.int64)
    for p in range(N):
        r, k = _find(node, p)
        n[p] = k
    return n


@njit(cache=True)
def count_residues(psi, mask):
    """Number of non-zero residues of the elementary 2 x 2 loops with all four pixels valid."""
    H, W = psi.shape
    c = 0
    for i in range(H - 1):
        for j in range(W - 1):
            if not (mask[i, j] and mask[i, j + 1] and mask[i + 1, j] and mask[i + 1, j + 1]):
                continue
            s = (_wrapd(psi[i, j + 1] - psi[i, j]) + _wrapd(psi[i + 1, j + 1] - psi[i, j + 1])
                 + _wrapd(psi[i + 1, j] - psi[i + 1, j + 1]) + _wrapd(psi[i, j] - psi[i + 1, j]))
            if abs(s) > PI:
                c += 1
    return c


@njit(cache=True)
def weighted_laplacian(phi, wx, wy, out):
    """out = A phi for the weighted LS normal equations (Ghiglia & Pritt 1998, eq. 5.67).

    ``A phi [i,j] = wx[i,j](phi[i,j+1]-phi[i,j]) - wx[i,j-1](phi[i,j]-phi[i,j-1])
    + wy[i,j](phi[i+1,j]-phi[i,j]) - wy[i-1,j](phi[i,j]-phi[i-1,j])`` with wx (H, W-1) and
    wy (H-1, W) the squared edge weights; terms beyond the border are absent (Neumann).
    """
    H, W = phi.shape
    for i in range(H):
        for j in range(W):
            c = phi[i, j]
            s = 0.0
            if j < W - 1:
                s += wx[i, j] * (phi[i, j + 1] - c)
            if j > 0:
                s -= wx[i, j - 1] * (c - phi[i, j - 1])
            if i < H - 1:
                s += wy[i, j] * (phi[i + 1, j] - c)
            if i > 0:
                s -= wy[i - 1, j] * (c - phi[i - 1, j])
            out[i, j] = s
    return out


@njit(cache=True)
def weighted_divergence(gx, gy, wx, wy, out):
    """out = weighted divergence of (gx, gy): the right-hand side of the weighted LS equations."""
    H, W = out.shape
    for i in range(H):
        for j in range(W):
            s = 0.0
            if j < W - 1:
                s += wx[i, j] * gx[i, j]
            if j > 0:
                s -= wx[i, j - 1] * gx[i, j - 1]
            if i < H - 1:
                s += wy[i, j] * gy[i, j]
            if i > 0:
                s -= wy[i - 1, j] * gy[i - 1, j]
            out[i, j] = s
    return out


@njit(cache=True)
def box_sum(a, r):
    """Sum of ``a`` over the (2r+1) x (2r+1) box around each pixel (zero outside the image)."""
    H, W = a.shape
    tmp = np.empty((H, W))
    out = np.empty((H, W))
    for i in range(H):
        s = 0.0
        for j in range(min(r, W)):
            s += a[i, j]
        for j in range(W):
            if j + r < W:
                s += a[i, j + r]
            if j - r - 1 >= 0:
                s -= a[i, j - r - 1]
            tmp[i, j] = s
    acc = np.zeros(W)
    for i in range(min(r, H)):
        for j in range(W):
            acc[j] += tmp[i, j]
    for i in range(H):
        if i + r < H:
            for j in range(W):
                acc[j] += tmp[i + r, j]
        if i - r - 1 >= 0:
            for j in range(W):
                acc[j] -= tmp[i - r - 1, j]
        for j in range(W):
            out[i, j] = acc[j]
    return out


@njit(cache=True)
def phasor_parts(psi, mask):
    """cos(psi), sin(psi) and the mask as floats, zero where masked."""
    H, W = psi.shape
    c = np.zeros((H, W))
    s = np.zeros((H, W))
    m = np.zeros((H, W))
    for i in range(H):
        for j in range(W):
            if mask[i, j]:
                c[i, j] = np.cos(psi[i, j])
                s[i, j] = np.sin(psi[i, j])
                m[i, j] = 1.0
    return c, s, m


@njit(cache=True)
def fdot(a, b):
    """Sum of a * b over all elements (single-threaded; avoids BLAS thread start-up)."""
    fa = a.ravel()
    fb = b.ravel()
    s = 0.0
    for k in range(fa.shape[0]):
        s += fa[k] * fb[k]
    return s


@njit(cache=True)
def local_frequency_sample(c, s, mask, r, step):
    """Local phase-gradient magnitude (rad/pixel) on a grid of every `step`-th pixel.

    At each grid pixel the lag-one products ``z[.., j+1] conj(z[.., j])`` (and along i) of the
    unit phasors ``z = c + i s`` are summed over the (2r+1)^2 box; the angle of each sum is the
    mean wrapped gradient along that axis (noise averages out in the complex sum).  Grid pixels
    without any valid pair are skipped.  Returns a 1-D array.
    """
    H, W = c.shape
    out = np.empty(((H + step - 1) // step) * ((W + step - 1) // step))
    k = 0
    for i0 in range(0, H, step):
        for j0 in range(0, W, step):
            xr = 0.0
            xi = 0.0
            yr = 0.0
            yi = 0.0
            nx = 0
            ny = 0
            for i in range(max(0, i0 - r), min(H, i0 + r + 1)):
                for j in range(max(0, j0 - r), min(W, j0 + r + 1)):
                    if not mask[i, j]:
                        continue
                    if j + 1 < W and mask[i, j + 1]:
                        xr += c[i, j + 1] * c[i, j] + s[i, j + 1] * s[i, j]
                        xi += s[i, j + 1] * c[i, j] - c[i, j + 1] * s[i, j]
                        nx += 1
                    if i + 1 < H and mask[i + 1, j]:
                        yr += c[i + 1, j] * c[i, j] + s[i + 1, j] * s[i, j]
                        yi += s[i + 1, j] * c[i, j] - c[i + 1, j] * s[i, j]
                        ny += 1
            if nx == 0 and ny == 0:
                continue
            gx = np.arctan2(xi, xr) if nx > 0 else 0.0
            gy = np.arctan2(yi, yr) if ny > 0 else 0.0
            out[k] = np.sqrt(gx * gx + gy * gy)
            k += 1
    return out[:k]
