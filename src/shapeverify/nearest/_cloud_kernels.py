"""Distance to a point-cloud reference's local surface (private; see :class:`.exact.ExactCloud`).

For each query: a weighted least-squares quadric ``h = a0 + a1 u + a2 v + a3 u^2 + a4 uv +
a5 v^2`` through the k nearest reference points of its nearest reference point (lists made once
per reference; one k = 1 kd-tree query per query instead of a k-neighbour one), in the frame
``(t1, t2, n0)`` of the nearest model point's normal ``n0`` (the tilt of the true tangent plane is absorbed by ``a1, a2``);
Gaussian weights ``exp(-2 (r / r_k)^2)`` of the distance r to the query (``r_k``: the largest
such distance); neighbours whose own normal is more than 45 degrees from ``n0`` are left
out (the other side of a sharp edge).  With fewer than 10 neighbours left or an ill-conditioned
system the plane ``a0 + a1 u + a2 v``; with fewer than 3 the nearest reference point itself.
The foot is the closest point of that surface (Newton on the squared distance, from the query's
own (u, v)); the normal is the surface's, oriented along ``n0``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_QUADRIC_MIN = 10
_COS_SAME_SIDE = 0.7071
_SHARP = 2.0


@njit(cache=True, nogil=True)
def _solve(A, b, m):
    """Solve the symmetric positive definite m x m system A x = b in place (Cholesky); False
    when a pivot is not clearly positive (then A, b are garbage)."""
    scale = 0.0
    for i in range(m):
        scale = max(scale, A[i, i])
    for j in range(m):
        s = A[j, j]
        for k in range(j):
            s -= A[j, k] * A[j, k]
        if s <= 1e-10 * scale:
            return False
        A[j, j] = math.sqrt(s)
        for i in range(j + 1, m):
            s = A[i, j]
            for k in range(j):
                s -= A[i, k] * A[j, k]
            A[i, j] = s / A[j, j]
    for i in range(m):          # L y = b
        s = b[i]
        for k in range(i):
            s -= A[i, k] * b[k]
        b[i] = s / A[i, i]
    for i in range(m - 1, -1, -1):  # L^T x = y
        s = b[i]
        for k in range(i + 1, m):
            s -= A[k, i] * b[k]
        b[i] = s / A[i, i]
    return True


@njit(cache=True, nogil=True)
def surface_distance(q, near, nbr, V, VN, n0, ref_rk, k_ref, foot, normal, dist, onb, kind):
    """Fill foot (N, 3), normal (N, 3), signed dist (N,), on_boundary (N,) and the fit used
    (``kind``: 2 quadric, 1 plane, 0 nearest point) for queries q (N, 3).

    near : (N,) nearest reference point of each query
    nbr : (M, K) the K nearest reference points of each reference point (itself first)
    V, VN : (M, 3) reference points and their unit normals (either orientation)
    n0 : (N, 3) unit normal of each query's nearest model point (orients everything)
    ref_rk : (M,) each reference point's distance to its ``k_ref``-th neighbour (local spacing)
    """
    n = q.shape[0]
    K = nbr.shape[1]
    dk = np.empty(K)
    A = np.empty((6, 6))
    b = np.empty(6)
    row = np.empty(6)
    uu = np.empty(K)
    vv = np.empty(K)
    hh = np.empty(K)
    ww = np.empty(K)
    spacing_factor = math.sqrt(math.pi / k_ref)
    for i in range(n):
        nx, ny, nz = n0[i, 0], n0[i, 1], n0[i, 2]
        # a tangent t1 perpendicular to n0, t2 = n0 x t1
        if abs(nx) < 0.9:
            ax, ay, az = 1.0, 0.0, 0.0
        else:
            ax, ay, az = 0.0, 1.0, 0.0
        d0 = ax * nx + ay * ny + az * nz
        t1x, t1y, t1z = ax - d0 * nx, ay - d0 * ny, az - d0 * nz
        ln = math.sqrt(t1x * t1x + t1y * t1y + t1z * t1z)
        t1x /= ln
        t1y /= ln
        t1z /= ln
        t2x = ny * t1z - nz * t1y
        t2y = nz * t1x - nx * t1z
        t2z = nx * t1y - ny * t1x
        qx, qy, qz = q[i, 0], q[i, 1], q[i, 2]
        p0 = near[i]
        h = 1e-300
        for j in range(K):
            p = nbr[p0, j]
            ex, ey, ez = V[p, 0] - qx, V[p, 1] - qy, V[p, 2] - qz
            dk[j] = math.sqrt(ex * ex + ey * ey + ez * ez)
            h = max(h, dk[j])
        m = 0
        sw = 0.0
        for j in range(K):
            p = nbr[p0, j]
            if abs(VN[p, 0] * nx + VN[p, 1] * ny + VN[p, 2] * nz) < _COS_SAME_SIDE:
                continue
            ex, ey, ez = V[p, 0] - qx, V[p, 1] - qy, V[p, 2] - qz
            # scaled coordinates (units of h): a well-conditioned system at any size
            uu[m] = (ex * t1x + ey * t1y + ez * t1z) / h
            vv[m] = (ex * t2x + ey * t2y + ez * t2z) / h
            hh[m] = (ex * nx + ey * ny + ez * nz) / h
            r = dk[j] / h
            ww[m] = math.exp(-_SHARP * r * r)
            sw += ww[m]
            m += 1
        fit = 0
        c0 = c1 = c2 = c3 = c4 = c5 = 0.0
        for npar in (6, 3):
            if (npar == 6 and m < _QUADRIC_MIN) or m < 3:
                continue
            for a in range(npar):
                b[a] = 0.0
                for c in range(npar):
                    A[a, c] = 0.0
            for j in range(m):
                row[0] = 1.0
                row[1] = uu[j]
                row[2] = vv[j]
                if npar == 6:
                    row[3] = uu[j] * uu[j]
                    row[4] = uu[j] * vv[j]
                    row[5] = vv[j] * vv[j]
                w = ww[j]
                for a in range(npar):
                    wa = w * row[a]
                    b[a] += wa * hh[j]
                    for c in range(a + 1):
                        A[a, c] += wa * row[c]
            for a in range(npar):
                A[a, a] += 1e-9 * sw
                for c in range(a):
                    A[c, a] = A[a, c]
            if _solve(A, b, npar):
                c0, c1, c2 = b[0], b[1], b[2]
                if npar == 6:
                    c3, c4, c5 = b[3], b[4], b[5]
                fit = 2 if npar == 6 else 1
                break
        kind[i] = fit
        if fit == 0:   # too few neighbours on this side: the nearest reference point
            fx, fy, fz = V[p0, 0], V[p0, 1], V[p0, 2]
            ex, ey, ez = qx - fx, qy - fy, qz - fz
            foot[i, 0], foot[i, 1], foot[i, 2] = fx, fy, fz
            normal[i, 0], normal[i, 1], normal[i, 2] = nx, ny, nz
            dd = math.sqrt(ex * ex + ey * ey + ez * ez)
            dist[i] = -dd if ex * nx + ey * ny + ez * nz < 0.0 else dd
            onb[i] = False
            continue
        # foot: minimise (u)^2 + (v)^2 + (f(u, v))^2 -- the query is the origin (scaled units)
        u = 0.0
        v = 0.0
        for _ in range(8):
            f = c0 + c1 * u + c2 * v + c3 * u * u + c4 * u * v + c5 * v * v
            fu = c1 + 2.0 * c3 * u + c4 * v
            fv = c2 + c4 * u + 2.0 * c5 * v
            gu = u + f * fu
            gv = v + f * fv
            huu = 1.0 + fu * fu + f * 2.0 * c3
            hvv = 1.0 + fv * fv + f * 2.0 * c5
            huv = fu * fv + f * c4
            det = huu * hvv - huv * huv
            if det <= 1e-12:  # not convex here: a Gauss-Newton step
                huu = 1.0 + fu * fu
                hvv = 1.0 + fv * fv
                huv = fu * fv
                det = huu * hvv - huv * huv
            du = (hvv * gu - huv * gv) / det
            dv = (huu * gv - huv * gu) / det
            u -= du
            v -= dv
            if abs(du) + abs(dv) < 1e-12:
                break
        f = c0 + c1 * u + c2 * v + c3 * u * u + c4 * u * v + c5 * v * v
        fu = c1 + 2.0 * c3 * u + c4 * v
        fv = c2 + c4 * u + 2.0 * c5 * v
        fx = qx + h * (u * t1x + v * t2x + f * nx)
        fy = qy + h * (u * t1y + v * t2y + f * ny)
        fz = qz + h * (u * t1z + v * t2z + f * nz)
        mx = nx - fu * t1x - fv * t2x
        my = ny - fu * t1y - fv * t2y
        mz = nz - fu * t1z - fv * t2z
        ln = math.sqrt(mx * mx + my * my + mz * mz)
        mx /= ln
        my /= ln
        mz /= ln
        foot[i, 0], foot[i, 1], foot[i, 2] = fx, fy, fz
        normal[i, 0], normal[i, 1], normal[i, 2] = mx, my, mz
        ex, ey, ez = qx - fx, qy - fy, qz - fz
        dd = math.sqrt(ex * ex + ey * ey + ez * ez)
        dist[i] = -dd if ex * mx + ey * my + ez * mz < 0.0 else dd
        # past the reference's edge: no reference point near the foot (2.5 local spacings;
        # an empty disc that large inside a random cloud has probability exp(-6.25 pi))
        near2 = 1e300
        for j in range(K):
            p = nbr[p0, j]
            ex, ey, ez = V[p, 0] - fx, V[p, 1] - fy, V[p, 2] - fz
            near2 = min(near2, ex * ex + ey * ey + ez * ez)
        lim = 2.5 * spacing_factor * ref_rk[p0]
        onb[i] = near2 > lim * lim
