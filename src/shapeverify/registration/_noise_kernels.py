"""numba kernels of :func:`~shapeverify.registration._noise.scan_noise` (private; the caller
validates its input).

One centre at a time, the same arithmetic as the vectorised numpy of the first version (kept as
the reference in ``tests/test_scan_noise_compiled.py``), so the estimate agrees with it to
round-off: the copies' test of the neighbours, the frame (the seed plane among the candidate
planes), the growth of one or two quadric sheets and the centre's residual and leverage.  The
candidate planes' flatness test (a 3 x 3 eigenvalue problem, 57 per centre) runs only on the
candidates in order of their seed's width until one passes, which picks the candidate the
vectorised version picked (the narrowest good and flat seed, the first of equals).
"""
import numpy as np
from numba import njit

_SQRT3 = np.sqrt(3.0)


@njit(cache=True, nogil=True)
def copies(Q, d, seq, delta2, K):
    """The neighbours kept after the copies' test, in index order, K per centre.

    Q : (m, kk, 3) neighbours about their centre (the centre itself first), d : (m, kk) their
    distances from it, ascending; seq : (m, kk) the order they are visited in (the file's
    order; 0 first); delta2 : (m,) squared copy distance.  Only neighbours whose distances
    from the centre differ by about delta or less can be within delta of each other (the
    triangle inequality, with a margin far above the round-off), so each is compared with
    the kept ones of that run of distances alone.
    Returns ``order`` (m, K) int64 (the first K kept, then -- where fewer than K are kept --
    the others in index order, as a stable argsort of "not selected") and ``full`` (m,) bool.
    """
    m, kk = Q.shape[0], Q.shape[1]
    order = np.empty((m, K), np.int64)
    full = np.empty(m, np.bool_)
    keep = np.empty(kk, np.bool_)
    q2 = np.empty(kk)
    for i in range(m):
        for a in range(kk):
            q2[a] = Q[i, a, 0] * Q[i, a, 0] + Q[i, a, 1] * Q[i, a, 1] + Q[i, a, 2] * Q[i, a, 2]
            keep[a] = False
        keep[0] = True
        for j in range(1, kk):
            c = seq[i, j]
            near = False
            for step in (-1, 1):        # outwards from c, while the distances allow
                b = c + step
                while 0 <= b < kk:
                    gap = d[i, c] - d[i, b]
                    if gap * gap > delta2[i] + 1e-12 * (q2[c] + q2[b]):
                        break
                    if keep[b]:
                        dot = (Q[i, c, 0] * Q[i, b, 0] + Q[i, c, 1] * Q[i, b, 1]
                               + Q[i, c, 2] * Q[i, b, 2])
                        if q2[c] + q2[b] - 2.0 * dot <= delta2[i]:
                            near = True
                            break
                    b += step
                if near:
                    break
            keep[c] = not near
        keep[0] = False
        n_sel = 0
        for a in range(kk):
            if keep[a] and n_sel < K:
                order[i, n_sel] = a
                n_sel += 1
        full[i] = n_sel >= K
        for a in range(kk):                 # fewer kept than K: every kept one is
            if n_sel >= K:                  # selected, the others follow in index order
                break
            if not keep[a]:
                order[i, n_sel] = a
                n_sel += 1
    return order, full


@njit(cache=True, nogil=True)
def _argsort_small(x, out):
    """out = the indices that sort the short array x (insertion sort; equal values keep their
    order)."""
    n = x.shape[0]
    for a in range(n):
        out[a] = a
    for a in range(1, n):
        j = out[a]
        xv = x[j]
        b = a - 1
        while b >= 0 and x[out[b]] > xv:
            out[b + 1] = out[b]
            b -= 1
        out[b + 1] = j


@njit(cache=True, nogil=True)
def _sort_small(x, out):
    """out = x sorted (insertion sort: short arrays)."""
    n = x.shape[0]
    for a in range(n):
        xv = x[a]
        b = a - 1
        while b >= 0 and out[b] > xv:
            out[b + 1] = out[b]
            b -= 1
        out[b + 1] = xv


@njit(cache=True, nogil=True)
def _flat3(X, win, flat):
    """Whether the points X[win] (equal weights) span a plane: the middle eigenvalue of their
    scatter at least ``flat`` x the largest."""
    k = win.shape[0]
    c0 = 0.0
    c1 = 0.0
    c2 = 0.0
    for a in range(k):
        c0 += X[win[a], 0]
        c1 += X[win[a], 1]
        c2 += X[win[a], 2]
    c0 /= k
    c1 /= k
    c2 /= k
    m00 = m01 = m02 = m11 = m12 = m22 = 0.0
    for a in range(k):
        d0, d1, d2 = X[win[a], 0] - c0, X[win[a], 1] - c1, X[win[a], 2] - c2
        m00 += d0 * d0
        m01 += d0 * d1
        m02 += d0 * d2
        m11 += d1 * d1
        m12 += d1 * d2
        m22 += d2 * d2
    e_lo, e_mid, e_hi = _eig3(m00, m11, m22, m01, m02, m12)
    return e_mid >= flat * e_hi


@njit(cache=True, nogil=True)
def _eig3(a00, a11, a22, a01, a02, a12):
    """Eigenvalues (ascending) of a symmetric 3 x 3 matrix (the trigonometric solution; to
    round-off of the matrix's size, all that a ratio test against a fixed share needs)."""
    p1 = a01 * a01 + a02 * a02 + a12 * a12
    q = (a00 + a11 + a22) / 3.0
    b00, b11, b22 = a00 - q, a11 - q, a22 - q
    p2 = b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * p1
    if p2 == 0.0:
        return q, q, q
    p = np.sqrt(p2 / 6.0)
    det = (b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02)
           + a02 * (a01 * a12 - b11 * a02))
    r = min(max(det / (2.0 * p * p * p), -1.0), 1.0)
    phi = np.arccos(r) / 3.0
    e_hi = q + 2.0 * p * np.cos(phi)
    e_lo = q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
    return e_lo, 3.0 * q - e_hi - e_lo, e_hi


@njit(cache=True, nogil=True)
def _flat2(u, v, w, flat):
    """Whether the points (u, v) weighted by w span the plane (the smaller eigenvalue of their
    weighted scatter at least ``flat`` x the larger)."""
    sw = 0.0
    cu = 0.0
    cv = 0.0
    for a in range(u.shape[0]):
        sw += w[a]
        cu += w[a] * u[a]
        cv += w[a] * v[a]
    sw = max(sw, 1e-300)
    cu /= sw
    cv /= sw
    m00 = 0.0
    m01 = 0.0
    m11 = 0.0
    for a in range(u.shape[0]):
        du, dv = u[a] - cu, v[a] - cv
        m00 += w[a] * du * du
        m01 += w[a] * du * dv
        m11 += w[a] * dv * dv
    mid = 0.5 * (m00 + m11)
    rad = np.hypot(0.5 * (m00 - m11), m01)
    return mid - rad >= flat * (mid + rad)


@njit(cache=True, nogil=True)
def _frame(X, triples, seed, qmin, flat, h, u, v, w, nc, good, H, Hs, best, jbest, win):
    """One centre's frame (``_noise._frame`` of the first version): fills h, u, v, w (K,).

    The other arrays are work space: nc (t + 1, 3), good (t + 1,), H and Hs (t + 1, K),
    best (t + 1,), jbest (t + 1,) int, win (K,) int."""
    K = X.shape[0]
    S = np.zeros((3, 3))
    for k in range(K):
        for a in range(3):
            for b in range(3):
                S[a, b] += X[k, a] * X[k, b]
    _, V = np.linalg.eigh(S)
    nt = triples.shape[0]
    nc[0, 0], nc[0, 1], nc[0, 2] = V[0, 0], V[1, 0], V[2, 0]
    good[0] = True
    for t in range(nt):
        p, q, r = triples[t, 0], triples[t, 1], triples[t, 2]
        a0, a1, a2 = X[q, 0] - X[p, 0], X[q, 1] - X[p, 1], X[q, 2] - X[p, 2]
        b0, b1, b2 = X[r, 0] - X[p, 0], X[r, 1] - X[p, 1], X[r, 2] - X[p, 2]
        n0, n1, n2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
        e2 = ((a0 * a0 + a1 * a1 + a2 * a2) + (b0 * b0 + b1 * b1 + b2 * b2)
              + ((b0 - a0) ** 2 + (b1 - a1) ** 2 + (b2 - a2) ** 2))
        nn = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        good[t + 1] = 2.0 * _SQRT3 * nn / max(e2, 1e-300) >= qmin
        nc[t + 1, 0], nc[t + 1, 1], nc[t + 1, 2] = n0, n1, n2
    nc_n = nc.shape[0]
    for c in range(nc_n):
        nn = max(np.sqrt(nc[c, 0] ** 2 + nc[c, 1] ** 2 + nc[c, 2] ** 2), 1e-300)
        nc[c, 0] /= nn
        nc[c, 1] /= nn
        nc[c, 2] /= nn
    for c in range(nc_n):
        for k in range(K):
            H[c, k] = X[k, 0] * nc[c, 0] + X[k, 1] * nc[c, 1] + X[k, 2] * nc[c, 2]
        if not good[c]:                 # never chosen: no seed needed
            best[c] = np.inf
            jbest[c] = 0
            continue
        _sort_small(H[c], Hs[c])        # the heights in order: the windows of SEED of them
        jb = 0
        wb = np.inf
        for j in range(K - seed + 1):
            wd = Hs[c, j + seed - 1] - Hs[c, j]
            if wd < wb:
                wb = wd
                jb = j
        best[c] = wb
        jbest[c] = jb
    # the narrowest good candidate whose seed spans a plane (first of equals), tried in order
    chosen = -1
    floor = -np.inf                     # (best, index) of the last one tried
    floor_c = -1
    while True:
        c = -1
        for i in range(nc_n):
            if not good[i] or not np.isfinite(best[i]):
                continue
            if best[i] < floor or (best[i] == floor and i <= floor_c):
                continue                # tried already
            if c < 0 or best[i] < best[c]:
                c = i
        if c < 0:
            break
        _argsort_small(H[c], win)
        if _flat3(X, win[jbest[c]:jbest[c] + seed], flat):
            chosen = c
            break
        floor, floor_c = best[c], c
    found = chosen >= 0
    c = chosen if found else 0
    lo = Hs[c, jbest[c]]
    hi = Hs[c, jbest[c] + seed - 1]
    pad = hi - lo
    for k in range(K):
        h[k] = H[c, k]
        w[k] = 1.0 if ((h[k] >= lo - pad) and (h[k] <= hi + pad)) or not found else 0.0
    n0, n1, n2 = nc[c, 0], nc[c, 1], nc[c, 2]
    if abs(n0) < 0.9:
        r0, r1, r2 = 1.0, 0.0, 0.0
    else:
        r0, r1, r2 = 0.0, 1.0, 0.0
    t0, t1, t2 = n1 * r2 - n2 * r1, n2 * r0 - n0 * r2, n0 * r1 - n1 * r0
    tn = np.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    t0 /= tn
    t1 /= tn
    t2 /= tn
    s0, s1, s2 = n1 * t2 - n2 * t1, n2 * t0 - n0 * t2, n0 * t1 - n1 * t0
    for k in range(K):
        u[k] = X[k, 0] * t0 + X[k, 1] * t1 + X[k, 2] * t2
        v[k] = X[k, 0] * s0 + X[k, 1] * s1 + X[k, 2] * s2


@njit(cache=True, nogil=True)
def _inv6(M):
    """Inverse of a small square matrix as numpy's ``inv`` computes it (LU with partial
    pivoting, solved against the identity), or its pseudo-inverse where a pivot is exactly
    zero (numpy's ``inv`` raises there and ``_noise`` took the pseudo-inverse)."""
    p = M.shape[0]
    LU = M.copy()
    perm = np.arange(p)
    for c in range(p):
        piv = c
        big = abs(LU[c, c])
        for r in range(c + 1, p):
            if abs(LU[r, c]) > big:
                big = abs(LU[r, c])
                piv = r
        if big == 0.0:
            return np.linalg.pinv(M)
        if piv != c:
            for k in range(p):
                LU[c, k], LU[piv, k] = LU[piv, k], LU[c, k]
            perm[c], perm[piv] = perm[piv], perm[c]
        inv_d = 1.0 / LU[c, c]
        for r in range(c + 1, p):
            f = LU[r, c] * inv_d
            LU[r, c] = f
            for k in range(c + 1, p):
                LU[r, k] -= f * LU[c, k]
    out = np.empty((p, p))
    y = np.empty(p)
    for j in range(p):                  # column j of the inverse: solve LU x = P e_j
        for r in range(p):
            acc = 1.0 if perm[r] == j else 0.0
            for k in range(r):
                acc -= LU[r, k] * y[k]
            y[r] = acc
        for r in range(p - 1, -1, -1):
            acc = y[r]
            for k in range(r + 1, p):
                acc -= LU[r, k] * out[k, j]
            out[r, j] = acc / LU[r, r]
    return out


@njit(cache=True, nogil=True)
def _fit(A, h, w):
    """Weighted least-squares quadric: ``(A^T W A, its inverse, coefficients)``."""
    K, p = A.shape
    AtA = np.zeros((p, p))
    Ath = np.zeros(p)
    for k in range(K):
        for a in range(p):
            wa = A[k, a] * w[k]
            Ath[a] += wa * h[k]
            for b in range(p):
                AtA[a, b] += wa * A[k, b]
    for a in range(p):
        AtA[a, a] += 1e-12
    Ai = _inv6(AtA)
    coef = np.zeros(p)
    for a in range(p):
        for b in range(p):
            coef[a] += Ai[a, b] * Ath[b]
    return AtA, Ai, coef


@njit(cache=True, nogil=True)
def _sheet(A, h, w0, rounds):
    """Grow one quadric sheet from the seed weights w0 (``_noise._sheet`` of the first version):
    ``((A^T W A)^-1, coefficients, weights, sigma)``, sigma NaN where no inlier is left."""
    K, p = A.shape
    w = w0.copy()
    s = np.nan
    hk = np.empty(K)
    t_in = np.empty(K)
    t_out = np.empty(K)
    srt = np.empty(K)
    for _ in range(rounds):
        AtA, Ai, coef = _fit(A, h, w)
        cnt = 0
        for k in range(K):
            q = 0.0
            for a in range(p):
                row = 0.0
                for b in range(p):
                    row += Ai[a, b] * A[k, b]
                q += A[k, a] * row
            hk[k] = q
            pred = 0.0
            for a in range(p):
                pred += A[k, a] * coef[a]
            res = abs(h[k] - pred)
            t_in[k] = res / np.sqrt(max(1.0 - q, 1e-12))
            t_out[k] = res / np.sqrt(1.0 + q)
            if w[k] > 0 and q < 0.99:
                srt[cnt] = t_in[k]
                cnt += 1
        if cnt == 0:
            s = np.nan
            continue                        # no inlier: the weights stay
        vals = np.sort(srt[:cnt])
        med = 0.5 * (vals[(cnt - 1) // 2] + vals[cnt // 2])
        s = 1.4826 * med
        if not np.isfinite(s):
            continue
        lim = 3.0 * max(s, 1e-300)
        for k in range(K):
            t = t_in[k] if w[k] > 0 else t_out[k]
            w[k] = 1.0 if t <= lim else 0.0
    _, Ai, coef = _fit(A, h, w)
    return Ai, coef, w, s


@njit(cache=True, nogil=True)
def centres(X, full, triples, seed, qmin, flat, rounds, sep, max_leverage, miss):
    """Each centre's residual off its sheet's quadric, the quadric's leverage there and whether
    the centre counts (``ok``): ``(r, lev, ok)`` (m,) of the neighbours X (m, K, 3) about
    their centres."""
    m, K = X.shape[0], X.shape[1]
    r_out = np.full(m, np.nan)
    lev_out = np.full(m, np.nan)
    ok = np.zeros(m, np.bool_)
    h = np.empty(K)
    u = np.empty(K)
    v = np.empty(K)
    w = np.empty(K)
    A = np.empty((K, 6))
    nc_n = triples.shape[0] + 1
    nc = np.empty((nc_n, 3))
    good = np.empty(nc_n, np.bool_)
    H = np.empty((nc_n, K))
    Hs = np.empty((nc_n, K))
    best = np.empty(nc_n)
    jbest = np.empty(nc_n, np.int64)
    win = np.empty(K, np.int64)
    for i in range(m):
        _frame(X[i], triples, seed, qmin, flat, h, u, v, w, nc, good, H, Hs, best, jbest, win)
        for k in range(K):
            A[k, 0] = u[k] * u[k]
            A[k, 1] = u[k] * v[k]
            A[k, 2] = v[k] * v[k]
            A[k, 3] = u[k]
            A[k, 4] = v[k]
            A[k, 5] = 1.0
        Ai, coef, ws, s = _sheet(A, h, w, rounds)
        rest = 0.0
        for k in range(K):
            rest += 1.0 - ws[k]
        if rest >= seed:
            w2 = 1.0 - ws
            Ai2, coef2, ws2, s2 = _sheet(A, h, w2, rounds)
            c1, c2 = coef[5], coef2[5]
            if (ws2.sum() >= seed and abs(c2 - c1) > sep * (s + s2)
                    and abs(c2) < abs(c1)):
                Ai, coef, ws, s = Ai2, coef2, ws2, s2
        r = coef[5]
        lev = Ai[5, 5]                      # (A^T W A)^-1 of the sheet's last fit
        r_out[i] = r
        lev_out[i] = lev
        ok[i] = (full[i] and lev >= 0.0 and lev <= max_leverage and _flat2(u, v, ws, flat)
                 and abs(r) <= miss * s * np.sqrt(1.0 + max(lev, 0.0)))
    return r_out, lev_out, ok
