"""numba kernels of the optical chain: OpenCV lens model, ray/plane sampling, stereo phase matching.

Device parameters are passed flat: ``K`` (3, 3), ``dist`` (5,) = k1 k2 p1 p2 k3, ``R`` (3, 3), ``T`` (3,),
with ``x_device = R @ x_left + T``.  Private: the algorithms around them live in ``camera.rig`` and
``camera.stereo``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange  # noqa: F401

TWO_PI = 2.0 * math.pi


@njit(cache=True, nogil=True, inline="always")
def _distort(x, y, dist):
    r2 = x * x + y * y
    radial = 1.0 + r2 * (dist[0] + r2 * (dist[1] + r2 * dist[4]))
    xd = x * radial + 2.0 * dist[2] * x * y + dist[3] * (r2 + 2.0 * x * x)
    yd = y * radial + dist[2] * (r2 + 2.0 * y * y) + 2.0 * dist[3] * x * y
    return xd, yd


@njit(cache=True, nogil=True, inline="always")
def _project(K, dist, R, T, X0, X1, X2):
    """Pixel (u, v) and device depth z of the left-frame point X."""
    xc = R[0, 0] * X0 + R[0, 1] * X1 + R[0, 2] * X2 + T[0]
    yc = R[1, 0] * X0 + R[1, 1] * X1 + R[1, 2] * X2 + T[1]
    zc = R[2, 0] * X0 + R[2, 1] * X1 + R[2, 2] * X2 + T[2]
    if zc <= 0.0:
        return np.nan, np.nan, zc
    xd, yd = _distort(xc / zc, yc / zc, dist)
    return K[0, 0] * xd + K[0, 1] * yd + K[0, 2], K[1, 1] * yd + K[1, 2], zc


@njit(cache=True, nogil=True)
def project_many(K, dist, R, T, X, out_uv, out_z):
    for i in range(X.shape[0]):
        u, v, z = _project(K, dist, R, T, X[i, 0], X[i, 1], X[i, 2])
        out_uv[i, 0] = u
        out_uv[i, 1] = v
        out_z[i] = z


@njit(cache=True, nogil=True)
def undistort_many(K, dist, pix, out):
    """Normalised undistorted coordinates of distorted pixels (Newton on the OpenCV model)."""
    fx, fy, s, cx, cy = K[0, 0], K[1, 1], K[0, 1], K[0, 2], K[1, 2]
    plain = dist[0] == 0.0 and dist[1] == 0.0 and dist[2] == 0.0 and dist[3] == 0.0 and dist[4] == 0.0
    for i in range(pix.shape[0]):
        yd = (pix[i, 1] - cy) / fy
        xd = (pix[i, 0] - cx - s * yd) / fx
        x, y = xd, yd
        if not plain:
            for _ in range(20):
                ex, ey = _distort(x, y, dist)
                ex -= xd
                ey -= yd
                # numerical Jacobian of the distortion (2 x 2)
                h = 1e-7
                ax, ay = _distort(x + h, y, dist)
                bx, by = _distort(x, y + h, dist)
                j00 = (ax - ex - xd) / h
                j10 = (ay - ey - yd) / h
                j01 = (bx - ex - xd) / h
                j11 = (by - ey - yd) / h
                det = j00 * j11 - j01 * j10
                if det == 0.0:
                    break
                dx = (j11 * ex - j01 * ey) / det
                dy = (-j10 * ex + j00 * ey) / det
                x -= dx
                y -= dy
                if abs(dx) + abs(dy) < 1e-15:
                    break
        out[i, 0] = x
        out[i, 1] = y


@njit(cache=True, nogil=True, inline="always")
def _bilinear_phase(psi, valid, u, v):
    """Wrapped phase at sub-pixel (u, v): neighbours unwrapped against the first; NaN if any invalid."""
    H, W = psi.shape
    if not (u >= 0.0 and v >= 0.0 and u <= W - 1.0 and v <= H - 1.0):
        return np.nan
    i0 = min(int(v), H - 2)
    j0 = min(int(u), W - 2)
    fy = v - i0
    fx = u - j0
    if not (valid[i0, j0] and valid[i0, j0 + 1] and valid[i0 + 1, j0] and valid[i0 + 1, j0 + 1]):
        return np.nan
    p00 = psi[i0, j0]
    p01 = p00 + _wrap(psi[i0, j0 + 1] - p00)
    p10 = p00 + _wrap(psi[i0 + 1, j0] - p00)
    p11 = p00 + _wrap(psi[i0 + 1, j0 + 1] - p00)
    return (p00 * (1 - fx) + p01 * fx) * (1 - fy) + (p10 * (1 - fx) + p11 * fx) * fy


@njit(cache=True, nogil=True, inline="always")
def _wrap(a):
    return a - TWO_PI * math.floor((a + math.pi) / TWO_PI)


@njit(cache=True, nogil=True, inline="always")
def _projector_coord(Kp, dp, Rp, Tp, rows, X0, X1, X2):
    """Pattern coordinate (column u, or row v when ``rows``) of a left-frame point in the projector."""
    u, v, z = _project(Kp, dp, Rp, Tp, X0, X1, X2)
    return v if rows else u


@njit(cache=True, nogil=True)
def ray_for_coord(o, d, Kp, dp, Rp, Tp, rows, target, t_lo, t_hi):
    """Ray parameter t in [t_lo, t_hi] where the projector coordinate of o + t d equals ``target``.

    The coordinate is monotone along a ray in the working volume; secant/bisection (NaN if outside).
    """
    a, b = t_lo, t_hi
    fa = _projector_coord(Kp, dp, Rp, Tp, rows, o[0] + a * d[0], o[1] + a * d[1], o[2] + a * d[2]) - target
    fb = _projector_coord(Kp, dp, Rp, Tp, rows, o[0] + b * d[0], o[1] + b * d[1], o[2] + b * d[2]) - target
    if not (fa * fb <= 0.0):
        return np.nan
    for _ in range(60):
        t = b - fb * (b - a) / (fb - fa) if fb != fa else 0.5 * (a + b)
        if not (t > min(a, b) and t < max(a, b)):
            t = 0.5 * (a + b)
        f = _projector_coord(Kp, dp, Rp, Tp, rows, o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]) - target
        if abs(f) < 1e-9 or abs(b - a) < 1e-10:
            return t
        if (f < 0.0) == (fa < 0.0):
            a, fa = t, f
        else:
            b, fb = t, f
    return 0.5 * (a + b)


# ---------------------------------------------------------------------------------------------
# stereo phase matching


@njit(cache=True, nogil=True)
def flood_unwrap(psi, quality, valid, max_step, labels, order):
    """Quality-guided flood fill (bucket queue): relative fringe order per pixel and region labels.

    labels (H, W) int32 -1 outside; order (H, W) int32 with ``psi + 2 pi order`` continuous inside a
    region.  Returns the number of regions.
    """
    H, W = psi.shape
    NB = 64
    N = H * W
    cap = 4 * N + 1
    head = np.full(NB, -1, np.int64)
    nxt = np.empty(cap, np.int64)
    item = np.empty(cap, np.int64)
    parent = np.empty(cap, np.int64)
    n_items = 0
    n_reg = 0
    for i in range(H):
        for j in range(W):
            labels[i, j] = -1
    for s in range(N):
        si, sj = s // W, s % W
        if not valid[si, sj] or labels[si, sj] >= 0:
            continue
        labels[si, sj] = n_reg
        order[si, sj] = 0
        n_items = 0
        for b in range(NB):
            head[b] = -1
        cur = 0
        p = s
        while True:
            pi_, pj = p // W, p % W
            for k in range(4):
                qi, qj = pi_, pj
                if k == 0:
                    qi -= 1
                elif k == 1:
                    qi += 1
                elif k == 2:
                    qj -= 1
                else:
                    qj += 1
                if qi < 0 or qj < 0 or qi >= H or qj >= W:
                    continue
                if not valid[qi, qj] or labels[qi, qj] >= 0:
                    continue
                step = _wrap(psi[qi, qj] - psi[pi_, pj])
                if abs(step) > max_step:
                    continue
                b = int(min(max(min(quality[qi, qj], quality[pi_, pj]), 0.0), 1.0) * (NB - 1))
                if n_items >= cap:
                    continue
                item[n_items] = qi * W + qj
                parent[n_items] = p
                nxt[n_items] = head[b]
                head[b] = n_items
                n_items += 1
                if b > cur:
                    cur = b
            # pop the best unvisited
            p = -1
            while cur >= 0:
                e = head[cur]
                if e < 0:
                    cur -= 1
                    continue
                head[cur] = nxt[e]
                q = item[e]
                qi, qj = q // W, q % W
                if labels[qi, qj] >= 0:
                    continue
                par = parent[e]
                ai, aj = par // W, par % W
                val = psi[ai, aj] + TWO_PI * order[ai, aj] + _wrap(psi[qi, qj] - psi[ai, aj])
                order[qi, qj] = int(np.round((val - psi[qi, qj]) / TWO_PI))
                labels[qi, qj] = n_reg
                p = q
                break
            if p < 0:
                break
        n_reg += 1
    return n_reg


@njit(cache=True, nogil=True, inline="always")
def _coord_along(d, Kp, dp, Rp, Tp, rows, t):
    return _projector_coord(Kp, dp, Rp, Tp, rows, t * d[0], t * d[1], t * d[2])


@njit(cache=True, nogil=True)
def _solve_coord(d, Kp, dp, Rp, Tp, rows, target, t_start, t_lo, t_hi):
    """t on the left ray (origin 0, direction d) with projector coordinate ``target`` (Newton, bisection fallback)."""
    t = t_start
    h = 1e-3 * t_start
    for _ in range(12):
        f = _coord_along(d, Kp, dp, Rp, Tp, rows, t) - target
        if abs(f) < 1e-7:
            break
        f2 = _coord_along(d, Kp, dp, Rp, Tp, rows, t + h) - target
        der = (f2 - f) / h
        if der == 0.0 or not np.isfinite(der) or not np.isfinite(f):
            t = np.nan
            break
        t_new = t - f / der
        if not (t_new > t_lo and t_new < t_hi):
            t = np.nan
            break
        t = t_new
    if not np.isfinite(t) or abs(_coord_along(d, Kp, dp, Rp, Tp, rows, t) - target) > 1e-4:
        o = np.zeros(3)
        t = ray_for_coord(o, d, Kp, dp, Rp, Tp, rows, target, t_lo, t_hi)
    return t


@njit(cache=True, nogil=True, inline="always")
def _right_error(d, t, psi_l, Kr, dr, Rr, Tr, psi_r, valid_r):
    u, v, z = _project(Kr, dr, Rr, Tr, t * d[0], t * d[1], t * d[2])
    if not (z > 0):
        return np.nan
    pr = _bilinear_phase(psi_r, valid_r, u, v)
    if not np.isfinite(pr):
        return np.nan
    return _wrap(pr - psi_l)


@njit(cache=True, nogil=True)
def candidate_errors(dirs, psi_l, base, cands, Kp, dp, Rp, Tp, rows, period, Kr, dr, Rr, Tr, psi_r, valid_r,
                     t_start, t_lo, t_hi, delta, out):
    """out[s, c]: wrapped right-phase error of sample s at absolute order base[s] + cands[c] (NaN: none)."""
    for s in range(dirs.shape[0]):
        d = dirs[s]
        ts = t_start
        for c in range(cands.shape[0]):
            k = base[s] + cands[c]
            target = period * ((psi_l[s] + delta) / TWO_PI + k)
            t = _solve_coord(d, Kp, dp, Rp, Tp, rows, target, ts, t_lo, t_hi)
            if not np.isfinite(t):
                out[s, c] = np.nan
                continue
            out[s, c] = _right_error(d, t, psi_l[s], Kr, dr, Rr, Tr, psi_r, valid_r)


@njit(cache=True, nogil=True)
def _right_root(d, t, psi, Kr, dr, Rr, Tr, psi_r, valid_r, slope, out_slope):
    """Secant iterations on the left ray for the point whose right-image phase equals ``psi``.

    ``slope`` (d error / d t, e.g. the previous pixel's) starts the secant when finite; the last
    secant slope is returned in ``out_slope[0]``.
    """
    e0 = _right_error(d, t, psi, Kr, dr, Rr, Tr, psi_r, valid_r)
    if not np.isfinite(e0):
        return np.nan
    if np.isfinite(slope) and slope != 0.0:
        step = -e0 / slope
        if abs(step) > 0.05 * t:
            step = 2e-4 * t
        t1 = t + step if abs(step) > 1e-9 * t else t + 2e-4 * t
    else:
        t1 = t + 2e-4 * t
    e1 = _right_error(d, t1, psi, Kr, dr, Rr, Tr, psi_r, valid_r)
    if not np.isfinite(e1):
        t1 = t - 2e-4 * t
        e1 = _right_error(d, t1, psi, Kr, dr, Rr, Tr, psi_r, valid_r)
        if not np.isfinite(e1):
            return np.nan
    t0 = t
    for _ in range(8):
        if e1 == e0:
            return t1 if abs(e1) < 1e-6 else np.nan
        k = (e1 - e0) / (t1 - t0)
        out_slope[0] = k
        t2 = t1 - e1 / k
        if abs(t2 - t1) < 1e-7 * t1:
            return t2
        e2 = _right_error(d, t2, psi, Kr, dr, Rr, Tr, psi_r, valid_r)
        if not np.isfinite(e2):
            return np.nan
        t0, e0, t1, e1 = t1, e1, t2, e2
    return t1 if abs(e1) < 1e-6 else np.nan


@njit(cache=True, nogil=True)
def match_pixels(idx, dirs, psi_l, korder, Kp, dp, Rp, Tp, rows, period, Kr, dr, Rr, Tr, psi_r, valid_r,
                 t_start, t_lo, t_hi, tol_p, delta, out_t, out_err):
    """Stereo match of left pixels at absolute fringe order ``korder``.

    For each pixel, the point on its ray whose right-image phase equals its left phase (the
    sub-pixel point on the epipolar line), by secant iterations started from the previous pixel's
    solution (raster order) or, failing that, from the projector's ray surface of the pixel's
    absolute phase.  out_t: ray parameter (NaN if rejected); out_err: projector-phase residual (rad).
    ``delta``: pattern phase = measured phase + delta (0 for the documented pattern).
    """
    t_prev = np.nan
    i_prev = -10
    slope = np.full(1, np.nan)
    for n in range(idx.shape[0]):
        i = idx[n]
        d = dirs[i]
        psi = psi_l[i]
        target = period * ((psi + delta) / TWO_PI + korder[n])
        out_t[n] = np.nan
        out_err[n] = np.nan
        t = np.nan
        ep = np.inf
        if i == i_prev + 1 and np.isfinite(t_prev):
            t = _right_root(d, t_prev, psi, Kr, dr, Rr, Tr, psi_r, valid_r, slope[0], slope)
            if np.isfinite(t):
                ep = TWO_PI * (_coord_along(d, Kp, dp, Rp, Tp, rows, t) - target) / period
        if not abs(ep) <= tol_p:
            t0 = _solve_coord(d, Kp, dp, Rp, Tp, rows, target, t_start if not np.isfinite(t_prev) else t_prev,
                              t_lo, t_hi)
            if np.isfinite(t0):
                t = _right_root(d, t0, psi, Kr, dr, Rr, Tr, psi_r, valid_r, np.nan, slope)
                if np.isfinite(t):
                    ep = TWO_PI * (_coord_along(d, Kp, dp, Rp, Tp, rows, t) - target) / period
        i_prev = i
        if np.isfinite(t) and np.isfinite(ep):
            out_err[n] = ep
            if abs(ep) <= tol_p:
                out_t[n] = t
                t_prev = t
                continue
        t_prev = np.nan


@njit(cache=True, nogil=True)
def board_image(dirs, origin, Rb, tb, cols, rows, sq, dark, light, bg, out):
    """Mean over sub-pixel rays dirs (S, N, 3) (from ``origin``, left frame) of a chessboard in the
    z = 0 plane of the board frame (x_left = Rb x_board + tb); out (N,)."""
    S, N = dirs.shape[0], dirs.shape[1]
    # origin in the board frame: Rb^T (origin - tb)
    o0 = origin[0] - tb[0]
    o1 = origin[1] - tb[1]
    o2 = origin[2] - tb[2]
    ob0 = Rb[0, 0] * o0 + Rb[1, 0] * o1 + Rb[2, 0] * o2
    ob1 = Rb[0, 1] * o0 + Rb[1, 1] * o1 + Rb[2, 1] * o2
    ob2 = Rb[0, 2] * o0 + Rb[1, 2] * o1 + Rb[2, 2] * o2
    for n in range(N):
        acc = 0.0
        for s in range(S):
            d0, d1, d2 = dirs[s, n, 0], dirs[s, n, 1], dirs[s, n, 2]
            db0 = Rb[0, 0] * d0 + Rb[1, 0] * d1 + Rb[2, 0] * d2
            db1 = Rb[0, 1] * d0 + Rb[1, 1] * d1 + Rb[2, 1] * d2
            db2 = Rb[0, 2] * d0 + Rb[1, 2] * d1 + Rb[2, 2] * d2
            if db2 == 0.0:
                acc += bg
                continue
            t = -ob2 / db2
            if t <= 0.0:
                acc += bg
                continue
            qx = math.floor((ob0 + t * db0) / sq)
            qy = math.floor((ob1 + t * db1) / sq)
            if qx >= -2 and qx <= cols and qy >= -2 and qy <= rows:
                inside = qx >= -1 and qx <= cols - 1 and qy >= -1 and qy <= rows - 1
                if inside and (int(qx + qy) % 2 == 0):
                    acc += dark
                else:
                    acc += light
            else:
                acc += bg
        out[n] = acc / S
