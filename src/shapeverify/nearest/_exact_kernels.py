"""numba kernels of the exact closest point: NURBS point inversion with trims, triangles (private).

CAD faces
---------
Surfaces come as tables of polynomial patches (``tab``, :func:`shapeverify.nearest.exact.
power_tables`), evaluated by :func:`_eval`.  Trimming loops are flat segment arrays (see
:mod:`shapeverify.nearest.exact`): per face ``f`` the segments ``seg_off[f]:seg_off[f+1]``
with end points ``(x0, y0) -> (x1, y1)`` in (u, v), their 3D end points ``a3``, ``b3`` and a
``free`` flag, and the packed trims (:class:`shapeverify.cad.trim.PackedTrims`) for the
even-odd test.

Meshes
------
Triangles ``tri`` (T, 3) into ``verts`` (V, 3), unit normals ``tri_n``, and the triangles
around each vertex (CSR ``vt_ptr``, ``vt_idx``).

All kernels trust their input and allocate scratch space once per call, not per point.

Speed notes (:func:`refine_cad`, a few hundred ns per point): the per-point path (Newton on a
face, the trim test, the normal) is inlined into one function, since a call that passes a
dozen arrays costs about as much as a surface evaluation, and works on views of the arrays
without reference counting (:func:`_borrow`; every array passed into a callee otherwise costs
two atomic operations per call).  The surface derivatives travel as tuples of floats, not in
a scratch array.  The model point records of the next queries are prefetched.

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
from numba.core import cgutils
from numba.extending import intrinsic

from shapeverify.cad._trim_kernels import inside
from shapeverify.cad.trim import PackedTrims

from . import _patch_kernels
from ._kernels import frame, prefetch

_MAX_NEWTON = 50
_MAX_HALVING = 40
_PREFETCH = 4  # queries ahead whose model point records are prefetched
# states of newton_face between two evaluations
_STEP = 0      # at a new iterate: take it, then compute the next step
_TRIAL = 1     # at a line-search trial point: take it if the distance did not grow
_LAST = 2      # at the last (converged) iterate: take it and stop
_RESTORE = 3   # back at the current iterate after a failed line search: stop
_ZERO18 = (0.0,) * 18


@intrinsic
def _borrow(typingctx, arr):
    """A view of ``arr`` without its memory-info pointer, which numba's reference counting
    skips (NRT_incref / NRT_decref return at once on a null pointer).

    Only for arrays that outlive every use of the view: here the arguments of a kernel,
    which the caller holds for the whole call.  The view must not be returned or stored.
    """
    def codegen(context, builder, signature, args):
        src = context.make_array(signature.args[0])(context, builder, args[0])
        dst = context.make_array(signature.return_type)(context, builder)
        for name in ("nitems", "itemsize", "data", "shape", "strides"):
            setattr(dst, name, getattr(src, name))
        dst.meminfo = cgutils.get_null_value(dst.meminfo.type)
        dst.parent = cgutils.get_null_value(dst.parent.type)
        return dst._getvalue()

    return arr(arr), codegen


# ------------------------------------------------------------------------------ CAD faces
# Surfaces as tables of polynomial patches (``tab``, built by exact.py): per face f
#   deg[f] = (p, q); spans along u: bu[bu_off[f]:bu_off[f+1]] (breakpoints, n_u + 1 of them),
#   mu[mu_off[f] + i] = centre of span i (same for v with bv/mv); coefficient rows
#   coef[c_off[f] + ((i * n_v + j) * (p + 1) + a) * (q + 1) + b] = (wx, wy, wz, w) of
#   (u - mu_i)^a (v - mv_j)^b on span (i, j).  Homogeneous, divided back with the quotient rule.
# Derivatives travel as 18-tuples D: S = D[0:3], S_u = D[3:6], S_v = D[6:9], S_uu = D[9:12],
# S_uv = D[12:15], S_vv = D[15:18] (x, y, z each).
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


@njit(cache=True, nogil=True, inline="always")
def _span_near(x, br, lo, hi, g):
    """:func:`_span`, trying span g first (the span of a nearby point, -1 for none); the same
    answer, since the spans are non-empty."""
    if g >= 0 and br[lo + g] <= x and x < br[lo + g + 1]:
        return g
    return _span(x, br, lo, hi)


@njit(cache=True, nogil=True, inline="always")
def _eval(tab, f, u, v, order, gi, gj):
    """Derivatives of face f's surface at (u, v): (D, i, j).

    D: the 18-tuple described above; ``order`` 2: up to the second derivatives, ``order`` 1:
    S, S_u and S_v only (D[9:] = 0).  (i, j): the knot span of (u, v); (gi, gj): a guess for
    it (-1: none), e.g. the span of the previous Newton iterate.

    Horner along v within each coefficient row of the span, fed straight into Horner along u
    (no scratch array); the four homogeneous components run as independent chains
    (instruction-level parallelism), and each derivative chain starts at its first non-zero
    term instead of multiplying zeros.  The same operations in the same order as a two-pass
    evaluation through a scratch array, so the same values to the last bit.
    """
    deg, bu, bu_off, mu, mu_off, bv, bv_off, mv, mv_off, coef, c_off = tab
    p = deg[f, 0]
    q = deg[f, 1]
    nsv = bv_off[f + 1] - bv_off[f] - 1
    i = _span_near(u, bu, bu_off[f], bu_off[f + 1], gi)
    j = _span_near(v, bv, bv_off[f], bv_off[f + 1], gj)
    s = u - mu[mu_off[f] + i]
    t = v - mv[mv_off[f] + j]
    base = c_off[f] + (i * nsv + j) * (p + 1) * (q + 1)
    # x<k><l> (and y, z, w): d^(k+l)/du^k dv^l of the homogeneous surface (wx, wy, wz, w),
    # but x20 (like a row's rx2) is half the second derivative (a Taylor coefficient)
    x00 = y00 = z00 = w00 = 0.0
    x10 = y10 = z10 = w10 = 0.0
    x20 = y20 = z20 = w20 = 0.0
    x01 = y01 = z01 = w01 = 0.0
    x11 = y11 = z11 = w11 = 0.0
    x02 = y02 = z02 = w02 = 0.0
    for a in range(p, -1, -1):
        # row a along v: value (r0), first (r1) and half the second (r2) t-derivative
        row = base + a * (q + 1)
        rx0 = coef[row + q, 0]
        ry0 = coef[row + q, 1]
        rz0 = coef[row + q, 2]
        rw0 = coef[row + q, 3]
        rx1 = ry1 = rz1 = rw1 = 0.0
        rx2 = ry2 = rz2 = rw2 = 0.0
        for b in range(q - 1, -1, -1):
            if order == 2:
                if b < q - 2:
                    rx2 = rx2 * t + rx1
                    ry2 = ry2 * t + ry1
                    rz2 = rz2 * t + rz1
                    rw2 = rw2 * t + rw1
                elif b == q - 2:
                    rx2 = rx1
                    ry2 = ry1
                    rz2 = rz1
                    rw2 = rw1
            if b < q - 1:
                rx1 = rx1 * t + rx0
                ry1 = ry1 * t + ry0
                rz1 = rz1 * t + rz0
                rw1 = rw1 * t + rw0
            else:
                rx1 = rx0
                ry1 = ry0
                rz1 = rz0
                rw1 = rw0
            rx0 = rx0 * t + coef[row + b, 0]
            ry0 = ry0 * t + coef[row + b, 1]
            rz0 = rz0 * t + coef[row + b, 2]
            rw0 = rw0 * t + coef[row + b, 3]
        # along u
        if order == 2:
            if a < p - 2:
                x20 = x20 * s + x10
                y20 = y20 * s + y10
                z20 = z20 * s + z10
                w20 = w20 * s + w10
            elif a == p - 2:
                x20 = x10
                y20 = y10
                z20 = z10
                w20 = w10
            if a < p - 1:
                x11 = x11 * s + x01
                y11 = y11 * s + y01
                z11 = z11 * s + z01
                w11 = w11 * s + w01
            elif a == p - 1:
                x11 = x01
                y11 = y01
                z11 = z01
                w11 = w01
            if a < p:
                x02 = x02 * s + 2.0 * rx2
                y02 = y02 * s + 2.0 * ry2
                z02 = z02 * s + 2.0 * rz2
                w02 = w02 * s + 2.0 * rw2
            else:
                x02 = 2.0 * rx2
                y02 = 2.0 * ry2
                z02 = 2.0 * rz2
                w02 = 2.0 * rw2
        if a < p - 1:
            x10 = x10 * s + x00
            y10 = y10 * s + y00
            z10 = z10 * s + z00
            w10 = w10 * s + w00
        elif a == p - 1:
            x10 = x00
            y10 = y00
            z10 = z00
            w10 = w00
        if a < p:
            x00 = x00 * s + rx0
            y00 = y00 * s + ry0
            z00 = z00 * s + rz0
            w00 = w00 * s + rw0
            x01 = x01 * s + rx1
            y01 = y01 * s + ry1
            z01 = z01 * s + rz1
            w01 = w01 * s + rw1
        else:
            x00 = rx0
            y00 = ry0
            z00 = rz0
            w00 = rw0
            x01 = rx1
            y01 = ry1
            z01 = rz1
            w01 = rw1
    # back from homogeneous coordinates (quotient rule)
    iw = 1.0 / w00
    Sx = x00 * iw
    Sy = y00 * iw
    Sz = z00 * iw
    Sux = (x10 - w10 * Sx) * iw
    Suy = (y10 - w10 * Sy) * iw
    Suz = (z10 - w10 * Sz) * iw
    Svx = (x01 - w01 * Sx) * iw
    Svy = (y01 - w01 * Sy) * iw
    Svz = (z01 - w01 * Sz) * iw
    if order == 1:
        return (Sx, Sy, Sz, Sux, Suy, Suz, Svx, Svy, Svz,
                0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0), i, j
    wu2 = 2.0 * w10
    wv2 = 2.0 * w01
    wuu = 2.0 * w20
    return (Sx, Sy, Sz, Sux, Suy, Suz, Svx, Svy, Svz,
            (2.0 * x20 - wu2 * Sux - wuu * Sx) * iw,
            (2.0 * y20 - wu2 * Suy - wuu * Sy) * iw,
            (2.0 * z20 - wu2 * Suz - wuu * Sz) * iw,
            (x11 - w10 * Svx - w01 * Sux - w11 * Sx) * iw,
            (y11 - w10 * Svy - w01 * Suy - w11 * Sy) * iw,
            (z11 - w10 * Svz - w01 * Suz - w11 * Sz) * iw,
            (x02 - wv2 * Svx - w02 * Sx) * iw,
            (y02 - wv2 * Svy - w02 * Sy) * iw,
            (z02 - wv2 * Svz - w02 * Sz) * iw), i, j


@njit(cache=True, nogil=True)
def _eval_call(tab, f, u, v, order):
    """:func:`_eval` as a call, for the rare paths (one inlined copy is enough)."""
    return _eval(tab, f, u, v, order, -1, -1)[0]


@njit(cache=True, nogil=True)
def eval_many(tab, faces, u, v, out):
    """out[i, k, l] = d^(k+l)S/du^k dv^l (k + l <= 2) of face faces[i] at (u[i], v[i]).

    ``out`` (N, 3, 3, 3); entries with k + l > 2 are left as they are.
    """
    for i in range(u.shape[0]):
        D = _eval(tab, faces[i], u[i], v[i], 2, -1, -1)[0]
        for c in range(3):
            out[i, 0, 0, c] = D[c]
            out[i, 1, 0, c] = D[3 + c]
            out[i, 0, 1, c] = D[6 + c]
            out[i, 2, 0, c] = D[9 + c]
            out[i, 1, 1, c] = D[12 + c]
            out[i, 0, 2, c] = D[15 + c]


@njit(cache=True, nogil=True, inline="always")
def _dist2(D, q0, q1, q2):
    a = D[0] - q0
    b = D[1] - q1
    c = D[2] - q2
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
    D = _eval_call(tab, f, u, v, 2)
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
            Dn = _eval_call(tab, f, un, vn, 2)
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


@njit(cache=True, nogil=True)
def refine_cad(Q, idx, rf, nbr, aux, pt_face, pt_uv, rh, rs, spacing, tab, domains, closed,
               rev,
               seg_off, x0, y0, x1, y1, a3, b3, sag, free, ch_off, ch_seg, ch_c, ch_r,
               trims,
               p_face, p_inner, p_centre, p_axes, p_half, p_uv, n_lo, n_hi, n_child, n_first, n_count,
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
    Then every patch of every face (:mod:`shapeverify.nearest.patches`) whose oriented
    bounding box is closer than the best foot so far is tried too (unless a foot already
    found on that face lies in the patch's parameter box): Newton from the patch's centre,
    kept in its parameter box, then the trim test (none for patches wholly inside the trims)
    and the face's boundary if outside.  The seeds only make the search fast, the bounds
    make it complete.
    The closest candidate wins; its distance is signed by the face's outward normal.
    """
    n = pt_face.shape[0]
    K = nbr.shape[1]
    multi = domains.shape[0] > 1
    # the arguments outlive the call: views without reference counting for the callees
    tab = (_borrow(tab[0]), _borrow(tab[1]), _borrow(tab[2]), _borrow(tab[3]),
           _borrow(tab[4]), _borrow(tab[5]), _borrow(tab[6]), _borrow(tab[7]),
           _borrow(tab[8]), _borrow(tab[9]), _borrow(tab[10]))
    domains = _borrow(domains)
    closed = _borrow(closed)
    rh = _borrow(rh)
    rs = _borrow(rs)
    x0 = _borrow(x0)
    y0 = _borrow(y0)
    x1 = _borrow(x1)
    y1 = _borrow(y1)
    a3 = _borrow(a3)
    b3 = _borrow(b3)
    ch_off = _borrow(ch_off)
    ch_seg = _borrow(ch_seg)
    ch_c = _borrow(ch_c)
    ch_r = _borrow(ch_r)
    trims = PackedTrims(_borrow(trims.lo), _borrow(trims.hi), _borrow(trims.inv),
                        _borrow(trims.bin_off), _borrow(trims.bin_start), _borrow(trims.bin_xy))
    # flat element strides of the per-point rows, for prefetching
    rf_row = rf.strides[0] // rf.itemsize
    uv_row = pt_uv.strides[0] // pt_uv.itemsize
    cf = np.empty(K + 2, dtype=np.int64)
    cj = np.empty(K + 2, dtype=np.int64)
    cd = np.empty(K + 2)
    n_patch = p_face.shape[0]
    walk = n_patch > 0
    pk = np.empty(K + 2 + n_patch, dtype=np.int64)
    pd = np.empty(K + 2 + n_patch)
    sf = np.empty(K + 2 + n_patch, dtype=np.int64)
    su = np.empty(K + 2 + n_patch)
    sv = np.empty(K + 2 + n_patch)
    stack = np.empty(_patch_kernels.STACK, dtype=np.int64)
    searched = np.full(domains.shape[0], -1, dtype=np.int64)
    dom_s = domains.copy()  # row f is a patch's box while that patch is solved
    cl_s = closed.copy()
    p_centre = _borrow(p_centre)
    p_axes = _borrow(p_axes)
    p_half = _borrow(p_half)
    p_uv = _borrow(p_uv)
    n_lo = _borrow(n_lo)
    n_hi = _borrow(n_hi)
    n_child = _borrow(n_child)
    n_first = _borrow(n_first)
    n_count = _borrow(n_count)
    max_ch = 1
    for f in range(ch_off.shape[0] - 1):
        max_ch = max(max_ch, ch_off[f + 1] - ch_off[f])
    lb = np.empty(max_ch)
    m = Q.shape[0]
    for i in range(m):
        # the model point data of the queries ahead (their records are read at random)
        if i + _PREFETCH < m:
            bb = idx[i + _PREFETCH]
            prefetch(rf, bb * rf_row)
            prefetch(pt_face, bb)
            prefetch(pt_uv, bb * uv_row)
            prefetch(aux, bb)
        q0 = Q[i, 0]
        q1 = Q[i, 1]
        q2 = Q[i, 2]
        b = idx[i]
        nc = 1
        cf[0] = pt_face[b]
        cj[0] = b
        cd[0] = (rf[b, 0] - q0) ** 2 + (rf[b, 1] - q1) ** 2 + (rf[b, 2] - q2) ** 2
        # faces of the neighbours and of the other-face point of b (none on a one-face model)
        for k in range(K + 1 if multi else 0):
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
        ns = 0
        nt = nc
        walked = not walk
        c = -1
        while True:
            c += 1
            if c == nt:
                if walked:
                    break
                # the patches that can still hold a closer foot
                walked = True
                nt = _patch_kernels.candidates(q0, q1, q2, best, p_centre, p_axes, p_half,
                                               n_lo, n_hi, n_child, n_first, n_count, stack,
                                               pk, pd, nc)
                c -= 1
                continue
            if c < nc:
                f = cf[c]
                if c > 0 and not primary_on_edge and cd[c] > near:
                    continue
                us = np.float64(pt_uv[cj[c], 0])
                vs = np.float64(pt_uv[cj[c], 1])
            else:
                k = pk[c]
                if not pd[c] < best:
                    continue
                f = p_face[k]
                seen = False
                for r in range(ns):
                    if (sf[r] == f and p_uv[k, 0] <= su[r] <= p_uv[k, 1]
                            and p_uv[k, 2] <= sv[r] <= p_uv[k, 3]):
                        seen = True
                        break
                if seen:
                    continue
                us = 0.5 * (p_uv[k, 0] + p_uv[k, 1])
                vs = 0.5 * (p_uv[k, 2] + p_uv[k, 3])
            on_patch = c >= nc
            if on_patch:  # solve on the patch's parameter box only
                dom_s[f, 0, 0] = p_uv[k, 0]
                dom_s[f, 0, 1] = p_uv[k, 1]
                dom_s[f, 1, 0] = p_uv[k, 2]
                dom_s[f, 1, 1] = p_uv[k, 3]
                cl_s[f, 0] = False
                cl_s[f, 1] = False
            u, v, d2, edge, D = newton_face(tab, dom_s, cl_s, f, us, vs, q0, q1, q2)
            onb = False
            if not edge:  # a local minimum (not stopped by a box): its patch needs no retry
                sf[ns] = f
                su[ns] = u
                sv[ns] = v
                ns += 1
            if on_patch:
                for r in range(2):
                    dom_s[f, r, 0] = domains[f, r, 0]
                    dom_s[f, r, 1] = domains[f, r, 1]
                    cl_s[f, r] = closed[f, r]
                # a patch wholly inside the trims needs no trim test; its foot, even on the
                # patch's border, is a point of the face (a closer one lies on another
                # patch).  On an edge of the face's domain the trims may run: search them.
                trim = ((not closed[f, 0] and (u <= domains[f, 0, 0] or u >= domains[f, 0, 1]))
                        or (not closed[f, 1] and (v <= domains[f, 1, 0]
                                                  or v >= domains[f, 1, 1]))
                        or (not p_inner[k] and not inside(trims, f, u, v)))
            else:
                trim = edge or not inside(trims, f, u, v)
            if trim:
                if searched[f] == i:
                    continue  # this face's boundary was searched for this query already
                searched[f] = i
                # the two closest chords of the face's trimming polylines
                s1, t1, e1, s2, t2, e2 = two_closest_chords(q0, q1, q2, f, a3, b3, ch_off,
                                                            ch_seg, ch_c, ch_r, lb)
                # a segment's curve lies within sag[s] of its chord: refine only chords
                # that can still beat the best foot found so far
                d2 = np.inf
                if s1 >= 0 and np.sqrt(e1) - sag[s1] < np.sqrt(best):
                    _, u, v, d2 = newton_segment(tab, domains, f, s1, t1, x0, y0, x1, y1,
                                                 q0, q1, q2)
                    onb = free[s1]
                if s2 >= 0 and np.sqrt(e2) - sag[s2] < np.sqrt(min(best, d2)):
                    _, ub, vb, db = newton_segment(tab, domains, f, s2, t2, x0, y0, x1, y1,
                                                   q0, q1, q2)
                    if db < d2:
                        u = ub
                        v = vb
                        d2 = db
                        onb = free[s2]
                if not d2 < best:
                    continue
                D = _eval_call(tab, f, u, v, 1)
                if c == 0:
                    primary_on_edge = True
            # a patch's foot must beat the seeds' clearly: a tie (the same point, found
            # again) keeps the first answer and its flags
            if d2 < (best if c < nc else best * (1.0 - 1e-12)):
                best = d2
                p0 = D[0]
                p1 = D[1]
                p2 = D[2]
                n0, n1, n2 = _normal(D, rev[f], b, rh, rs)
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
