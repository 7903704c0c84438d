"""numba exact closest points on triangle meshes, signed by the angle weighted pseudonormal (private).

References
----------
Ericson, Real-Time Collision Detection (2005), §5.1.5 (closest point on a triangle).
Bærentzen & Aanæs, "Signed distance computation using the angle weighted pseudonormal",
IEEE TVCG 11 (2005) 243-253.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def closest_on_triangle(q0, q1, q2, a0, a1, a2, b0, b1, b2, c0, c1, c2):
    """Closest point of triangle abc to q (Ericson §5.1.5): (x, y, z, feature).

    feature: 0 interior, 1-3 vertex a/b/c, 4 edge ab, 5 edge bc, 6 edge ca.
    """
    ab0 = b0 - a0
    ab1 = b1 - a1
    ab2 = b2 - a2
    ac0 = c0 - a0
    ac1 = c1 - a1
    ac2 = c2 - a2
    ap0 = q0 - a0
    ap1 = q1 - a1
    ap2 = q2 - a2
    d1 = ab0 * ap0 + ab1 * ap1 + ab2 * ap2
    d2 = ac0 * ap0 + ac1 * ap1 + ac2 * ap2
    if d1 <= 0.0 and d2 <= 0.0:
        return a0, a1, a2, 1
    bp0 = q0 - b0
    bp1 = q1 - b1
    bp2 = q2 - b2
    d3 = ab0 * bp0 + ab1 * bp1 + ab2 * bp2
    d4 = ac0 * bp0 + ac1 * bp1 + ac2 * bp2
    if d3 >= 0.0 and d4 <= d3:
        return b0, b1, b2, 2
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        w = d1 / (d1 - d3)
        return a0 + w * ab0, a1 + w * ab1, a2 + w * ab2, 4
    cp0 = q0 - c0
    cp1 = q1 - c1
    cp2 = q2 - c2
    d5 = ab0 * cp0 + ab1 * cp1 + ab2 * cp2
    d6 = ac0 * cp0 + ac1 * cp1 + ac2 * cp2
    if d6 >= 0.0 and d5 <= d6:
        return c0, c1, c2, 3
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return a0 + w * ac0, a1 + w * ac1, a2 + w * ac2, 6
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return b0 + w * (c0 - b0), b1 + w * (c1 - b1), b2 + w * (c2 - b2), 5
    den = 1.0 / (va + vb + vc)
    v = vb * den
    w = vc * den
    return (a0 + ab0 * v + ac0 * w, a1 + ab1 * v + ac1 * w, a2 + ab2 * v + ac2 * w, 0)


@njit(cache=True, nogil=True)
def _corner_angle(verts, tri, t, k):
    """Interior angle of triangle t at its corner k."""
    a = tri[t, k]
    b = tri[t, (k + 1) % 3]
    c = tri[t, (k + 2) % 3]
    e0 = verts[b, 0] - verts[a, 0]
    e1 = verts[b, 1] - verts[a, 1]
    e2 = verts[b, 2] - verts[a, 2]
    f0 = verts[c, 0] - verts[a, 0]
    f1 = verts[c, 1] - verts[a, 1]
    f2 = verts[c, 2] - verts[a, 2]
    l0 = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    l1 = np.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    if l0 == 0.0 or l1 == 0.0:
        return 0.0
    cs = (e0 * f0 + e1 * f1 + e2 * f2) / (l0 * l1)
    return np.arccos(min(1.0, max(-1.0, cs)))


@njit(cache=True, nogil=True)
def refine_mesh(Q, cand_lo, cand_hi, cand, verts, tri, tri_n, dist, feat,
                out_foot, out_normal, out_dist, out_face, out_uv):
    """Exact closest point of each query over its candidate triangles.

    ``cand[cand_lo[i]:cand_hi[i]]`` must hold every triangle that can be the closest one
    (exact.py passes all triangles whose centroid lies within the distance to the nearest
    model point plus the largest triangle radius).  The distance is signed with the angle
    weighted pseudonormal of the closest feature (face, edge or vertex), so the sign is right
    at edges and corners too.  ``out_uv`` gets the barycentric (u, v) of the foot,
    ``p = A + u (B - A) + v (C - A)``.  ``dist``, ``feat``: scratch (>= longest list).
    """
    for i in range(Q.shape[0]):
        q0 = Q[i, 0]
        q1 = Q[i, 1]
        q2 = Q[i, 2]
        lo = cand_lo[i]
        nc = cand_hi[i] - lo
        best = np.inf
        bt = -1
        bx = 0.0
        by = 0.0
        bz = 0.0
        for c in range(nc):
            t = cand[lo + c]
            A = tri[t, 0]
            B = tri[t, 1]
            C = tri[t, 2]
            x, y, z, ft = closest_on_triangle(q0, q1, q2, verts[A, 0], verts[A, 1], verts[A, 2],
                                              verts[B, 0], verts[B, 1], verts[B, 2],
                                              verts[C, 0], verts[C, 1], verts[C, 2])
            d = (x - q0) ** 2 + (y - q1) ** 2 + (z - q2) ** 2
            dist[c] = d
            feat[c] = ft
            if d < best:
                best = d
                bt = t
                bx = x
                by = y
                bz = z
        # angle weighted pseudonormal over the candidates that reach the same foot
        tol = 1e-18 + 1e-12 * best
        n0 = 0.0
        n1 = 0.0
        n2 = 0.0
        for c in range(nc):
            if dist[c] <= best + tol:
                t = cand[lo + c]
                w = 1.0
                ft = feat[c]
                if 1 <= ft <= 3:
                    w = _corner_angle(verts, tri, t, ft - 1)
                elif ft == 0 and t != bt:
                    continue
                n0 += w * tri_n[t, 0]
                n1 += w * tri_n[t, 1]
                n2 += w * tri_n[t, 2]
        d = np.sqrt(best)
        if (q0 - bx) * n0 + (q1 - by) * n1 + (q2 - bz) * n2 < 0.0:
            d = -d
        out_foot[i, 0] = bx
        out_foot[i, 1] = by
        out_foot[i, 2] = bz
        out_normal[i, 0] = tri_n[bt, 0]
        out_normal[i, 1] = tri_n[bt, 1]
        out_normal[i, 2] = tri_n[bt, 2]
        out_dist[i] = d
        out_face[i] = bt
        # barycentric (u, v) of the foot in its triangle
        A = tri[bt, 0]
        B = tri[bt, 1]
        C = tri[bt, 2]
        e0 = verts[B, 0] - verts[A, 0]
        e1 = verts[B, 1] - verts[A, 1]
        e2 = verts[B, 2] - verts[A, 2]
        f0 = verts[C, 0] - verts[A, 0]
        f1 = verts[C, 1] - verts[A, 1]
        f2 = verts[C, 2] - verts[A, 2]
        w0 = bx - verts[A, 0]
        w1 = by - verts[A, 1]
        w2 = bz - verts[A, 2]
        d00 = e0 * e0 + e1 * e1 + e2 * e2
        d01 = e0 * f0 + e1 * f1 + e2 * f2
        d11 = f0 * f0 + f1 * f1 + f2 * f2
        d20 = w0 * e0 + w1 * e1 + w2 * e2
        d21 = w0 * f0 + w1 * f1 + w2 * f2
        den = d00 * d11 - d01 * d01
        if den > 0.0:
            out_uv[i, 0] = (d11 * d20 - d01 * d21) / den
            out_uv[i, 1] = (d00 * d21 - d01 * d20) / den
        else:
            out_uv[i, 0] = 0.0
            out_uv[i, 1] = 0.0
