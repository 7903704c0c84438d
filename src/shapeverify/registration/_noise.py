"""The scan's own noise, from the scan alone: the yardstick of a registration's residuals.

A right pose leaves residuals at the sensor's noise (plus the part's form deviations); a wrong
minimum leaves them at a fraction of the features it missed.  The fit distance the registration
warns at (4 model spacings, or 0.5 % of the size) knows neither: on the impeller a pose 105 deg
off converged at a robust scale of 0.86 mm, under that bar, with a sensor noise of 0.02 mm.
:func:`scan_noise` measures the noise as the scatter of scan points about a quadric fitted to
their neighbours (which absorbs the surface's curvature): the median absolute leave-one-out
residual, scaled to a standard deviation.

Examples
--------
>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> x, y = rng.uniform(-10, 10, (2, 20000))
>>> P = np.c_[x, y, 0.01 * (x ** 2 + y ** 2) + rng.normal(0, 0.02, x.size)]
>>> round(scan_noise(P), 2)
0.02
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["scan_noise"]

#: scan points whose scatter is measured
POINTS = 1000
#: neighbours of each, for its quadric
K = 24


def scan_noise(P, rng=0) -> float:
    """Noise sigma (mm) of the scan points P (n, 3) about their local quadrics, or nan with
    fewer than ``K + 1`` points."""
    P = np.asarray(P, np.float64)
    n = P.shape[0]
    if n <= K:
        return float("nan")
    rng = np.random.default_rng(rng)
    idx = np.arange(n) if n <= POINTS else np.sort(rng.choice(n, POINTS, replace=False))
    _, nb = cKDTree(P).query(P[idx], k=K + 1)
    X = P[nb[:, 1:]] - P[idx][:, None, :]              # (m, K, 3) neighbours about the point
    C = np.einsum("mki,mkj->mij", X, X)
    _, V = np.linalg.eigh(C)                            # local frame: V[:, :, 0] the normal
    L = np.einsum("mki,mij->mkj", X, V)                 # (u, v) = columns 2, 1; h = column 0
    u, v, h = L[:, :, 2], L[:, :, 1], L[:, :, 0]
    A = np.stack([u * u, u * v, v * v, u, v, np.ones_like(u)], axis=2)   # (m, K, 6)
    AtA = np.einsum("mki,mkj->mij", A, A) + 1e-12 * np.eye(6)
    coef = np.linalg.solve(AtA, np.einsum("mki,mk->mi", A, h)[..., None])[..., 0]
    r = coef[:, 5]                                      # the point (origin) off its quadric
    # its variance: sigma^2 (1 + leverage of the origin), the leverage e6^T (A^T A)^-1 e6
    lev = np.linalg.solve(AtA, np.broadcast_to(np.eye(6)[5], (len(idx), 6))[..., None])[:, 5, 0]
    z = r / np.sqrt(1.0 + np.maximum(lev, 0.0))
    return float(1.4826 * np.median(np.abs(z)))
