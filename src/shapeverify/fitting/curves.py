"""Least-squares NURBS curve fitting: fixed parameters, orthogonal distance (ODR), variable projection.

``fit_curve`` fits a (rational) B-spline curve to ordered points:

* ``method="fixed"``: linear least squares with chord-length or centripetal parameters and the
  knot placement of The NURBS Book eqs. (9.68)-(9.69) (algorithm A9.7's knots); the baseline.
* ``method="odr"``: Levenberg-Marquardt on control points (and weights when rational) plus the
  foot-point parameters, minimising orthogonal distances; the foot-point block is eliminated so
  each step solves only the control-point system (Paper VI).
* ``method="varpro"``: variable projection (Golub-Pereyra, Kaufman's simplification); the control
  points are projected out and recomputed by linear least squares after each step (Paper VII).

Both nonlinear methods minimise the same objective, so they reach the same optimum.  After each
trial step the foot points are moved to the orthogonal projections (two safeguarded Newton steps
per point), so every accepted iterate is judged by its orthogonal distances.

Convergence: the objective is nearly flat along "tangential" changes of the control points
(sliding them along the curve mostly reparametrises it), so in the last phase the iteration
converges linearly and can take tens to hundreds of iterations; ``method="varpro"`` usually needs
fewer.  Points are expected to be ordered along the curve (for the initial parameters).

References
----------
Piegl & Tiller, The NURBS Book, 2nd ed., sections 9.2.1 (parameters), 9.4.1 (A9.7, eqs. 9.63-9.69).
Bergström (2011), thesis ch. 10-12, Papers VI and VII.
G. Golub and V. Pereyra, "Separable nonlinear least squares", Inverse Problems 19 (2003).
L. Kaufman, "A variable projection method for solving separable nonlinear least squares
problems", BIT 15 (1975).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse
import scipy.sparse.linalg

from .._renamed import grouped_keywords, renamed_keywords
from ..cad.nurbs import NurbsCurve
from . import _kernels, _odr, _slide
from ._element_base import _Repr

logger = logging.getLogger(__name__)

#: default of ``slide_stiffness`` (see _slide.py)
SLIDE_STIFFNESS = 100.0

__all__ = ["CurveFit", "FitSolver", "fit_curve", "chord_length_params", "approximation_knots", "uniform_knots",
           "project_to_curve"]

METHODS = ("fixed", "odr", "varpro")


@dataclass(frozen=True, repr=False)
class CurveFit(_Repr):
    """Result of :func:`fit_curve`.

    Attributes
    ----------
    curve : NurbsCurve
    params : (N,) float64 foot-point parameters (orthogonal projections of the points)
    residuals : (N,) float64 orthogonal distances of the points from the curve
    rms, max_error : float  root-mean-square and largest orthogonal distance
    iterations : int   Levenberg-Marquardt iterations (0 for ``method="fixed"``)
    converged : bool
    method : str
    history : (iterations + 1,) float64 objective value per accepted iterate
    """
    curve: NurbsCurve
    params: np.ndarray
    residuals: np.ndarray
    rms: float
    max_error: float
    iterations: int
    converged: bool
    method: str
    history: np.ndarray


# ----------------------------------------------------------------------------------------------
# parameters and knots
# ----------------------------------------------------------------------------------------------
def chord_length_params(points, centripetal: bool = False) -> np.ndarray:
    """Chord-length (or centripetal) parameters in [0, 1] of ordered points (NURBS Book 9.2.1).

    Parameters
    ----------
    points : (N, d) float64, ordered along the curve
    centripetal : bool
        Use the square roots of the chord lengths (Lee's centripetal method).

    Returns
    -------
    (N,) float64, non-decreasing, 0 first and 1 last.

    Raises
    ------
    ValueError
        All points coincide.

    Examples
    --------
    >>> chord_length_params([[0, 0], [1, 0], [3, 0]])
    array([0.        , 0.33333333, 1.        ])
    """
    x = np.asarray(points, np.float64)
    d = np.linalg.norm(np.diff(x, axis=0), axis=1)
    if centripetal:
        d = np.sqrt(d)
    total = d.sum()
    if not total > 0:
        raise ValueError("all points coincide: no parameters can be assigned")
    t = np.concatenate([[0.0], np.cumsum(d) / total])
    t[-1] = 1.0
    return t


def uniform_knots(n_ctrl: int, degree: int) -> np.ndarray:
    """Clamped uniform knot vector on [0, 1] for ``n_ctrl`` control points."""
    inner = np.linspace(0.0, 1.0, n_ctrl - degree + 1)[1:-1]
    return np.concatenate([np.zeros(degree + 1), inner, np.ones(degree + 1)])


def approximation_knots(params, n_ctrl: int, degree: int) -> np.ndarray:
    """Clamped knots for least-squares approximation (The NURBS Book eqs. 9.68-9.69).

    ``d = (m + 1) / (n - p + 1)``; interior knot ``u_{p+j} = (1 - a) t_{i-1} + a t_i`` with
    ``i = int(j d)``, ``a = j d - i``, so that every knot span holds parameters.

    Parameters
    ----------
    params : (N,) float64 sorted parameters (N >= n_ctrl)
    n_ctrl : int number of control points (> degree)
    degree : int

    Returns
    -------
    (n_ctrl + degree + 1,) float64 knots, clamped to [params[0], params[-1]].
    """
    t = np.sort(np.asarray(params, np.float64))
    m1 = t.shape[0]                      # m + 1 parameters
    n = n_ctrl - 1
    p = degree
    d = m1 / (n - p + 1)
    inner = np.empty(n - p)
    for j in range(1, n - p + 1):
        i = int(j * d)
        a = j * d - i
        inner[j - 1] = (1.0 - a) * t[i - 1] + a * t[i]
    return np.concatenate([np.full(p + 1, t[0]), inner, np.full(p + 1, t[-1])])


# ----------------------------------------------------------------------------------------------
# basis, linear least squares, foot points
# ----------------------------------------------------------------------------------------------
def _basis(p: int, U: np.ndarray, n: int, t: np.ndarray, nd: int):
    spans = np.empty(t.shape[0], np.int64)
    B = np.empty((t.shape[0], nd + 1, p + 1))
    _kernels.basis_ders(p, U, n - 1, np.ascontiguousarray(t), nd, spans, B)
    return spans, B


def _second_difference(n: int) -> scipy.sparse.csr_matrix:
    if n < 3:
        return scipy.sparse.csr_matrix((0, n))
    return scipy.sparse.diags([1.0, -2.0, 1.0], [0, 1, 2], shape=(n - 2, n)).tocsr()


def _solve_spd(G, rhs, what: str):
    """Solve the symmetric positive definite system G X = rhs (sparse G), ValueError if singular."""
    n = G.shape[0]
    if n <= 3000:
        Gd = G.toarray() if scipy.sparse.issparse(G) else G
        try:
            cf = scipy.linalg.cho_factor(Gd, check_finite=False)
        except np.linalg.LinAlgError:
            raise ValueError(f"{what}: the least-squares system is singular: too many control points "
                             "for the data (some have no points in their support); use fewer "
                             "control points or smoothing > 0") from None
        dL = np.abs(np.diag(cf[0]))
        if dL.min() ** 2 < 1e-14 * dL.max() ** 2:
            raise ValueError(f"{what}: the least-squares system is numerically singular: too many "
                             "control points for the data; use fewer control points or smoothing > 0")
        X = scipy.linalg.cho_solve(cf, rhs, check_finite=False)
        return X
    lu = scipy.sparse.linalg.splu(G.tocsc())
    X = lu.solve(np.asarray(rhs))
    if not np.all(np.isfinite(X)):
        raise ValueError(f"{what}: the least-squares system is singular; use fewer control "
                         "points or smoothing > 0")
    return X


def project_to_curve(curve: NurbsCurve, points, t0, iterations: int = 30):
    """Foot points of ``points`` on ``curve`` by safeguarded Newton iteration from ``t0``.

    Parameters
    ----------
    curve : NurbsCurve
    points : (N, d) float64
    t0 : (N,) float64 start parameters (e.g. the fitting parameters)

    Returns
    -------
    t : (N,) float64 parameters (clamped to the domain); dist : (N,) float64 distances.
    """
    x = np.asarray(points, np.float64)
    lo, hi = curve.domain
    t = np.clip(np.asarray(t0, np.float64), lo, hi)
    d = curve.derivatives(t, 2)
    r = d[:, 0] - x
    f = np.einsum("ij,ij->i", r, r)
    for _ in range(iterations):
        g = np.einsum("ij,ij->i", r, d[:, 1])
        h = np.einsum("ij,ij->i", d[:, 1], d[:, 1]) + np.einsum("ij,ij->i", r, d[:, 2])
        gn = np.einsum("ij,ij->i", d[:, 1], d[:, 1])
        h = np.where(h > 0.1 * gn, h, gn)
        step = -g / np.maximum(h, 1e-300)
        t_new = np.clip(t + step, lo, hi)
        d_new = curve.derivatives(t_new, 2)
        r_new = d_new[:, 0] - x
        f_new = np.einsum("ij,ij->i", r_new, r_new)
        better = f_new < f
        if not better.any():
            break
        t = np.where(better, t_new, t)
        d = np.where(better[:, None, None], d_new, d)
        r = np.where(better[:, None], r_new, r)
        f = np.where(better, f_new, f)
        if np.max(np.abs(np.where(better, step, 0.0))) <= 1e-15 * (hi - lo):
            break
    return t, np.sqrt(f)


# ----------------------------------------------------------------------------------------------
# the problem object used by _odr.solve
# ----------------------------------------------------------------------------------------------
class _CurveProblem:
    def __init__(self, x, p, U, n, rational, smoothing):
        self.x = x
        self.d = x.shape[1]
        self.q = 1
        self.p, self.U, self.n = p, U, n
        self.rational = rational
        d = self.d
        self.M = n * d + (n if rational else 0)
        self.weight_slice = slice(n * d, n * d + n) if rational else None
        # weight gauges: the overall scale, and for a single-span (Bezier) curve also the rational
        # (Moebius) reparametrisation, which the foot points absorb
        fixed = [0, n - 1] if n == p + 1 else [0]
        self.fixed = n * d + np.array(fixed if rational else [], dtype=np.int64)
        C = n - p
        j = np.arange(C)[:, None] + np.arange(p + 1)[None, :]              # (C, p+1)
        idx = (j[:, :, None] * d + np.arange(d)).reshape(C, -1)
        if rational:
            idx = np.hstack([idx, n * d + j])
        self.idx_cell = np.ascontiguousarray(idx)
        self.D2 = _second_difference(n)
        self.smoothing = float(smoothing)
        if smoothing > 0:
            S = smoothing * scipy.sparse.kron(self.D2.T @ self.D2, scipy.sparse.eye(d))
            pad = self.M - n * d
            self.penalty = scipy.sparse.block_diag([S, scipy.sparse.csr_matrix((pad, pad))]).tocsr() \
                if pad else S.tocsr()
        else:
            self.penalty = None
        self.lo, self.hi = float(U[p]), float(U[n])
        self.slide = None                # the sliding prior, installed by _slide.Slide

    def unpack(self, theta):
        n, d = self.n, self.d
        P = theta[:n * d].reshape(n, d)
        w = theta[n * d:] if self.rational else None
        return P, w

    def pack(self, P, w):
        return np.concatenate([P.ravel(), w]) if self.rational else P.ravel().copy()

    def clip(self, t):
        return np.clip(t, self.lo, self.hi)

    def curve(self, theta) -> NurbsCurve:
        P, w = self.unpack(theta)
        return NurbsCurve(self.p, self.U, P, None if w is None else w.copy())

    def local(self, t, nd):
        """Basis derivatives of the p + 1 control points acting on each parameter (for _odr)."""
        spans, B = _basis(self.p, self.U, self.n, t, nd)
        j = spans[:, None] - self.p + np.arange(self.p + 1)
        return {(k,): B[:, k] for k in range(nd + 1)}, j, spans - self.p

    def project(self, theta, t):
        return project_to_curve(self.curve(theta), self.x, t, iterations=2)[0]

    def design(self, t, w):
        """Sparse (N, n) (rational) basis matrix at parameters t with weights w."""
        p = self.p
        spans, B = _basis(p, self.U, self.n, t, 0)
        j = spans[:, None] - p + np.arange(p + 1)
        vals = B[:, 0] if w is None else B[:, 0] * w[j]
        if w is not None:
            vals = vals / vals.sum(axis=1, keepdims=True)
        rows = np.repeat(np.arange(t.shape[0]), p + 1)
        return scipy.sparse.csr_matrix((vals.ravel(), (rows, j.ravel())), shape=(t.shape[0], self.n))

    def linear_control(self, t, w):
        Phi = self.design(t, w)
        G = (Phi.T @ Phi).tocsr()
        if self.smoothing > 0:
            G = G + self.smoothing * (self.D2.T @ self.D2)
        if self.slide is not None:
            return _slide.coupled_control(self, G, Phi.T @ self.x, _solve_spd, "fit_curve")
        return _solve_spd(G, Phi.T @ self.x, "fit_curve")

    def relinearise(self, theta, t):
        _, w = self.unpack(theta)
        return self.pack(self.linear_control(t, w), w)


# ----------------------------------------------------------------------------------------------
# public entry point
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FitSolver:
    """How :func:`fit_curve` and :func:`~shapeverify.fitting.fit_surface` iterate (their
    ``solver=``; the loose keywords of the same names still work, with a DeprecationWarning).

    Attributes
    ----------
    max_iterations : int
    rtol : float
        Stop when an iteration decreases the objective by less than ``rtol`` times its value.
    second_order : bool, optional
        Include the foot-point curvature terms in the Levenberg-Marquardt matrix (see
        :func:`fit_curve`); default: True for polynomial, False for rational fits.
    slide_stiffness : float >= 0
        ``odr`` / ``varpro``: resistance of the control points to sliding along the curve or
        surface (see :func:`fit_curve`); 0 gives the plain ODR objective.

    >>> FitSolver(rtol=1e-8)
    FitSolver(max_iterations=100, rtol=1e-08, second_order=None, slide_stiffness=100.0)
    """

    max_iterations: int = 100
    rtol: float = 1e-10
    second_order: bool | None = None
    slide_stiffness: float = SLIDE_STIFFNESS


def _check_common(method, max_iterations, tolerance, smoothing, parametrization, slide_stiffness=0.0):
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of {METHODS}")
    if parametrization not in ("chord", "centripetal"):
        raise ValueError(f"parametrization must be 'chord' or 'centripetal', got {parametrization!r}")
    if not (isinstance(max_iterations, (int, np.integer)) and max_iterations >= 1):
        raise ValueError(f"max_iterations must be an integer >= 1, got {max_iterations!r}")
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise ValueError(f"rtol must be a positive number, got {tolerance!r}")
    if not (np.isfinite(smoothing) and smoothing >= 0):
        raise ValueError(f"smoothing must be a finite number >= 0, got {smoothing!r}")
    if not (np.isfinite(slide_stiffness) and slide_stiffness >= 0):
        raise ValueError(f"slide_stiffness must be a finite number >= 0, got {slide_stiffness!r}")


@renamed_keywords(tolerance="rtol")
@grouped_keywords("solver", FitSolver)
def fit_curve(points, degree: int = 3, n_ctrl: int | None = None, rational: bool = False,
              method: str = "odr", knots=None, params=None, parametrization: str = "chord",
              smoothing: float = 0.0, solver: FitSolver = FitSolver()) -> CurveFit:
    """Fit a B-spline / NURBS curve to ordered points.

    Parameters
    ----------
    points : (N, d) float64, d in {2, 3}, ordered along the curve
    degree : int >= 1
    n_ctrl : int, optional
        Number of control points, ``degree < n_ctrl <= N`` (default ``min(N // 5, 50)``, at least
        ``degree + 1``).
    rational : bool
        Also fit the weights (``method`` "odr" or "varpro"; the first weight is fixed to 1 as the
        gauge).  With ``method="fixed"`` the weights stay 1.
    method : {"odr", "varpro", "fixed"}
    knots : (n_ctrl + degree + 1,) float64, optional
        Clamped knot vector; default :func:`approximation_knots` of the initial parameters.
    params : (N,) float64, optional
        Initial parameters in the knots' domain; default chord-length / centripetal, scaled to
        the knots' domain ([0, 1] without ``knots``).
    parametrization : {"chord", "centripetal"}
    smoothing : float >= 0
        Adds ``smoothing * sum_j ||P_{j-1} - 2 P_j + P_{j+1}||^2`` to the objective.
    solver : FitSolver
        The iteration's settings (``max_iterations``, ``rtol``, ``second_order``,
        ``slide_stiffness``; the loose keywords of these names still work, with a
        DeprecationWarning):

    max_iterations : int
    rtol : float
        Stop when an iteration decreases the objective by less than ``rtol`` times its value.
    slide_stiffness : float >= 0
        ``odr`` / ``varpro``: resistance of the control points to sliding along the curve, away
        from the fixed-parameter fit.  Sliding changes the shape only to second order, so the
        data hardly determine it; unchecked, the control points bunch up over hundreds of
        iterations and the curve folds to follow the noise.  A Gaussian prior on each control
        point's tangential drift, with standard deviation ``spacing / sqrt(slide_stiffness)``
        (default: a tenth of the mean control-point spacing) scaled by the noise, holds them;
        moves normal to the curve are free, and the prior shrinks with the residuals (exact data
        are still reproduced to rounding).  0 gives the plain ODR objective.
    second_order : bool, optional
        Include the foot-point curvature terms (``r . C''`` and ``r . dR/dt``) in the
        Levenberg-Marquardt matrix: exact Newton for a non-rational curve (Gauss-Newton for the
        weight-weight block of a rational one).  ``False`` gives the plain Gauss-Newton step of
        Paper VI.  Both converge to the same optimum; the Newton variant usually needs fewer
        iterations on noisy polynomial fits.  Default: True for polynomial, False for rational
        fits.

    Returns
    -------
    CurveFit
        ``rms``, ``max_error`` and ``residuals`` are orthogonal distances for every method (the
        points are projected onto the fitted curve).

    Raises
    ------
    ValueError
        Wrong shape, NaN, too few points, bad degree / n_ctrl / knots / params, or a
        least-squares system that is singular because of too many control points.

    References
    ----------
    The NURBS Book eqs. 9.63-9.69; Papers VI (ODR) and VII (variable projection).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 1, 200)
    >>> fit = fit_curve(np.column_stack([t, np.sin(3 * t)]), degree=3, n_ctrl=8, method="varpro")
    >>> fit.converged, bool(fit.max_error < 1e-4)
    (True, True)
    """
    x = np.asarray(points, np.float64)
    if x.ndim != 2 or x.shape[1] not in (2, 3):
        raise ValueError(f"fit_curve: points must have shape (N, 2) or (N, 3), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("fit_curve: points contain NaN or inf; remove them before fitting")
    max_iterations, rtol = solver.max_iterations, solver.rtol
    second_order, slide_stiffness = solver.second_order, solver.slide_stiffness
    _check_common(method, max_iterations, rtol, smoothing, parametrization, slide_stiffness)
    if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)) or degree < 1:
        raise ValueError(f"fit_curve: degree must be an integer >= 1, got {degree!r}")
    N = x.shape[0]
    if N < degree + 1:
        raise ValueError(f"fit_curve: a degree-{degree} curve needs at least {degree + 1} points, got {N}")
    if n_ctrl is None:
        n_ctrl = max(degree + 1, min(N // 5, 50))
    if isinstance(n_ctrl, bool) or not isinstance(n_ctrl, (int, np.integer)) or n_ctrl <= degree:
        raise ValueError(f"fit_curve: n_ctrl must be an integer > degree = {degree}, got {n_ctrl!r}")
    if n_ctrl > N:
        raise ValueError(f"fit_curve: n_ctrl = {n_ctrl} exceeds the number of points N = {N}; "
                         "use at most N control points (fewer for a smooth fit)")
    if params is None:
        t0 = chord_length_params(x, centripetal=parametrization == "centripetal")
    else:
        t0 = np.asarray(params, np.float64)
        if t0.shape != (N,) or not np.all(np.isfinite(t0)):
            raise ValueError(f"fit_curve: params must be a finite (N,) = ({N},) array, got shape {t0.shape}")
    if knots is None:
        U = approximation_knots(t0, n_ctrl, degree)
    else:
        U = np.asarray(knots, np.float64)
        NurbsCurve(degree, U, np.zeros((n_ctrl, x.shape[1])))   # validates count and order
        if not (np.all(U[:degree + 1] == U[0]) and np.all(U[-degree - 1:] == U[-1])):
            raise ValueError("fit_curve: knots must be clamped (first and last degree + 1 equal)")
        if params is None:                       # chord-length parameters on the knots' domain
            t0 = U[0] + t0 * (U[-1] - U[0])
        if t0.min() < U[0] or t0.max() > U[-1]:
            raise ValueError(f"fit_curve: params span [{t0.min()}, {t0.max()}] outside the knots' "
                             f"domain [{U[0]}, {U[-1]}]")
    U = np.ascontiguousarray(U)
    prob = _CurveProblem(x, degree, U, n_ctrl, rational and method != "fixed", smoothing)
    if second_order is None:
        second_order = not prob.rational
    _check_coverage(prob, t0)
    w0 = np.ones(n_ctrl) if prob.rational else None
    theta = prob.pack(prob.linear_control(t0, w0), w0)
    if method == "fixed":
        curve = prob.curve(theta)
        t, dist = project_to_curve(curve, x, t0)
        if rational:
            curve = NurbsCurve(degree, U, curve.control, np.ones(n_ctrl))
        hist = np.array([_odr.cost_of(prob, theta, _odr.evaluate(prob, theta, t0).r)])
        return _result(curve, t, dist, 0, True, method, hist)
    t, _ = project_to_curve(prob.curve(theta), x, t0)
    theta, t, it, ok, hist = _slide.solve(prob, theta, t, method, max_iterations, rtol,
                                          second_order, slide_stiffness)
    curve = prob.curve(theta)
    t, dist = project_to_curve(curve, x, t, iterations=5)
    if not ok:
        logger.warning("fit_curve(%s) did not converge in %d iterations", method, it)
    return _result(curve, t, dist, it, ok, method, hist)


def _check_coverage(prob, t) -> None:
    spans, _ = _basis(prob.p, prob.U, prob.n, t, 0)
    count = np.bincount((spans[:, None] - prob.p + np.arange(prob.p + 1)).ravel(), minlength=prob.n)
    empty = np.flatnonzero(count == 0)
    if empty.size and prob.smoothing == 0:
        raise ValueError(f"fit_curve: control point(s) {empty[:10].tolist()} have no data in their "
                         f"support: n_ctrl = {prob.n} is too large for the data (or the knots leave "
                         "spans without points); use fewer control points or smoothing > 0")


def _result(curve, t, dist, it, ok, method, hist) -> CurveFit:
    return CurveFit(curve, t, dist, float(np.sqrt(np.mean(dist ** 2))), float(dist.max()),
                    int(it), bool(ok), method, hist)
