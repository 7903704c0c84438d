"""numba kernels of the IRLS-ICP loop (private; callers validate their input)."""
import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def plane_system(X, Y, N, w, center, H, g):
    """Accumulate ``H = sum w J^T J`` and ``g = sum w r J`` of the point-to-plane step.

    ``J_k = [((x_k - c) x n_k)^T, n_k^T]``, ``r_k = n_k . (x_k - y_k)`` (thesis eq. 12-13).
    X, Y, N : (n, 3); w : (n,); center : (3,); H : (6, 6) out; g : (6,) out.
    """
    H[:, :] = 0.0
    g[:] = 0.0
    j = np.empty(6)
    for k in range(X.shape[0]):
        wk = w[k]
        if wk == 0.0:
            continue
        qx = X[k, 0] - center[0]
        qy = X[k, 1] - center[1]
        qz = X[k, 2] - center[2]
        nx, ny, nz = N[k, 0], N[k, 1], N[k, 2]
        j[0] = qy * nz - qz * ny
        j[1] = qz * nx - qx * nz
        j[2] = qx * ny - qy * nx
        j[3] = nx
        j[4] = ny
        j[5] = nz
        r = nx * (X[k, 0] - Y[k, 0]) + ny * (X[k, 1] - Y[k, 1]) + nz * (X[k, 2] - Y[k, 2])
        for a in range(6):
            wa = wk * j[a]
            g[a] += wa * r
            for b in range(a, 6):
                H[a, b] += wa * j[b]
    for a in range(6):
        for b in range(a):
            H[a, b] = H[b, a]


@njit(cache=True, nogil=True)
def move_and_residuals(P, R, t, Y, N, valid, clamped, X, d):
    """X = P R^T + t and the signed distances to fixed closest points (0 where not valid).

    Where the foot was an orthogonal projection, the distance to its tangent plane
    ``n . (x - y)``; where it was clamped to a patch edge, the distance to the foot point itself,
    signed by the side of the plane (as ``Prepared.closest`` reports it).
    """
    for k in range(P.shape[0]):
        for i in range(3):
            X[k, i] = R[i, 0] * P[k, 0] + R[i, 1] * P[k, 1] + R[i, 2] * P[k, 2] + t[i]
        if valid[k]:
            ex = X[k, 0] - Y[k, 0]
            ey = X[k, 1] - Y[k, 1]
            ez = X[k, 2] - Y[k, 2]
            dn = N[k, 0] * ex + N[k, 1] * ey + N[k, 2] * ez
            if clamped[k]:
                e = np.sqrt(ex * ex + ey * ey + ez * ez)
                d[k] = e if dn >= 0.0 else -e
            else:
                d[k] = dn
        else:
            d[k] = 0.0


@njit(cache=True, nogil=True)
def weighted_centroid(X, w):
    c = np.zeros(3)
    s = 0.0
    for k in range(X.shape[0]):
        if w[k] != 0.0:
            s += w[k]
            for i in range(3):
                c[i] += w[k] * X[k, i]
    return c / s


#: loss codes of :func:`weigh_residuals` (registration.losses.LOSSES)
LOSS_CODES = {"l2": 0, "huber": 1, "tukey": 2, "cauchy": 3, "welsch": 4}


@njit(cache=True, nogil=True, inline="always")
def _rho_w(code, r, k):
    """(rho(r), w(r)) of the loss ``code`` with tuning constant k (losses.py, same formulas)."""
    if code == 0:
        return 0.5 * r * r, 1.0
    if code == 1:
        a = abs(r)
        if a <= k:
            return 0.5 * r * r, 1.0
        return k * a - 0.5 * k * k, k / max(a, 1e-300)
    u2 = (r / k) ** 2
    if code == 2:
        if u2 < 1.0:
            return (k * k / 6.0) * (1.0 - (1.0 - u2) ** 3), (1.0 - u2) ** 2
        return k * k / 6.0, 0.0
    if code == 3:
        return 0.5 * k * k * np.log1p(u2), 1.0 / (1.0 + u2)
    e = np.exp(-u2)
    return 0.5 * k * k * (1.0 - e), e


@njit(cache=True, nogil=True)
def abs_valid(d, valid):
    """|d| of the valid entries (for the median)."""
    out = np.empty(d.shape[0])
    m = 0
    for i in range(d.shape[0]):
        if valid[i]:
            out[m] = abs(d[i])
            m += 1
    return out[:m]


@njit(cache=True, nogil=True)
def weigh_residuals(code, d, valid, k, w, inl):
    """IRLS weights ``w`` (0 where invalid), inlier flags ``inl`` (|d| <= k), and
    (mean rho over valid, RMS of the inliers, number valid) in one pass."""
    s_rho = 0.0
    s2 = 0.0
    n_in = 0
    n_val = 0
    for i in range(d.shape[0]):
        if not valid[i]:
            w[i] = 0.0
            inl[i] = False
            continue
        r = d[i]
        rho, wi = _rho_w(code, r, k)
        w[i] = wi
        s_rho += rho
        n_val += 1
        if abs(r) <= k:
            inl[i] = True
            s2 += r * r
            n_in += 1
        else:
            inl[i] = False
    mean_rho = s_rho / n_val if n_val else np.nan
    rms = np.sqrt(s2 / n_in) if n_in else np.nan
    return mean_rho, rms, n_val
