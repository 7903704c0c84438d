"""numba kernels for minimum-cost-flow unwrapping (private; they trust their input).

Grid conventions as :mod:`shapeverify.phase._kernels` (flat pixel ``p = i*W + j``; horizontal
edge ``e = i*(W-1) + j`` joins ``(i, j)``-``(i, j+1)``; vertical edge ``nh + i*W + j`` joins
``(i, j)``-``(i+1, j)``).  ``jumps[e]`` is the integer ``n[b] - n[a]`` the wrapped gradient implies.

Dual graph (Costantini 1998): node ``v = i*(W-1) + j`` is the elementary loop with top-left pixel
``(i, j)``; node ``G = (H-1)*(W-1)`` is the ground (everything outside the image).  The loop's
charge is ``jx(i,j) + jy(i,j+1) - jx(i+1,j) - jy(i,j)`` (integer; equal to the residue of the
wrapped phase).  A correction ``k`` on horizontal edge ``(i, j)`` adds ``+k`` to loop ``(i, j)``
and ``-k`` to loop ``(i-1, j)``; on vertical edge ``(i, j)`` it adds ``+k`` to loop ``(i, j-1)``
and ``-k`` to loop ``(i, j)``.  One unit of flow along a dual arc ``A -> B`` lowers A's charge by
one and raises B's: flows are the corrections, and the minimum-cost flow that cancels every
charge is the L1 (weighted) unwrapping.

The solver is successive shortest paths with node potentials (Dijkstra on reduced costs, one unit
per augmentation from an excess node to the nearest deficit node), exact for the linear
per-direction costs used here (Ahuja, Magnanti & Orlin 1993, Ch. 9.7).
"""

from __future__ import annotations

import numpy as np
from numba import njit

TWO_PI = 2.0 * np.pi
PI = np.pi


@njit(cache=True, nogil=True)
def loop_charges(jumps, H, W):
    """Integer charge of every elementary loop, plus the ground's balancing charge (last)."""
    nh = H * (W - 1)
    M = (H - 1) * (W - 1)
    q = np.zeros(M + 1, np.int64)
    tot = 0
    for i in range(H - 1):
        for j in range(W - 1):
            c = (np.int64(jumps[i * (W - 1) + j]) + jumps[nh + i * W + j + 1]
                 - jumps[(i + 1) * (W - 1) + j] - jumps[nh + i * W + j])
            q[i * (W - 1) + j] = c
            tot += c
    q[M] = -tot
    return q


@njit(cache=True, nogil=True)
def _arc(v, d, H, W):
    """Arc ``d`` (0 up, 1 down, 2 left, 3 right) of dual node v: (edge, dk, other node).

    ``dk`` is the change of the edge's correction when one unit flows along the arc.
    """
    Wl = W - 1
    G = (H - 1) * Wl
    nh = H * Wl
    i = v // Wl
    j = v - i * Wl
    if d == 0:       # across horizontal edge (i, j) to loop (i-1, j)
        return i * Wl + j, -1, (G if i == 0 else v - Wl)
    if d == 1:       # across horizontal edge (i+1, j) to loop (i+1, j)
        return (i + 1) * Wl + j, 1, (G if i + 1 == H - 1 else v + Wl)
    if d == 2:       # across vertical edge (i, j) to loop (i, j-1)
        return nh + i * W + j, 1, (G if j == 0 else v - 1)
    return nh + i * W + j + 1, -1, (G if j + 1 == W - 1 else v + 1)


@njit(cache=True, nogil=True)
def ground_arcs(H, W):
    """Arcs of the ground node: (edge, dk, other node) for every border edge (int64 (K, 3))."""
    Wl = W - 1
    nh = H * Wl
    K = 2 * Wl + 2 * (H - 1)
    out = np.empty((K, 3), np.int64)
    k = 0
    for j in range(Wl):
        out[k, 0] = j                              # top row: ground is "up" of loop (0, j)
        out[k, 1] = 1
        out[k, 2] = j
        k += 1
        out[k, 0] = (H - 1) * Wl + j               # bottom row: ground is "down" of loop (H-2, j)
        out[k, 1] = -1
        out[k, 2] = (H - 2) * Wl + j
        k += 1
    for i in range(H - 1):
        out[k, 0] = nh + i * W                     # left column: ground is "left" of loop (i, 0)
        out[k, 1] = -1
        out[k, 2] = i * Wl
        k += 1
        out[k, 0] = nh + i * W + W - 1             # right column: ground is "right" of (i, W-2)
        out[k, 1] = 1
        out[k, 2] = i * Wl + Wl - 1
        k += 1
    return out


@njit(cache=True, nogil=True, inline="always")
def _cost(cp, cm, flow, e, dk):
    """Cost of changing edge e's correction by dk (+-1) given its current net correction."""
    f = flow[e]
    if dk > 0:
        return cp[e] if f >= 0 else -cm[e]
    return cm[e] if f <= 0 else -cp[e]


@njit(cache=True, nogil=True)
def _heap_push(hk, hv, n, key, val):
    k = n
    hk[k] = key
    hv[k] = val
    while k > 0:
        p = (k - 1) >> 1
        if hk[p] <= hk[k]:
            break
        hk[p], hk[k] = hk[k], hk[p]
        hv[p], hv[k] = hv[k], hv[p]
        k = p
    return n + 1


@njit(cache=True, nogil=True)
def _heap_pop(hk, hv, n):
    key = hk[0]
    val = hv[0]
    n -= 1
    hk[0] = hk[n]
    hv[0] = hv[n]
    k = 0
    while True:
        c = 2 * k + 1
        if c >= n:
            break
        if c + 1 < n and hk[c + 1] < hk[c]:
            c += 1
        if hk[k] <= hk[c]:
            break
        hk[c], hk[k] = hk[k], hk[c]
        hv[c], hv[k] = hv[k], hv[c]
        k = c
    return key, val, n


@njit(cache=True, nogil=True)
def _search(s, q, cp, cm, flow, pot, dist, stamp, done, pred_e, pred_d, pred_v, hk, hv, settled,
            garcs, it, limit, H, W):
    """One Dijkstra on reduced costs from s; augment one unit to the nearest deficit node.

    Returns the number of settled nodes, or -1 if more than `limit` nodes were settled first
    (then nothing is changed), or -2 if no deficit is reachable.
    """
    G = (H - 1) * (W - 1)
    cap = hk.shape[0]
    dist[s] = 0.0
    stamp[s] = it
    done[s] = False
    nheap = _heap_push(hk, hv, 0, 0.0, s)
    nset = 0
    t = -1
    D = 0.0
    while nheap > 0:
        du, u, nheap = _heap_pop(hk, hv, nheap)
        if done[u] or du > dist[u]:
            continue
        done[u] = True
        settled[nset] = u
        nset += 1
        if q[u] < 0:
            t = u
            D = du
            break
        if nset > limit:
            return -1
        pu = pot[u]
        na = garcs.shape[0] if u == G else 4
        for a in range(na):
            if u == G:
                e = garcs[a, 0]
                dk = garcs[a, 1]
                v = garcs[a, 2]
            else:
                e, dk, v = _arc(u, a, H, W)
            c = _cost(cp, cm, flow, e, dk) + pu - pot[v]
            if c < 0.0:
                c = 0.0          # rounding of the potentials
            nd = du + c
            if stamp[v] != it:
                stamp[v] = it
                done[v] = False
            elif done[v] or nd >= dist[v]:
                continue
            dist[v] = nd
            pred_e[v] = e
            pred_d[v] = dk
            pred_v[v] = u
            if nheap >= cap:
                raise RuntimeError("min_cost_flow: heap overflow")
            nheap = _heap_push(hk, hv, nheap, nd, v)
    if t < 0:
        return -2
    for k in range(nset):
        v = settled[k]
        pot[v] += dist[v] - D
    v = t
    while v != s:
        flow[pred_e[v]] += pred_d[v]
        v = pred_v[v]
    q[s] -= 1
    q[t] += 1
    return nset


@njit(cache=True, nogil=True)
def min_cost_flow(q, cp, cm, H, W):
    """Net integer correction per edge that cancels all charges `q` at minimum cost.

    Successive shortest paths with potentials, one unit per path.  The sources are served in
    passes with a growing limit on the search size (64, 512, ... nodes, then none): near pairs
    first, far ones last, so that the zero-reduced-cost trees left behind by long paths are
    crossed by few later searches.  A search stopped by the limit changes nothing (the potentials
    stay valid), so the result is the exact minimum whatever the order.

    Parameters
    ----------
    q : (M+1,) int64
        Loop charges and the ground's (from :func:`loop_charges`); modified in place (ends 0).
    cp, cm : (E,) float64 >= 0
        Cost of a correction of +1 / -1 on each edge.

    Returns
    -------
    flow : (E,) int32 net corrections; augmentations : int; settled : int (search work)
    """
    M = (H - 1) * (W - 1)
    N = M + 1
    E = cp.shape[0]
    flow = np.zeros(E, np.int32)
    pot = np.zeros(N)
    dist = np.empty(N)
    stamp = np.full(N, -1, np.int64)
    done = np.zeros(N, np.bool_)
    pred_e = np.empty(N, np.int64)
    pred_d = np.empty(N, np.int8)
    pred_v = np.empty(N, np.int64)
    garcs = ground_arcs(H, W)
    cap = 4 * N + garcs.shape[0] + 16
    hk = np.empty(cap)
    hv = np.empty(cap, np.int64)
    settled = np.empty(N, np.int64)
    n_aug = 0
    work = 0
    it = 0
    limit = 64
    while True:
        last = limit >= N
        lim = N + 1 if last else limit
        pending = 0
        for s in range(N):
            while q[s] > 0:
                it += 1
                r = _search(s, q, cp, cm, flow, pot, dist, stamp, done, pred_e, pred_d, pred_v,
                            hk, hv, settled, garcs, it, lim, H, W)
                if r == -2:
                    raise RuntimeError("min_cost_flow: no deficit reachable (charges do not balance)")
                if r == -1:
                    work += lim
                    pending += 1
                    break
                work += r
                n_aug += 1
        if last or pending == 0:
            break
        limit *= 8
    return flow, n_aug, work


@njit(cache=True, nogil=True)
def _box1(a, r, axis):
    """Running sum of `a` over 2r+1 samples along `axis` (zero outside)."""
    h, w = a.shape
    out = np.empty((h, w))
    if axis == 1:
        for i in range(h):
            s = 0.0
            for j in range(min(r, w)):
                s += a[i, j]
            for j in range(w):
                if j + r < w:
                    s += a[i, j + r]
                if j - r - 1 >= 0:
                    s -= a[i, j - r - 1]
                out[i, j] = s
    else:
        acc = np.zeros(w)
        for i in range(min(r, h)):
            for j in range(w):
                acc[j] += a[i, j]
        for i in range(h):
            if i + r < h:
                for j in range(w):
                    acc[j] += a[i + r, j]
            if i - r - 1 >= 0:
                for j in range(w):
                    acc[j] -= a[i - r - 1, j]
            for j in range(w):
                out[i, j] = acc[j]
    return out


@njit(cache=True, nogil=True)
def _box2(a, ri, rj):
    return _box1(_box1(a, ri, 0), rj, 1)


@njit(cache=True, nogil=True, inline="always")
def _angle_diff(br, bi, ar, ai):
    """angle(b * conj(a)) of two phasor sums."""
    return np.arctan2(bi * ar - br * ai, br * ar + bi * ai)


@njit(cache=True, nogil=True)
def _lag_angles(bc, bs, L, axis):
    """angle(B[k + L] conj(B[k])) along `axis` of the box phasor sums (NaN beyond the border)."""
    H, W = bc.shape
    out = np.full((H, W), np.nan)
    for i in range(H):
        for j in range(W):
            i1, j1 = (i, j + L) if axis == 1 else (i + L, j)
            if i1 < H and j1 < W:
                out[i, j] = _angle_diff(bc[i1, j1], bs[i1, j1], bc[i, j], bs[i, j])
    return out


@njit(cache=True, nogil=True)
def step_anomaly(mask, bc, bs, b):
    """Per edge: the phase step across it seen by adjacent boxes, minus the smooth trend.

    `bc`, `bs` are the sums of ``cos(psi)``, ``sin(psi)`` (zero where masked) over the
    ``(2b+1)^2`` box around each pixel (the phasors themselves for ``b = 0``).  Along the axis of
    the edge (columns for a horizontal edge ``(i, j)-(i, j+1)``, rows for a vertical one) four
    boxes sit side by side, two on each side: ``A | Bl || Br | C`` with the edge between ``Bl``
    and ``Br``.  With ``D`` the phase difference between neighbouring boxes,
    ``S = W(D(Bl, Br) - median(D(A, Bl), D(Bl, Br), D(Br, C)))``: the median is the local trend
    (a step that lies between ``A`` and ``Bl`` or ``Br`` and ``C`` is outvoted), so a smooth phase
    gives ``S ~ 0`` with the noise reduced by the box size, and a discontinuity ``s`` on the edge
    gives ``W(s)``, falling off over ``2b+1`` pixels on either side.  Near the border the boxes
    are cut and the missing outer difference is replaced by the other one.  Edges with a masked
    end get NaN.  Returns (E,) float64.
    """
    H, W = mask.shape
    nh = H * (W - 1)
    out = np.empty(nh + (H - 1) * W)
    L = 2 * b + 1
    for axis in range(2):
        h = H if axis == 0 else H - 1
        w = W - 1 if axis == 0 else W
        n_along = W if axis == 0 else H
        base = 0 if axis == 0 else nh
        lag = _lag_angles(bc, bs, L, 1 if axis == 0 else 0)
        for i in range(h):
            for j in range(w):
                e = base + i * w + j
                i1, j1 = (i, j + 1) if axis == 0 else (i + 1, j)
                if not (mask[i, j] and mask[i1, j1]):
                    out[e] = np.nan
                    continue
                k0 = j if axis == 0 else i
                kl = k0 - b
                kr = k0 + 1 + b
                if kl >= 0 and kr <= n_along - 1:
                    dm = lag[i, kl] if axis == 0 else lag[kl, j]
                else:          # cut at the border: the nearest boxes inside
                    kl = max(kl, 0)
                    kr = min(kr, n_along - 1)
                    if axis == 0:
                        dm = _angle_diff(bc[i, kr], bs[i, kr], bc[i, kl], bs[i, kl])
                    else:
                        dm = _angle_diff(bc[kr, j], bs[kr, j], bc[kl, j], bs[kl, j])
                    dm *= L / max(kr - kl, 1)
                ka = kl - L
                has_a = ka >= 0
                has_c = kr + L <= n_along - 1
                da = 0.0
                dc = 0.0
                if has_a:
                    da = lag[i, ka] if axis == 0 else lag[ka, j]
                if has_c:
                    dc = lag[i, kr] if axis == 0 else lag[kr, j]
                if not has_a:
                    da = dc
                if not has_c:
                    dc = da
                if has_a or has_c:
                    lo = min(da, dc)
                    hi = max(da, dc)
                    med = lo if dm < lo else (hi if dm > hi else dm)
                else:
                    med = 0.0
                d = dm - med
                out[e] = d - TWO_PI * np.floor((d + PI) / TWO_PI)
    return out


@njit(cache=True, nogil=True)
def robust_costs(d1, sigma1, d0, sigma0, weight0, ew, log_beta, eps):
    """Costs of a +1 / -1 correction per edge from the anomalies of two scales (NaN = masked).

    For each term ``c(k) = log(exp(-x^2/2s^2) + beta) - log(exp(-(x + 2 pi k)^2/2s^2) + beta)``
    (``x`` the anomaly, ``s`` its noise): the log-likelihood ratio under a mixture of Gaussian
    noise and a uniform discontinuity term of weight `beta`.  An edge whose anomaly is many noise
    levels off is almost free to cut, a smooth one costs about ``-log(beta)``.  The box-scale term
    (d1) plus `weight0` times the pixel-scale term (d0; skipped if weight0 is 0), scaled by the
    edge weight `ew`, plus `eps`.  Masked edges cost `eps`.
    """
    E = d1.shape[0]
    cp = np.empty(E)
    cm = np.empty(E)
    beta = np.exp(log_beta)
    for e in range(E):
        x = d1[e]
        if not np.isfinite(x):
            cp[e] = eps
            cm[e] = eps
            continue
        ap = 0.0
        am = 0.0
        for t in range(2):
            if t == 0:
                s2 = 2.0 * sigma1 * sigma1
                f = 1.0
            else:
                if weight0 <= 0.0:
                    break
                x = d0[e]
                s2 = 2.0 * sigma0 * sigma0
                f = weight0
            g0 = np.exp(-x * x / s2) + beta
            yp = x + TWO_PI
            ym = x - TWO_PI
            ap += f * np.log(g0 / (np.exp(-yp * yp / s2) + beta))
            am += f * np.log(g0 / (np.exp(-ym * ym / s2) + beta))
        cp[e] = ap * ew[e] + eps
        cm[e] = am * ew[e] + eps
    return cp, cm


@njit(cache=True, nogil=True)
def corner_relief(cp, cm, H, W):
    """Make the corners of a staircase cut as cheap as the cut (in place).

    A cut along a slanted discontinuity crosses edges of one direction on every row (or column)
    and, where the line moves on by a pixel, one edge of the other direction: the corner, whose
    own boxes straddle the line and see no step.  A vertical edge ``(i, j)-(i+1, j)`` is such a
    corner when the horizontal edges diagonal to it -- ``(i, j-1|j)`` and ``(i+1, j|j+1)``, or
    ``(i, j|j+1)`` and ``(i+1, j-1|j)`` -- are both on the cut; its costs are then lowered to
    the larger of theirs (and likewise for horizontal edges between vertical ones).  Costs are
    symmetric in the correction's sign here (``min(cp, cm)``).
    """
    nh = H * (W - 1)
    c0 = np.minimum(cp, cm)
    # vertical edge (i, j)-(i+1, j): index nh + i*W + j; horizontal (i, j)-(i, j+1): i*(W-1) + j
    for i in range(H - 1):
        for j in range(W):
            e = nh + i * W + j
            best = c0[e]
            if j >= 1 and j + 1 <= W - 1:
                a = c0[i * (W - 1) + j - 1]
                b = c0[(i + 1) * (W - 1) + j]
                m = max(a, b)
                a2 = c0[i * (W - 1) + j]
                b2 = c0[(i + 1) * (W - 1) + j - 1]
                m2 = max(a2, b2)
                best = min(best, m, m2)
            if best < c0[e]:
                cp[e] = min(cp[e], best)
                cm[e] = min(cm[e], best)
    # horizontal edge (i, j)-(i, j+1) between vertical edges (i-1|i, j) & (i|i+1, j+1) etc.
    for i in range(H):
        for j in range(W - 1):
            e = i * (W - 1) + j
            best = c0[e]
            if i >= 1 and i + 1 <= H - 1:
                a = c0[nh + (i - 1) * W + j]
                b = c0[nh + i * W + j + 1]
                a2 = c0[nh + i * W + j]
                b2 = c0[nh + (i - 1) * W + j + 1]
                best = min(best, max(a, b), max(a2, b2))
            if best < c0[e]:
                cp[e] = min(cp[e], best)
                cm[e] = min(cm[e], best)
    return cp, cm
