"""numba kernels for rays: a bounding-volume hierarchy over seed triangles and Newton line-surface
intersection on the exact NURBS (thesis §9.2). Private; inputs are trusted.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shapeverify.cad._kernels import surface_derivs_packed_ws, surface_work_size
from shapeverify.cad._trim_kernels import inside

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
def collect_hits(o, d, tmin, window, bary_tol, verts, tris, order, lo, hi, left, right, start, count,
                 stack, cand_tri, cand_t, cand_b):
    """All seed triangles hit by the ray with tmin < t <= t_first + window (Möller-Trumbore with a
    barycentric tolerance), sorted by t. Returns their number (at most len(cand_tri))."""
    inv = np.empty(3)
    for k in range(3):
        inv[k] = 1.0 / d[k] if d[k] != 0.0 else 1e300
    cap = cand_tri.shape[0]
    nc = 0
    best_t = INF
    sp = 0
    stack[sp] = 0
    sp += 1
    while sp > 0:
        sp -= 1
        node = stack[sp]
        if not _ray_box(o, inv, lo[node], hi[node], best_t + window):
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
                if b1 < -bary_tol or b1 > 1 + bary_tol:
                    continue
                qx = ty * e1z - tz * e1y
                qy = tz * e1x - tx * e1z
                qz = tx * e1y - ty * e1x
                b2 = (d[0] * qx + d[1] * qy + d[2] * qz) * idet
                if b2 < -bary_tol or b1 + b2 > 1 + bary_tol:
                    continue
                t = (e2x * qx + e2y * qy + e2z * qz) * idet
                if t <= tmin or t > best_t + window:
                    continue
                if t < best_t:
                    best_t = t
                # insert sorted by t; when full, drop the farthest
                if nc < cap:
                    j = nc
                    nc += 1
                elif t < cand_t[cap - 1]:
                    j = cap - 1
                else:
                    continue
                while j > 0 and cand_t[j - 1] > t:
                    cand_tri[j] = cand_tri[j - 1]
                    cand_t[j] = cand_t[j - 1]
                    cand_b[j, 0] = cand_b[j - 1, 0]
                    cand_b[j, 1] = cand_b[j - 1, 1]
                    j -= 1
                cand_tri[j] = t_id
                cand_t[j] = t
                cand_b[j, 0] = b1
                cand_b[j, 1] = b2
        else:
            stack[sp] = left[node]
            stack[sp + 1] = right[node]
            sp += 2
    k = 0
    for i in range(nc):
        if cand_t[i] <= best_t + window:
            k += 1
    return k


@njit(cache=True)
def _store(out, pn):
    """Point, unit normal Su x Sv, Su and Sv from a derivative block into pn (12,)."""
    nx = out[1, 0, 1] * out[0, 1, 2] - out[1, 0, 2] * out[0, 1, 1]
    ny = out[1, 0, 2] * out[0, 1, 0] - out[1, 0, 0] * out[0, 1, 2]
    nz = out[1, 0, 0] * out[0, 1, 1] - out[1, 0, 1] * out[0, 1, 0]
    nn = np.sqrt(nx * nx + ny * ny + nz * nz)
    if nn == 0.0:
        nn = 1.0
    pn[0], pn[1], pn[2] = out[0, 0, 0], out[0, 0, 1], out[0, 0, 2]
    pn[3], pn[4], pn[5] = nx / nn, ny / nn, nz / nn
    for k in range(3):
        pn[6 + k] = out[1, 0, k]
        pn[9 + k] = out[0, 1, k]


@njit(cache=True)
def newton_line_surface(pk, f, o, d, u, v, t, dom, out, work, max_iter, tol, pn):
    """Solve S(u, v) = o + t d for (u, v, t) by Newton from a seed. Returns (ok, u, v, t, iters).

    ``pk`` is the 7-tuple of packed surface arrays; (u, v) are clamped to the face domain ``dom``
    (2, 2); the iteration fails when it stalls on the domain boundary or does not converge.
    On success ``pn`` (12,) holds the surface point, the unit normal Su x Sv, Su and Sv there.
    """
    for it in range(max_iter):
        surface_derivs_packed_ws(pk[0], pk[1], pk[2], pk[3], pk[4], pk[5], pk[6], f, u, v, 1, out, work)
        fx = out[0, 0, 0] - o[0] - t * d[0]
        fy = out[0, 0, 1] - o[1] - t * d[1]
        fz = out[0, 0, 2] - o[2] - t * d[2]
        res = np.sqrt(fx * fx + fy * fy + fz * fz)
        if res < tol:
            _store(out, pn)
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
    surface_derivs_packed_ws(pk[0], pk[1], pk[2], pk[3], pk[4], pk[5], pk[6], f, u, v, 1, out, work)
    fx = out[0, 0, 0] - o[0] - t * d[0]
    fy = out[0, 0, 1] - o[1] - t * d[1]
    fz = out[0, 0, 2] - o[2] - t * d[2]
    _store(out, pn)
    return np.sqrt(fx * fx + fy * fy + fz * fz) < tol, u, v, t, max_iter


@njit(cache=True)
def intersect_many(origins, directions, tmins, verts, tris, tri_face, vert_uv, bvh, pk, domains, trims,
                   pmax, qmax, tol, window, bary_tol, out_face, out_uv, out_t, out_pn):
    """First exact hit of each ray: seed candidates in depth order, Newton on each candidate's
    face, the first solution inside its face's trims wins. ``out_face`` -1 where no hit."""
    lo, hi, left, right, start, count, order = bvh
    stack = np.empty(256, np.int64)
    out = np.empty((2, 2, 3))
    work = np.empty(surface_work_size(pmax, qmax, 1))
    cand_tri = np.empty(48, np.int64)
    cand_t = np.empty(48)
    cand_b = np.empty((48, 2))
    pn = np.empty(12)
    for r in range(origins.shape[0]):
        o = origins[r]
        d = directions[r]
        out_face[r] = -1
        tmin = tmins[r]
        for _round in range(8):
            nc = collect_hits(o, d, tmin, window, bary_tol, verts, tris, order, lo, hi, left, right,
                              start, count, stack, cand_tri, cand_t, cand_b)
            if nc == 0:
                break
            for c in range(nc):
                tri = cand_tri[c]
                f = tri_face[tri]
                b1 = cand_b[c, 0]
                b2 = cand_b[c, 1]
                ia, ib, ic = tris[tri, 0], tris[tri, 1], tris[tri, 2]
                u = (1 - b1 - b2) * vert_uv[ia, 0] + b1 * vert_uv[ib, 0] + b2 * vert_uv[ic, 0]
                v = (1 - b1 - b2) * vert_uv[ia, 1] + b1 * vert_uv[ib, 1] + b2 * vert_uv[ic, 1]
                u = min(max(u, domains[f, 0, 0]), domains[f, 0, 1])
                v = min(max(v, domains[f, 1, 0]), domains[f, 1, 1])
                ok, u, v, t, _ = newton_line_surface(pk, f, o, d, u, v, cand_t[c], domains[f], out, work,
                                                     30, tol, pn)
                if ok and t > tmin and inside(trims, f, u, v):
                    if out_face[r] < 0 or t < out_t[r]:
                        out_face[r] = f
                        out_uv[r, 0] = u
                        out_uv[r, 1] = v
                        out_t[r] = t
                        for k in range(12):
                            out_pn[r, k] = pn[k]
            if out_face[r] >= 0:
                break
            tmin = cand_t[nc - 1]  # nothing valid in this window: look beyond it


@njit(cache=True)
def _solve3(a, b, c, r):
    """Solve [a b c] x = r (3x3, columns a, b, c) by Cramer's rule; ok False if singular."""
    det = a[0] * (b[1] * c[2] - b[2] * c[1]) - b[0] * (a[1] * c[2] - a[2] * c[1]) + c[0] * (a[1] * b[2] - a[2] * b[1])
    if abs(det) < 1e-300:
        return False, 0.0, 0.0, 0.0
    x = (r[0] * (b[1] * c[2] - b[2] * c[1]) - b[0] * (r[1] * c[2] - r[2] * c[1]) + c[0] * (r[1] * b[2] - r[2] * b[1])) / det
    y = (a[0] * (r[1] * c[2] - r[2] * c[1]) - r[0] * (a[1] * c[2] - a[2] * c[1]) + c[0] * (a[1] * r[2] - a[2] * r[1])) / det
    z = (a[0] * (b[1] * r[2] - b[2] * r[1]) - b[0] * (a[1] * r[2] - a[2] * r[1]) + r[0] * (a[1] * b[2] - a[2] * b[1])) / det
    return True, x, y, z


@njit(cache=True)
def update_many(origins, directions, faces, uvs, ts, stored, pk, domains, trims, pmax, qmax, tol,
                out_ok, out_uv, out_t, out_pn):
    """Re-solve stored intersections after a small motion (Paper IV).

    The first Newton step uses the stored point and derivatives (``stored`` (N, 12): point,
    normal, Su, Sv), so it costs no surface evaluation; Newton then finishes on the exact surface.
    """
    out = np.empty((2, 2, 3))
    work = np.empty(surface_work_size(pmax, qmax, 1))
    a = np.empty(3)
    b = np.empty(3)
    c = np.empty(3)
    rhs = np.empty(3)
    for r in range(origins.shape[0]):
        f = faces[r]
        if f < 0:
            out_ok[r] = False
            continue
        o = origins[r]
        d = directions[r]
        t0 = ts[r]
        for k in range(3):
            a[k] = stored[r, 6 + k]
            b[k] = stored[r, 9 + k]
            c[k] = -d[k]
            rhs[k] = -(stored[r, k] - o[k] - t0 * d[k])
        ok, du, dv, dt = _solve3(a, b, c, rhs)
        u, v, t = uvs[r, 0], uvs[r, 1], t0
        if ok:
            u = min(max(u + du, domains[f, 0, 0]), domains[f, 0, 1])
            v = min(max(v + dv, domains[f, 1, 0]), domains[f, 1, 1])
            t = t + dt
        ok, u, v, t, _ = newton_line_surface(pk, f, o, d, u, v, t, domains[f], out, work, 12, tol, out_pn[r])
        out_ok[r] = ok and inside(trims, f, u, v)
        out_uv[r, 0] = u
        out_uv[r, 1] = v
        out_t[r] = t


@njit(cache=True)
def finish(face, uv, t, pn, reversed_, out_points, out_normals, out_uv, out_t, out_face, out_deriv):
    """Assemble per-ray results in one pass: NaN/inf/-1 where no hit, normals oriented outward."""
    for r in range(face.shape[0]):
        f = face[r]
        if f < 0:
            out_face[r] = -1
            out_t[r] = np.inf
            for k in range(3):
                out_points[r, k] = np.nan
                out_normals[r, k] = np.nan
            out_uv[r, 0] = np.nan
            out_uv[r, 1] = np.nan
            for k in range(6):
                out_deriv[r, k] = pn[r, 6 + k]
            continue
        s = -1.0 if reversed_[f] else 1.0
        out_face[r] = f
        out_t[r] = t[r]
        for k in range(3):
            out_points[r, k] = pn[r, k]
            out_normals[r, k] = s * pn[r, 3 + k]
        out_uv[r, 0] = uv[r, 0]
        out_uv[r, 1] = uv[r, 1]
        for k in range(6):
            out_deriv[r, k] = pn[r, 6 + k]
