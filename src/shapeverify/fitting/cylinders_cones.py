"""Orthogonal-distance cylinder and cone fits.

Levenberg-Marquardt in a local chart around the current axis, started from each principal
direction of the points (or an axis hint) with a Pratt circle fit of the projected points; the
best converged start wins.  Holds :class:`CylinderFit`, :class:`ConeFit`, :func:`fit_cylinder`,
:func:`fit_cone` and the axial helpers.

References
----------
A. Forbes, "Least-squares best-fit geometric elements", NPL report DITC 140/89, 1989.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from .._renamed import renamed_keywords
from ._element_base import (_check_loss, _check_points, _ElementFit, _fit_stats, _irls, _lm,
                            _perp_basis, _unit)
from .spheres_circles import _pratt

logger = logging.getLogger(__name__)

__all__ = ["CylinderFit", "ConeFit", "fit_cylinder", "fit_cone"]


@dataclass(frozen=True, repr=False)
class CylinderFit(_ElementFit):
    """Cylinder; ``point`` is the point of the axis closest to the centroid of the data."""
    point: np.ndarray
    axis: np.ndarray
    radius: float


@dataclass(frozen=True, repr=False)
class ConeFit(_ElementFit):
    """Cone: radius ``radius`` at ``point`` (axis point closest to the centroid), opening towards ``axis``.

    The radius at axial position ``h`` (from ``point`` along ``axis``) is ``radius + h * tan(half_angle)``;
    ``half_angle`` is in radians, in [0, pi/2).  ``residuals`` are signed distances (+ outside).
    """
    point: np.ndarray
    axis: np.ndarray
    radius: float
    half_angle: float

    @property
    def apex(self) -> np.ndarray:
        """(3,) the apex (infinite for a cylinder-like cone with half_angle == 0)."""
        t = np.tan(self.half_angle)
        if t == 0.0:
            return np.full(3, np.inf)
        return self.point - (self.radius / t) * self.axis


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


@renamed_keywords(tolerance="rtol")
def fit_cylinder(points, loss: str = "l2", scale: float | None = None, axis=None,
                 max_iterations: int = 100, rtol: float = 1e-12) -> CylinderFit:
    """Orthogonal-distance cylinder fit (5 parameters: axis line and radius).

    The distance of ``x`` is ``||(x - p) - ((x - p).a) a|| - R``.  Levenberg-Marquardt runs in a
    local chart around the current axis (steps of the axis point and direction orthogonal to the
    axis), started from each principal direction of the points (or from the ``axis`` hint), with a
    Pratt circle fit of the projected points; the best converged start wins.

    Parameters
    ----------
    points : (N, 3) float64, N >= 5
    loss, scale, max_iterations, rtol : as in :func:`fit_sphere`.
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
    x = _check_points(points, (3,), 5, "fit_cylinder", spread=2)
    _check_loss(loss, scale)
    p, a, (R,), r, w, s, it, ok = _fit_axial(x, loss, scale, axis, max_iterations, rtol, "cylinder")
    if R <= 0:
        raise ValueError("fit_cylinder: the fit degenerated to a non-positive radius")
    return CylinderFit(p, a, float(R), **_fit_stats(r, w, s, loss, it, ok))


@renamed_keywords(tolerance="rtol")
def fit_cone(points, loss: str = "l2", scale: float | None = None, axis=None,
             max_iterations: int = 100, rtol: float = 1e-12) -> ConeFit:
    """Orthogonal-distance cone fit (6 parameters: axis line, radius at the axis point, half-angle).

    The signed distance of ``x`` from the cone is ``(rho - R) cos(psi) - h sin(psi)`` with ``h``
    the axial position of ``x`` from the axis point, ``rho`` its distance from the axis, ``R`` the
    radius at the axis point and ``psi`` the half-angle (exact for points on the side of the apex
    the surface lies on).  Starts as in :func:`fit_cylinder`, with a line fit of ``rho`` against ``h``.

    Parameters
    ----------
    points : (N, 3) float64, N >= 6
    loss, scale, axis, max_iterations, rtol : as in :func:`fit_cylinder`.

    Returns
    -------
    ConeFit

    Raises
    ------
    ValueError
        Wrong shape, too few points, non-finite values, unknown loss, no start converged.
    """
    x = _check_points(points, (3,), 6, "fit_cone", spread=2)
    _check_loss(loss, scale)
    p, a, (R, psi), r, w, s, it, ok = _fit_axial(x, loss, scale, axis, max_iterations, rtol, "cone")
    return ConeFit(p, a, float(R), float(psi), **_fit_stats(r, w, s, loss, it, ok))
