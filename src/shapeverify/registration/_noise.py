"""The scan's own noise, from the scan alone: the yardstick of a registration's residuals.

A right pose leaves residuals at the sensor's noise (plus the part's form deviations); a wrong
minimum leaves them at a fraction of the features it missed.  The fit distance the registration
warns at (4 model spacings, or 0.5 % of the size) knows neither: on the impeller a pose 105 deg
off converged at a robust scale of 0.86 mm, under that bar, with a sensor noise of 0.02 mm.
:func:`scan_noise` measures the noise as the scatter of scan points about a quadric fitted to
their neighbours (which absorbs the surface's curvature; refitted without the neighbours far
off it: outliers, another surface): the median absolute residual of the points themselves,
each scaled by its leverage, as a standard deviation.

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
from shapeverify._lazy import cKDTree

__all__ = ["scan_noise"]

#: scan points whose scatter is measured
POINTS = 1000
#: neighbours of each, for its quadric
K = 24
#: fits of each quadric: the first on all neighbours, each later one without those more than
#: 3 robust sigmas off the previous (outliers, a neighbouring surface)
ROUNDS = 3
#: points whose quadric predicts them with more than this variance (in noise variances) are
#: left out, and fewer than MIN_POINTS left give no estimate
MAX_LEVERAGE = 1.0
MIN_POINTS = 50


def scan_noise(P) -> float:
    """Noise sigma (mm) of the scan points P (n, 3) about their local quadrics, or nan with
    fewer than ``K + 1`` points or :data:`MIN_POINTS` well-fixed quadrics."""
    P = np.asarray(P, np.float64)
    n = P.shape[0]
    if n <= K:
        return float("nan")
    # evenly spaced in the file's order (no random draw: a simulated scan's outliers drawn with
    # the same seed were once exactly the points measured)
    idx = np.arange(n) if n <= POINTS else np.linspace(0, n - 1, POINTS).astype(np.int64)
    _, nb = cKDTree(P).query(P[idx], k=K + 1)
    X = P[nb[:, 1:]] - P[idx][:, None, :]              # (m, K, 3) neighbours about the point
    C = np.einsum("mki,mkj->mij", X, X)
    _, V = np.linalg.eigh(C)                            # local frame: V[:, :, 0] the normal
    L = np.einsum("mki,mij->mkj", X, V)                 # (u, v) = columns 2, 1; h = column 0
    u, v, h = L[:, :, 2], L[:, :, 1], L[:, :, 0]
    A = np.stack([u * u, u * v, v * v, u, v, np.ones_like(u)], axis=2)   # (m, K, 6)
    w = np.ones_like(h)
    for _ in range(ROUNDS):     # neighbours off their quadric (outliers) left out, refitted
        Aw = A * w[..., None]
        AtA = np.einsum("mki,mkj->mij", Aw, A) + 1e-12 * np.eye(6)
        coef = np.linalg.solve(AtA, np.einsum("mki,mk->mi", Aw, h)[..., None])[..., 0]
        res = np.abs(h - np.einsum("mki,mi->mk", A, coef))
        s = 1.4826 * np.median(res, axis=1, keepdims=True)
        w = (res <= 3.0 * np.maximum(s, 1e-300)).astype(np.float64)
    r = coef[:, 5]                                      # the point (origin) off its quadric
    # its variance: sigma^2 (1 + leverage of the origin), the leverage e6^T (A^T W A)^-1 e6
    lev = np.linalg.solve(AtA, np.broadcast_to(np.eye(6)[5], (len(idx), 6))[..., None])[:, 5, 0]
    # neighbours (nearly) on a line, as along one row of a raster seen at a grazing angle, do
    # not fix the quadric at the point: such points are left out
    ok = (lev >= 0.0) & (lev <= MAX_LEVERAGE)
    if np.count_nonzero(ok) < MIN_POINTS:
        return float("nan")
    z = r[ok] / np.sqrt(1.0 + lev[ok])
    return float(1.4826 * np.median(np.abs(z)))
