"""Robust loss functions (M-estimators) for IRLS registration.

Each loss is a rho-function of the residual ``r`` and a tuning constant ``k``
(same unit as ``r``).  The IRLS weight is ``w(r) = rho'(r) / r`` (thesis eq. 17,
with ``w(0) = rho''(0) = 1``).  The tuning constant is never chosen by the user:
it is ``k = c * sigma`` with ``c`` the constant giving 95 % asymptotic
efficiency at the Gaussian and ``sigma`` a robust scale estimate of the
residuals, ``sigma = 1.4826 * median(|r|)`` (re-estimated every iteration).

References
----------
Bergström (2011), thesis §6.2-6.3, Fig. 10 (Huber and Tukey's biweight), eq. 17.
Holland & Welsch (1977), "Robust regression using iteratively reweighted least-squares"
(the 95 %-efficiency constants 1.345, 4.685, 2.385, 2.985).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

__all__ = ["Loss", "LOSSES", "get_loss", "robust_scale", "MAD_TO_SIGMA"]

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
