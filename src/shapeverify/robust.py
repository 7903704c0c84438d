"""Robust loss functions (M-estimators): the one module every robust fit in shapeverify uses.

Registration (IRLS ICP), the geometric-element fits of :mod:`shapeverify.fitting` and
:func:`robust_lstsq` (Algorithm 3 of the thesis: iteratively reweighted least squares for a
linear model, e.g. the straight-line fit of its Figures 9 and 11) all take their rho-functions,
weights, tuning constants and scale estimate from here; the numba kernel of registration
(``registration._kernels._rho_w``) implements the same formulas and is tested against this
module (``tests/test_robust.py``).

Each loss is a rho-function of the residual ``r`` and a tuning constant ``k``
(same unit as ``r``).  The IRLS weight is ``w(r) = rho'(r) / r`` (thesis eq. 17,
with ``w(0) = rho''(0) = 1``).  The tuning constant is ``k = c * sigma`` with ``c`` the constant
giving 95 % asymptotic efficiency at the Gaussian and ``sigma`` a robust scale estimate of the
residuals, ``sigma = 1.4826 * median(|r|)`` (re-estimated every iteration).

>>> get_loss("tukey").weight([0.0, 1.0, 10.0], sigma=1.0).round(3).tolist()
[1.0, 0.911, 0.0]

References
----------
Bergström (2011), thesis §6.2-6.3, Fig. 10 (Huber and Tukey's biweight), eq. 17, Algorithm 3.
Holland & Welsch (1977), "Robust regression using iteratively reweighted least-squares"
(the 95 %-efficiency constants 1.345, 4.685, 2.385, 2.985).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

__all__ = ["Loss", "LOSSES", "get_loss", "robust_scale", "robust_weights", "robust_lstsq",
           "RobustFit", "MAD_TO_SIGMA"]

#: 1 / Phi^-1(3/4): turns the median absolute residual into a Gaussian sigma.
MAD_TO_SIGMA = 1.4826


def _l2_rho(r, k):
    return 0.5 * r * r


def _l2_w(r, k):
    return np.ones_like(r)


def _huber_rho(r, k):
    a = np.abs(r)
    return np.where(a <= k, 0.5 * r * r, k * a - 0.5 * k * k)


def _huber_w(r, k):
    a = np.abs(r)
    with np.errstate(divide="ignore"):
        return np.where(a <= k, 1.0, k / np.maximum(a, 1e-300))


def _tukey_rho(r, k):
    u2 = np.minimum((r / k) ** 2, 1.0)
    return (k * k / 6.0) * (1.0 - (1.0 - u2) ** 3)


def _tukey_w(r, k):
    u2 = (r / k) ** 2
    return np.where(u2 < 1.0, (1.0 - u2) ** 2, 0.0)


def _cauchy_rho(r, k):
    return 0.5 * k * k * np.log1p((r / k) ** 2)


def _cauchy_w(r, k):
    return 1.0 / (1.0 + (r / k) ** 2)


def _welsch_rho(r, k):
    return 0.5 * k * k * -np.expm1(-((r / k) ** 2))


def _welsch_w(r, k):
    return np.exp(-((r / k) ** 2))


@dataclass(frozen=True)
class Loss:
    """A rho-function with its IRLS weight and its 95 %-efficiency constant.

    Attributes
    ----------
    name : str
    c : float
        Tuning constant in units of the scale: ``k = c * sigma``.
    redescending : bool
        True when the weight goes to zero for large residuals (non-convex rho).
    """

    name: str
    c: float
    redescending: bool
    _rho: Callable = None
    _w: Callable = None

    def rho(self, r: np.ndarray, sigma: float) -> np.ndarray:
        """rho(r) for the tuning constant ``k = c * sigma``; r: (N,) -> (N,)."""
        return self._rho(np.asarray(r, np.float64), self.c * sigma)

    def weight(self, r: np.ndarray, sigma: float) -> np.ndarray:
        """IRLS weight ``w(r) = rho'(r) / r`` in [0, 1]; r: (N,) -> (N,) (thesis eq. 17)."""
        return self._w(np.asarray(r, np.float64), self.c * sigma)

    def __repr__(self) -> str:
        return f"Loss({self.name!r}, k={self.c}*sigma)"


LOSSES: dict[str, Loss] = {
    "l2": Loss("l2", 4.685, False, _l2_rho, _l2_w),  # c only defines "inlier" for L2
    "huber": Loss("huber", 1.345, False, _huber_rho, _huber_w),
    "tukey": Loss("tukey", 4.685, True, _tukey_rho, _tukey_w),
    "cauchy": Loss("cauchy", 2.385, False, _cauchy_rho, _cauchy_w),
    "welsch": Loss("welsch", 2.985, True, _welsch_rho, _welsch_w),
}


def get_loss(name: str) -> Loss:
    """Look up a loss by name ('l2', 'huber', 'tukey', 'cauchy', 'welsch').

    Raises
    ------
    ValueError
        For an unknown name (the message lists the valid ones).
    """
    if isinstance(name, Loss):
        return name
    key = str(name).lower().replace("-", "").replace("_", "")
    aliases = {"ls": "l2", "leastsquares": "l2", "biweight": "tukey", "bisquare": "tukey"}
    key = aliases.get(key, key)
    if key not in LOSSES:
        raise ValueError(f"unknown loss {name!r}; use one of {sorted(LOSSES)}")
    return LOSSES[key]


def robust_scale(residuals: np.ndarray, floor: float = 0.0) -> float:
    """Robust Gaussian scale of residuals: ``1.4826 * median(|r|)``.

    Parameters
    ----------
    residuals : (N,) float64
        Residuals (assumed centred at zero, as registration residuals are at the optimum).
    floor : float
        Lower bound returned for (nearly) exact data, so that weights stay defined.

    Returns
    -------
    float
    """
    r = np.abs(np.asarray(residuals, np.float64))
    if r.size == 0:
        return float(floor)
    return float(max(MAD_TO_SIGMA * np.median(r), floor))


def robust_weights(residuals, loss, scale: float) -> np.ndarray:
    """IRLS weights ``w(r) = rho'(r) / r`` in [0, 1] of ``loss`` at residual scale ``scale``."""
    return get_loss(loss).weight(residuals, float(scale))


@dataclass(frozen=True, eq=False)
class RobustFit:
    """Result of :func:`robust_lstsq`.

    Attributes
    ----------
    x : (p,) float64
        Coefficients.
    weights : (N,) float64
        Final IRLS weights (0: rejected).
    scale : float
        Final robust residual scale (sigma).
    residuals : (N,) float64
        ``b - A @ x``.
    iterations : int
    converged : bool
        The weights stopped changing (max change below ``tol``).
    """

    x: np.ndarray
    weights: np.ndarray
    scale: float
    residuals: np.ndarray
    iterations: int
    converged: bool
    history: tuple = field(default=())

    def __repr__(self) -> str:
        return (f"RobustFit(x={np.array2string(self.x, precision=6)}, scale={self.scale:.4g}, "
                f"iterations={self.iterations}, converged={self.converged}, "
                f"rejected={int(np.count_nonzero(self.weights == 0))})")


def robust_lstsq(A, b, loss: str = "tukey", scale: float | None = None,
                 max_iterations: int = 50, tol: float = 1e-8) -> RobustFit:
    """Robust linear least squares by IRLS (thesis Algorithm 3): minimise ``sum rho(b - A x)``.

    Starts from the least-squares solution; for a redescending loss (Tukey, Welsch) and the
    Cauchy loss, the Huber loss is iterated first so that the non-convex stage starts near the
    robust optimum.  Each step solves the weighted normal equations with the weights
    ``w(r_i) = rho'(r_i) / r_i`` of the current residuals and re-estimates the scale
    ``1.4826 median |r|`` unless ``scale`` is given.

    Parameters
    ----------
    A : (N, p) array_like
        Design matrix (e.g. ``[x, 1]`` for a straight line ``y = a x + c``).
    b : (N,) array_like
    loss : {"l2", "huber", "tukey", "cauchy", "welsch"}
    scale : float, optional
        Fixed residual scale (same unit as ``b``); None: robust estimate each iteration.
    max_iterations : int
        Per stage.
    tol : float
        Convergence: largest weight change.

    Returns
    -------
    RobustFit

    Raises
    ------
    ValueError
        Shapes that do not match, non-finite values, fewer rows than unknowns, an unknown loss,
        a bad ``scale``, or fewer than ``p`` points keeping a non-zero weight.

    Examples
    --------
    >>> x = np.linspace(0, 10, 21); y = 2 * x + 1; y[[3, 15]] += [30, -40]   # two outliers
    >>> fit = robust_lstsq(np.column_stack([x, np.ones_like(x)]), y, loss="tukey")
    >>> np.round(fit.x, 6).tolist(), int((fit.weights == 0).sum())
    ([2.0, 1.0], 2)
    """
    A = np.asarray(A, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if A.ndim != 2 or b.ndim != 1 or A.shape[0] != b.shape[0]:
        raise ValueError(f"A must be (N, p) and b (N,), got {A.shape} and {b.shape}")
    if not (np.isfinite(A).all() and np.isfinite(b).all()):
        raise ValueError("A and b must be finite (remove NaN/inf rows first)")
    n, p = A.shape
    if n < p:
        raise ValueError(f"{n} equations cannot determine {p} unknowns")
    lossobj = get_loss(loss)
    if scale is not None and not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a positive finite number or None, got {scale!r}")

    def solve(w):
        sw = np.sqrt(w)
        return np.linalg.lstsq(A * sw[:, None], b * sw, rcond=None)[0]

    w = np.ones(n)
    x = solve(w)
    if lossobj.name == "l2":
        return RobustFit(x, w, float("nan"), b - A @ x, 1, True)
    stages = ["huber", lossobj.name] if lossobj.name in ("tukey", "welsch", "cauchy") else [lossobj.name]
    floor = 1e-12 * max(1.0, float(np.max(np.abs(b))))
    iterations, converged, s, history = 1, False, float("nan"), []
    for stage in stages:
        converged = False
        for _ in range(max_iterations):
            r = b - A @ x
            s = float(scale) if scale is not None else robust_scale(r, floor)
            w_new = get_loss(stage).weight(r, s)
            if np.count_nonzero(w_new > 0) < p:
                raise ValueError(f"robust fit: fewer than {p} points keep a non-zero weight; give "
                                 "a larger `scale` or use a softer loss")
            x = solve(w_new)
            iterations += 1
            change = float(np.max(np.abs(w_new - w)))
            history.append(float(np.sum(get_loss(stage).rho(b - A @ x, s))))
            w = w_new
            if change < tol:
                converged = True
                break
    r = b - A @ x
    return RobustFit(x, w, s, r, iterations, converged, tuple(history))
