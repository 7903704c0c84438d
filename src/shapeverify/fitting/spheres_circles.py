"""Orthogonal-distance sphere and circle fits (2-D and 3-D circles).

Levenberg-Marquardt on the geometric distances, started from Pratt's algebraic fit; the robust
losses also try a least-median-of-squares start from random minimal subsets.  Holds
:class:`SphereFit`, :class:`CircleFit`, :func:`fit_sphere`, :func:`fit_circle` and the shared
hypersphere helpers (``_pratt`` is also the circle start of the cylinder and cone fits).

References
----------
V. Pratt, "Direct least-squares fitting of algebraic surfaces", SIGGRAPH 1987.
A. Forbes, "Least-squares best-fit geometric elements", NPL report DITC 140/89, 1989.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from .._random import generator
from .._renamed import renamed_keywords
from ._element_base import (_check_loss, _check_points, _ElementFit, _fit_stats, _irls, _lm,
                            _perp_basis, _unit)

__all__ = ["CircleFit", "SphereFit", "fit_circle", "fit_sphere"]


@dataclass(frozen=True, repr=False)
class CircleFit(_ElementFit):
    """Circle: ``center`` (2,) or (3,), ``radius``; ``normal`` (3,) of its plane for 3-D data, else None.

    ``residuals``: signed radial distance (+ outside) in 2-D; unsigned distance to the circle in 3-D.
    """
    center: np.ndarray
    radius: float
    normal: np.ndarray | None


@dataclass(frozen=True, repr=False)
class SphereFit(_ElementFit):
    """Sphere; ``residuals`` are signed distances (+ outside)."""
    center: np.ndarray
    radius: float


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
        lm = _lmeds_hypersphere(y, generator(rng))
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


@renamed_keywords(tolerance="rtol")
def fit_sphere(points, loss: str = "l2", scale: float | None = None,
               max_iterations: int = 100, rtol: float = 1e-12, rng=0) -> SphereFit:
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
    rtol : float
        Relative step tolerance of the Levenberg-Marquardt solve (``tolerance=``: its old
        name, a DeprecationWarning).
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
    x = _check_points(points, (3,), 4, "fit_sphere", spread=2)
    _check_loss(loss, scale)
    c, R, r, w, s, it, ok = _fit_hypersphere(x, loss, scale, max_iterations, rtol, "fit_sphere", rng)
    return SphereFit(c, R, **_fit_stats(r, w, s, loss, it, ok))


@renamed_keywords(tolerance="rtol")
def fit_circle(points, loss: str = "l2", scale: float | None = None,
               max_iterations: int = 100, rtol: float = 1e-12, rng=0) -> CircleFit:
    """Orthogonal-distance circle fit in 2-D or 3-D.

    In 2-D the distance is ``||x - c|| - R``.  In 3-D the circle has centre ``c``, unit plane
    normal ``n`` and radius ``R``; the distance of ``x`` is ``sqrt(h^2 + (rho - R)^2)`` with ``h``
    the height over the plane and ``rho`` the distance from the axis; the two components enter
    the least squares as separate residuals (smooth at zero distance).

    Parameters
    ----------
    points : (N, 2) or (N, 3) float64, N >= 3 (2-D) or N >= 4 (3-D)
    loss, scale, max_iterations, rtol, rng : as in :func:`fit_sphere` (the least-median
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
    x = _check_points(points, (2, 3), 3, "fit_circle", spread=2)
    _check_loss(loss, scale)
    if x.shape[1] == 2:
        c, R, r, w, s, it, ok = _fit_hypersphere(x, loss, scale, max_iterations, rtol, "fit_circle", rng)
        return CircleFit(c, R, None, **_fit_stats(r, w, s, loss, it, ok))
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
        return _lm(st, fun, retract, np.concatenate([w, w]), L, max_iterations, rtol)

    def dist(st):
        _, h, _, rho = parts(st)
        return np.hypot(h, rho - st[2])

    st, w, s, it, ok = _irls(solve, state0, dist, loss, scale, len(x), 1e-12 * L, max_iterations, 1e-10)
    c, n, R = st
    n = n if n[np.argmax(np.abs(n))] > 0 else -n
    r = dist(st)
    return CircleFit(c + c0, float(R), n, **_fit_stats(r, w, s, loss, it, ok))
