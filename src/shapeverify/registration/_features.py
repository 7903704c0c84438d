"""numba kernels of the global search (private; callers validate their input).

FPFH descriptors (Rusu, Blodow, Beetz 2009) on padded neighbour lists and a RANSAC over
feature correspondences with the edge-length pre-check of Open3D / Zhou et al. (2016).
"""
import numpy as np
from numba import njit

#: bins per angle of the FPFH histogram (33 = 3 x 11 values)
BINS = 11


@njit(cache=True, nogil=True)
def _pair(p, n, q, m):
    """(alpha, phi, theta) of the Darboux frame of the point pair (p, n) -> (q, m), or a
    NaN triple for coincident points.  Source and target are swapped when that gives the
    smaller angle (Rusu et al. 2008, as in PCL), so the triple is symmetric in the pair."""
    d0 = q[0] - p[0]
    d1 = q[1] - p[1]
    d2 = q[2] - p[2]
    dist = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if dist == 0.0:
        return np.nan, np.nan, np.nan
    d0 /= dist
    d1 /= dist
    d2 /= dist
    a1 = n[0] * d0 + n[1] * d1 + n[2] * d2
    a2 = m[0] * d0 + m[1] * d1 + m[2] * d2
    u0, u1, u2 = n[0], n[1], n[2]
    t0, t1, t2 = m[0], m[1], m[2]
    if abs(a1) < abs(a2):    # swap source and target
        u0, u1, u2 = m[0], m[1], m[2]
        t0, t1, t2 = n[0], n[1], n[2]
        d0, d1, d2 = -d0, -d1, -d2
        phi = a2 * -1.0
    else:
        phi = a1
    # v = u x d, w = u x v
    v0 = u1 * d2 - u2 * d1
    v1 = u2 * d0 - u0 * d2
    v2 = u0 * d1 - u1 * d0
    nv = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if nv < 1e-12:
        return np.nan, np.nan, np.nan
    v0 /= nv
    v1 /= nv
    v2 /= nv
    w0 = u1 * v2 - u2 * v1
    w1 = u2 * v0 - u0 * v2
    w2 = u0 * v1 - u1 * v0
    alpha = v0 * t0 + v1 * t1 + v2 * t2
    theta = np.arctan2(w0 * t0 + w1 * t1 + w2 * t2, u0 * t0 + u1 * t1 + u2 * t2)
    return alpha, phi, theta


@njit(cache=True, nogil=True, inline="always")
def _bin(x, lo, hi):
    b = int((x - lo) / (hi - lo) * BINS)
    return min(max(b, 0), BINS - 1)


@njit(cache=True, nogil=True)
def fpfh(P, N, nbr, dist):
    """FPFH (n, 33) of points P (n, 3) with unit normals N from padded neighbour lists.

    ``nbr`` (n, k) int64: neighbour indices (``n`` = none, the point itself excluded or
    skipped), ``dist`` (n, k) their distances.  SPFH: per point, the normalised histograms of
    (alpha, phi, theta) over its neighbours; FPFH(p) = SPFH(p) + mean_k SPFH(p_k) / d_k, each
    third normalised to sum 100 (Rusu et al. 2009, eq. 4).
    """
    n = P.shape[0]
    k = nbr.shape[1]
    S = np.zeros((n, 3 * BINS))
    for i in range(n):
        cnt = 0
        for j in range(k):
            q = nbr[i, j]
            if q >= n or q == i:
                continue
            a, f, t = _pair(P[i], N[i], P[q], N[q])
            if np.isnan(a):
                continue
            S[i, _bin(a, -1.0, 1.0)] += 1.0
            S[i, BINS + _bin(f, -1.0, 1.0)] += 1.0
            S[i, 2 * BINS + _bin(t, -np.pi, np.pi)] += 1.0
            cnt += 1
        if cnt > 0:
            for b in range(3 * BINS):
                S[i, b] *= 100.0 / cnt
    F = np.zeros((n, 3 * BINS))
    for i in range(n):
        cnt = 0
        for j in range(k):
            q = nbr[i, j]
            if q >= n or q == i or dist[i, j] <= 0.0:
                continue
            wq = 1.0 / dist[i, j]
            for b in range(3 * BINS):
                F[i, b] += wq * S[q, b]
            cnt += 1
        for b in range(3 * BINS):
            F[i, b] = S[i, b] + (F[i, b] / cnt if cnt else 0.0)
        for h in range(3):
            s = 0.0
            for b in range(h * BINS, (h + 1) * BINS):
                s += F[i, b]
            if s > 0.0:
                for b in range(h * BINS, (h + 1) * BINS):
                    F[i, b] *= 100.0 / s
    return F


@njit(cache=True, nogil=True)
def kabsch(A, B):
    """R (3, 3), t (3,) minimising sum |R a + t - b|^2 (unweighted, det R = +1)."""
    ca = np.zeros(3)
    cb = np.zeros(3)
    m = A.shape[0]
    for i in range(m):
        ca += A[i]
        cb += B[i]
    ca /= m
    cb /= m
    S = np.zeros((3, 3))
    for i in range(m):
        for r in range(3):
            for c in range(3):
                S[r, c] += (B[i, r] - cb[r]) * (A[i, c] - ca[c])
    U, _, Vt = np.linalg.svd(S)
    D = np.eye(3)
    if np.linalg.det(U @ Vt) < 0:
        D[2, 2] = -1.0
    R = U @ D @ Vt
    return R, cb - R @ ca


@njit(cache=True, nogil=True)
def ransac(src, dst, iterations, threshold, edge_ratio, seed):
    """RANSAC over correspondences src[i] <-> dst[i] (c, 3): poses from random triples.

    A triple is kept only if its three edge lengths agree within ``edge_ratio`` (Zhou et al.
    2016's tuple test, Open3D's ``CorrespondenceCheckerBasedOnEdgeLength``).  Returns the
    inlier count (correspondences within ``threshold`` mm) of every kept triple's pose and
    the poses (m, 12): R row-major, then t.  ``seed`` seeds numba's own generator: the result
    is the same on every run.
    """
    np.random.seed(seed)
    c = src.shape[0]
    counts = np.zeros(iterations, np.int64)
    poses = np.zeros((iterations, 12))
    kept = 0
    A = np.empty((3, 3))
    B = np.empty((3, 3))
    th2 = threshold * threshold
    for _ in range(iterations):
        i0 = np.random.randint(c)
        i1 = np.random.randint(c)
        i2 = np.random.randint(c)
        if i0 == i1 or i1 == i2 or i0 == i2:
            continue
        idx = (i0, i1, i2)
        ok = True
        for a in range(3):
            for b in range(a + 1, 3):
                ls = np.sqrt(np.sum((src[idx[a]] - src[idx[b]]) ** 2))
                ld = np.sqrt(np.sum((dst[idx[a]] - dst[idx[b]]) ** 2))
                if ls < edge_ratio * ld or ld < edge_ratio * ls or ls < 3.0 * threshold:
                    ok = False
        if not ok:
            continue
        for a in range(3):
            A[a] = src[idx[a]]
            B[a] = dst[idx[a]]
        R, t = kabsch(A, B)
        cnt = 0
        for i in range(c):
            e = 0.0
            for r in range(3):
                x = R[r, 0] * src[i, 0] + R[r, 1] * src[i, 1] + R[r, 2] * src[i, 2] + t[r]
                e += (x - dst[i, r]) ** 2
            if e < th2:
                cnt += 1
        counts[kept] = cnt
        for r in range(3):
            for s in range(3):
                poses[kept, 3 * r + s] = R[r, s]
            poses[kept, 9 + r] = t[r]
        kept += 1
    return counts[:kept], poses[:kept]


@njit(cache=True, nogil=True)
def truncated_fit(d, valid, tau):
    """Mean of ``max(0, 1 - (d / tau)^2)`` (0 where not valid): the share of points that fit,
    each weighted by how well (a Tukey-like kernel; 1 = every point on the surface)."""
    s = 0.0
    for i in range(d.shape[0]):
        if valid[i]:
            u = d[i] / tau
            u2 = u * u
            if u2 < 1.0:
                s += 1.0 - u2
    return s / max(d.shape[0], 1)
