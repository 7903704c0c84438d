"""numba kernels for B-spline / NURBS evaluation (private; trust their input).

Notation follows The NURBS Book (Piegl & Tiller, 2nd ed.): a basis of degree ``p`` over the knot
vector ``U`` of length ``m + 1`` has ``n + 1 = m - p`` functions (``n`` is the LAST control-point
index, not the count).  The valid parameter range is ``[U[p], U[n + 1]]``.

Rational curves and surfaces are evaluated on homogeneous control points
``Pw = (w*x, w*y, w*z, w)`` (thesis eqs. 20-21, 24-25) and divided back with the quotient rule
(NURBS Book A4.2 for curves, A4.4 for surfaces).  A non-rational shape is a rational one with
unit weights (the quotient is then exact up to rounding).

Many points on one surface (:func:`surface_derivs`) take a faster route to the same numbers: the
basis on each knot span is a polynomial, so its Taylor coefficients at the span centre are
computed once per call with A2.3 and each point costs a table lookup for its span plus Horner
steps (no division, no binary search).  Agreement with the A2.3 path is ~1e-15 relative up to
degree 11 (tests/test_nurbs.py).  The tensor-product loops use ``fastmath={"contract"}`` (FMA
contraction only).

Kernels callable from other modules' njit code
----------------------------------------------
``surface_derivs_packed(degrees, knot_offsets, knot_lengths, knots, ctrl_offsets, shapes, ctrl,
f, u, v, order, out)``
    Derivatives of face ``f`` of a :class:`shapeverify.cad.nurbs.PackedSurfaces` at one ``(u, v)``.

    degrees      : (F, 2) int64   -- (p, q) per face
    knot_offsets : (F, 2) int64   -- start of U and V of face f in ``knots``
    knot_lengths : (F, 2) int64   -- len(U), len(V)
    knots        : (M,) float64   -- all knot vectors, concatenated
    ctrl_offsets : (F,) int64     -- start row of face f in ``ctrl``
    shapes       : (F, 2) int64   -- (nu, nv) control-net shape; control point (i, j) is row
                                     ``ctrl_offsets[f] + i * nv + j``
    ctrl         : (K, 4) float64 -- homogeneous control points (w*x, w*y, w*z, w)
    f            : int            -- face index
    u, v         : float          -- parameters (inside the face's domain; not checked)
    order        : int            -- highest total derivative order wanted: 0, 1 or 2
    out          : (order+1, order+1, 3) float64, C-contiguous, written in place:
                   ``out[k, l] = d^(k+l) S / du^k dv^l`` for ``k + l <= order``; entries with
                   ``k + l > order`` are set to NaN.

    It allocates one small scratch buffer per call.  In a hot loop over many points, allocate
    ``work = np.empty(surface_work_size(pmax, qmax, order))`` once and call
    ``surface_derivs_packed_ws(<same arguments>, work)`` instead (``pmax``/``qmax``: the
    largest degrees over the faces you will evaluate).

References
----------
Piegl & Tiller, The NURBS Book, 2nd ed., algorithms A2.1 (FindSpan), A2.2 (BasisFuns),
A2.3 (DersBasisFuns), A3.2/A3.6 (curve/surface derivatives), A4.2/A4.4 (rational derivatives).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def find_span(n, p, u, U):
    """Knot span index ``s`` with ``U[s] <= u < U[s+1]`` (NURBS Book A2.1, binary search).

    ``n`` is the last control-point index.  At ``u >= U[n+1]`` (the end of the domain) the last
    non-empty span is returned; at ``u <= U[p]`` the first one.  Never returns an empty span.
    """
    if u >= U[n + 1]:
        s = n
        while s > p and U[s] >= U[s + 1]:
            s -= 1
        return s
    if u <= U[p]:
        s = p
        while s < n and U[s] >= U[s + 1]:
            s += 1
        return s
    lo = p
    hi = n + 1
    # invariant: U[lo] <= u < U[hi]
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if u < U[mid]:
            hi = mid
        else:
            lo = mid
    return lo


@njit(cache=True)
def basis_funs(i, u, p, U, N, left, right):
    """Non-zero basis functions ``N[0..p] = N_{i-p..i, p}(u)`` (NURBS Book A2.2).

    ``N``, ``left``, ``right`` are scratch/output arrays of length >= p + 1.
    """
    N[0] = 1.0
    for j in range(1, p + 1):
        left[j] = u - U[i + 1 - j]
        right[j] = U[i + j] - u
        saved = 0.0
        for r in range(j):
            temp = N[r] / (right[r + 1] + left[j - r])
            N[r] = saved + right[r + 1] * temp
            saved = left[j - r] * temp
        N[j] = saved


@njit(cache=True)
def ders_basis_funs(i, u, p, nd, U, ders, ndu, a, left, right):
    """Basis functions and derivatives ``ders[k, r] = N^(k)_{i-p+r, p}(u)`` (NURBS Book A2.3).

    ``k = 0..nd``; rows ``k > p`` are zero.  Scratch: ``ndu (p+1, p+1)``, ``a (2, p+1)``,
    ``left, right (p+1,)``; ``ders`` must be at least ``(nd+1, p+1)``.
    """
    ndu[0, 0] = 1.0
    for j in range(1, p + 1):
        left[j] = u - U[i + 1 - j]
        right[j] = U[i + j] - u
        saved = 0.0
        for r in range(j):
            ndu[j, r] = right[r + 1] + left[j - r]  # lower triangle: knot differences
            temp = ndu[r, j - 1] / ndu[j, r]
            ndu[r, j] = saved + right[r + 1] * temp  # upper triangle: basis functions
            saved = left[j - r] * temp
        ndu[j, j] = saved
    for j in range(p + 1):
        ders[0, j] = ndu[j, p]
    nmax = min(nd, p)
    for r in range(p + 1):
        s1 = 0
        s2 = 1
        a[0, 0] = 1.0
        for k in range(1, nmax + 1):
            d = 0.0
            rk = r - k
            pk = p - k
            if r >= k:
                a[s2, 0] = a[s1, 0] / ndu[pk + 1, rk]
                d = a[s2, 0] * ndu[rk, pk]
            j1 = 1 if rk >= -1 else -rk
            j2 = k - 1 if r - 1 <= pk else p - r
            for j in range(j1, j2 + 1):
                a[s2, j] = (a[s1, j] - a[s1, j - 1]) / ndu[pk + 1, rk + j]
                d += a[s2, j] * ndu[rk + j, pk]
            if r <= pk:
                a[s2, k] = -a[s1, k - 1] / ndu[pk + 1, r]
                d += a[s2, k] * ndu[r, pk]
            ders[k, r] = d
            s1, s2 = s2, s1
    fac = float(p)
    for k in range(1, nmax + 1):
        for j in range(p + 1):
            ders[k, j] *= fac
        fac *= p - k
    for k in range(nmax + 1, nd + 1):
        for j in range(p + 1):
            ders[k, j] = 0.0


@njit(cache=True)
def binom(n, k):
    """Binomial coefficient as float (small n)."""
    r = 1.0
    for i in range(1, k + 1):
        r = r * (n - k + i) / i
    return r


# ----------------------------------------------------------------------------------- curves
@njit(cache=True)
def curve_derivs(p, U, Pw, t, order, out):
    """Curve derivatives at many parameters (A3.2 on homogeneous points + A4.2 quotient rule).

    Pw : (n+1, d+1) homogeneous control points (last column = weight).
    t : (N,) parameters; out : (N, order+1, d) -- out[i, k] = k-th derivative at t[i].
    """
    n = Pw.shape[0] - 1
    dim = Pw.shape[1] - 1
    ders = np.zeros((order + 1, p + 1))
    ndu = np.empty((p + 1, p + 1))
    a = np.empty((2, p + 1))
    left = np.empty(p + 1)
    right = np.empty(p + 1)
    Aw = np.empty((order + 1, dim + 1))
    bc = np.empty((order + 1, order + 1))
    for k in range(order + 1):
        for i in range(k + 1):
            bc[k, i] = binom(k, i)
    for it in range(t.shape[0]):
        u = t[it]
        s = find_span(n, p, u, U)
        ders_basis_funs(s, u, p, order, U, ders, ndu, a, left, right)
        for k in range(order + 1):
            for c in range(dim + 1):
                acc = 0.0
                for j in range(p + 1):
                    acc += ders[k, j] * Pw[s - p + j, c]
                Aw[k, c] = acc
        w0 = Aw[0, dim]
        for k in range(order + 1):
            for c in range(dim):
                val = Aw[k, c]
                for i in range(1, k + 1):
                    val -= bc[k, i] * Aw[i, dim] * out[it, k - i, c]
                out[it, k, c] = val / w0


# --------------------------------------------------------------------------------- surfaces
# The surface tensor products below use fastmath={"contract"} only: it lets LLVM fuse a*b + c
# into one FMA (one rounding instead of two); no reassociation, no finite-math assumptions.
_FM = {"contract"}


@njit(cache=True, fastmath=_FM)
def _tensor0(p, q, nv, ctrl, base, Nu, Nv, out, i):
    """S(u, v) from the homogeneous net rows ``base + r*nv + s`` (A3.5 + eq. 25)."""
    a0 = a1 = a2 = a3 = 0.0
    for s in range(q + 1):
        t0 = t1 = t2 = t3 = 0.0
        for r in range(p + 1):
            k = base + r * nv + s
            n0 = Nu[0, r]
            t0 += n0 * ctrl[k, 0]
            t1 += n0 * ctrl[k, 1]
            t2 += n0 * ctrl[k, 2]
            t3 += n0 * ctrl[k, 3]
        m0 = Nv[0, s]
        a0 += m0 * t0
        a1 += m0 * t1
        a2 += m0 * t2
        a3 += m0 * t3
    out[i, 0, 0, 0] = a0 / a3
    out[i, 0, 0, 1] = a1 / a3
    out[i, 0, 0, 2] = a2 / a3


@njit(cache=True, fastmath=_FM)
def _tensor1(p, q, nv, ctrl, base, Nu, Nv, out, i):
    """S, Su, Sv (A3.6 with d = 1, then the quotient rule A4.4)."""
    a0 = a1 = a2 = a3 = 0.0
    b0 = b1 = b2 = b3 = 0.0  # d/du
    c0 = c1 = c2 = c3 = 0.0  # d/dv
    for s in range(q + 1):
        t0 = t1 = t2 = t3 = 0.0  # sum_r Nu[0, r] P[r, s]
        d0 = d1 = d2 = d3 = 0.0  # sum_r Nu[1, r] P[r, s]
        for r in range(p + 1):
            k = base + r * nv + s
            x = ctrl[k, 0]
            y = ctrl[k, 1]
            z = ctrl[k, 2]
            w = ctrl[k, 3]
            n0 = Nu[0, r]
            n1 = Nu[1, r]
            t0 += n0 * x
            t1 += n0 * y
            t2 += n0 * z
            t3 += n0 * w
            d0 += n1 * x
            d1 += n1 * y
            d2 += n1 * z
            d3 += n1 * w
        m0 = Nv[0, s]
        m1 = Nv[1, s]
        a0 += m0 * t0
        a1 += m0 * t1
        a2 += m0 * t2
        a3 += m0 * t3
        b0 += m0 * d0
        b1 += m0 * d1
        b2 += m0 * d2
        b3 += m0 * d3
        c0 += m1 * t0
        c1 += m1 * t1
        c2 += m1 * t2
        c3 += m1 * t3
    iw = 1.0 / a3
    x = a0 * iw
    y = a1 * iw
    z = a2 * iw
    out[i, 0, 0, 0] = x
    out[i, 0, 0, 1] = y
    out[i, 0, 0, 2] = z
    out[i, 1, 0, 0] = (b0 - b3 * x) * iw
    out[i, 1, 0, 1] = (b1 - b3 * y) * iw
    out[i, 1, 0, 2] = (b2 - b3 * z) * iw
    out[i, 0, 1, 0] = (c0 - c3 * x) * iw
    out[i, 0, 1, 1] = (c1 - c3 * y) * iw
    out[i, 0, 1, 2] = (c2 - c3 * z) * iw
    for c in range(3):
        out[i, 1, 1, c] = np.nan


@njit(cache=True, fastmath=_FM)
def _tensor2(p, q, nv, ctrl, base, Nu, Nv, out, i):
    """S and all partials up to total order 2 (A3.6 with d = 2, then A4.4).

    Homogeneous sums: A = S^w, B = S^w_u, C = S^w_v, D = S^w_uu, E = S^w_uv, F = S^w_vv
    (suffix x, y, z, w = component), kept in scalars (no per-point allocation).
    """
    Ax = Ay = Az = Aw = 0.0
    Bx = By = Bz = Bw = 0.0
    Cx = Cy = Cz = Cw = 0.0
    Dx = Dy = Dz = Dw = 0.0
    Ex = Ey = Ez = Ew = 0.0
    Fx = Fy = Fz = Fw = 0.0
    for s in range(q + 1):
        tx = ty = tz = tw = 0.0
        dx = dy = dz = dw = 0.0
        ex = ey = ez = ew = 0.0
        for r in range(p + 1):
            k = base + r * nv + s
            px = ctrl[k, 0]
            py = ctrl[k, 1]
            pz = ctrl[k, 2]
            pw = ctrl[k, 3]
            n0 = Nu[0, r]
            n1 = Nu[1, r]
            n2 = Nu[2, r]
            tx += n0 * px
            ty += n0 * py
            tz += n0 * pz
            tw += n0 * pw
            dx += n1 * px
            dy += n1 * py
            dz += n1 * pz
            dw += n1 * pw
            ex += n2 * px
            ey += n2 * py
            ez += n2 * pz
            ew += n2 * pw
        m0 = Nv[0, s]
        m1 = Nv[1, s]
        m2 = Nv[2, s]
        Ax += m0 * tx
        Ay += m0 * ty
        Az += m0 * tz
        Aw += m0 * tw
        Bx += m0 * dx
        By += m0 * dy
        Bz += m0 * dz
        Bw += m0 * dw
        Cx += m1 * tx
        Cy += m1 * ty
        Cz += m1 * tz
        Cw += m1 * tw
        Dx += m0 * ex
        Dy += m0 * ey
        Dz += m0 * ez
        Dw += m0 * ew
        Ex += m1 * dx
        Ey += m1 * dy
        Ez += m1 * dz
        Ew += m1 * dw
        Fx += m2 * tx
        Fy += m2 * ty
        Fz += m2 * tz
        Fw += m2 * tw
    iw = 1.0 / Aw
    S = Ax * iw
    Su = (Bx - Bw * S) * iw
    Sv = (Cx - Cw * S) * iw
    out[i, 0, 0, 0] = S
    out[i, 1, 0, 0] = Su
    out[i, 0, 1, 0] = Sv
    out[i, 2, 0, 0] = (Dx - 2.0 * Bw * Su - Dw * S) * iw
    out[i, 1, 1, 0] = (Ex - Bw * Sv - Cw * Su - Ew * S) * iw
    out[i, 0, 2, 0] = (Fx - 2.0 * Cw * Sv - Fw * S) * iw
    S = Ay * iw
    Su = (By - Bw * S) * iw
    Sv = (Cy - Cw * S) * iw
    out[i, 0, 0, 1] = S
    out[i, 1, 0, 1] = Su
    out[i, 0, 1, 1] = Sv
    out[i, 2, 0, 1] = (Dy - 2.0 * Bw * Su - Dw * S) * iw
    out[i, 1, 1, 1] = (Ey - Bw * Sv - Cw * Su - Ew * S) * iw
    out[i, 0, 2, 1] = (Fy - 2.0 * Cw * Sv - Fw * S) * iw
    S = Az * iw
    Su = (Bz - Bw * S) * iw
    Sv = (Cz - Cw * S) * iw
    out[i, 0, 0, 2] = S
    out[i, 1, 0, 2] = Su
    out[i, 0, 1, 2] = Sv
    out[i, 2, 0, 2] = (Dz - 2.0 * Bw * Su - Dw * S) * iw
    out[i, 1, 1, 2] = (Ez - Bw * Sv - Cw * Su - Ew * S) * iw
    out[i, 0, 2, 2] = (Fz - 2.0 * Cw * Sv - Fw * S) * iw
    for c in range(3):
        out[i, 1, 2, c] = np.nan
        out[i, 2, 1, c] = np.nan
        out[i, 2, 2, c] = np.nan


@njit(cache=True)
def _tensor(p, q, nv, ctrl, base, order, Nu, Nv, out, i):
    """Dispatch on the derivative order (0, 1 or 2)."""
    if order == 0:
        _tensor0(p, q, nv, ctrl, base, Nu, Nv, out, i)
    elif order == 1:
        _tensor1(p, q, nv, ctrl, base, Nu, Nv, out, i)
    else:
        _tensor2(p, q, nv, ctrl, base, Nu, Nv, out, i)


@njit(cache=True)
def surface_work_size(p, q, order):
    """Length of the float64 scratch buffer for one surface evaluation (degrees <= p, q)."""
    m = max(p, q) + 1
    return (order + 1) * (p + 1) + (order + 1) * (q + 1) + m * m + 4 * m


@njit(cache=True)
def _surf_scratch(work, p, q, order):
    """Carve Nu (order+1, p+1), Nv (order+1, q+1), ndu (m, m), a (2, m), left, right (m,)."""
    m = max(p, q) + 1
    o = order + 1
    i0 = o * (p + 1)
    Nu = work[:i0].reshape((o, p + 1))
    Nv = work[i0:i0 + o * (q + 1)].reshape((o, q + 1))
    i0 += o * (q + 1)
    ndu = work[i0:i0 + m * m].reshape((m, m))
    i0 += m * m
    a = work[i0:i0 + 2 * m].reshape((2, m))
    i0 += 2 * m
    left = work[i0:i0 + m]
    right = work[i0 + m:i0 + 2 * m]
    return Nu, Nv, ndu, a, left, right


@njit(cache=True)
def surface_derivs_packed_ws(degrees, knot_offsets, knot_lengths, knots, ctrl_offsets, shapes,
                             ctrl, f, u, v, order, out, work):
    """As :func:`surface_derivs_packed`, with a caller-owned scratch buffer ``work``.

    ``work`` : (>= surface_work_size(p, q, order),) float64 with p, q >= this face's degrees.
    Basis by A2.1 + A2.3, tensor product A3.6, quotient rule A4.4.
    """
    p = degrees[f, 0]
    q = degrees[f, 1]
    ku = knot_offsets[f, 0]
    kv = knot_offsets[f, 1]
    U = knots[ku:ku + knot_lengths[f, 0]]
    V = knots[kv:kv + knot_lengths[f, 1]]
    nu = shapes[f, 0]
    nv = shapes[f, 1]
    Nu, Nv, ndu, a, left, right = _surf_scratch(work, p, q, order)
    su = find_span(nu - 1, p, u, U)
    sv = find_span(nv - 1, q, v, V)
    ders_basis_funs(su, u, p, order, U, Nu, ndu, a, left, right)
    ders_basis_funs(sv, v, q, order, V, Nv, ndu, a, left, right)
    _tensor(p, q, nv, ctrl, ctrl_offsets[f] + (su - p) * nv + (sv - q), order, Nu, Nv,
            out.reshape((1, out.shape[0], out.shape[1], out.shape[2])), 0)


@njit(cache=True)
def surface_derivs_packed(degrees, knot_offsets, knot_lengths, knots, ctrl_offsets, shapes,
                          ctrl, f, u, v, order, out):
    """Derivatives of packed face ``f`` at one (u, v); see the module docstring for arguments."""
    work = np.empty(surface_work_size(degrees[f, 0], degrees[f, 1], order))
    surface_derivs_packed_ws(degrees, knot_offsets, knot_lengths, knots, ctrl_offsets, shapes,
                             ctrl, f, u, v, order, out, work)


@njit(cache=True)
def surface_derivs_packed_many(degrees, knot_offsets, knot_lengths, knots, ctrl_offsets, shapes,
                               ctrl, faces, u, v, order, out):
    """Vectorised :func:`surface_derivs_packed`: faces, u, v (N,); out (N, order+1, order+1, 3)."""
    pmax = 0
    qmax = 0
    for f in range(degrees.shape[0]):
        pmax = max(pmax, degrees[f, 0])
        qmax = max(qmax, degrees[f, 1])
    work = np.empty(surface_work_size(pmax, qmax, order))
    for i in range(u.shape[0]):
        surface_derivs_packed_ws(degrees, knot_offsets, knot_lengths, knots, ctrl_offsets, shapes,
                                 ctrl, faces[i], u[i], v[i], order, out[i], work)


# ------------------------------------------------------- many points on one surface (fast path)
@njit(cache=True)
def span_table(p, U, n):
    """O(1) span lookup: ``table[g]`` = span at the left end of cell g of a uniform grid.

    Returns (table (G,) int64, u0, cells_per_unit, last) where ``last`` is the last non-empty
    span.  Use with :func:`lookup_span`.
    """
    u0 = U[p]
    u1 = U[n + 1]
    G = 4 * (n - p + 1)
    scale = G / (u1 - u0)
    table = np.empty(G, dtype=np.int64)
    for g in range(G):
        table[g] = find_span(n, p, u0 + g / scale, U)
    last = find_span(n, p, u1, U)
    return table, u0, scale, last


@njit(cache=True)
def lookup_span(u, p, U, table, u0, scale, last):
    """Span of u (same answer as :func:`find_span`) from a :func:`span_table` + a short walk."""
    g = int((u - u0) * scale)
    if g < 0:
        g = 0
    elif g >= table.shape[0]:
        g = table.shape[0] - 1
    s = table[g]
    while s < last and u >= U[s + 1]:
        s += 1
    while s > p and u < U[s]:  # the cell's left end may round past a knot
        s -= 1
    return s


@njit(cache=True)
def taylor_table(p, U, n, nd):
    """Per-span Taylor coefficients of the basis functions and their derivatives.

    ``T[s, k, i, r] = N^(k+i)_{s-p+r}(m_s) / i!`` with ``m_s = mid[s]`` the centre of span s,
    computed with :func:`ders_basis_funs` (A2.3) at the centre.  On span s the basis is a
    polynomial of degree p, so ``N^(k)_{s-p+r}(m_s + t) = sum_i T[s, k, i, r] t^i`` exactly
    (Horner in :func:`_basis_taylor`).  k = 0..nd (rows k > p stay zero); empty spans stay zero.
    """
    T = np.zeros((n + 1, nd + 1, p + 1, p + 1))
    mid = np.zeros(n + 1)
    D = np.zeros((p + 1, p + 1))
    ndu = np.empty((p + 1, p + 1))
    a = np.empty((2, p + 1))
    left = np.empty(p + 1)
    right = np.empty(p + 1)
    invfact = np.empty(p + 1)
    invfact[0] = 1.0
    for i in range(1, p + 1):
        invfact[i] = invfact[i - 1] / i
    for s in range(p, n + 1):
        if U[s] < U[s + 1]:
            m = 0.5 * (U[s] + U[s + 1])
            mid[s] = m
            ders_basis_funs(s, m, p, p, U, D, ndu, a, left, right)
            for k in range(min(nd, p) + 1):
                for i in range(p + 1 - k):
                    for r in range(p + 1):
                        T[s, k, i, r] = D[k + i, r] * invfact[i]
    return T, mid


@njit(cache=True, fastmath=_FM)
def _basis_taylor(T, s, t, p, nd, N):
    """N[k, r] = k-th derivative of basis r of span s at offset t from the span centre."""
    for k in range(nd + 1):
        deg = p - k
        if deg < 0:
            for r in range(p + 1):
                N[k, r] = 0.0
            continue
        for r in range(p + 1):
            N[k, r] = T[s, k, deg, r]
        for i in range(deg - 1, -1, -1):
            for r in range(p + 1):
                N[k, r] = N[k, r] * t + T[s, k, i, r]


@njit(cache=True)
def _surface_loop(p, q, U, V, Pw, u, v, order, out):
    nu = Pw.shape[0]
    nv = Pw.shape[1]
    ctrl = Pw.reshape((nu * nv, 4))
    Tu, midu = taylor_table(p, U, nu - 1, order)
    Tv, midv = taylor_table(q, V, nv - 1, order)
    tabu, u0, scu, lastu = span_table(p, U, nu - 1)
    tabv, v0, scv, lastv = span_table(q, V, nv - 1)
    Nu = np.empty((order + 1, p + 1))
    Nv = np.empty((order + 1, q + 1))
    for i in range(u.shape[0]):
        su = lookup_span(u[i], p, U, tabu, u0, scu, lastu)
        sv = lookup_span(v[i], q, V, tabv, v0, scv, lastv)
        _basis_taylor(Tu, su, u[i] - midu[su], p, order, Nu)
        _basis_taylor(Tv, sv, v[i] - midv[sv], q, order, Nv)
        _tensor(p, q, nv, ctrl, (su - p) * nv + (sv - q), order, Nu, Nv, out, i)


@njit(cache=True)
def surface_derivs(p, q, U, V, Pw, u, v, order, out):
    """Derivatives of one surface at many (u, v).

    Pw : (nu, nv, 4) C-contiguous homogeneous control net; u, v : (N,); order 0, 1 or 2;
    out : (N, order+1, order+1, 3), out[i, k, l] = d^(k+l)S/du^k dv^l (NaN where k+l > order).

    The basis comes from per-span Taylor tables (:func:`taylor_table`, built with A2.3 once per
    call) and spans from a lookup table (:func:`span_table`): no division and no binary search
    per point.
    """
    _surface_loop(p, q, U, V, Pw, u, v, order, out)
