"""numba point inversion on one trimmed NURBS face and on its boundary (private; trusts its input).

:func:`newton_face` projects a point onto a face's surface (kept in its domain, wrapping across
closed directions); :func:`two_closest_chords` and :func:`newton_segment` find the closest point
of the face's trimming polylines' images; :func:`_normal` gives the outward normal at a foot.

References
----------
Piegl & Tiller, The NURBS Book, 2nd ed., §6.1 (point inversion and projection by Newton).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import frame
from ._surface_kernels import _eval, _eval_call

_MAX_NEWTON = 50
_MAX_HALVING = 40
# states of newton_face between two evaluations
_STEP = 0      # at a new iterate: take it, then compute the next step
_TRIAL = 1     # at a line-search trial point: take it if the distance did not grow
_LAST = 2      # at the last (converged) iterate: take it and stop
_RESTORE = 3   # back at the current iterate after a failed line search: stop
_ZERO18 = (0.0,) * 18


# small: LLVM inlines it; numba's inline="always" rebuilt and re-typed it at every call site
@njit(cache=True, nogil=True)
def _dist2(D, q0, q1, q2):
    a = D[0] - q0
    b = D[1] - q1
    c = D[2] - q2
    return a * a + b * b + c * c


# small: LLVM inlines it; numba's inline="always" rebuilt and re-typed it at every call site
@njit(cache=True, nogil=True)
def _wrap(x, lo, hi, closed):
    if closed:  # into [lo, hi): the seam belongs to the start of the domain
        if x < lo or x >= hi:
            x = lo + (x - lo) % (hi - lo)
            if x >= hi:
                x = lo
        return x
    return min(max(x, lo), hi)


@njit(cache=True, nogil=True, inline="always")
def newton_face(tab, domains, closed, f, u, v, q0, q1, q2):
    """Point inversion on face f's surface from (u, v): (u, v, squared distance, at_bound, D).

    Newton on the gradient of |S(u, v) - q|^2 / 2 with the exact Hessian (Gauss-Newton when
    it is not positive definite), a backtracking line search, and the box constraint of the
    surface domain handled by an active set (a parameter on a bound that would leave the
    domain is frozen and the other one is solved in 1D).  Closed directions wrap around.
    ``D``: the derivatives at the returned (u, v) -- S, S_u and S_v always, the second
    derivatives unless the last step was a converged Newton step; ``at_bound`` says that
    (u, v) lies on an edge of the (not closed) domain, where the trims may run.

    The surface is evaluated at one place (a loop over evaluations whose state says what the
    point is: a new iterate, a line-search trial, the last iterate, or the current iterate
    again after a failed line search), so its inlined code exists once; the last evaluation
    skips the second derivatives.
    """
    u0 = domains[f, 0, 0]
    u1 = domains[f, 0, 1]
    v0 = domains[f, 1, 0]
    v1 = domains[f, 1, 1]
    cu = closed[f, 0]
    cv = closed[f, 1]
    scale = 1.0 + abs(q0) + abs(q1) + abs(q2)
    ue = u
    ve = v
    order = 2
    state = _STEP
    D = _ZERO18
    d0 = 0.0
    prev = 0.0
    du = 0.0
    dv = 0.0
    step3 = 0.0
    t = 1.0
    halvings = 0
    it = 0
    si = -1
    sj = -1
    while True:
        D, si, sj = _eval(tab, f, ue, ve, order, si, sj)
        d = _dist2(D, q0, q1, q2)
        if state == _TRIAL:
            if not d <= d0:
                halvings += 1
                if halvings < _MAX_HALVING:
                    t *= 0.5
                    ue = _wrap(u + t * du, u0, u1, cu)
                    ve = _wrap(v + t * dv, v0, v1, cv)
                else:  # no descent: back to the current iterate, and stop
                    ue = u
                    ve = v
                    order = 1
                    state = _RESTORE
                continue
            prev = t * step3
        elif state == _RESTORE:
            break
        u = ue
        v = ve
        d0 = d
        if state == _LAST or it == _MAX_NEWTON:
            break
        it += 1
        r0 = D[0] - q0
        r1 = D[1] - q1
        r2 = D[2] - q2
        su0 = D[3]
        su1 = D[4]
        su2 = D[5]
        sv0 = D[6]
        sv1 = D[7]
        sv2 = D[8]
        gu = r0 * su0 + r1 * su1 + r2 * su2
        gv = r0 * sv0 + r1 * sv1 + r2 * sv2
        guu = su0 * su0 + su1 * su1 + su2 * su2
        gvv = sv0 * sv0 + sv1 * sv1 + sv2 * sv2
        guv = su0 * sv0 + su1 * sv1 + su2 * sv2
        a = guu + r0 * D[9] + r1 * D[10] + r2 * D[11]
        b = guv + r0 * D[12] + r1 * D[13] + r2 * D[14]
        c = gvv + r0 * D[15] + r1 * D[16] + r2 * D[17]
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
        if step3 <= 1e-5 * scale:
            # quadratic convergence region: take the full step (rounding makes the
            # distance useless as a merit function this close to the minimum); the next
            # step ~ C step^2 with C estimated from the last two steps
            ue = _wrap(u + du, u0, u1, cu)
            ve = _wrap(v + dv, v0, v1, cv)
            if step3 <= 1e-9 * scale or (prev > 0.0 and step3 * step3 * step3
                                         <= 1e-13 * scale * prev * prev):
                order = 1
                state = _LAST
            else:
                order = 2
                state = _STEP
                prev = step3
        else:
            t = 1.0
            halvings = 0
            ue = _wrap(u + t * du, u0, u1, cu)
            ve = _wrap(v + t * dv, v0, v1, cv)
            order = 2
            state = _TRIAL
    at_bound = (not cu and (u <= u0 or u >= u1)) or (not cv and (v <= v0 or v >= v1))
    return u, v, d0, at_bound, D


# small: LLVM inlines it; numba's inline="always" rebuilt and re-typed it at every call site
@njit(cache=True, nogil=True)
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
def newton_segment(tab, domains, f, s, t, x0, y0, x1, y1, q0, q1, q2):
    """Closest point to q on the image S(uv(t)) of trimming segment s, t in [0, 1].

    uv(t) = (x0, y0) + t ((x1, y1) - (x0, y0)), clamped to the surface domain.  Newton in t
    with a line search.  Returns (t, u, v, squared distance).
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
    D = _eval_call(tab, f, u, v, np.int64(2))  # not a literal 2: one compiled _eval_call
    d0 = _dist2(D, q0, q1, q2)
    for it in range(_MAX_NEWTON):
        r0 = D[0] - q0
        r1 = D[1] - q1
        r2 = D[2] - q2
        D0 = D[3] * du + D[6] * dv
        D1 = D[4] * du + D[7] * dv
        D2 = D[5] * du + D[8] * dv
        g = r0 * D0 + r1 * D1 + r2 * D2
        DD = D0 * D0 + D1 * D1 + D2 * D2
        H = DD
        H += r0 * (D[9] * du * du + 2.0 * D[12] * du * dv + D[15] * dv * dv)
        H += r1 * (D[10] * du * du + 2.0 * D[13] * du * dv + D[16] * dv * dv)
        H += r2 * (D[11] * du * du + 2.0 * D[14] * du * dv + D[17] * dv * dv)
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
            last = step <= 1e-9 * scale
            D = _eval_call(tab, f, u, v, 1 if last else 2)
            d0 = _dist2(D, q0, q1, q2)
            if last:
                break
            continue
        lam = 1.0
        accepted = False
        tn = t
        un = u
        vn = v
        dn = d0
        Dn = D
        for _ in range(_MAX_HALVING):
            tn = min(max(t + lam * dt, 0.0), 1.0)
            un = min(max(au + tn * du, u0), u1)
            vn = min(max(av + tn * dv, v0), v1)
            Dn = _eval_call(tab, f, un, vn, np.int64(2))
            dn = _dist2(Dn, q0, q1, q2)
            if dn <= d0:
                accepted = True
                break
            lam *= 0.5
        if not accepted:
            break
        t = tn
        u = un
        v = vn
        d0 = dn
        D = Dn
    return t, u, v, d0


@njit(cache=True, nogil=True, inline="always")
def _normal(D, rev, b, rh, rs):
    """Outward unit normal from the derivatives D; where Su x Sv vanishes (a pole), the
    normal of model point b."""
    n0 = D[4] * D[8] - D[5] * D[7]
    n1 = D[5] * D[6] - D[3] * D[8]
    n2 = D[3] * D[7] - D[4] * D[6]
    ln = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    su = np.sqrt(D[3] ** 2 + D[4] ** 2 + D[5] ** 2)
    sv = np.sqrt(D[6] ** 2 + D[7] ** 2 + D[8] ** 2)
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
