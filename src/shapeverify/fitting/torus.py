"""Orthogonal-distance torus fit, and the torus of a CAD face.

The distance of ``x`` from the torus (centre ``c``, unit axis ``a``, major radius ``R`` -- the
spine circle's -- and minor radius ``r``) is ``sqrt((rho - R)^2 + h^2) - r``, with ``h = (x - c).a``
and ``rho`` the distance of ``x`` from the axis; positive outside the tube.  Levenberg-Marquardt
(:func:`._element_base._lm`) in a local chart: the centre moves freely, the axis turns in its
tangent plane.  The derivatives: by the centre ``-n`` (``n`` the unit normal from the spine to
the point), by a turn of the axis towards ``u`` ``h (x - c).u R / (rho s)`` (``s`` the distance
from the spine), by ``R`` ``-(rho - R) / s``, by ``r`` ``-1``.

A torus fit needs a start near the answer (a fillet's tube is a thin band of a torus, nearly a
cylinder or a cone locally): :func:`torus_of_surface` gives the one of a CAD face, from the
circles its surface's iso-parameter lines draw (a torus's are the tube's circles, all of radius
``r``, and the parallels, of radii ``R +- r cos``), the spine from the points moved ``r`` along
their normals, then the fit of the face's own points.

>>> import numpy as np
>>> t, p = np.meshgrid(np.linspace(0, 2 * np.pi, 40), np.linspace(0, np.pi / 2, 10))
>>> X = np.column_stack([((20 + 3 * np.cos(p)) * np.cos(t)).ravel(),
...                      ((20 + 3 * np.cos(p)) * np.sin(t)).ravel(), (3 * np.sin(p)).ravel()])
>>> f = fit_torus(X, start=((0.1, 0, 0.1), (0.01, 0, 1), 19.8, 3.2))
>>> round(f.major_radius, 9), round(f.minor_radius, 9)
(20.0, 3.0)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._element_base import (_check_loss, _check_points, _ElementFit, _fit_stats, _irls, _lm,
                            _perp_basis, _unit)
from .cylinders_cones import _axial
from .spheres_circles import _pratt

__all__ = ["TorusFit", "fit_torus", "torus_of_surface", "torus_jacobian"]


@dataclass(frozen=True, repr=False)
class TorusFit(_ElementFit):
    """Torus: ``center``, unit ``axis``, ``major_radius`` (the spine circle's), ``minor_radius``
    (the tube's); ``residuals`` are signed distances (+ outside the tube)."""
    center: np.ndarray
    axis: np.ndarray
    major_radius: float
    minor_radius: float


def torus_jacobian(points, center, axis, major_radius) -> tuple[np.ndarray, np.ndarray]:
    """(distances without the minor radius ``s``, (N, 7) Jacobian of the distance) at a torus:
    columns: the centre's x, y, z, the axis turned towards the two vectors of
    :func:`._element_base._perp_basis`, ``R``, ``r`` (module docstring)."""
    x = np.asarray(points, np.float64)
    a = _unit(np.asarray(axis, np.float64))
    c = np.asarray(center, np.float64)
    h, e, rho = _axial(x, c, a)
    q = x - c
    g = rho - major_radius
    s = np.sqrt(g * g + h * h)
    s = np.where(s > 0, s, 1e-300)
    n = (g[:, None] * e + h[:, None] * a) / s[:, None]
    u, v = _perp_basis(a)
    turn = h * major_radius / (rho * s)
    J = np.column_stack([-n, turn * (q @ u), turn * (q @ v), -g / s, -np.ones(len(x))])
    return s, J


def fit_torus(points, start, loss: str = "l2", scale: float | None = None,
              max_iterations: int = 100, rtol: float = 1e-12) -> TorusFit:
    """Orthogonal-distance torus fit (7 parameters) from a start near the answer.

    Parameters
    ----------
    points : (N, 3) float64, N >= 7
    start : (centre (3,), axis (3,), major radius, minor radius)
        E.g. the CAD's torus (:func:`torus_of_surface`) or a :class:`TorusFit`.
    loss, scale, max_iterations, rtol : as in :func:`shapeverify.fitting.fit_sphere`.

    Returns
    -------
    TorusFit

    Raises
    ------
    ValueError
        Wrong shape, too few points, non-finite values, unknown loss, a start that is not a
        torus (radii not positive and finite), or a fit that degenerates.
    """
    x = _check_points(points, (3,), 7, "fit_torus", spread=2)
    _check_loss(loss, scale)
    if isinstance(start, TorusFit):
        start = (start.center, start.axis, start.major_radius, start.minor_radius)
    c0, a0, R0, r0 = start
    c0, a0 = np.asarray(c0, np.float64), np.asarray(a0, np.float64)
    if c0.shape != (3,) or a0.shape != (3,) or not np.all(np.isfinite(np.r_[c0, a0])) \
            or not np.linalg.norm(a0) > 0 or not (np.isfinite(R0) and np.isfinite(r0)
                                                  and R0 > 0 and r0 > 0):
        raise ValueError("fit_torus: start must be (centre (3,), axis (3,), major radius > 0, "
                         f"minor radius > 0), got {start!r}")
    o = x.mean(axis=0)
    y = x - o
    L = float(np.sqrt(np.mean(np.sum(y * y, axis=1)))) or 1.0

    def fun(st):
        s, J = torus_jacobian(y, st[0], st[1], st[2])
        return s - st[3], J

    def retract(st, step):
        u, v = _perp_basis(st[1])
        return (st[0] + step[:3], _unit(st[1] + step[3] * u + step[4] * v),
                st[2] + step[5], st[3] + step[6])

    def solve(st, w):
        return _lm(st, fun, retract, w, L, max_iterations, rtol)

    st0 = (c0 - o, _unit(a0), float(R0), float(r0))
    try:
        st, w, s, it, ok = _irls(solve, st0, lambda st: fun(st)[0], loss, scale, len(x),
                                 1e-12 * L, max_iterations, 1e-10)
    except np.linalg.LinAlgError as exc:
        raise ValueError(f"fit_torus: the fit failed ({exc})") from None
    c, a, R, r = st
    if not (R > 0 and r > 0):
        raise ValueError(f"fit_torus: the fit degenerated (major radius {R:.4g}, minor radius "
                         f"{r:.4g}); the points do not describe this torus")
    if a[np.argmax(np.abs(a))] < 0:
        a = -a
    return TorusFit(c + o, a, float(R), float(r),
                    **_fit_stats(fun(st)[0], w, s, loss, it, ok))


def _circle_radius(P: np.ndarray) -> tuple[float, float]:
    """(radius, largest residual) of the best circle through 3-D points ``P`` (on a plane)."""
    m = P.mean(axis=0)
    _, _, vt = np.linalg.svd(P - m, full_matrices=False)
    xy = (P - m) @ vt[:2].T
    c, r = _pratt(xy)
    return float(r), float(np.abs(np.hypot(*(xy - c).T) - r).max())


def torus_of_surface(surface, uv_bounds, n: int = 24, rtol: float = 1e-6) -> TorusFit | None:
    """The torus a NURBS surface is over ``uv_bounds`` ((u0, u1), (v0, v1)), or None.

    Both families of iso-parameter lines of a torus are circles: the tube's, of one radius
    ``r``, and the parallels, of radii ``R + r cos`` (one radius only on a torus whose tube
    runs along its parallels' family too).  ``r`` is that of the family with one radius (the
    smaller, when both have one); the spine is the circle of the points moved ``r`` into the
    tube along their normals; a fit of the points from there.  None when the lines are not
    circles, or the fit leaves a residual beyond ``rtol`` x the torus's size.
    """
    (u0, u1), (v0, v1) = uv_bounds
    (du0, du1), (dv0, dv1) = surface.domain     # a face's trims may run a little past it
    u0, u1, v0, v1 = max(u0, du0), min(u1, du1), max(v0, dv0), min(v1, dv1)
    if not (u1 > u0 and v1 > v0):
        return None
    U, V = np.meshgrid(np.linspace(u0, u1, n), np.linspace(v0, v1, n), indexing="ij")
    X = surface.evaluate(U.ravel(), V.ravel()).reshape(n, n, 3)
    N = surface.normal(U.ravel(), V.ravel())
    size = float(np.ptp(X.reshape(-1, 3), axis=0).max()) or 1.0
    fam = []
    for lines in (X, X.transpose(1, 0, 2)):         # lines of constant u, then of constant v
        fits = []
        for P in lines:
            if np.ptp(P, axis=0).max() <= 1e-9 * size:
                continue                            # a pole: the line is one point
            try:
                fits.append(_circle_radius(P))
            except ValueError:
                return None
        if not fits:
            return None
        radii, res = np.array(fits).T
        if res.max() > rtol * size * 10:
            return None                             # not circles
        fam.append(radii)
    one = [k for k in (0, 1) if np.ptp(fam[k]) <= rtol * size * 10]
    if not one:
        return None
    r = min(float(np.median(fam[k])) for k in one)
    P = X.reshape(-1, 3)
    for sign in (1.0, -1.0):                        # the tube's centre inside or outside
        S = P - sign * r * N
        m = S.mean(axis=0)
        _, sv, vt = np.linalg.svd(S - m, full_matrices=False)
        if sv[2] > 1e-6 * size * np.sqrt(len(S)):
            continue
        a = vt[2]
        xy = (S - m) @ vt[:2].T
        try:
            c2, R = _pratt(xy)
        except ValueError:
            continue
        if not R > 0:
            continue
        try:
            f = fit_torus(P, start=(m + c2[0] * vt[0] + c2[1] * vt[1], a, R, r))
        except ValueError:
            continue
        if np.abs(f.residuals).max() <= rtol * size:
            return f
    return None
