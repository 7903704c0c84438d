"""numba kernels of the exact closest point: NURBS point inversion with trims, triangles (private).

CAD faces
---------
Surfaces come packed (:class:`shapeverify.cad.nurbs.PackedSurfaces`, the 7 ``kernel_args``)
and are evaluated with ``shapeverify.cad._kernels.surface_derivs_packed_ws``.  Trimming loops
are flat segment arrays (see :mod:`shapeverify.nearest.exact`): per face ``f`` the segments
``seg_off[f]:seg_off[f+1]`` with end points ``(x0, y0) -> (x1, y1)`` in (u, v), their 3D end
points ``a3``, ``b3`` and a ``free`` flag, and slab bins along v for the even-odd test.

Meshes
------
Triangles ``tri`` (T, 3) into ``verts`` (V, 3), unit normals ``tri_n``, and the triangles
around each vertex (CSR ``vt_ptr``, ``vt_idx``).

All kernels trust their input and allocate scratch space once per call, not per point.

References
----------
Piegl & Tiller, The NURBS Book, 2nd ed., §6.1 (point inversion and projection by Newton).
Ericson, Real-Time Collision Detection (2005), §5.1.5 (closest point on a triangle).
Bærentzen & Aanæs, "Signed distance computation using the angle weighted pseudonormal",
IEEE TVCG 11 (2005) 243-253.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import frame

_MAX_NEWTON = 50
_MAX_HALVING = 40


# ------------------------------------------------------------------------------ CAD faces
# Surfaces as tables of polynomial patches (``tab``, built by exact.py): per face f
#   deg[f] = (p, q); spans along u: bu[bu_off[f]:bu_off[f+1]] (breakpoints, n_u + 1 of them),
#   mu[mu_off[f] + i] = centre of span i (same for v with bv/mv); coefficient rows
#   coef[c_off[f] + ((i * n_v + j) * (p + 1) + a) * (q + 1) + b] = (wx, wy, wz, w) of
#   (u - mu_i)^a (v - mv_j)^b on span (i, j).  Homogeneous, divided back with the quotient rule.
@njit(cache=True, nogil=True, inline="always")
def _span(x, br, lo, hi):
    """Index i of the span [br[lo+i], br[lo+i+1]] holding x (clamped to the ends)."""
    a = lo
    b = hi - 1
    if x <= br[a]:
        return 0
    if x >= br[b]:
        return b - 1 - lo
    while b - a > 1:
        m = (a + b) >> 1
        if x < br[m]:
            b = m
        else:
            a = m
    return a - lo


@njit(cache=True, nogil=True)
def _eval(tab, f, u, v, out, work):
    """out[k, l] = d^(k+l)S/du^k dv^l at (u, v) for k + l <= 2 (out (3, 3, 3))."""
    deg, bu, bu_off, mu, mu_off, bv, bv_off, mv, mv_off, coef, c_off = tab
    p = deg[f, 0]
    q = deg[f, 1]
    nsv = bv_off[f + 1] - bv_off[f] - 1
    i = _span(u, bu, bu_off[f], bu_off[f + 1])
    j = _span(v, bv, bv_off[f], bv_off[f + 1])
    s = u - mu[mu_off[f] + i]
    t = v - mv[mv_off[f] + j]
    base = c_off[f] + (i * nsv + j) * (p + 1) * (q + 1)
    # work rows a*3 + k: k-th t-derivative of sum_b C[a, b] t^b; the 4 homogeneous
    # components run as independent Horner chains (instruction-level parallelism)
    for a in range(p + 1):
        row = base + a * (q + 1)
        x0 = coef[row + q, 0]
        y0 = coef[row + q, 1]
        z0 = coef[row + q, 2]
        w0 = coef[row + q, 3]
        x1 = y1 = z1 = w1 = 0.0
        x2 = y2 = z2 = w2 = 0.0
        for b in range(q - 1, -1, -1):
            x2 = x2 * t + x1
            y2 = y2 * t + y1
            z2 = z2 * t + z1
            w2 = w2 * t + w1
            x1 = x1 * t + x0
            y1 = y1 * t + y0
            z1 = z1 * t + z0
            w1 = w1 * t + w0
            x0 = x0 * t + coef[row + b, 0]
            y0 = y0 * t + coef[row + b, 1]
            z0 = z0 * t + coef[row + b, 2]
            w0 = w0 * t + coef[row + b, 3]
        k = a * 3
        work[k, 0] = x0
        work[k, 1] = y0
        work[k, 2] = z0
        work[k, 3] = w0
        work[k + 1, 0] = x1
        work[k + 1, 1] = y1
        work[k + 1, 2] = z1
        work[k + 1, 3] = w1
        work[k + 2, 0] = 2.0 * x2
        work[k + 2, 1] = 2.0 * y2
        work[k + 2, 2] = 2.0 * z2
        work[k + 2, 3] = 2.0 * w2
    # along u: H[k][l] homogeneous d^(k+l)/du^k dv^l
    for c in range(4):
        h0 = work[p * 3, c]
        h0s = 0.0
        h0ss = 0.0
        h1 = work[p * 3 + 1, c]
        h1s = 0.0
        h2 = work[p * 3 + 2, c]
        for a in range(p - 1, -1, -1):
            h0ss = h0ss * s + h0s
            h0s = h0s * s + h0
            h0 = h0 * s + work[a * 3, c]
            h1s = h1s * s + h1
            h1 = h1 * s + work[a * 3 + 1, c]
            h2 = h2 * s + work[a * 3 + 2, c]
        work[3 * (p + 1), c] = h0
        work[3 * (p + 1) + 1, c] = h0s
        work[3 * (p + 1) + 2, c] = 2.0 * h0ss
        work[3 * (p + 1) + 3, c] = h1
        work[3 * (p + 1) + 4, c] = h1s
        work[3 * (p + 1) + 5, c] = h2
    r = 3 * (p + 1)
    iw = 1.0 / work[r, 3]
    wu = work[r + 1, 3]
    wuu = work[r + 2, 3]
    wv = work[r + 3, 3]
    wuv = work[r + 4, 3]
    wvv = work[r + 5, 3]
    for c in range(3):
        S = work[r, c] * iw
        Su = (work[r + 1, c] - wu * S) * iw
        Sv = (work[r + 3, c] - wv * S) * iw
        out[0, 0, c] = S
        out[1, 0, c] = Su
        out[0, 1, c] = Sv
        out[2, 0, c] = (work[r + 2, c] - 2.0 * wu * Su - wuu * S) * iw
        out[1, 1, c] = (work[r + 4, c] - wu * Sv - wv * Su - wuv * S) * iw
        out[0, 2, c] = (work[r + 5, c] - 2.0 * wv * Sv - wvv * S) * iw


@njit(cache=True, nogil=True)
def eval_many(tab, faces, u, v, work_rows, out):
    """out[i] = derivatives (3, 3, 3) of face faces[i] at (u[i], v[i]) (see :func:`_eval`)."""
    work = np.empty((work_rows, 4))
    for i in range(u.shape[0]):
        _eval(tab, faces[i], u[i], v[i], out[i], work)


@njit(cache=True, nogil=True, inline="always")
def _dist2_at(tab, f, u, v, q0, q1, q2, out, work):
    _eval(tab, f, u, v, out, work)
    a = out[0, 0, 0] - q0
    b = out[0, 0, 1] - q1
    c = out[0, 0, 2] - q2
    return a * a + b * b + c * c


@njit(cache=True, nogil=True, inline="always")
def _wrap(x, lo, hi, closed):
    if closed:  # into [lo, hi): the seam belongs to the start of the domain
        if x < lo or x >= hi:
            x = lo + (x - lo) % (hi - lo)
            if x >= hi:
                x = lo
        return x
    return min(max(x, lo), hi)


@njit(cache=True, nogil=True)
def newton_face(tab, domains, closed, f, u, v, q0, q1, q2, out, work):
    """Point inversion on face f's surface from (u, v): (u, v, squared distance, at_bound).

    Newton on the gradient of |S(u, v) - q|^2 / 2 with the exact Hessian (Gauss-Newton when
    it is not positive definite), a backtracking line search, and the box constraint of the
    surface domain handled by an active set (a parameter on a bound that would leave the
    domain is frozen and the other one is solved in 1D).  Closed directions wrap around.
    ``out`` holds the order-2 derivatives at the returned (u, v) on exit; ``at_bound`` says
    that (u, v) lies on an edge of the (not closed) domain, where the trims may run.
    """
    u0 = domains[f, 0, 0]
    u1 = domains[f, 0, 1]
    v0 = domains[f, 1, 0]
    v1 = domains[f, 1, 1]
    cu = closed[f, 0]
    cv = closed[f, 1]
    d0 = _dist2_at(tab, f, u, v, q0, q1, q2, out, work)
    prev = 0.0
    for it in range(_MAX_NEWTON):
        r0 = out[0, 0, 0] - q0
        r1 = out[0, 0, 1] - q1
        r2 = out[0, 0, 2] - q2
        su0 = out[1, 0, 0]
        su1 = out[1, 0, 1]
        su2 = out[1, 0, 2]
        sv0 = out[0, 1, 0]
        sv1 = out[0, 1, 1]
        sv2 = out[0, 1, 2]
        gu = r0 * su0 + r1 * su1 + r2 * su2
        gv = r0 * sv0 + r1 * sv1 + r2 * sv2
        guu = su0 * su0 + su1 * su1 + su2 * su2
        gvv = sv0 * sv0 + sv1 * sv1 + sv2 * sv2
        guv = su0 * sv0 + su1 * sv1 + su2 * sv2
        a = guu + r0 * out[2, 0, 0] + r1 * out[2, 0, 1] + r2 * out[2, 0, 2]
        b = guv + r0 * out[1, 1, 0] + r1 * out[1, 1, 1] + r2 * out[1, 1, 2]
        c = gvv + r0 * out[0, 2, 0] + r1 * out[0, 2, 1] + r2 * out[0, 2, 2]
        if not (a > 0.0 and a * c - b * b > 0.0):
            a = guu
            b = guv
            c = gvv
        det = a * c - b * b
        if det > 1e-30 * (a * c + 1e-300):
            du = -(c * gu - b * gv) / det
            dv = -(a * gv - b * gu) / det
        else:
            du = -gu / a if a > 0.0 else 0.0
            dv = -gv / c if c > 0.0 else 0.0
        # active set on the domain bounds
        if not cu and ((u <= u0 and du < 0.0) or (u >= u1 and du > 0.0)):
            du = 0.0
            dv = -gv / c if c > 0.0 else 0.0
        if not cv and ((v <= v0 and dv < 0.0) or (v >= v1 and dv > 0.0)):
            dv = 0.0
            if not cu and ((u <= u0 and gu > 0.0) or (u >= u1 and gu < 0.0)):
                du = 0.0
            else:
                du = -gu / a if a > 0.0 else 0.0
        if du == 0.0 and dv == 0.0:
            break
        step3 = np.sqrt((su0 * du + sv0 * dv) ** 2 + (su1 * du + sv1 * dv) ** 2
                        + (su2 * du + sv2 * dv) ** 2)
        scale = 1.0 + abs(q0) + abs(q1) + abs(q2)
        if step3 <= 1e-5 * scale:
            # quadratic convergence region: take the full step (rounding makes the
            # distance useless as a merit function this close to the minimum)
            u = _wrap(u + du, u0, u1, cu)
            v = _wrap(v + dv, v0, v1, cv)
            d0 = _dist2_at(tab, f, u, v, q0, q1, q2, out, work)
            # next step ~ C step^2 with C estimated from the last two steps
            if step3 <= 1e-9 * scale or (prev > 0.0 and step3 * step3 * step3
                                         <= 1e-13 * scale * prev * prev):
                break
            prev = step3
            continue
        t = 1.0
        accepted = False
        un = u
        vn = v
        dn = d0
        for _ in range(_MAX_HALVING):
            un = _wrap(u + t * du, u0, u1, cu)
            vn = _wrap(v + t * dv, v0, v1, cv)
            dn = _dist2_at(tab, f, un, vn, q0, q1, q2, out, work)
            if dn <= d0:
                accepted = True
                break
            t *= 0.5
        if not accepted:
            _eval(tab, f, u, v, out, work)
            break
        u = un
        v = vn
        d0 = dn
        prev = t * step3
    at_bound = (not cu and (u <= u0 or u >= u1)) or (not cv and (v <= v0 or v >= v1))
    return u, v, d0, at_bound


@njit(cache=True, nogil=True)
def inside(f, u, v, bin_off, bin_lo, bin_hi, bin_inv, bin_start, bin_xy):
    """Even-odd test of (u, v) against the trimming loops of face f (slab bins along v).

    Bin g of face f holds copies of the segments crossing its v range,
    ``bin_xy[bin_start[g]:bin_start[g+1]]`` = (u0, v0, u1, v1), so the test reads contiguous
    memory.  A segment counts when v lies in its half-open v range and the crossing lies at
    u' > u (the PNPOLY rule), so a ray through a shared vertex is counted once.
    """
    if not (v >= bin_lo[f] and v <= bin_hi[f]):
        return False
    nb = bin_off[f + 1] - bin_off[f]
    b = min(max(int((v - bin_lo[f]) * bin_inv[f]), 0), nb - 1)
    g = bin_off[f] + b
    res = False
    for k in range(bin_start[g], bin_start[g + 1]):
        ya = bin_xy[k, 1]
        yb = bin_xy[k, 3]
        if (ya > v) != (yb > v):
            xc = bin_xy[k, 0] + (v - ya) * (bin_xy[k, 2] - bin_xy[k, 0]) / (yb - ya)
            if u < xc:
                res = not res
    return res


@njit(cache=True, nogil=True, inline="always")
def _chord_d2(q0, q1, q2, a3, b3, s):
    e0 = b3[s, 0] - a3[s, 0]
    e1 = b3[s, 1] - a3[s, 1]
    e2 = b3[s, 2] - a3[s, 2]
    w0 = q0 - a3[s, 0]
    w1 = q1 - a3[s, 1]
    w2 = q2 - a3[s, 2]
    ee = e0 * e0 + e1 * e1 + e2 * e2
    t = 0.0
    if ee > 0.0:
        t = min(max((w0 * e0 + w1 * e1 + w2 * e2) / ee, 0.0), 1.0)
    d0 = w0 - t * e0
    d1 = w1 - t * e1
    d2 = w2 - t * e2
    return d0 * d0 + d1 * d1 + d2 * d2, t


@njit(cache=True, nogil=True)
def newton_segment(tab, domains, f, s, t, x0, y0, x1, y1, q0, q1, q2, out, work):
    """Closest point to q on the image S(uv(t)) of trimming segment s, t in [0, 1].

    uv(t) = (x0, y0) + t ((x1, y1) - (x0, y0)), clamped to the surface domain.  Newton in t
    with a line search.  Returns (t, u, v, squared distance); ``out`` holds the derivatives.
    """
    u0 = domains[f, 0, 0]
    u1 = domains[f, 0, 1]
    v0 = domains[f, 1, 0]
    v1 = domains[f, 1, 1]
    au = x0[s]
    av = y0[s]
    du = x1[s] - au
    dv = y1[s] - av
    u = min(max(au + t * du, u0), u1)
    v = min(max(av + t * dv, v0), v1)
    d0 = _dist2_at(tab, f, u, v, q0, q1, q2, out, work)
    for it in range(_MAX_NEWTON):
        r0 = out[0, 0, 0] - q0
        r1 = out[0, 0, 1] - q1
        r2 = out[0, 0, 2] - q2
        D0 = out[1, 0, 0] * du + out[0, 1, 0] * dv
        D1 = out[1, 0, 1] * du + out[0, 1, 1] * dv
        D2 = out[1, 0, 2] * du + out[0, 1, 2] * dv
        g = r0 * D0 + r1 * D1 + r2 * D2
        DD = D0 * D0 + D1 * D1 + D2 * D2
        H = DD
        for c in range(3):
            r = out[0, 0, c] - (q0 if c == 0 else (q1 if c == 1 else q2))
            H += r * (out[2, 0, c] * du * du + 2.0 * out[1, 1, c] * du * dv
                      + out[0, 2, c] * dv * dv)
        if not H > 0.0:
            H = DD
        if not H > 0.0:
            break
        dt = -g / H
        if (t <= 0.0 and dt < 0.0) or (t >= 1.0 and dt > 0.0):
            break
        scale = 1.0 + abs(q0) + abs(q1) + abs(q2)
        step = abs(dt) * np.sqrt(DD)
        if step <= 1e-7 * scale:
            t = min(max(t + dt, 0.0), 1.0)
            u = min(max(au + t * du, u0), u1)
            v = min(max(av + t * dv, v0), v1)
            d0 = _dist2_at(tab, f, u, v, q0, q1, q2, out, work)
            if step <= 1e-9 * scale:
                break
            continue
        lam = 1.0
        accepted = False
        tn = t
        un = u
        vn = v
        dn = d0
        for _ in range(_MAX_HALVING):
            tn = min(max(t + lam * dt, 0.0), 1.0)
            un = min(max(au + tn * du, u0), u1)
            vn = min(max(av + tn * dv, v0), v1)
            dn = _dist2_at(tab, f, un, vn, q0, q1, q2, out, work)
            if dn <= d0:
                accepted = True
                break
            lam *= 0.5
        if not accepted:
            _eval(tab, f, u, v, out, work)
            break
        t = tn
        u = un
        v = vn
        d0 = dn
    return t, u, v, d0


@njit(cache=True, nogil=True)
def _normal(out, rev, b, rh, rs):
    """Outward unit normal from the derivatives in ``out``; where Su x Sv vanishes (a pole),
    the normal of model point b."""
    n0 = out[1, 0, 1] * out[0, 1, 2] - out[1, 0, 2] * out[0, 1, 1]
    n1 = out[1, 0, 2] * out[0, 1, 0] - out[1, 0, 0] * out[0, 1, 2]
    n2 = out[1, 0, 0] * out[0, 1, 1] - out[1, 0, 1] * out[0, 1, 0]
    ln = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    su = np.sqrt(out[1, 0, 0] ** 2 + out[1, 0, 1] ** 2 + out[1, 0, 2] ** 2)
    sv = np.sqrt(out[0, 1, 0] ** 2 + out[0, 1, 1] ** 2 + out[0, 1, 2] ** 2)
    if not ln > 1e-10 * su * sv or ln == 0.0:
        fr = frame(b, rs, rh)
        return fr[0], fr[1], fr[2]
    if rev:
        ln = -ln
    return n0 / ln, n1 / ln, n2 / ln


@njit(cache=True, nogil=True)
def two_closest_chords(q0, q1, q2, f, a3, b3, ch_off, ch_seg, ch_c, ch_r, lb):
    """The two trimming segments of face f whose 3D chords are closest to q.

    Returns (s1, t1, e1, s2, t2, e2): segment, chord parameter and squared chord distance.

    Segments come in chunks of consecutive segments with bounding spheres (centre ``ch_c``,
    radius ``ch_r``; chunk c holds segments ``ch_seg[c]:ch_seg[c+1]``, face f the chunks
    ``ch_off[f]:ch_off[f+1]``).  The chunk with the smallest lower bound is scanned first,
    then only chunks whose bound can still beat the second best.  ``lb``: scratch.
    """
    c0 = ch_off[f]
    nch = ch_off[f + 1] - c0
    first = 0
    for c in range(nch):
        e0 = q0 - ch_c[c0 + c, 0]
        e1 = q1 - ch_c[c0 + c, 1]
        e2 = q2 - ch_c[c0 + c, 2]
        g = max(0.0, np.sqrt(e0 * e0 + e1 * e1 + e2 * e2) - ch_r[c0 + c])
        lb[c] = g * g
        if lb[c] < lb[first]:
            first = c
    s1 = -1
    s2 = -1
    d1 = np.inf
    d2 = np.inf
    t1 = 0.0
    t2 = 0.0
    for r in range(nch + 1):
        c = first if r == 0 else r - 1
        if (r > 0 and c == first) or lb[c] >= d2:
            continue
        for s in range(ch_seg[c0 + c], ch_seg[c0 + c + 1]):
            e, t = _chord_d2(q0, q1, q2, a3, b3, s)
            if e < d1:
                d2 = d1
                s2 = s1
                t2 = t1
                d1 = e
                s1 = s
                t1 = t
            elif e < d2:
                d2 = e
                s2 = s
                t2 = t
    return s1, t1, d1, s2, t2, d2


@njit(cache=True, nogil=True)
def refine_cad(Q, idx, rf, nbr, aux, pt_face, pt_uv, rh, rs, spacing, tab, domains, closed,
               rev,
               seg_off, x0, y0, x1, y1, a3, b3, sag, free, ch_off, ch_seg, ch_c, ch_r,
               bin_off, bin_lo, bin_hi, bin_inv, bin_start, bin_xy, work_size,
               out_foot, out_normal, out_dist, out_face, out_uv, out_onb):
    """Exact closest point on the trimmed faces around each query's nearest model point.

    Candidate faces: the face of model point ``idx[i]`` (the nearest model point), and those
    of its graph neighbours and of ``aux[idx[i]]`` (its nearest model point on another face
    within a few spacings, -1 if none).  Each face starts from the (u, v) of
    its candidate point closest to the query.  On each face: point inversion
    (:func:`newton_face`); if the foot lies outside the trims (or on the edge of the surface
    domain, where the unconstrained minimum lies outside), the closest point on the face's
    boundary instead (the two closest chords of the trimming polyline refined with
    :func:`newton_segment`), flagged ``on_boundary`` when that segment is a free edge.

    The nearest point's face is always solved.  The other faces are solved when that foot
    ended on the boundary (the closest point may be across a shared edge), or when their
    candidate point is at most ``spacing`` farther from the query than the nearest model
    point (concave corners, and the rare query whose nearest model point the tree missed).
    The closest candidate wins; its distance is signed by the face's outward normal.
    """
    n = pt_face.shape[0]
    K = nbr.shape[1]
    out = np.empty((3, 3, 3))
    work = np.empty((work_size, 4))
    cf = np.empty(K + 2, dtype=np.int64)
    cj = np.empty(K + 2, dtype=np.int64)
    cd = np.empty(K + 2)
    max_ch = 1
    for f in range(ch_off.shape[0] - 1):
        max_ch = max(max_ch, ch_off[f + 1] - ch_off[f])
    lb = np.empty(max_ch)
    for i in range(Q.shape[0]):
        q0 = Q[i, 0]
        q1 = Q[i, 1]
        q2 = Q[i, 2]
        b = idx[i]
        nc = 1
        cf[0] = pt_face[b]
        cj[0] = b
        cd[0] = (rf[b, 0] - q0) ** 2 + (rf[b, 1] - q1) ** 2 + (rf[b, 2] - q2) ** 2
        # faces of the neighbours and of the other-face point of b
        for k in range(K + 1):
            j = nbr[b, k] if k < K else aux[b]
            if j < 0 or j >= n:
                continue
            fj = pt_face[j]
            if fj == cf[0]:
                continue
            dj = (rf[j, 0] - q0) ** 2 + (rf[j, 1] - q1) ** 2 + (rf[j, 2] - q2) ** 2
            new = True
            for c in range(1, nc):
                if cf[c] == fj:
                    new = False
                    if dj < cd[c]:
                        cj[c] = j
                        cd[c] = dj
                    break
            if new:
                cf[nc] = fj
                cj[nc] = j
                cd[nc] = dj
                nc += 1
        near = (np.sqrt(cd[0]) + spacing) ** 2
        best = np.inf
        primary_on_edge = False
        for c in range(nc):
            f = cf[c]
            if c > 0 and not primary_on_edge and cd[c] > near:
                continue
            u, v, d2, edge = newton_face(tab, domains, closed, f, np.float64(pt_uv[cj[c], 0]),
                                         np.float64(pt_uv[cj[c], 1]), q0, q1, q2, out, work)
            onb = False
            if edge or not inside(f, u, v, bin_off, bin_lo, bin_hi, bin_inv, bin_start,
                                  bin_xy):
                # the two closest chords of the face's trimming polylines
                s1, t1, e1, s2, t2, e2 = two_closest_chords(q0, q1, q2, f, a3, b3, ch_off,
                                                            ch_seg, ch_c, ch_r, lb)
                # a segment's curve lies within sag[s] of its chord: refine only chords
                # that can still beat the best foot found so far
                d2 = np.inf
                if s1 >= 0 and np.sqrt(e1) - sag[s1] < np.sqrt(best):
                    _, u, v, d2 = newton_segment(tab, domains, f, s1, t1, x0, y0, x1, y1,
                                                 q0, q1, q2, out, work)
                    onb = free[s1]
                if s2 >= 0 and np.sqrt(e2) - sag[s2] < np.sqrt(min(best, d2)):
                    _, ub, vb, db = newton_segment(tab, domains, f, s2, t2, x0, y0, x1, y1,
                                                   q0, q1, q2, out, work)
                    if db < d2:
                        u = ub
                        v = vb
                        d2 = db
                        onb = free[s2]
                if not d2 < best:
                    continue
                _eval(tab, f, u, v, out, work)
                if c == 0:
                    primary_on_edge = True
            if d2 < best:
                best = d2
                p0 = out[0, 0, 0]
                p1 = out[0, 0, 1]
                p2 = out[0, 0, 2]
                n0, n1, n2 = _normal(out, rev[f], b, rh, rs)
                out_foot[i, 0] = p0
                out_foot[i, 1] = p1
                out_foot[i, 2] = p2
                out_normal[i, 0] = n0
                out_normal[i, 1] = n1
                out_normal[i, 2] = n2
                d = np.sqrt(d2)
                if (q0 - p0) * n0 + (q1 - p1) * n1 + (q2 - p2) * n2 < 0.0:
                    d = -d
                out_dist[i] = d
                out_face[i] = f
                out_uv[i, 0] = u
                out_uv[i, 1] = v
                out_onb[i] = onb


# ---------------------------------------------------------------------------------- meshes
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
def refine_mesh(Q, cand_ptr, cand, verts, tri, tri_n, dist, feat,
                out_foot, out_normal, out_dist, out_face, out_uv):
    """Exact closest point of each query over its candidate triangles.

    ``cand[cand_ptr[i]:cand_ptr[i+1]]`` must hold every triangle that can be the closest one
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
        lo = cand_ptr[i]
        nc = cand_ptr[i + 1] - lo
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
