"""Least-squares NURBS surface fitting: fixed parameters, orthogonal distance (ODR), variable projection.

``fit_surface`` fits a tensor-product (rational) B-spline surface to a grid of points
``(ku, kv, 3)`` or to scattered points ``(N, 3)`` (e.g. a region of a scan), with the same three
methods as :func:`shapeverify.fitting.fit_curve`:

* ``"fixed"``: linear least squares at fixed parameters (grid: averaged chord-length or
  centripetal parameters, NURBS Book 9.2.5; scattered: coordinates in the best-fit plane) and
  knots by NURBS Book eqs. (9.68)-(9.69) per direction;
* ``"odr"``: Levenberg-Marquardt on control points (and weights) plus the (u, v) foot points,
  with each point's 2 x 2 foot-point block eliminated (Paper VI);
* ``"varpro"``: variable projection with Kaufman's simplification (Paper VII).

References
----------
Piegl & Tiller, The NURBS Book, 2nd ed., sections 9.2.5 and 9.4.3.
Bergström (2011), thesis ch. 11-12, Papers VI and VII.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse
import scipy.spatial

from .._renamed import grouped_keywords, renamed_keywords
from ..cad.nurbs import NurbsSurface
from . import _odr, _slide
from ._element_base import _Repr
from .curves import (SLIDE_STIFFNESS, FitSolver, _basis, _check_common, _second_difference, _solve_spd,
                     approximation_knots, chord_length_params)

logger = logging.getLogger(__name__)

__all__ = ["SurfaceFit", "fit_surface", "surface_params", "project_to_surface"]


@dataclass(frozen=True, repr=False)
class SurfaceFit(_Repr):
    """Result of :func:`fit_surface`.

    Attributes
    ----------
    surface : NurbsSurface
    params : (N, 2) float64 foot-point parameters (u, v) (orthogonal projections of the points)
    residuals : (N,) float64 signed orthogonal distances (+ on the side of Su x Sv)
    rms, max_error : float   root-mean-square and largest absolute orthogonal distance
    iterations : int   Levenberg-Marquardt iterations (0 for ``method="fixed"``)
    converged : bool
    method : str
    history : (iterations + 1,) float64 objective value per accepted iterate
    """
    surface: NurbsSurface
    params: np.ndarray
    residuals: np.ndarray
    rms: float
    max_error: float
    iterations: int
    converged: bool
    method: str
    history: np.ndarray


# ----------------------------------------------------------------------------------------------
# parameters
# ----------------------------------------------------------------------------------------------
def surface_params(points, centripetal: bool = False) -> np.ndarray:
    """Initial (u, v) parameters in [0, 1]^2.

    Parameters
    ----------
    points : (ku, kv, 3) grid (rows along u) or (N, 3) scattered points
    centripetal : bool
        Grid only: centripetal instead of chord-length parameters.

    Returns
    -------
    (ku * kv, 2) or (N, 2) float64.  Grid: chord-length parameters averaged over the rows and
    columns (NURBS Book eqs. 9.5-9.6); scattered: coordinates in the best-fit plane along the
    sides of the points' minimum-area bounding rectangle, scaled to [0, 1] (suitable for
    height-field-like regions).
    """
    x = np.asarray(points, np.float64)
    if x.ndim == 3:
        ku, kv, _ = x.shape
        u = np.mean([chord_length_params(x[:, j], centripetal) for j in range(kv)], axis=0)
        v = np.mean([chord_length_params(x[i, :], centripetal) for i in range(ku)], axis=0)
        uu, vv = np.meshgrid(u, v, indexing="ij")
        return np.column_stack([uu.ravel(), vv.ravel()])
    c = x.mean(axis=0)
    _, s, vt = np.linalg.svd(x - c, full_matrices=False)
    if s[1] <= 1e-12 * s[0]:
        raise ValueError("the points are collinear: no surface parameters can be assigned")
    uv = (x - c) @ vt[:2].T
    # in-plane axes along the minimum-area bounding rectangle (so that a rectangular region
    # fills the parameter square; principal axes are arbitrary for a square region)
    try:
        hull = uv[scipy.spatial.ConvexHull(uv).vertices]
        edges = np.roll(hull, -1, axis=0) - hull
        ang = np.unique(np.mod(np.arctan2(edges[:, 1], edges[:, 0]), np.pi / 2))
        cs, sn = np.cos(ang), np.sin(ang)
        a = hull @ np.stack([cs, sn])                     # (H, A) coordinates along each angle
        b = hull @ np.stack([-sn, cs])
        area = np.ptp(a, axis=0) * np.ptp(b, axis=0)
        k = int(np.argmin(area))
        R = np.array([[cs[k], sn[k]], [-sn[k], cs[k]]])
        uv = uv @ R.T
    except scipy.spatial.QhullError:                      # degenerate hull: keep principal axes
        pass
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    return (uv - lo) / (hi - lo)


def project_to_surface(surface: NurbsSurface, points, uv0, iterations: int = 30):
    """Foot points of ``points`` on ``surface`` by safeguarded Newton iteration from ``uv0``.

    Returns
    -------
    uv : (N, 2) float64 (clamped to the domain); dist : (N,) float64 signed distances
    (+ on the side of Su x Sv).
    """
    x = np.asarray(points, np.float64)
    (u0, u1), (v0, v1) = surface.domain
    lo, hi = np.array([u0, v0]), np.array([u1, v1])
    uv = np.clip(np.asarray(uv0, np.float64), lo, hi)

    def ev(uv):
        d = surface.derivatives(uv[:, 0], uv[:, 1], 2)
        return d, d[:, 0, 0] - x

    d, r = ev(uv)
    f = np.einsum("ij,ij->i", r, r)
    for _ in range(iterations):
        su, sv = d[:, 1, 0], d[:, 0, 1]
        g = np.column_stack([np.einsum("ij,ij->i", r, su), np.einsum("ij,ij->i", r, sv)])
        a = np.einsum("ij,ij->i", su, su)
        b = np.einsum("ij,ij->i", su, sv)
        c = np.einsum("ij,ij->i", sv, sv)
        A = a + np.einsum("ij,ij->i", r, d[:, 2, 0])
        B = b + np.einsum("ij,ij->i", r, d[:, 1, 1])
        C = c + np.einsum("ij,ij->i", r, d[:, 0, 2])
        det = A * C - B * B
        gn = (A <= 0.05 * a) | (det <= 0.01 * (a * c - b * b))
        A, B, C = np.where(gn, a, A), np.where(gn, b, B), np.where(gn, c, C)
        det = np.maximum(A * C - B * B, 1e-300)
        step = -np.column_stack([C * g[:, 0] - B * g[:, 1], A * g[:, 1] - B * g[:, 0]]) / det[:, None]
        uv_new = np.clip(uv + step, lo, hi)
        d_new, r_new = ev(uv_new)
        f_new = np.einsum("ij,ij->i", r_new, r_new)
        better = f_new < f
        if not better.any():
            break
        uv = np.where(better[:, None], uv_new, uv)
        d = np.where(better[:, None, None, None], d_new, d)
        r = np.where(better[:, None], r_new, r)
        f = np.where(better, f_new, f)
        if np.max(np.abs(np.where(better[:, None], step, 0.0))) <= 1e-15 * max(u1 - u0, v1 - v0):
            break
    n = np.cross(d[:, 1, 0], d[:, 0, 1])
    sign = np.where(np.einsum("ij,ij->i", -r, n) >= 0, 1.0, -1.0)
    return uv, sign * np.sqrt(f)


# ----------------------------------------------------------------------------------------------
# the problem object used by _odr.solve
# ----------------------------------------------------------------------------------------------
class _SurfaceProblem:
    def __init__(self, x, p, q, U, V, nu, nv, rational, smoothing):
        self.x = x
        self.d = 3
        self.q = 2
        self.p, self.pq, self.U, self.V, self.nu, self.nv = p, q, U, V, nu, nv
        n = nu * nv
        self.n = n
        self.rational = rational
        self.M = 3 * n + (n if rational else 0)
        self.weight_slice = slice(3 * n, 4 * n) if rational else None
        # weight gauges: the overall scale, plus the rational (Moebius) reparametrisation of a
        # direction with a single knot span (a Bezier direction), absorbed by the foot points
        fixed = [0] + ([(nu - 1) * nv] if nu == p + 1 else []) + ([nv - 1] if nv == q + 1 else [])
        self.fixed = 3 * n + np.array(fixed if rational else [], dtype=np.int64)
        cu, cv = np.meshgrid(np.arange(nu - p), np.arange(nv - q), indexing="ij")
        cu, cv = cu.ravel(), cv.ravel()
        a, b = np.meshgrid(np.arange(p + 1), np.arange(q + 1), indexing="ij")
        j = (cu[:, None] + a.ravel()[None, :]) * nv + (cv[:, None] + b.ravel()[None, :])  # (C, L)
        idx = (j[:, :, None] * 3 + np.arange(3)).reshape(j.shape[0], -1)
        if rational:
            idx = np.hstack([idx, 3 * n + j])
        self.idx_cell = np.ascontiguousarray(idx)
        self.smoothing = float(smoothing)
        if smoothing > 0:
            Du = scipy.sparse.kron(_second_difference(nu), scipy.sparse.eye(nv))
            Dv = scipy.sparse.kron(scipy.sparse.eye(nu), _second_difference(nv))
            self.R = (Du.T @ Du + Dv.T @ Dv).tocsr()
            S = smoothing * scipy.sparse.kron(self.R, scipy.sparse.eye(3))
            pad = self.M - 3 * n
            self.penalty = (scipy.sparse.block_diag([S, scipy.sparse.csr_matrix((pad, pad))])
                            if pad else S).tocsr()
        else:
            self.R = None
            self.penalty = None
        self.lo = np.array([U[p], V[q]], np.float64)
        self.hi = np.array([U[nu], V[nv]], np.float64)
        self.slide = None                # the sliding prior, installed by _slide.Slide

    def unpack(self, theta):
        n = self.n
        P = theta[:3 * n].reshape(self.nu, self.nv, 3)
        w = theta[3 * n:].reshape(self.nu, self.nv) if self.rational else None
        return P, w

    def pack(self, P, w):
        P = np.asarray(P).reshape(-1)
        return np.concatenate([P, np.asarray(w).reshape(-1)]) if self.rational else P.copy()

    def clip(self, uv):
        return np.clip(uv, self.lo, self.hi)

    def surface(self, theta) -> NurbsSurface:
        P, w = self.unpack(theta)
        return NurbsSurface(self.p, self.pq, self.U, self.V, P, None if w is None else w.copy())

    def _spans(self, uv, nd):
        su, Bu = _basis(self.p, self.U, self.nu, np.ascontiguousarray(uv[:, 0]), nd)
        sv, Bv = _basis(self.pq, self.V, self.nv, np.ascontiguousarray(uv[:, 1]), nd)
        return su, Bu, sv, Bv

    def local(self, uv, nd):
        p, q, nv = self.p, self.pq, self.nv
        su, Bu, sv, Bv = self._spans(uv, nd)
        N = uv.shape[0]
        B = {}
        for k in range(nd + 1):
            for l in range(nd + 1 - k):
                B[(k, l)] = (Bu[:, k, :, None] * Bv[:, l, None, :]).reshape(N, -1)
        a, b = np.meshgrid(np.arange(p + 1), np.arange(q + 1), indexing="ij")
        j = (su[:, None] - p + a.ravel()) * nv + (sv[:, None] - q + b.ravel())
        cell = (su - p) * (nv - q) + (sv - q)
        return B, j, cell

    def project(self, theta, uv):
        return project_to_surface(self.surface(theta), self.x, uv, iterations=2)[0]

    def design(self, uv, w):
        B, j, _ = self.local(uv, 0)
        vals = B[(0, 0)]
        if w is not None:
            vals = vals * w.reshape(-1)[j]
            vals = vals / vals.sum(axis=1, keepdims=True)
        rows = np.repeat(np.arange(uv.shape[0]), j.shape[1])
        return scipy.sparse.csr_matrix((vals.ravel(), (rows, j.ravel())), shape=(uv.shape[0], self.n))

    def linear_control(self, uv, w):
        Phi = self.design(uv, w)
        G = (Phi.T @ Phi).tocsr()
        if self.R is not None:
            G = G + self.smoothing * self.R
        if self.slide is not None:
            return _slide.coupled_control(self, G, Phi.T @ self.x, _solve_spd,
                                          "fit_surface").reshape(self.nu, self.nv, 3)
        return _solve_spd(G, Phi.T @ self.x, "fit_surface").reshape(self.nu, self.nv, 3)

    def relinearise(self, theta, uv):
        _, w = self.unpack(theta)
        return self.pack(self.linear_control(uv, w), w)


# ----------------------------------------------------------------------------------------------
# public entry point
# ----------------------------------------------------------------------------------------------
def _pair(value, name):
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return int(value), int(value)
    try:
        a, b = value
    except (TypeError, ValueError):
        raise ValueError(f"fit_surface: {name} must be an integer or a pair of integers, "
                         f"got {value!r}") from None
    for v in (a, b):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            raise ValueError(f"fit_surface: {name} must be integers, got {value!r}")
    return int(a), int(b)


def _knots(given, t, n_ctrl, degree, name):
    if given is None:
        return np.ascontiguousarray(approximation_knots(t, n_ctrl, degree))
    U = np.asarray(given, np.float64)
    if U.shape != (n_ctrl + degree + 1,):
        raise ValueError(f"fit_surface: {name} must have n + p + 1 = {n_ctrl + degree + 1} knots, "
                         f"got shape {U.shape}")
    if not np.all(np.isfinite(U)) or np.any(np.diff(U) < 0):
        raise ValueError(f"fit_surface: {name} must be finite and non-decreasing")
    if not (np.all(U[:degree + 1] == U[0]) and np.all(U[-degree - 1:] == U[-1])):
        raise ValueError(f"fit_surface: {name} must be clamped (first and last degree + 1 equal)")
    if t.min() < U[0] or t.max() > U[-1]:
        raise ValueError(f"fit_surface: params outside the domain [{U[0]}, {U[-1]}] of {name}")
    return np.ascontiguousarray(U)


@renamed_keywords(tolerance="rtol")
@grouped_keywords("solver", FitSolver)
def fit_surface(points, degrees=(3, 3), n_ctrl=(8, 8), rational: bool = False,
                method: str = "odr", knots=None, params=None, parametrization: str = "chord",
                smoothing: float = 0.0, solver: FitSolver = FitSolver()) -> SurfaceFit:
    """Fit a tensor-product B-spline / NURBS surface to points.

    Parameters
    ----------
    points : (ku, kv, 3) grid or (N, 3) scattered points, float64
    degrees : int or (int, int)
    n_ctrl : int or (int, int)
        Control net size (nu, nv), each > its degree.
    rational : bool
        Also fit the weights ("odr" / "varpro"; weight [0, 0] fixed to 1 as the gauge).
    method : {"odr", "varpro", "fixed"}
    knots : (U, V), optional
        Clamped knot vectors; default NURBS Book eqs. 9.68-9.69 on the initial parameters.
    params : (N, 2) float64, optional
        Initial (u, v) per point (row-major for a grid); default :func:`surface_params`.
    parametrization : {"chord", "centripetal"}   (grid input only)
    smoothing : float >= 0
        Adds ``smoothing * sum ||second differences of the control net along u and v||^2``;
        needed when parts of the parameter domain hold no points.
    solver : FitSolver
        ``max_iterations``, ``rtol``, ``second_order``, ``slide_stiffness``: as in
        :func:`shapeverify.fitting.fit_curve` (the loose keywords still work, with a
        DeprecationWarning).
    slide_stiffness : float >= 0
        As in :func:`shapeverify.fitting.fit_curve`: resistance of the control points to sliding
        along the surface (two tangent directions per control point); 0 gives plain ODR.

    Returns
    -------
    SurfaceFit (orthogonal ``rms``, ``max_error``, signed ``residuals`` for every method).

    Raises
    ------
    ValueError
        Wrong shape, NaN, too few points, bad degrees / n_ctrl / knots / params, or a singular
        least-squares system (too many control points for the data).

    Examples
    --------
    >>> import numpy as np
    >>> u, v = np.meshgrid(np.linspace(0, 1, 15), np.linspace(0, 1, 15), indexing="ij")
    >>> grid = np.stack([u, v, 0.5 * u - v], axis=-1)
    >>> fit = fit_surface(grid, degrees=(2, 2), n_ctrl=(3, 3), method="fixed")
    >>> bool(fit.max_error < 1e-12)
    True
    """
    x = np.asarray(points, np.float64)
    grid = x.ndim == 3
    if not ((x.ndim == 2 and x.shape[1] == 3) or (grid and x.shape[2] == 3)):
        raise ValueError(f"fit_surface: points must have shape (N, 3) or (ku, kv, 3), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("fit_surface: points contain NaN or inf; remove them before fitting")
    max_iterations, rtol = solver.max_iterations, solver.rtol
    second_order, slide_stiffness = solver.second_order, solver.slide_stiffness
    _check_common(method, max_iterations, rtol, smoothing, parametrization, slide_stiffness)
    p, q = _pair(degrees, "degrees")
    nu, nv = _pair(n_ctrl, "n_ctrl")
    if p < 1 or q < 1:
        raise ValueError(f"fit_surface: degrees must be >= 1, got {(p, q)}")
    if nu <= p or nv <= q:
        raise ValueError(f"fit_surface: n_ctrl = {(nu, nv)} must exceed the degrees {(p, q)}")
    flat = x.reshape(-1, 3)
    N = flat.shape[0]
    if N < nu * nv:
        raise ValueError(f"fit_surface: {N} points cannot determine {nu} x {nv} = {nu * nv} control "
                         "points; use fewer control points")
    if grid and (x.shape[0] < nu or x.shape[1] < nv):
        raise ValueError(f"fit_surface: a {x.shape[0]} x {x.shape[1]} grid cannot determine "
                         f"{nu} x {nv} control points")
    if params is None:
        uv0 = surface_params(x, centripetal=parametrization == "centripetal")
    else:
        uv0 = np.asarray(params, np.float64)
        if uv0.shape != (N, 2) or not np.all(np.isfinite(uv0)):
            raise ValueError(f"fit_surface: params must be a finite ({N}, 2) array, got {uv0.shape}")
    if knots is None:
        ku = uv0[:, 0].reshape(x.shape[:2])[:, 0] if grid else uv0[:, 0]
        kv = uv0[:, 1].reshape(x.shape[:2])[0, :] if grid else uv0[:, 1]
        U = _knots(None, ku, nu, p, "knots U")
        V = _knots(None, kv, nv, q, "knots V")
    else:
        try:
            kU, kV = knots
        except (TypeError, ValueError):
            raise ValueError("fit_surface: knots must be a pair (U, V)") from None
        if params is None:                       # default parameters on the knots' domain
            kU, kV = np.asarray(kU, np.float64), np.asarray(kV, np.float64)
            if kU.ndim == 1 and kV.ndim == 1 and kU.size and kV.size:
                uv0 = np.column_stack([kU[0] + uv0[:, 0] * (kU[-1] - kU[0]),
                                       kV[0] + uv0[:, 1] * (kV[-1] - kV[0])])
        U = _knots(kU, uv0[:, 0], nu, p, "knots U")
        V = _knots(kV, uv0[:, 1], nv, q, "knots V")
    prob = _SurfaceProblem(flat, p, q, U, V, nu, nv, rational and method != "fixed", smoothing)
    if second_order is None:
        second_order = not prob.rational
    _check_coverage(prob, uv0)
    w0 = np.ones((nu, nv)) if prob.rational else None
    theta = prob.pack(prob.linear_control(uv0, w0), w0)
    if method == "fixed":
        surf = prob.surface(theta)
        uv, dist = project_to_surface(surf, flat, uv0)
        if rational:
            surf = NurbsSurface(p, q, U, V, surf.control, np.ones((nu, nv)))
        hist = np.array([_odr.cost_of(prob, theta, _odr.evaluate(prob, theta, uv0).r)])
        return _result(surf, uv, dist, 0, True, method, hist)
    uv, _ = project_to_surface(prob.surface(theta), flat, uv0)
    theta, uv, it, ok, hist = _slide.solve(prob, theta, uv, method, max_iterations, rtol,
                                           second_order, slide_stiffness)
    surf = prob.surface(theta)
    uv, dist = project_to_surface(surf, flat, uv, iterations=5)
    if not ok:
        logger.warning("fit_surface(%s) did not converge in %d iterations", method, it)
    return _result(surf, uv, dist, it, ok, method, hist)


def _check_coverage(prob, uv) -> None:
    if prob.smoothing > 0:
        return
    _, j, _ = prob.local(uv, 0)
    count = np.bincount(j.ravel(), minlength=prob.n)
    empty = np.flatnonzero(count == 0)
    if empty.size:
        ij = [divmod(int(k), prob.nv) for k in empty[:6]]
        raise ValueError(f"fit_surface: control point(s) {ij}{'...' if empty.size > 6 else ''} have no "
                         f"data in their support: n_ctrl = {(prob.nu, prob.nv)} is too large for the "
                         "data (or the points do not cover the parameter rectangle); use fewer "
                         "control points or smoothing > 0")


def _result(surf, uv, dist, it, ok, method, hist) -> SurfaceFit:
    return SurfaceFit(surf, uv, dist, float(np.sqrt(np.mean(dist ** 2))), float(np.abs(dist).max()),
                      int(it), bool(ok), method, hist)
