"""Orthogonal-distance line and plane fits (closed form: weighted principal axes).

:func:`fit_line` in 2-D or 3-D and :func:`fit_plane` in 3-D, with their result objects
:class:`LineFit` and :class:`PlaneFit`.  The robust losses (``loss="huber" | "tukey" |
"cauchy" | "welsch"``) run iteratively reweighted least squares with the MAD residual scale,
re-estimated each step unless ``scale`` is given (see :mod:`shapeverify.fitting.elements`).

References
----------
ASME B89.4.10-2000; A. Forbes, "Least-squares best-fit geometric elements", NPL DITC 140/89, 1989.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._renamed import renamed_keywords
from ._element_base import _check_loss, _check_points, _ElementFit, _fit_stats, _irls

__all__ = ["LineFit", "PlaneFit", "fit_line", "fit_plane"]


@dataclass(frozen=True, repr=False)
class LineFit(_ElementFit):
    """Line ``point + s * direction``; ``residuals`` are (unsigned) distances to the line."""
    point: np.ndarray
    direction: np.ndarray


@dataclass(frozen=True, repr=False)
class PlaneFit(_ElementFit):
    """Plane through ``point`` with unit ``normal``; ``residuals`` signed along the normal."""
    point: np.ndarray
    normal: np.ndarray


# ----------------------------------------------------------------------------------------------
# line and plane (closed form, weighted principal axes)
# ----------------------------------------------------------------------------------------------
def _principal(x: np.ndarray, w: np.ndarray):
    c = (w @ x) / w.sum()
    _, _, vt = np.linalg.svd(np.sqrt(w)[:, None] * (x - c), full_matrices=False)
    return c, vt


@renamed_keywords(tolerance="rtol")
def fit_line(points, loss: str = "l2", scale: float | None = None,
             max_iterations: int = 50, rtol: float = 1e-10) -> LineFit:
    """Orthogonal-distance line through (N, 2) or (N, 3) points.

    Parameters
    ----------
    points : (N, 2) or (N, 3) float64, N >= 2
    loss, scale, max_iterations, rtol : see module docstring (IRLS).

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

    state, w, s, it, ok = _irls(solve, None, dist, loss, scale, len(x), floor, max_iterations, rtol)
    c, a = state
    a = a if a[np.argmax(np.abs(a))] > 0 else -a
    r = dist((c, a))
    return LineFit(c, a, **_fit_stats(r, w, s, loss, it, ok))


@renamed_keywords(tolerance="rtol")
def fit_plane(points, loss: str = "l2", scale: float | None = None,
              max_iterations: int = 50, rtol: float = 1e-10) -> PlaneFit:
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
    x = _check_points(points, (3,), 3, "fit_plane", spread=2)
    _check_loss(loss, scale)
    floor = 1e-12 * (1.0 + float(np.ptp(x)))

    def solve(state, w):
        c, vt = _principal(x, w)
        return (c, vt[2]), True, 1

    def dist(state):
        c, n = state
        return (x - c) @ n

    state, w, s, it, ok = _irls(solve, None, dist, loss, scale, len(x), floor, max_iterations, rtol)
    c, n = state
    n = n if n[np.argmax(np.abs(n))] > 0 else -n
    n = n + 0.0  # no negative zeros
    r = dist((c, n))
    return PlaneFit(c, n, **_fit_stats(r, w, s, loss, it, ok))
