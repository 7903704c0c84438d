"""The first, vectorised-numpy version of ``registration._noise.scan_noise`` (before the
numba kernels of ``registration._noise_kernels``), kept verbatim as the reference the compiled
one is compared with (``tests/test_scan_noise_compiled.py``)."""
from itertools import combinations

import numpy as np
from scipy.spatial import cKDTree

from shapeverify.registration._noise import (COPIES, COPY, FLAT, K, MAX_LEVERAGE, MIN_POINTS,
                                             MISS, NEAR, POINTS, QMIN, ROUNDS, SEED, SEP)

_TRIPLES = np.array(list(combinations(range(NEAR), 3)))


def _inv(M):
    """Inverses of the stacked matrices M; a stack holding a singular one (a neighbourhood
    left with too few inliers to fix its quadric: seen on a plate scanned at 1 mm) is
    pseudo-inverted, so such a centre gets a huge leverage and is left out, never an error."""
    try:
        return np.linalg.inv(M)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(M)


def _fit(A, h, w):
    """Weighted least squares quadrics: ``(A^T W A, coefficients)``."""
    Aw = A * w[..., None]
    AtA = np.einsum("mki,mkj->mij", Aw, A) + 1e-12 * np.eye(A.shape[-1])
    coef = np.einsum("mij,mj->mi", _inv(AtA), np.einsum("mki,mk->mi", Aw, h))
    return AtA, coef


def _flat(Y, w):
    """Whether the points Y (..., k, d) weighted by w (..., k) span a plane (:data:`FLAT`)."""
    sw = np.maximum(w.sum(-1, keepdims=True), 1e-300)
    D = Y - ((w[..., None] * Y).sum(axis=-2) / sw)[..., None, :]
    e = np.linalg.eigvalsh(np.matmul((D * w[..., None]).swapaxes(-1, -2), D))
    return e[..., -2] >= FLAT * e[..., -1]


def _sheet(A, h, w):
    """Grow the quadrics seeded by w: ``(A^T W A, coefficients, weights, sigma)``, sigma NaN
    where no inlier is left to measure it."""
    s = np.full((h.shape[0], 1), np.nan)
    for _ in range(ROUNDS):
        AtA, coef = _fit(A, h, w)
        hk = np.einsum("mki,mij,mkj->mk", A, _inv(AtA), A)      # hat values
        res = np.abs(h - np.einsum("mki,mi->mk", A, coef))
        t_in = res / np.sqrt(np.maximum(1.0 - hk, 1e-12))      # studentized: inliers
        t_out = res / np.sqrt(1.0 + hk)                         # predicted: the others
        use = (w > 0) & (hk < 0.99)
        cnt = use.sum(axis=1)
        srt = np.sort(np.where(use, t_in, np.inf), axis=1)
        lo, hi = np.maximum(cnt - 1, 0) // 2, cnt // 2
        med = 0.5 * (np.take_along_axis(srt, lo[:, None], 1)
                     + np.take_along_axis(srt, hi[:, None], 1))       # of the inliers
        s = np.where(cnt[:, None] > 0, 1.4826 * med, np.nan)
        keep = np.isfinite(s[:, 0])
        w_new = (np.where(w > 0, t_in, t_out) <= 3.0 * np.maximum(s, 1e-300)).astype(np.float64)
        w = np.where(keep[:, None], w_new, w)
    AtA, coef = _fit(A, h, w)
    return AtA, coef, w, s


def _neighbours(P, idx):
    """The K neighbours of each point ``P[idx]`` about it (m, K, 3), copies left out, and
    whether K were found.

    A neighbour closer than :data:`COPY` x the distance of the (COPIES x K)-th to the point or
    to a nearer neighbour is a copy (a doubled exposure, a merged file): its noise is the
    other's, and counted twice it pulled the quadric onto the point (a scan with each point
    twice read a third of its noise)."""
    kk = min(COPIES * K + 1, P.shape[0])
    d, nb = cKDTree(P).query(P[idx], k=kk)
    Q = P[nb] - P[idx][:, None, :]                      # (m, kk, 3), the point itself first
    delta = COPY * d[:, -1]
    q2 = np.einsum("mki,mki->mk", Q, Q)
    D2 = q2[:, :, None] + q2[:, None, :] - 2.0 * np.matmul(Q, Q.transpose(0, 2, 1))
    # which of two copies stays is decided by the file's order, not by the distance: the copy
    # nearer to the point is the one whose noise is nearer to the point's (two passes with
    # independent noise read half their noise)
    seq = np.concatenate([np.zeros((len(idx), 1), np.int64),
                          1 + np.argsort(nb[:, 1:], axis=1, kind="stable")], axis=1)
    keep = np.zeros(d.shape, bool)
    ar = np.arange(len(idx))
    keep[:, 0] = True
    for j in range(1, kk):
        c = seq[:, j]
        near = (D2[ar, c] <= (delta ** 2)[:, None]) & keep
        keep[ar, c] = ~near.any(axis=1)
    keep[:, 0] = False
    rank = np.cumsum(keep, axis=1)
    full = rank[:, -1] >= K
    sel = keep & (rank <= K)
    order = np.argsort(~sel, axis=1, kind="stable")[:, :K]
    return np.take_along_axis(Q, order[..., None], 1), full


def _frame(X):
    """Per point: the neighbours' heights h (m, K) along the chosen normal, their in-plane
    coordinates u, v (m, K) and the seed's weights (m, K) (all neighbours where no candidate
    plane's seed spans the plane)."""
    m = X.shape[0]
    ar = np.arange(m)
    _, V = np.linalg.eigh(np.einsum("mki,mkj->mij", X, X))
    T = X[:, _TRIPLES]                                          # (m, t, 3, 3)
    a, b = T[:, :, 1] - T[:, :, 0], T[:, :, 2] - T[:, :, 0]
    nc = np.cross(a, b)
    e2 = np.sum(a * a, -1) + np.sum(b * b, -1) + np.sum((b - a) ** 2, -1)
    quality = 2.0 * np.sqrt(3.0) * np.linalg.norm(nc, axis=2) / np.maximum(e2, 1e-300)
    good = np.concatenate([np.ones((m, 1), bool), quality >= QMIN], axis=1)
    nc = np.concatenate([V[:, None, :, 0], nc], axis=1)        # principal normal first
    nc /= np.maximum(np.linalg.norm(nc, axis=2, keepdims=True), 1e-300)
    H = np.einsum("mki,mci->mck", X, nc)                        # (m, c, K)
    order = np.argsort(H, axis=2)
    Hs = np.take_along_axis(H, order, 2)
    width = Hs[:, :, SEED - 1:] - Hs[:, :, :K - SEED + 1]       # windows of SEED heights
    j = np.argmin(width, axis=2)
    best = np.take_along_axis(width, j[..., None], 2)[..., 0]
    win = np.take_along_axis(order, j[..., None] + np.arange(SEED), 2)   # (m, c, SEED)
    Y = X[ar[:, None, None], win]
    best = np.where(good & _flat(Y, np.ones(Y.shape[:-1])), best, np.inf)
    c = np.argmin(best, axis=1)
    found = np.isfinite(best[ar, c])
    c = np.where(found, c, 0)
    n = nc[ar, c]
    h = H[ar, c]
    lo, hi = Hs[ar, c, j[ar, c]], Hs[ar, c, j[ar, c] + SEED - 1]
    pad = hi - lo                                   # the seed: its window widened by its width
    w = (h >= (lo - pad)[:, None]) & (h <= (hi + pad)[:, None]) | ~found[:, None]
    ref = np.where(np.abs(n[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    t1 = np.cross(n, ref)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n, t1)
    return h, np.einsum("mki,mi->mk", X, t1), np.einsum("mki,mi->mk", X, t2), w.astype(np.float64)


def reference_scan_noise(P) -> float:
    """Noise sigma (mm) of the scan points P (n, 3) about their local quadrics, or nan with
    fewer than ``K + 1`` points (copies counted once) or :data:`MIN_POINTS` well-fixed
    quadrics."""
    P = np.asarray(P, np.float64)
    n = P.shape[0]
    if n <= K:
        return float("nan")
    # evenly spaced in the file's order (no random draw: a simulated scan's outliers drawn with
    # the same seed were once exactly the points measured)
    idx = np.arange(n) if n <= POINTS else np.linspace(0, n - 1, POINTS).astype(np.int64)
    X, full = _neighbours(P, idx)                      # (m, K, 3) neighbours about the point
    h, u, v, w = _frame(X)
    A = np.stack([u * u, u * v, v * v, u, v, np.ones_like(u)], axis=2)   # (m, K, 6)
    AtA, coef, w, s = _sheet(A, h, w)
    # the neighbours the first sheet left: a second sheet (the other side of a thin wall)
    rest = (1.0 - w).sum(axis=1) >= SEED
    if rest.any():
        AtA2, coef2, w2, s2 = _sheet(A[rest], h[rest], 1.0 - w[rest])
        c1, c2 = coef[rest, 5], coef2[:, 5]
        with np.errstate(invalid="ignore"):
            other = ((w2.sum(axis=1) >= SEED) & (np.abs(c2 - c1) > SEP * (s[rest, 0] + s2[:, 0]))
                     & (np.abs(c2) < np.abs(c1)))
        i = np.flatnonzero(rest)[other]
        AtA[i], coef[i], w[i], s[i] = AtA2[other], coef2[other], w2[other], s2[other]
    r = coef[:, 5]                                      # the point (origin) off its quadric
    # its variance: sigma^2 (1 + leverage of the origin), the leverage e6^T (A^T W A)^-1 e6
    lev = _inv(AtA)[:, 5, 5]
    # neighbours (nearly) on a line, as along one row of a raster seen at a grazing angle, do
    # not fix the quadric at the point: such points are left out
    with np.errstate(invalid="ignore"):
        ok = (full & (lev >= 0.0) & (lev <= MAX_LEVERAGE) & _flat(np.stack([u, v], -1), w)
              & (np.abs(r) <= MISS * s[:, 0] * np.sqrt(1.0 + np.maximum(lev, 0.0))))
    if np.count_nonzero(ok) < MIN_POINTS:
        return float("nan")
    z = r[ok] / np.sqrt(1.0 + lev[ok])
    return float(1.4826 * np.median(np.abs(z)))
