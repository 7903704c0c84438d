"""numba kernels of the NURBS fitting (private; they trust their input).

``basis_ders``      B-spline basis functions and derivatives at many parameters (NURBS Book A2.1 +
                    A2.3, through :mod:`shapeverify.cad._kernels`).
``reduced_blocks``  Per knot-span cell sums of the control-point normal equations after
                    eliminating each point's foot-point parameters (Schur complement, Paper VI).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..cad._kernels import ders_basis_funs, find_span


@njit(cache=True)
def basis_ders(p, U, n_last, t, nd, spans, out):
    """Spans and basis derivatives: ``out[i, k, r] = N^(k)_{spans[i]-p+r, p}(t[i])``.

    p : degree; U : knots; n_last : last control-point index; t : (N,); nd : highest derivative;
    spans : (N,) int64 output; out : (N, nd+1, p+1) output.
    """
    ders = np.zeros((nd + 1, p + 1))
    ndu = np.empty((p + 1, p + 1))
    a = np.empty((2, p + 1))
    left = np.empty(p + 1)
    right = np.empty(p + 1)
    for i in range(t.shape[0]):
        s = find_span(n_last, p, t[i], U)
        spans[i] = s
        ders_basis_funs(s, t[i], p, nd, U, ders, ndu, a, left, right)
        for k in range(nd + 1):
            for r in range(p + 1):
                out[i, k, r] = ders[k, r]


@njit(cache=True)
def reduced_blocks(Jl, r, Bx, Dinv, gt, cell, cellA, cellg, celldiag):
    """Accumulate the foot-point-eliminated normal equations per cell.

    Jl : (N, d, k) local Jacobian of point i w.r.t. its k global unknowns; r : (N, d) residuals
    Bx : (N, k, q) coupling block (Hessian d2f / dtheta dt_i; J_i^T T_i for Gauss-Newton)
    Dinv : (N, q, q) inverse of the (damped) foot-point block; gt : (N, q) = T_i^T r_i
    cell : (N,) cell index of each point (all points of a cell share their k unknowns)
    cellA : (C, k, k) += Jl^T Jl - Bx Dinv Bx^T;  cellg : (C, k) += Jl^T r - Bx Dinv gt;
    celldiag : (C, k) += diag(Jl^T Jl)
    """
    N, d, k = Jl.shape
    q = Bx.shape[2]
    BD = np.empty((k, q))
    for i in range(N):
        c = cell[i]
        for j in range(k):
            for a in range(q):
                s = 0.0
                for b in range(q):
                    s += Bx[i, j, b] * Dinv[i, b, a]
                BD[j, a] = s
        for j in range(k):
            dj = 0.0
            gj = 0.0
            for e in range(d):
                dj += Jl[i, e, j] * Jl[i, e, j]
                gj += Jl[i, e, j] * r[i, e]
            for a in range(q):
                gj -= BD[j, a] * gt[i, a]
            celldiag[c, j] += dj
            cellg[c, j] += gj
            for l in range(j, k):
                acc = 0.0
                for e in range(d):
                    acc += Jl[i, e, j] * Jl[i, e, l]
                for a in range(q):
                    acc -= BD[j, a] * Bx[i, l, a]
                cellA[c, j, l] += acc
    # mirror the upper triangle
    for c in range(cellA.shape[0]):
        for j in range(k):
            for l in range(j + 1, k):
                cellA[c, l, j] = cellA[c, j, l]


@njit(cache=True)
def reduced_blocks_poly(R, r, Bx, Dinv, gt, cell, cellA, cellg, celldiag):
    """:func:`reduced_blocks` for a polynomial (non-rational) shape, using ``Jl = R kron I_d``.

    R : (N, L) basis values of the cell's L control points; unknown (l, e) is column l d + e;
    q (foot-point dimension) must be 1 or 2.
    """
    N, L = R.shape
    d = r.shape[1]
    k = L * d
    q = Bx.shape[2]
    X0 = np.empty(k)
    X1 = np.empty(k)
    Y0 = np.empty(k)
    Y1 = np.zeros(k)
    for i in range(N):
        c = cell[i]
        A = cellA[c]
        for j in range(k):
            Y0[j] = Bx[i, j, 0]
            if q == 2:
                Y1[j] = Bx[i, j, 1]
        if q == 1:
            for j in range(k):
                X0[j] = Y0[j] * Dinv[i, 0, 0]
            g0 = gt[i, 0]
            for j in range(k):
                cellg[c, j] -= X0[j] * g0
                x0 = X0[j]
                for jj in range(j, k):
                    A[j, jj] -= x0 * Y0[jj]
        else:
            d00, d01, d10, d11 = Dinv[i, 0, 0], Dinv[i, 0, 1], Dinv[i, 1, 0], Dinv[i, 1, 1]
            for j in range(k):
                X0[j] = Y0[j] * d00 + Y1[j] * d10
                X1[j] = Y0[j] * d01 + Y1[j] * d11
            g0, g1 = gt[i, 0], gt[i, 1]
            for j in range(k):
                cellg[c, j] -= X0[j] * g0 + X1[j] * g1
                x0, x1 = X0[j], X1[j]
                for jj in range(j, k):
                    A[j, jj] -= x0 * Y0[jj] + x1 * Y1[jj]
        for l in range(L):
            Rl = R[i, l]
            for e in range(d):
                celldiag[c, l * d + e] += Rl * Rl
                cellg[c, l * d + e] += Rl * r[i, e]
            for m in range(l, L):
                rr = Rl * R[i, m]
                for e in range(d):
                    A[l * d + e, m * d + e] += rr
    for c in range(cellA.shape[0]):
        for j in range(k):
            for l in range(j + 1, k):
                cellA[c, l, j] = cellA[c, j, l]
