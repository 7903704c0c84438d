"""numba kernels for rays: a bounding-volume hierarchy over seed triangles and Newton line-surface
intersection on the exact NURBS (thesis §9.2). Private; inputs are trusted.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shapeverify.cad._kernels import surface_derivs_packed_ws, surface_work_size

LEAF = 4
INF = np.inf


@njit(cache=True)
def build_bvh(tri_min, tri_max, centroids):
    """Median-split BVH. Returns node arrays and the triangle order.

    nodes: lo (M,3), hi (M,3), left (M,) (-1 for leaves), right (M,), start (M,), count (M,)
    """
    n = centroids.shape[0]
    order = np.arange(n)
    cap = 2 * n + 1
    lo = np.empty((cap, 3))
    hi = np.empty((cap, 3))
    left = np.full(cap, -1, np.int64)
    right = np.full(cap, -1, np.int64)
    start = np.zeros(cap, np.int64)
    count = np.zeros(cap, np.int64)
    stack = np.empty(128, np.int64)
    m = 1
    start[0] = 0
    count[0] = n
    sp = 0
    stack[sp] = 0
    sp += 1
    while sp > 0:
        sp -= 1
        node = stack[sp]
        s, c = start[node], count[node]
        for k in range(3):
            a = INF
            b = -INF
            for i in range(s, s + c):
                t = order[i]
                if tri_min[t, k] < a:
                    a = tri_min[t, k]
                if tri_max[t, k] > b:
                    b = tri_max[t, k]
            lo[node, k] = a
            hi[node, k] = b
        if c <= LEAF:
            continue
        # split on the longest axis of the centroid bounds at the median
        axis = 0
        ext = -1.0
        for k in range(3):
            a = INF
            b = -INF
            for i in range(s, s + c):
                x = centroids[order[i], k]
                a = min(a, x)
                b = max(b, x)
            if b - a > ext:
                ext = b - a
                axis = k
        keys = np.empty(c)
        for i in range(c):
            keys[i] = centroids[order[s + i], axis]
        perm = np.argsort(keys)
        seg = order[s:s + c].copy()
        for i in range(c):
            order[s + i] = seg[perm[i]]
        half = c // 2
        l, r = m, m + 1
        m += 2
        start[l], count[l] = s, half
        start[r], count[r] = s + half, c - half
        left[node], right[node] = l, r
        stack[sp] = l
        stack[sp + 1] = r
        sp += 2
    return lo[:m].copy(), hi[:m].copy(), left[:m].copy(), right[:m].copy(), start[:m].copy(), count[:m].copy(), order


@njit(cache=True)
def _ray_box(o, inv, lo, hi, tmax):
    t0 = 0.0
    t1 = tmax
    for k in range(3):
        a = (lo[k] - o[k]) * inv[k]
        b = (hi[k] - o[k]) * inv[k]
        if a > b:
            a, b = b, a
        if a > t0:
            t0 = a
        if b < t1:
            t1 = b
        if t0 > t1:
            return False
    return True


@njit(cache=True)
def first_hit(o, d, tmin, verts, tris, order, lo, hi, left, right, start, count, stack):
    """Closest triangle hit with t > tmin (Möller-Trumbore). Returns (tri, t, b1, b2); tri -1 if none."""
    inv = np.empty(3)
    for k in range(3):
        inv[k] = 1.0 / d[k] if d[k] != 0.0 else 1e300
    best_t = INF
    best = -1
    bb1 = 0.0
    bb2 = 0.0
    sp = 0
    stack[sp] = 0
    sp += 1
    while sp > 0:
        sp -= 1
        node = stack[sp]
        if not _ray_box(o, inv, lo[node], hi[node], best_t):
            continue
        if left[node] < 0:
            for i in range(start[node], start[node] + count[node]):
                t_id = order[i]
                a = verts[tris[t_id, 0]]
                b = verts[tris[t_id, 1]]
                c = verts[tris[t_id, 2]]
                e1x, e1y, e1z = b[0] - a[0], b[1] - a[1], b[2] - a[2]
                e2x, e2y, e2z = c[0] - a[0], c[1] - a[1], c[2] - a[2]
                px = d[1] * e2z - d[2] * e2y
                py = d[2] * e2x - d[0] * e2z
                pz = d[0] * e2y - d[1] * e2x
                det = e1x * px + e1y * py + e1z * pz
                if abs(det) < 1e-300:
                    continue
                idet = 1.0 / det
                tx, ty, tz = o[0] - a[0], o[1] - a[1], o[2] - a[2]
                b1 = (tx * px + ty * py + tz * pz) * idet
                if b1 < -1e-9 or b1 > 1 + 1e-9:
                    continue
                qx = ty * e1z - tz * e1y
                qy = tz * e1x - tx * e1z
                qz = tx * e1y - ty * e1x
                b2 = (d[0] * qx + d[1] * qy + d[2] * qz) * idet
                if b2 < -1e-9 or b1 + b2 > 1 + 1e-9:
                    continue
                t = (e2x * qx + e2y * qy + e2z * qz) * idet
                if t > tmin and t < best_t:
                    best_t = t
                    best = t_id
                    bb1 = b1
                    bb2 = b2
        else:
            stack[sp] = left[node]
            stack[sp + 1] = right[node]
            sp += 2
    return best, best_t, bb1, bb2


@njit(cache=True)
def newton_line_surface(pk, f, o, d, u, v, t, dom, out, work, max_iter, tol):
    """Solve S(u, v) = o + t d for (u, v, t) by Newton from a seed. Returns (ok, u, v, t, iters).

    ``pk`` is the 7-tuple of packed surface arrays; (u, v) are clamped to the face domain ``dom``
    (2, 2); the iteration fails when it stalls on the domain boundary or does not converge.
    """
    for it in range(max_iter):
        surface_derivs_packed_ws(pk[0], pk[1], pk[2], pk[3], pk[4], pk[5], pk[6], f, u, v, 1, out, work)
        fx = out[0, 0, 0] - o[0] - t * d[0]
        fy = out[0, 0, 1] - o[1] - t * d[1]
        fz = out[0, 0, 2] - o[2] - t * d[2]
        res = np.sqrt(fx * fx + fy * fy + fz * fz)
        if res < tol:
            return True, u, v, t, it
        # J = [Su, Sv, -d]; solve J delta = -F by Cramer's rule
        a0, a1, a2 = out[1, 0, 0], out[1, 0, 1], out[1, 0, 2]
        b0, b1, b2 = out[0, 1, 0], out[0, 1, 1], out[0, 1, 2]
        c0, c1, c2 = -d[0], -d[1], -d[2]
        det = a0 * (b1 * c2 - b2 * c1) - b0 * (a1 * c2 - a2 * c1) + c0 * (a1 * b2 - a2 * b1)
        if abs(det) < 1e-300:
            return False, u, v, t, it
        r0, r1, r2 = -fx, -fy, -fz
        du = (r0 * (b1 * c2 - b2 * c1) - b0 * (r1 * c2 - r2 * c1) + c0 * (r1 * b2 - r2 * b1)) / det
        dv = (a0 * (r1 * c2 - r2 * c1) - r0 * (a1 * c2 - a2 * c1) + c0 * (a1 * r2 - a2 * r1)) / det
        dt = (a0 * (b1 * r2 - b2 * r1) - b0 * (a1 * r2 - a2 * r1) + r0 * (a1 * b2 - a2 * b1)) / det
        nu = min(max(u + du, dom[0, 0]), dom[0, 1])
        nv = min(max(v + dv, dom[1, 0]), dom[1, 1])
        if nu == u and nv == v and (du != 0.0 or dv != 0.0) and abs(dt) < tol:
            return False, u, v, t, it  # stuck on the domain boundary
        u, v, t = nu, nv, t + dt
    surface_derivs_packed_ws(pk[0], pk[1], pk[2], pk[3], pk[4], pk[5], pk[6], f, u, v, 0, out, work)
    fx = out[0, 0, 0] - o[0] - t * d[0]
    fy = out[0, 0, 1] - o[1] - t * d[1]
    fz = out[0, 0, 2] - o[2] - t * d[2]
    return np.sqrt(fx * fx + fy * fy + fz * fz) < tol, u, v, t, max_iter


@njit(cache=True)
def intersect_many(origins, directions, tmins, verts, tris, tri_face, vert_uv, bvh, pk, domains,
                   pmax, qmax, tol, out_face, out_uv, out_t, out_tri):
    """For each ray: first seed triangle beyond tmin, then Newton on its face.

    Writes face (-1: no hit), uv, t and the seed triangle (for the caller's retry beyond it).
    """
    lo, hi, left, right, start, count, order = bvh
    stack = np.empty(256, np.int64)
    out = np.empty((2, 2, 3))
    work = np.empty(surface_work_size(pmax, qmax, 1))
    for r in range(origins.shape[0]):
        o = origins[r]
        d = directions[r]
        tri, t, b1, b2 = first_hit(o, d, tmins[r], verts, tris, order, lo, hi, left, right, start, count, stack)
        out_tri[r] = tri
        if tri < 0:
            out_face[r] = -1
            continue
        f = tri_face[tri]
        ia, ib, ic = tris[tri, 0], tris[tri, 1], tris[tri, 2]
        u = (1 - b1 - b2) * vert_uv[ia, 0] + b1 * vert_uv[ib, 0] + b2 * vert_uv[ic, 0]
        v = (1 - b1 - b2) * vert_uv[ia, 1] + b1 * vert_uv[ib, 1] + b2 * vert_uv[ic, 1]
        ok, u, v, t, _ = newton_line_surface(pk, f, o, d, u, v, t, domains[f], out, work, 30, tol)
        if ok and t > tmins[r]:
            out_face[r] = f
            out_uv[r, 0] = u
            out_uv[r, 1] = v
            out_t[r] = t
        else:
            out_face[r] = -2  # seed found but Newton failed: caller retries beyond this triangle
            out_t[r] = t


@njit(cache=True)
def update_many(origins, directions, faces, uvs, ts, pk, domains, pmax, qmax, tol,
                out_ok, out_uv, out_t):
    """Re-solve stored intersections from their previous (u, v, t) (small-motion update, Paper IV)."""
    out = np.empty((2, 2, 3))
    work = np.empty(surface_work_size(pmax, qmax, 1))
    for r in range(origins.shape[0]):
        f = faces[r]
        if f < 0:
            out_ok[r] = False
            continue
        ok, u, v, t, _ = newton_line_surface(pk, f, origins[r], directions[r], uvs[r, 0], uvs[r, 1],
                                             ts[r], domains[f], out, work, 12, tol)
        out_ok[r] = ok
        out_uv[r, 0] = u
        out_uv[r, 1] = v
        out_t[r] = t
