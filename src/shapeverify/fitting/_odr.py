"""Orthogonal-distance NURBS fitting: the Gauss-Newton / Levenberg-Marquardt machinery shared by
curves and surfaces (private).

Unknowns: the global parameters ``theta`` (control points, then the weights of a rational shape)
and one foot-point parameter vector ``t_i`` (1 for a curve, 2 for a surface) per data point.
Residuals ``r_i = S(t_i; theta) - x_i``; the objective is ``sum_i ||r_i||^2 + theta^T P theta``
(``P``: optional smoothness penalty on the control points; with the sliding prior of _slide.py
the penalty is ``theta^T P theta - 2 b^T theta + c``, a quadratic about an anchor).

The Jacobian has the block structure of Paper VI: ``[J_theta | blockdiag(T_i)]`` with ``T_i`` the
tangent(s) at the foot point.  Eliminating each point's small block ``T_i^T T_i`` (Schur
complement) leaves the normal equations of ``theta`` alone,

    (sum_i J_i^T Q_i J_i + P + lam D) dtheta = -(sum_i J_i^T Q_i r_i + P theta),
    Q_i = I - T_i (T_i^T T_i (1 + lam))^-1 T_i^T,
    dt_i = -(T_i^T T_i (1 + lam))^-1 T_i^T (r_i + J_i dtheta),

which is exactly the damped Gauss-Newton step of the full problem, at the cost of the small
``theta`` system; the full Jacobian is never formed.  The reduced matrix couples only control
points that share a knot-span cell: it is assembled per cell (numba kernels in _kernels.py) and
factorised as a banded matrix.  With ``newton=True`` the curvature terms of the foot points
(``r . S_tt`` in the foot-point block, ``r . dR/dt`` in the coupling) are added where they keep
the foot-point block definite: the exact Newton step for polynomial shapes.

``method="varpro"`` (Paper VII, Golub-Pereyra with Kaufman's simplification): the control points
are projected out; after each step on the nonlinear parameters (foot points and weights) the
control points are recomputed by linear least squares.  Kaufman's Jacobian of the projected
functional, ``-P_perp [T | V]``, gives the same reduced system as above with the control points
left undamped (their step is discarded), so both methods share :func:`reduced_step`.

The problem object (see curves.py / surfaces.py) provides ``x (N, d)``, ``n`` (control points),
``d``, ``q``, ``rational``, ``M`` (len(theta): n d coordinates, then n weights if rational),
``idx_cell (C, k)`` (the unknowns of each knot-span cell), ``fixed`` (indices of theta held
fixed: the weight gauge), ``weight_slice``, ``penalty`` (sparse (M, M) or None), ``lo``/``hi``
(domain), ``local(t, nd) -> (basis products, control indices, cell)``, ``clip(t)``,
``project(theta, t) -> t`` (foot points) and ``relinearise(theta, t) -> theta`` (optimal
control points for fixed foot points and weights).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from . import _kernels

logger = logging.getLogger(__name__)



@dataclass
class Evaluation:
    """Residuals and derivatives at the foot points, in compact per-point form.

    The local Jacobian w.r.t. the k = L d (+ L) unknowns of a point's cell is
    ``Jl[:, e, l d + e] = R[:, l]`` (control points) and ``Jl[:, :, L d + l] = G[:, l, :]``
    (weights, rational only); ``Ra``/``Ga`` are their derivatives w.r.t. the foot point.
    """
    r: np.ndarray                   # (N, d) residuals S(t) - x
    T: np.ndarray                   # (N, d, q) tangents dS/dt
    cell: np.ndarray                # (N,) int64
    R: np.ndarray                   # (N, L) rational basis values
    G: np.ndarray | None = None     # (N, L, d) dS/dw (rational only)
    H2: np.ndarray | None = None    # (N, d, q, q) second derivatives d2S / dt dt
    Ra: np.ndarray | None = None    # (N, L, q) dR/dt
    Ga: np.ndarray | None = None    # (N, L, d, q) dG/dt

    @property
    def Jl(self) -> np.ndarray:
        """(N, d, k) local Jacobian (dense per point)."""
        N, L = self.R.shape
        d = self.r.shape[1]
        k = L * d + (L if self.G is not None else 0)
        J = np.zeros((N, d, k))
        for e in range(d):
            J[:, e, np.arange(L) * d + e] = self.R
        if self.G is not None:
            J[:, :, L * d:] = np.transpose(self.G, (0, 2, 1))
        return J

    def coupling(self, newton: bool = False) -> np.ndarray:
        """(N, k, q) ``Jl^T T`` (+ ``(dJl/dt)^T r`` with the Newton terms)."""
        N, L = self.R.shape
        d, q = self.T.shape[1], self.T.shape[2]
        B = (self.R[:, :, None, None] * self.T[:, None, :, :]).reshape(N, L * d, q)
        if self.G is not None:
            B = np.concatenate([B, np.einsum("nld,nda->nla", self.G, self.T)], axis=1)
        return B + self.coupling_second() if newton else B

    def coupling_second(self) -> np.ndarray:
        """(N, k, q) ``(dJl/dt)^T r``: the second-order (Newton) part of the coupling."""
        N, L = self.R.shape
        d, q = self.T.shape[1], self.T.shape[2]
        B = (self.Ra[:, :, None, :] * self.r[:, None, :, None]).reshape(N, L * d, q)
        if self.G is not None:
            B = np.concatenate([B, np.einsum("nlda,nd->nla", self.Ga, self.r)], axis=1)
        return B

    def grad_local(self) -> np.ndarray:
        """(N, k) ``Jl^T r``."""
        N, L = self.R.shape
        g = (self.R[:, :, None] * self.r[:, None, :]).reshape(N, -1)
        if self.G is not None:
            g = np.concatenate([g, np.einsum("nld,nd->nl", self.G, self.r)], axis=1)
        return g


def _keys(q: int):
    zero = (0,) * q
    unit = [tuple(int(b == a) for b in range(q)) for a in range(q)]
    pair = [[tuple(int(c == a) + int(c == b) for c in range(q)) for b in range(q)] for a in range(q)]
    return zero, unit, pair


def evaluate(prob, theta: np.ndarray, t: np.ndarray, second: bool = False) -> Evaluation:
    """Residuals, tangents and local Jacobians at foot points ``t`` (quotient rule, NURBS Book A4.2/A4.4).

    ``prob.local(t, nd)`` gives ``(B, j, cell)``: ``B[multi-index]`` (N, L) products of basis
    derivatives of the L control points that act on each point, ``j`` (N, L) their indices.
    """
    n, d, q = prob.n, prob.d, prob.q
    B, j, cell = prob.local(t, 2 if second else 1)
    P = theta[:n * d].reshape(n, d)
    Pj = P[j]                                                         # (N, L, d)
    zero, unit, pair = _keys(q)
    rational = prob.rational
    if rational:
        wj = theta[n * d:][j]
        Wb = {key: val * wj for key, val in B.items()}
        Ws = {key: val.sum(axis=1) for key, val in Wb.items()}
        inv = (1.0 / Ws[zero])[:, None]
    else:
        Wb, Ws, inv = B, None, 1.0
    S = np.einsum("nl,nld->nd", Wb[zero], Pj) * inv
    Sa = []
    for a in range(q):
        A = np.einsum("nl,nld->nd", Wb[unit[a]], Pj)
        if rational:
            A = A - Ws[unit[a]][:, None] * S
        Sa.append(A * inv)
    T = np.stack(Sa, axis=2)                                         # (N, d, q)
    R = Wb[zero] * inv                                                 # (N, L)
    G = None
    if rational:
        G = B[zero][:, :, None] * (Pj - S[:, None, :]) * inv[:, :, None]   # (N, L, d)
    ev = Evaluation(S - prob.x, T, cell, R, G)
    if not second:
        return ev
    N = t.shape[0]
    H2 = np.empty((N, d, q, q))
    for a in range(q):
        for b in range(a, q):
            A = np.einsum("nl,nld->nd", Wb[pair[a][b]], Pj)
            if rational:
                A = A - Ws[unit[a]][:, None] * Sa[b] - Ws[unit[b]][:, None] * Sa[a] \
                    - Ws[pair[a][b]][:, None] * S
            H2[:, :, a, b] = H2[:, :, b, a] = A * inv
    Ra = np.empty(R.shape + (q,))
    Ga = np.empty(G.shape + (q,)) if rational else None
    for a in range(q):
        Ra[:, :, a] = Wb[unit[a]] * inv
        if rational:
            Ra[:, :, a] -= Ws[unit[a]][:, None] * R * inv
            Ga[..., a] = (B[unit[a]][:, :, None] * (Pj - S[:, None, :])
                          - B[zero][:, :, None] * Sa[a][:, None, :]
                          - Ws[unit[a]][:, None, None] * G) * inv[:, :, None]
    ev.H2, ev.Ra, ev.Ga = H2, Ra, Ga
    return ev


def cost_of(prob, theta: np.ndarray, r: np.ndarray) -> float:
    """``||r||^2`` plus the penalty ``theta^T P theta - 2 b^T theta + c`` (b, c: see _slide.py)."""
    c = float(np.einsum("ij,ij->", r, r))
    if prob.penalty is not None:
        c += float(theta @ (prob.penalty @ theta))
        b = getattr(prob, "penalty_b", None)
        if b is not None:
            c += prob.penalty_c - 2.0 * float(b @ theta)
    return c


def penalty_gradient(prob, theta: np.ndarray) -> np.ndarray | float:
    """Half the penalty's gradient, ``P theta - b`` (0 without a penalty)."""
    if prob.penalty is None:
        return 0.0
    g = prob.penalty @ theta
    b = getattr(prob, "penalty_b", None)
    return g if b is None else g - b


def _inv_small(D: np.ndarray) -> np.ndarray:
    q = D.shape[1]
    if q == 1:
        return 1.0 / np.where(np.abs(D) > 1e-300, D, 1e-300)
    det = D[:, 0, 0] * D[:, 1, 1] - D[:, 0, 1] * D[:, 1, 0]
    det = np.where(np.abs(det) > 1e-300, det, 1e-300)
    Dinv = np.empty_like(D)
    Dinv[:, 0, 0] = D[:, 1, 1] / det
    Dinv[:, 1, 1] = D[:, 0, 0] / det
    Dinv[:, 0, 1] = -D[:, 0, 1] / det
    Dinv[:, 1, 0] = -D[:, 1, 0] / det
    return Dinv


def _foot_blocks(ev: Evaluation, lam: float, frozen=None):
    """Per-point pieces: damped foot-point block inverse Dinv (N, q, q), coupling Bx (N, k, q),
    gt = T^T r (N, q), and the Gauss-Newton block T^T T (N, q, q).

    ``frozen`` (N, q) bool: foot-point coordinates held at a domain bound (active constraints).
    """
    q = ev.T.shape[2]
    T = ev.T
    fz = frozen is not None and frozen.any()
    if fz:
        T = T * ~frozen[:, None, :]
    gn = np.einsum("nda,ndb->nab", T, T)                             # T^T T
    if fz:
        gn = gn + frozen[:, :, None] * np.eye(q)[None]              # dt = 0 there
    gt = np.einsum("nda,nd->na", T, ev.r)
    H = gn
    Bx = ev.coupling(False)
    if ev.H2 is not None:
        # Newton in the foot points: add the curvature terms where they keep the block definite
        Hn = gn + np.einsum("nd,ndab->nab", ev.r, ev.H2)
        if fz:
            Hn = np.where(frozen[:, :, None] | frozen[:, None, :], gn, Hn)
        if q == 1:
            ok = Hn[:, 0, 0] > 0.05 * gn[:, 0, 0]
        else:
            det = Hn[:, 0, 0] * Hn[:, 1, 1] - Hn[:, 0, 1] ** 2
            detg = gn[:, 0, 0] * gn[:, 1, 1] - gn[:, 0, 1] ** 2
            ok = (Hn[:, 0, 0] > 0.05 * gn[:, 0, 0]) & (det > 0.01 * detg)
        H = np.where(ok[:, None, None], Hn, gn)
        Bx = Bx + ok[:, None, None] * ev.coupling_second()
    if fz:
        Bx = Bx * ~frozen[:, None, :]
    D = H + lam * gn * np.eye(q)[None]          # Marquardt: damp with the Gauss-Newton diagonal
    return _inv_small(D), np.ascontiguousarray(Bx), gt, gn


def _cells(prob, ev: Evaluation, Bx, Dinv, gt):
    """Cell sums (C, k, k), (C, k), (C, k) of the reduced matrix, gradient, diag(J^T J)."""
    k = Bx.shape[1]
    C = prob.idx_cell.shape[0]
    cellA = np.zeros((C, k, k))
    cellg = np.zeros((C, k))
    celld = np.zeros((C, k))
    if ev.G is None:
        _kernels.reduced_blocks_poly(ev.R, ev.r, Bx, Dinv, gt, ev.cell, cellA, cellg, celld)
    else:
        _kernels.reduced_blocks(ev.Jl, ev.r, Bx, Dinv, gt, ev.cell, cellA, cellg, celld)
    return cellA, cellg, celld


def active_bounds(prob, ev: Evaluation, t: np.ndarray) -> np.ndarray:
    """(N, q) foot-point coordinates at a domain bound whose gradient pushes them outside."""
    g = np.einsum("nda,nd->na", ev.T, ev.r)
    tt = t.reshape(g.shape)
    lo = np.asarray(prob.lo, np.float64).reshape(1, -1)
    hi = np.asarray(prob.hi, np.float64).reshape(1, -1)
    return ((tt <= lo) & (g > 0)) | ((tt >= hi) & (g < 0))


class _Band:
    """Banded (upper, LAPACK) layout of the reduced matrix in control-point-major order.

    The reduced matrix couples only control points that share a knot-span cell, so with each
    control point's unknowns (coordinates, weight) together it is banded: bandwidth about
    (p + 1) (d + 1) for a curve and (p nv + q + 1) (d + 1) for a surface.
    """

    def __init__(self, prob):
        M = prob.M
        owner = np.empty(M, np.int64)
        nd = prob.n * prob.d
        owner[:nd] = np.arange(nd) // prob.d
        owner[nd:] = np.arange(M - nd)
        self.order = np.argsort(owner, kind="stable")
        pos = np.empty(M, np.int64)
        pos[self.order] = np.arange(M)
        pr = pos[prob.idx_cell][:, :, None]
        pc = pos[prob.idx_cell][:, None, :]
        upper = np.broadcast_to(pc >= pr, (len(pr), pr.shape[1], pc.shape[2]))
        self.bw = int(np.max(pc - pr))
        if prob.penalty is not None:
            P = prob.penalty.tocoo()
            self.bw = max(self.bw, int(np.max(np.abs(pos[P.col] - pos[P.row]))) if P.nnz else 0)
            up = pos[P.col] >= pos[P.row]
            self.pen_flat = ((self.bw + pos[P.row] - pos[P.col]) * M + pos[P.col])[up]
            self.pen_val = P.data[up]
            self.pen_rc = (P.row[up], P.col[up])
        flat = (self.bw + pr - pc) * M + pc                          # (C, k, k) index into ab
        self.mask = upper.ravel()
        self.flat = np.broadcast_to(flat, upper.shape).ravel()[self.mask]
        self.rows = np.broadcast_to(prob.idx_cell[:, :, None], upper.shape).ravel()[self.mask]
        self.cols = np.broadcast_to(prob.idx_cell[:, None, :], upper.shape).ravel()[self.mask]
        self.pos = pos
        self.M = M

    def matrix(self, prob, cellA, diag, keep):
        """ab (bw + 1, M): cell blocks + penalty + diag, rows/columns with keep == 0 -> identity."""
        M, bw = self.M, self.bw
        w = cellA.ravel()[self.mask] * keep[self.rows] * keep[self.cols]
        ab = np.bincount(self.flat, weights=w, minlength=(bw + 1) * M)
        if prob.penalty is not None:
            r, c = self.pen_rc
            ab += np.bincount(self.pen_flat, weights=self.pen_val * keep[r] * keep[c],
                              minlength=(bw + 1) * M)
        ab = ab.reshape(bw + 1, M)
        ab[bw, self.pos] += diag * keep + (1.0 - keep)
        return ab

    def solve(self, ab, rhs):
        """x with A x = rhs, or None if A is not positive definite (banded Cholesky)."""
        try:
            cb = scipy.linalg.cholesky_banded(ab, lower=False, check_finite=False)
        except np.linalg.LinAlgError:
            return None
        x = scipy.linalg.cho_solve_banded((cb, False), rhs[self.order], check_finite=False)
        out = np.empty_like(x)
        out[self.order] = x
        return out


def _band(prob) -> _Band:
    band = getattr(prob, "_band", None)
    if band is None:
        band = prob._band = _Band(prob)
    return band


def reduced_step(prob, theta: np.ndarray, ev: Evaluation, lam: float, damp_theta: bool = True,
                 frozen=None):
    """One damped (Gauss-)Newton step ``(dtheta (M,), dt (N, q), predicted decrease)``.

    The foot points are eliminated point by point; only the banded control-point system is
    factorised.  ``damp_theta=False`` (variable projection) damps only the weights, not the
    control points.  Returns None when the damped reduced matrix is not positive definite
    (increase ``lam``).
    """
    Dinv, Bx, gt, gn = _foot_blocks(ev, lam, frozen)
    cellA, cellg, celld = _cells(prob, ev, Bx, Dinv, gt)
    M = prob.M
    idx = prob.idx_cell
    g = np.bincount(idx.ravel(), weights=cellg.ravel(), minlength=M)
    dg = np.bincount(idx.ravel(), weights=celld.ravel(), minlength=M)
    g = g + penalty_gradient(prob, theta)
    damp = np.zeros(M)
    top = float(dg.max()) if dg.size else 1.0
    floor = 1e-12 * top
    if damp_theta:
        damp[:] = lam * np.maximum(dg, floor)
    elif prob.weight_slice is not None:
        ws = prob.weight_slice
        damp[ws] = lam * np.maximum(dg[ws], floor)
    # structural singularities (no data over a control point) get a tiny ridge
    damp += 1e-14 * max(top, 1.0) * (dg == 0)
    keep = np.ones(M)
    keep[prob.fixed] = 0.0
    band = _band(prob)
    dtheta = band.solve(band.matrix(prob, cellA, damp, keep), -g * keep)
    if dtheta is None:
        return None
    idx_pt = idx[ev.cell]                                            # (N, k)
    lin = gt + np.einsum("nka,nk->na", Bx, dtheta[idx_pt])
    dt = -np.einsum("nab,nb->na", Dinv, lin)
    # predicted decrease of ||r||^2 (+ penalty) by the quadratic model: lam d^T D d - g^T d
    g_full = np.bincount(idx_pt.ravel(), weights=ev.grad_local().ravel(), minlength=M)
    g_full = g_full + penalty_gradient(prob, theta)
    q = gn.shape[1]
    dDd = float(np.sum(damp * keep * dtheta ** 2)) + \
        lam * float(np.einsum("na,nab,nb->", dt, gn * np.eye(q)[None], dt))
    pred = dDd - float(g_full @ dtheta) - float(np.sum(gt * dt))
    return dtheta, dt, pred


def _trial(prob, theta, t, dtheta, dt, varpro, reproject, newton):
    """Evaluate a trial step; None when it is infeasible (weights <= 0, emptied knot span)."""
    theta_new = theta + dtheta
    ws = prob.weight_slice
    if ws is not None and np.any(theta_new[ws] <= 0):
        return None
    t_new = prob.clip(t + dt.reshape(t.shape))
    if varpro:
        try:
            theta_new = prob.relinearise(theta_new, t_new)
        except ValueError:
            return None
    if reproject:
        t_new = prob.project(theta_new, t_new)
    ev_new = evaluate(prob, theta_new, t_new, newton)
    return theta_new, t_new, ev_new, cost_of(prob, theta_new, ev_new.r)


def solve(prob, theta: np.ndarray, t: np.ndarray, method: str, max_iterations: int,
          tolerance: float, newton: bool = True, reproject: bool = True):
    """Levenberg-Marquardt on (theta, t).  Returns (theta, t, iterations, converged, history).

    ``newton``: include the foot-point curvature terms (exact Newton for non-rational shapes);
    ``reproject``: move the foot points to the orthogonal projections after each trial step
    (a few Newton steps per point), so that each iterate's objective is the orthogonal one.
    The damping follows Nielsen's gain-ratio rule.
    """
    varpro = method == "varpro"
    if varpro:
        theta = prob.relinearise(theta, t)
    ev = evaluate(prob, theta, t, newton)
    cost = cost_of(prob, theta, ev.r)
    history = [cost]
    lam, nu = 1e-4, 2.0
    converged = False
    it = 0
    for it in range(1, max_iterations + 1):
        frozen = active_bounds(prob, ev, t)
        trial = None
        while lam <= 1e12:
            step = reduced_step(prob, theta, ev, lam, damp_theta=not varpro, frozen=frozen)
            if step is not None:
                dtheta, dt, pred = step
                trial = _trial(prob, theta, t, dtheta, dt, varpro, reproject, newton)
                if trial is not None and trial[3] <= cost:
                    rho = (cost - trial[3]) / pred if pred > 0 else 1.0
                    lam = max(lam * max(1.0 / 3.0, 1.0 - (2.0 * min(rho, 1.0) - 1.0) ** 3), 1e-12)
                    nu = 2.0
                    break
                trial = None
            lam *= nu
            nu *= 2.0
        if trial is None:
            converged = True   # no descent direction left: stationary up to rounding
            logger.debug("LM stopped: damping exhausted at cost %.6g", cost)
            break
        decrease = cost - trial[3]
        theta, t, ev, cost = trial
        history.append(cost)
        if decrease <= tolerance * cost:
            converged = True
            break
    return theta, t, it, converged, np.asarray(history)
