"""Least-squares geometric elements: line, plane, circle, sphere, cylinder, cone.

Every fit minimises the sum of squared *orthogonal* (geometric) distances from the points to
the element, as in ASME B89.4.10 / the NIST Algorithm Testing System.  Lines and planes have
closed-form solutions (principal axes of the centred points); circles, spheres, cylinders and
cones are solved by Levenberg-Marquardt on the geometric distances, started from an algebraic
fit (Pratt's circle/sphere fit, principal axes for the direction of a cylinder or cone).

Robust variants: ``loss="huber" | "tukey" | "cauchy" | "welsch"`` solves the M-estimation
problem by iteratively reweighted least squares (IRLS).  The residual scale is the MAD,
``1.4826 * median(|r|)``, re-estimated in every reweighting step unless ``scale`` is given;
the tuning constants give 95 % asymptotic efficiency at the normal distribution
(Huber 1.345, Tukey 4.685, Cauchy 2.385, Welsch 2.985).  Redescending losses (Tukey, Welsch,
Cauchy) start from a few Huber steps so that gross outliers cannot capture the start.

Units: those of the points (millimetres in this project).

References
----------
ASME B89.4.10-2000; NIST Algorithm Testing System (reference data in ``../shared/data/fitting/nist``).
V. Pratt, "Direct least-squares fitting of algebraic surfaces", SIGGRAPH 1987.
A. Forbes, "Least-squares best-fit geometric elements", NPL report DITC 140/89, 1989.
P. W. Holland and R. E. Welsch, "Robust regression using iteratively reweighted least-squares", 1977.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np
import scipy.linalg

logger = logging.getLogger(__name__)

__all__ = [
    "LineFit", "PlaneFit", "CircleFit", "SphereFit", "CylinderFit", "ConeFit",
    "fit_line", "fit_plane", "fit_circle", "fit_sphere", "fit_cylinder", "fit_cone",
    "robust_weights", "LOSSES",
]

#: tuning constants (95 % efficiency at the normal distribution), in units of the robust scale
LOSSES = {"l2": None, "huber": 1.345, "tukey": 4.685, "cauchy": 2.385, "welsch": 2.985}
_MAD_TO_SIGMA = 1.482602218505602


# ----------------------------------------------------------------------------------------------
# result objects
# ----------------------------------------------------------------------------------------------
def _fmt(value) -> str:
    if isinstance(value, np.ndarray):
        if value.size <= 3:
            return np.array2string(value, precision=6, separator=", ")
        return f"<{value.dtype} array {value.shape}>"
    if isinstance(value, float):
        return f"{value:.6g}"
    return repr(value)


class _Repr:
    def __repr__(self) -> str:
        parts = [f"{f.name}={_fmt(getattr(self, f.name))}" for f in dataclasses.fields(self)]
        return f"{type(self).__name__}({', '.join(parts)})"


@dataclass(frozen=True, repr=False)
class LineFit(_Repr):
    """Line ``point + s * direction``; ``residuals`` are (unsigned) distances to the line."""
    point: np.ndarray
    direction: np.ndarray
    rms: float
    residuals: np.ndarray
    weights: np.ndarray
    scale: float
    loss: str
    iterations: int
    converged: bool


@dataclass(frozen=True, repr=False)
class PlaneFit(_Repr):
    """Plane through ``point`` with unit ``normal``; ``residuals`` signed along the normal."""
    point: np.ndarray
    normal: np.ndarray
    rms: float
    residuals: np.ndarray
    weights: np.ndarray
    scale: float
    loss: str
    iterations: int
    converged: bool


@dataclass(frozen=True, repr=False)
class CircleFit(_Repr):
    """Circle: ``center`` (2,) or (3,), ``radius``; ``normal`` (3,) of its plane for 3-D data, else None.

    ``residuals``: signed radial distance (+ outside) in 2-D; unsigned distance to the circle in 3-D.
    """
    center: np.ndarray
    radius: float
    normal: np.ndarray | None
    rms: float
    residuals: np.ndarray
    weights: np.ndarray
    scale: float
    loss: str
    iterations: int
    converged: bool


@dataclass(frozen=True, repr=False)
class SphereFit(_Repr):
    """Sphere; ``residuals`` are signed distances (+ outside)."""
    center: np.ndarray
    radius: float
    rms: float
    residuals: np.ndarray
    weights: np.ndarray
    scale: float
    loss: str
    iterations: int
    converged: bool


@dataclass(frozen=True, repr=False)
class CylinderFit(_Repr):
    """Cylinder; ``point`` is the point of the axis closest to the centroid of the data."""
    point: np.ndarray
    axis: np.ndarray
    radius: float
    rms: float
    residuals: np.ndarray
    weights: np.ndarray
    scale: float
    loss: str
    iterations: int
    converged: bool


@dataclass(frozen=True, repr=False)
class ConeFit(_Repr):
    """Cone: radius ``radius`` at ``point`` (axis point closest to the centroid), opening towards ``axis``.

    The radius at axial position ``h`` (from ``point`` along ``axis``) is ``radius + h * tan(half_angle)``;
    ``half_angle`` is in radians, in [0, pi/2).  ``residuals`` are signed distances (+ outside).
    """
    point: np.ndarray
    axis: np.ndarray
    radius: float
    half_angle: float
    rms: float
    residuals: np.ndarray
    weights: np.ndarray
    scale: float
    loss: str
    iterations: int
    converged: bool

    @property
    def apex(self) -> np.ndarray:
        """(3,) the apex (infinite for a cylinder-like cone with half_angle == 0)."""
        t = np.tan(self.half_angle)
        if t == 0.0:
            return np.full(3, np.inf)
        return self.point - (self.radius / t) * self.axis


# ----------------------------------------------------------------------------------------------
# input checks and robust weights
# ----------------------------------------------------------------------------------------------
def _check_points(points, dims: tuple[int, ...], minimum: int, what: str) -> np.ndarray:
    x = np.asarray(points, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] not in dims:
        want = " or ".join(f"(N, {d})" for d in dims)
        raise ValueError(f"{what}: points must have shape {want}, got {x.shape}")
    if x.shape[0] < minimum:
        raise ValueError(f"{what}: needs at least {minimum} points, got {x.shape[0]}")
    if not np.all(np.isfinite(x)):
        bad = int(np.count_nonzero(~np.isfinite(x).all(axis=1)))
        raise ValueError(f"{what}: {bad} point(s) contain NaN or inf; remove them before fitting")
    return x


def _check_loss(loss: str, scale) -> None:
    if loss not in LOSSES:
        raise ValueError(f"unknown loss {loss!r}; choose one of {sorted(LOSSES)}")
    if scale is not None and not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a positive finite number or None, got {scale!r}")


def robust_weights(residuals: np.ndarray, loss: str, scale: float) -> np.ndarray:
    """IRLS weights ``w(r) = psi(r) / r`` of an M-estimator.

    Parameters
    ----------
    residuals : (N,) float64
    loss : {"l2", "huber", "tukey", "cauchy", "welsch"}
    scale : float
        Residual scale (e.g. ``1.4826 * median(|r|)``); the tuning constant multiplies it.

    Returns
    -------
    (N,) float64 weights in [0, 1].
    """
    c = LOSSES[loss]
    r = np.abs(np.asarray(residuals, np.float64))
    if c is None:
        return np.ones_like(r)
    u = r / (c * scale)
    if loss == "huber":
        return np.where(u <= 1.0, 1.0, 1.0 / np.maximum(u, 1.0))
    if loss == "tukey":
        return np.where(u < 1.0, (1.0 - u * u) ** 2, 0.0)
    if loss == "cauchy":
        return 1.0 / (1.0 + u * u)
    return np.exp(-u * u)  # welsch


def _mad_scale(residuals: np.ndarray, floor: float) -> float:
    return max(_MAD_TO_SIGMA * float(np.median(np.abs(residuals))), floor)


def _irls(solve, state, dist, loss, scale, n, floor, max_iterations, tol, robust_start=False):
    """Outer IRLS loop shared by all elements.

    solve(state, weights) -> (state, inner_converged, inner_iterations);
    dist(state) -> (N,) residuals used for weighting.  ``robust_start``: the start is already
    robust (LMedS), so reweighting starts from it instead of from the least-squares solution.
    Returns (state, weights, scale, iterations, converged).
    """
    w = np.ones(n)
    if loss == "l2":
        state, ok, iters = solve(state, w)
        return state, w, float("nan"), iters, ok
    total = 0
    if robust_start:
        stages = [loss]
    else:
        state, _, total = solve(state, w)
        stages = ["huber", loss] if loss in ("tukey", "welsch", "cauchy") else [loss]
    converged, s = False, float("nan")
    for stage in stages:
        converged = False
        for _ in range(max_iterations):
            r = dist(state)
            s = float(scale) if scale is not None else _mad_scale(r, floor)
            w_new = robust_weights(r, stage, s)
            if np.count_nonzero(w_new > 0) < 3:
                raise ValueError("robust fit: fewer than 3 points keep a non-zero weight; "
                                 "give a larger `scale` or use a softer loss")
            state, ok, iters = solve(state, w_new)
            total += iters
            change = float(np.max(np.abs(w_new - w)))
            w = w_new
            if change < tol:
                converged = ok
                break
    return state, w, s, total, converged


def _lmeds_hypersphere(x: np.ndarray, rng, n_subsets: int = 500, n_eval: int = 2000):
    """Least-median-of-squares start for a circle/sphere from random minimal subsets.

    Returns (center, radius, median |r|) of the best of ``n_subsets`` exact (d + 1)-point fits,
    judged on (at most) ``n_eval`` random points.  High breakdown point: up to half the points
    may be outliers.
    """
    n, d = x.shape
    idx = rng.integers(0, n, size=(n_subsets, d + 1))
    s = x[idx]                                           # (K, d+1, d)
    A = np.concatenate([2.0 * s, np.ones((n_subsets, d + 1, 1))], axis=2)
    b = np.einsum("kij,kij->ki", s, s)
    det = np.linalg.det(A)
    ext = float(np.max(np.ptp(x, axis=0))) or 1.0
    good = np.abs(det) > 1e-9 * ext ** d
    if not np.any(good):
        return None
    sol = np.linalg.solve(A[good], b[good][..., None])[..., 0]
    centers = sol[:, :d]
    r2 = sol[:, d] + np.einsum("ij,ij->i", centers, centers)
    ok = r2 > 0
    centers, radii = centers[ok], np.sqrt(r2[ok])
    if len(radii) == 0:
        return None
    ev = x if n <= n_eval else x[rng.choice(n, n_eval, replace=False)]
    res = np.abs(np.linalg.norm(ev[None, :, :] - centers[:, None, :], axis=2) - radii[:, None])
    med = np.median(res, axis=1)
    k = int(np.argmin(med))
    return centers[k], float(radii[k]), float(med[k])


def _lm(state, fun, retract, w, length, max_iterations=100, tol=1e-12):
    """Levenberg-Marquardt on the weighted sum of squares, with steps in a local chart.

    fun(state) -> (r (M,), J (M, k)): residuals and Jacobian w.r.t. the local step at ``state``.
    retract(state, step) -> new state.  ``w``: (M,) non-negative row weights.
    Returns (state, converged, iterations).
    """
    r, J = fun(state)
    sw = np.sqrt(w)
    cost = float(np.sum(w * r * r))
    lam = 1e-4
    for it in range(1, max_iterations + 1):
        A = sw[:, None] * J
        d = np.sqrt(np.maximum(np.einsum("ij,ij->j", A, A), 1e-300))
        while True:
            aug = np.vstack([A, np.diag(np.sqrt(lam) * d)])
            rhs = np.concatenate([-sw * r, np.zeros(J.shape[1])])
            step = np.linalg.lstsq(aug, rhs, rcond=None)[0]
            new = retract(state, step)
            r_new, J_new = fun(new)
            cost_new = float(np.sum(w * r_new * r_new))
            small = np.max(np.abs(step)) <= tol * (1.0 + length)
            if cost_new <= cost:
                state, r, J = new, r_new, J_new
                done = small or (cost - cost_new) <= 1e-15 * cost
                cost = cost_new
                lam = max(lam / 10.0, 1e-12)
                if done:
                    return state, True, it
                break
            if small or lam > 1e12:
                return state, True, it
            lam *= 10.0
    return state, False, max_iterations


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _perp_basis(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors orthogonal to unit ``a`` and to each other."""
    k = int(np.argmin(np.abs(a)))
    e = np.zeros(3)
    e[k] = 1.0
    u = _unit(np.cross(a, e))
    return u, np.cross(a, u)


# ----------------------------------------------------------------------------------------------
# line and plane (closed form, weighted principal axes)
# ----------------------------------------------------------------------------------------------
def _principal(x: np.ndarray, w: np.ndarray):
    c = (w @ x) / w.sum()
    _, _, vt = np.linalg.svd(np.sqrt(w)[:, None] * (x - c), full_matrices=False)
    return c, vt


def fit_line(points, loss: str = "l2", scale: float | None = None,
             max_iterations: int = 50, tolerance: float = 1e-10) -> LineFit:
    """Orthogonal-distance line through (N, 2) or (N, 3) points.

    Parameters
    ----------
    points : (N, 2) or (N, 3) float64, N >= 2
    loss, scale, max_iterations, tolerance : see module docstring (IRLS).

    Returns
    -------
    LineFit (``point`` is the weighted centroid, ``direction`` unit).

    Raises
    ------
    ValueError
        Wrong shape, fewer than 2 points, non-finite values, unknown loss.

    Examples
    --------
    >>> fit_line([[0, 0, 0], [1, 1, 1], [2, 2, 2]]).direction.round(6)
    array([0.57735, 0.57735, 0.57735])
    """
    x = _check_points(points, (2, 3), 2, "fit_line")
    _check_loss(loss, scale)
    floor = 1e-12 * (1.0 + float(np.ptp(x)))

    def solve(state, w):
        c, vt = _principal(x, w)
        return (c, vt[0]), True, 1

    def dist(state):
        c, a = state
        y = x - c
        return np.linalg.norm(y - np.outer(y @ a, a), axis=1)

    state, w, s, it, ok = _irls(solve, None, dist, loss, scale, len(x), floor, max_iterations, tolerance)
    c, a = state
    a = a if a[np.argmax(np.abs(a))] > 0 else -a
    r = dist((c, a))
    return LineFit(c, a, float(np.sqrt(np.mean(r * r))), r, w, s, loss, it, ok)


def fit_plane(points, loss: str = "l2", scale: float | None = None,
              max_iterations: int = 50, tolerance: float = 1e-10) -> PlaneFit:
    """Orthogonal-distance plane through (N, 3) points (N >= 3).

    Returns
    -------
    PlaneFit (``point`` the weighted centroid, ``normal`` unit, largest component positive).

    Raises
    ------
    ValueError
        Wrong shape, fewer than 3 points, non-finite values, unknown loss.

    Examples
    --------
    >>> fit_plane([[0, 0, 1], [1, 0, 1], [0, 1, 1], [1, 1, 1]]).normal
    array([0., 0., 1.])
    """
    x = _check_points(points, (3,), 3, "fit_plane")
    _check_loss(loss, scale)
    floor = 1e-12 * (1.0 + float(np.ptp(x)))

    def solve(state, w):
        c, vt = _principal(x, w)
        return (c, vt[2]), True, 1

    def dist(state):
        c, n = state
        return (x - c) @ n

    state, w, s, it, ok = _irls(solve, None, dist, loss, scale, len(x), floor, max_iterations, tolerance)
    c, n = state
    n = n if n[np.argmax(np.abs(n))] > 0 else -n
    n = n + 0.0  # no negative zeros
    r = dist((c, n))
    return PlaneFit(c, n, float(np.sqrt(np.mean(r * r))), r, w, s, loss, it, ok)


# ----------------------------------------------------------------------------------------------
# circle / sphere: Pratt start + LM on geometric distances
# ----------------------------------------------------------------------------------------------
def _pratt(x: np.ndarray) -> tuple[np.ndarray, float]:
    """Algebraic (Pratt) hypersphere fit of centred, scaled points x (N, d): (center, radius)."""
    n, d = x.shape
    Z = np.column_stack([np.einsum("ij,ij->i", x, x), x, np.ones(n)])
    M = Z.T @ Z / n
    B = np.zeros((d + 2, d + 2))
    B[1:d + 1, 1:d + 1] = np.eye(d)
    B[0, d + 1] = B[d + 1, 0] = -2.0
    vals, vecs = scipy.linalg.eig(M, B)
    vals = np.real(vals)
    ok = np.isfinite(vals) & (vals > -1e-10 * max(1.0, float(np.abs(M).max())))
    if not np.any(ok):
        raise ValueError("algebraic circle/sphere fit failed: points are degenerate (collinear or coplanar?)")
    k = np.flatnonzero(ok)[np.argmin(vals[ok])]
    A = np.real(vecs[:, k])
    a, b, c = A[0], A[1:d + 1], A[d + 1]
    if abs(a) < 1e-12 * np.linalg.norm(A):
        raise ValueError("points lie on a line/plane (infinite radius): no finite circle or sphere fits")
    center = -b / (2.0 * a)
    r2 = float(center @ center - c / a)
    return center, float(np.sqrt(max(r2, 0.0)))


def _fit_hypersphere(x, loss, scale, max_iterations, tolerance, what, rng):
    c0 = x.mean(axis=0)
    L = float(np.sqrt(np.mean(np.sum((x - c0) ** 2, axis=1)))) or 1.0
    y = x - c0
    center, radius = _pratt(y / L)
    state0 = np.concatenate([center * L, [radius * L]])
    robust_start = False
    if loss != "l2":
        # one-sided gross outliers (stray scanner points) capture the least-squares start:
        # take the least-median start when it explains the bulk of the points better
        lm = _lmeds_hypersphere(y, np.random.default_rng(rng))
        med0 = float(np.median(np.abs(np.linalg.norm(y - state0[:-1], axis=1) - state0[-1])))
        if lm is not None and lm[2] < med0:
            state0 = np.concatenate([lm[0], [lm[1]]])
            robust_start = True
    d = x.shape[1]

    def fun(p):
        v = y - p[:d]
        rho = np.linalg.norm(v, axis=1)
        rho = np.where(rho > 0, rho, 1e-300)
        J = np.column_stack([-v / rho[:, None], -np.ones(len(v))])
        return rho - p[d], J

    def retract(p, step):
        return p + step

    def solve(p, w):
        return _lm(p, fun, retract, w, L, max_iterations, tolerance)

    def dist(p):
        return fun(p)[0]

    p, w, s, it, ok = _irls(solve, state0, dist, loss, scale, len(x), 1e-12 * L, max_iterations, 1e-10,
                            robust_start)
    if p[d] <= 0:
        raise ValueError(f"{what}: the fit degenerated to a non-positive radius")
    r = dist(p)
    return p[:d] + c0, float(p[d]), r, w, s, it, ok


def fit_sphere(points, loss: str = "l2", scale: float | None = None,
               max_iterations: int = 100, tolerance: float = 1e-12, rng=0) -> SphereFit:
    """Orthogonal-distance (geometric) sphere fit.

    Minimises ``sum_i rho(||x_i - c|| - R)`` with ``rho`` the chosen loss (least squares by
    default), starting from Pratt's algebraic fit.  The robust losses also try a
    least-median-of-squares start from random 4-point subsets and keep it when its median
    residual is smaller, so that up to about half the points may be gross outliers (stray
    points of a laser scan) without capturing the fit.

    Parameters
    ----------
    points : (N, 3) float64, N >= 4
    loss : {"l2", "huber", "tukey", "cauchy", "welsch"}
    scale : float, optional
        Fixed residual scale for the robust losses (default: MAD, re-estimated each step).
    max_iterations : int
        Per Levenberg-Marquardt solve and per IRLS stage.
    tolerance : float
        Relative step tolerance of the Levenberg-Marquardt solve.
    rng : None, int or numpy Generator
        Seed of the random subsets of the robust start (default 0: repeatable results).

    Returns
    -------
    SphereFit

    Raises
    ------
    ValueError
        Wrong shape, fewer than 4 points, non-finite values, coplanar points, unknown loss.

    Examples
    --------
    >>> import numpy as np
    >>> d = np.random.default_rng(0).normal(size=(50, 3))
    >>> d /= np.linalg.norm(d, axis=1, keepdims=True)
    >>> fit = fit_sphere(2.0 * d + [1, 2, 3])
    >>> fit.center.round(9), round(fit.radius, 9)
    (array([1., 2., 3.]), 2.0)
    """
    x = _check_points(points, (3,), 4, "fit_sphere")
    _check_loss(loss, scale)
    c, R, r, w, s, it, ok = _fit_hypersphere(x, loss, scale, max_iterations, tolerance, "fit_sphere", rng)
    return SphereFit(c, R, float(np.sqrt(np.mean(r * r))), r, w, s, loss, it, ok)


def fit_circle(points, loss: str = "l2", scale: float | None = None,
               max_iterations: int = 100, tolerance: float = 1e-12, rng=0) -> CircleFit:
    """Orthogonal-distance circle fit in 2-D or 3-D.

    In 2-D the distance is ``||x - c|| - R``.  In 3-D the circle has centre ``c``, unit plane
    normal ``n`` and radius ``R``; the distance of ``x`` is ``sqrt(h^2 + (rho - R)^2)`` with ``h``
    the height over the plane and ``rho`` the distance from the axis; the two components enter
    the least squares as separate residuals (smooth at zero distance).

    Parameters
    ----------
    points : (N, 2) or (N, 3) float64, N >= 3 (2-D) or N >= 4 (3-D)
    loss, scale, max_iterations, tolerance, rng : as in :func:`fit_sphere` (the least-median
        start is used in 2-D only).

    Returns
    -------
    CircleFit

    Raises
    ------
    ValueError
        Wrong shape, too few points, non-finite values, collinear points, unknown loss.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 2, 20)
    >>> fit = fit_circle(np.column_stack([1 + 3 * np.cos(t), -2 + 3 * np.sin(t)]))
    >>> fit.center.round(9), round(fit.radius, 9)
    (array([ 1., -2.]), 3.0)
    """
    x = _check_points(points, (2, 3), 3, "fit_circle")
    _check_loss(loss, scale)
    if x.shape[1] == 2:
        c, R, r, w, s, it, ok = _fit_hypersphere(x, loss, scale, max_iterations, tolerance, "fit_circle", rng)
        return CircleFit(c, R, None, float(np.sqrt(np.mean(r * r))), r, w, s, loss, it, ok)
    if len(x) < 4:
        raise ValueError(f"fit_circle: a 3-D circle needs at least 4 points, got {len(x)}")
    c0 = x.mean(axis=0)
    y = x - c0
    L = float(np.sqrt(np.mean(np.sum(y * y, axis=1)))) or 1.0
    _, _, vt = np.linalg.svd(y, full_matrices=False)
    u, v, n0 = vt
    center2, radius = _pratt(np.column_stack([y @ u, y @ v]) / L)
    state0 = (L * (center2[0] * u + center2[1] * v), n0, L * radius)

    def parts(st):
        c, n, R = st
        z = y - c
        h = z @ n
        q = z - np.outer(h, n)
        rho = np.linalg.norm(q, axis=1)
        return z, h, q, np.where(rho > 0, rho, 1e-300)

    def fun(st):
        c, n, R = st
        _, h, q, rho = parts(st)
        e = q / rho[:, None]
        a, b = _perp_basis(n)
        m = len(y)
        J = np.zeros((2 * m, 6))
        # residual 1: h = (x - c).n ; residual 2: rho - R
        J[:m, 0:3] = -n
        J[:m, 3] = q @ a           # d h / d(n += eps a)
        J[:m, 4] = q @ b
        J[m:, 0:3] = -e + np.outer(e @ n, n)  # -e (e is orthogonal to n)
        J[m:, 3] = -h * (e @ a)
        J[m:, 4] = -h * (e @ b)
        J[m:, 5] = -1.0
        return np.concatenate([h, rho - R]), J

    def retract(st, step):
        c, n, R = st
        a, b = _perp_basis(n)
        return c + step[:3], _unit(n + step[3] * a + step[4] * b), R + step[5]

    def solve(st, w):
        return _lm(st, fun, retract, np.concatenate([w, w]), L, max_iterations, tolerance)

    def dist(st):
        _, h, _, rho = parts(st)
        return np.hypot(h, rho - st[2])

    st, w, s, it, ok = _irls(solve, state0, dist, loss, scale, len(x), 1e-12 * L, max_iterations, 1e-10)
    c, n, R = st
    n = n if n[np.argmax(np.abs(n))] > 0 else -n
    r = dist(st)
    return CircleFit(c + c0, float(R), n, float(np.sqrt(np.mean(r * r))), r, w, s, loss, it, ok)


# ----------------------------------------------------------------------------------------------
# cylinder and cone: LM in a local chart around the current axis
# ----------------------------------------------------------------------------------------------
def _axis_starts(y: np.ndarray, axis) -> list[np.ndarray]:
    if axis is not None:
        a = np.asarray(axis, np.float64)
        if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) == 0:
            raise ValueError(f"axis hint must be a finite non-zero (3,) vector, got {axis!r}")
        return [_unit(a)]
    _, _, vt = np.linalg.svd(y, full_matrices=False)
    return [vt[0], vt[1], vt[2]]


def _axial(y, p, a):
    z = y - p
    h = z @ a
    q = z - np.outer(h, a)
    rho = np.linalg.norm(q, axis=1)
    rho = np.where(rho > 0, rho, 1e-300)
    return h, q / rho[:, None], rho


def _recentre(p, a):
    """Move p along the axis to the point closest to the origin (= the data centroid)."""
    return p - (p @ a) * a


def _fit_axial(x, loss, scale, axis, max_iterations, tolerance, kind):
    c0 = x.mean(axis=0)
    y = x - c0
    L = float(np.sqrt(np.mean(np.sum(y * y, axis=1)))) or 1.0
    ncol = 5 if kind == "cylinder" else 6

    def fun(st):
        p, a, R = st[0], st[1], st[2]
        h, e, rho = _axial(y, p, a)
        u, v = _perp_basis(a)
        eu, ev = e @ u, e @ v
        J = np.empty((len(y), ncol))
        if kind == "cylinder":
            J[:, 0], J[:, 1] = -eu, -ev
            J[:, 2], J[:, 3] = -h * eu, -h * ev
            J[:, 4] = -1.0
            return rho - R, J
        psi = st[3]
        cs, sn = np.cos(psi), np.sin(psi)
        k = h * cs + rho * sn
        J[:, 0], J[:, 1] = -cs * eu, -cs * ev
        J[:, 2], J[:, 3] = -k * eu, -k * ev
        J[:, 4] = -cs
        J[:, 5] = -(rho - R) * sn - h * cs
        return (rho - R) * cs - h * sn, J

    def retract(st, step):
        p, a = st[0], st[1]
        u, v = _perp_basis(a)
        a_new = _unit(a + step[2] * u + step[3] * v)
        p_new = p + step[0] * u + step[1] * v
        if kind == "cone":
            # keep the surface fixed when sliding p to the new centroid-closest axis point
            s = -(p_new @ a_new)
            R = st[2] + step[4] + s * np.tan(st[3] + step[5])
            return (p_new + s * a_new, a_new, R, st[3] + step[5])
        return (_recentre(p_new, a_new), a_new, st[2] + step[4])

    def solve(st, w):
        return _lm(st, fun, retract, w, L, max_iterations, tolerance)

    def dist(st):
        return fun(st)[0]

    best = None
    for a0 in _axis_starts(y, axis):
        u, v = _perp_basis(a0)
        try:
            c2, r2 = _pratt(np.column_stack([y @ u, y @ v]) / L)
        except ValueError:
            continue
        p0 = L * (c2[0] * u + c2[1] * v)
        if kind == "cylinder":
            st0 = (p0, a0, L * r2)
        else:
            h, _, rho = _axial(y, p0, a0)
            slope, icpt = np.polyfit(h, rho, 1)
            st0 = (p0, a0, float(icpt), float(np.arctan(slope)))
        try:
            res = _irls(solve, st0, dist, loss, scale, len(x), 1e-12 * L, max_iterations, 1e-10)
        except (ValueError, np.linalg.LinAlgError) as exc:
            logger.debug("%s start %s failed: %s", kind, a0, exc)
            continue
        r = dist(res[0])
        cost = float(np.sum(res[1] * r * r)) / max(float(np.sum(res[1])), 1e-300)
        if best is None or cost < best[0]:
            best = (cost, res)
    if best is None:
        raise ValueError(f"fit_{kind}: no start converged; the points do not describe a {kind}")
    st, w, s, it, ok = best[1]
    p, a = st[0], st[1]
    extra = list(st[2:])
    if kind == "cone" and extra[1] < 0:
        a, extra[1] = -a, -extra[1]
    elif a[np.argmax(np.abs(a))] < 0:
        a = -a
    r = dist(st)
    return p + c0, a, extra, r, w, s, it, ok


def fit_cylinder(points, loss: str = "l2", scale: float | None = None, axis=None,
                 max_iterations: int = 100, tolerance: float = 1e-12) -> CylinderFit:
    """Orthogonal-distance cylinder fit (5 parameters: axis line and radius).

    The distance of ``x`` is ``||(x - p) - ((x - p).a) a|| - R``.  Levenberg-Marquardt runs in a
    local chart around the current axis (steps of the axis point and direction orthogonal to the
    axis), started from each principal direction of the points (or from the ``axis`` hint), with a
    Pratt circle fit of the projected points; the best converged start wins.

    Parameters
    ----------
    points : (N, 3) float64, N >= 5
    loss, scale, max_iterations, tolerance : as in :func:`fit_sphere`.
    axis : (3,) array_like, optional
        Approximate axis direction, used as the only start when given.

    Returns
    -------
    CylinderFit (``point`` on the axis closest to the centroid of the points, ``axis`` unit).

    Raises
    ------
    ValueError
        Wrong shape, too few points, non-finite values, unknown loss, no start converged.
    """
    x = _check_points(points, (3,), 5, "fit_cylinder")
    _check_loss(loss, scale)
    p, a, (R,), r, w, s, it, ok = _fit_axial(x, loss, scale, axis, max_iterations, tolerance, "cylinder")
    if R <= 0:
        raise ValueError("fit_cylinder: the fit degenerated to a non-positive radius")
    return CylinderFit(p, a, float(R), float(np.sqrt(np.mean(r * r))), r, w, s, loss, it, ok)


def fit_cone(points, loss: str = "l2", scale: float | None = None, axis=None,
             max_iterations: int = 100, tolerance: float = 1e-12) -> ConeFit:
    """Orthogonal-distance cone fit (6 parameters: axis line, radius at the axis point, half-angle).

    The signed distance of ``x`` from the cone is ``(rho - R) cos(psi) - h sin(psi)`` with ``h``
    the axial position of ``x`` from the axis point, ``rho`` its distance from the axis, ``R`` the
    radius at the axis point and ``psi`` the half-angle (exact for points on the side of the apex
    the surface lies on).  Starts as in :func:`fit_cylinder`, with a line fit of ``rho`` against ``h``.

    Parameters
    ----------
    points : (N, 3) float64, N >= 6
    loss, scale, axis, max_iterations, tolerance : as in :func:`fit_cylinder`.

    Returns
    -------
    ConeFit

    Raises
    ------
    ValueError
        Wrong shape, too few points, non-finite values, unknown loss, no start converged.
    """
    x = _check_points(points, (3,), 6, "fit_cone")
    _check_loss(loss, scale)
    p, a, (R, psi), r, w, s, it, ok = _fit_axial(x, loss, scale, axis, max_iterations, tolerance, "cone")
    return ConeFit(p, a, float(R), float(psi), float(np.sqrt(np.mean(r * r))), r, w, s, loss, it, ok)
