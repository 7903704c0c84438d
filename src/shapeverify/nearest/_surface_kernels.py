"""numba evaluation of NURBS faces from their polynomial patch tables (private; trusts its input).

The tables are built by :func:`shapeverify.nearest.exact.power_tables`: one tensor-product
polynomial per non-empty knot span, so an evaluation costs two Horner passes and no knot-span
recursion.
"""

from __future__ import annotations

import numpy as np
from numba import njit


# Surfaces as tables of polynomial patches (``tab``, built by exact.py): per face f
#   deg[f] = (p, q); spans along u: bu[bu_off[f]:bu_off[f+1]] (breakpoints, n_u + 1 of them),
#   mu[mu_off[f] + i] = centre of span i (same for v with bv/mv); coefficient rows
#   coef[c_off[f] + ((i * n_v + j) * (p + 1) + a) * (q + 1) + b] = (wx, wy, wz, w) of
#   (u - mu_i)^a (v - mv_j)^b on span (i, j).  Homogeneous, divided back with the quotient rule.
# Derivatives travel as 18-tuples D: S = D[0:3], S_u = D[3:6], S_v = D[6:9], S_uu = D[9:12],
# S_uv = D[12:15], S_vv = D[15:18] (x, y, z each).
# small: LLVM inlines it; numba's inline="always" rebuilt and re-typed it at every call site
@njit(cache=True, nogil=True)
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


# small: LLVM inlines it; numba's inline="always" rebuilt and re-typed it at every call site
@njit(cache=True, nogil=True)
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
    return _eval(tab, f, u, v, order, np.int64(-1), np.int64(-1))[0]


@njit(cache=True, nogil=True)
def eval_many(tab, faces, u, v, out):
    """out[i, k, l] = d^(k+l)S/du^k dv^l (k + l <= 2) of face faces[i] at (u[i], v[i]).

    ``out`` (N, 3, 3, 3); entries with k + l > 2 are left as they are.
    """
    for i in range(u.shape[0]):
        D = _eval(tab, faces[i], u[i], v[i], 2, np.int64(-1), np.int64(-1))[0]
        for c in range(3):
            out[i, 0, 0, c] = D[c]
            out[i, 1, 0, c] = D[3 + c]
            out[i, 0, 1, c] = D[6 + c]
            out[i, 2, 0, c] = D[9 + c]
            out[i, 1, 1, c] = D[12 + c]
            out[i, 0, 2, c] = D[15 + c]
