"""Other minima along the least-determined pose direction (private to registration).

Why: when one pose direction is fixed by a small share of the scan -- an impeller's spin by
the ~5 % of its points on the blade walls, the hub being a surface of revolution -- and those
points lie on *thin walls* (blades 0.6-1.7 mm thick), moving along that direction by one wall
thickness puts the scanned side of each wall onto the unseen other side: a second minimum where
almost every point fits again (the impeller: 1.31 deg = thickness / radius, 50 of 20,000
points misfit, the same robust scale as at the truth).  A start whose error in that direction
is more than half a wall thickness "into" the walls converges there; no local rule can tell
from its own neighbourhood, so the stopping rule has nothing to catch.

What: after the final stage, :func:`probe` takes the eigen-directions of the weighted
point-to-plane information (scaled; undetermined ones excluded) and, for each, the points that
hold its information.  Of the directions where a small share of the points (:data:`FEW`) holds
90 % of it -- a direction resting on few points -- it takes the one resting on the fewest, and
evaluates the robust fit of those points at the current scale along that direction,
at steps that move them by at most one tuning constant ``c * sigma`` (so no basin as wide as
the loss is stepped over), as far as :data:`REACH` fit distances either way, and returns the
best offset if it fits clearly better than the pose itself.  The caller re-runs the final stage
from there and keeps whichever end fits all points better (so nothing changes when there is no
better minimum).  The geometry alone decides; no part-specific constant.

References
----------
Gelfand, Ikemoto, Rusinkiewicz, Levoy, "Geometrically stable sampling for the ICP algorithm",
3DIM 2003 (the information of a pose direction and the points that carry it).
"""
from __future__ import annotations

import logging

import numpy as np

from . import _irls
from .options import StageSettings
from .rigid import rodrigues

logger = logging.getLogger(__name__)

#: the direction "rests on few points" when this share of the valid points holds 90 % of its
#: information (the impeller's spin: 4 %; the example panel's least-supported slide: 16 %)
FEW = 0.10
#: (logged: the share holding half of it)
HOLD = 0.5
#: points probed (those holding the most information in the direction), at most
MAX_POINTS = 3000
#: the support of the directions is judged on a regular subset of about this many points
SUPPORT_POINTS = 30000
#: probe as far as this many fit distances (normal displacement of the probed points) each way
REACH = 2.0
#: the probe scores the points with Tukey's rho at this many tuning constants (wide enough
#: that the small coupled error of a probe along one direction does not hide the basin,
#: narrow against wall thicknesses)
WIDTH = 2.0
#: probe steps per kernel width of normal displacement (a basin is met within a third of it)
STEPS_PER_K = 3
#: probes each way, at most
MAX_STEPS = 100
#: another minimum of the probed points' mean fit loss f (a share of its range) is refined
#: when ``f <= max(CLOSE * f0, f0 + GAIN)``, f0 at the pose; at most CANDIDATES of them, best
#: first (the caller keeps a new end only if it fits all points better)
CLOSE = 2.0
GAIN = 0.05
CANDIDATES = 2


def _jacobian(X, N, center):
    """(n, 6) point-to-plane Jacobians J = [(x - c) x n, n]."""
    return np.hstack([np.cross(X - center, N), N])


def probe(P, prep, ev, R, t, cfg: StageSettings, null_scaled, fit_distance: float):
    """Starts [(R, t), ...] in other minima along the direction resting on the fewest points
    (module docstring); empty when there is none.

    Parameters
    ----------
    P : (n, 3) scan points; ev : the final evaluation at the pose (R, t);
    null_scaled : (k, 6) undetermined directions (scaled, excluded); fit_distance : mm.
    """
    radius = cfg.radius
    w = ev.w
    center = _irls.centroid(ev.X, w)
    H, _ = _irls.system(ev.Y, ev.Y, ev.N, w, center)
    D = np.array([1.0 / radius] * 3 + [1.0] * 3)
    lam, V = np.linalg.eigh(H * np.outer(D, D))
    keep = lam > 1e-6 * max(lam[-1], 1e-300)
    if null_scaled.shape[0]:
        keep &= np.abs(V.T @ null_scaled.T).max(axis=1) < 0.5
    nv = int(ev.valid.sum())
    if not keep.any() or nv < 60:
        return []
    # the directions' support is judged on a regular subset (constant cost for any scan size)
    sub = np.arange(0, ev.X.shape[0], max(1, ev.X.shape[0] // SUPPORT_POINTS))
    valid = ev.valid[sub]
    nv = int(valid.sum())
    J = _jacobian(ev.Y[sub], ev.N[sub], center)
    best_dir = None
    for i in np.flatnonzero(keep):
        u_i = V[:, i] * D                           # the motion (rotation vector, translation)
        g_i = J @ u_i                               # normal displacement per unit motion
        # unweighted: the points the loss rejects here are those another minimum may fit
        info = np.where(valid, g_i * g_i, 0.0)
        total = float(info.sum())
        if total <= 0:
            continue
        k_few = int(FEW * nv)                       # a direction needs 90 % on <= k_few points
        if k_few < 1:
            continue
        if (k_few < info.size
                and np.partition(info, info.size - k_few - 1)[-k_few:].sum() < 0.8 * total):
            continue                                # clearly spread (< 80 %): no sort needed
        order = np.argsort(-info, kind="stable")
        share = np.cumsum(info[order]) / total
        few = int(np.searchsorted(share, HOLD)) + 1
        most = int(np.searchsorted(share, 0.9)) + 1
        logger.debug("probe: direction %d rests on %.4f (50 %%) / %.4f (90 %%) of the points",
                     i, few / nv, most / nv)
        if most <= FEW * nv and (best_dir is None or most < best_dir[0]):
            best_dir = (most, u_i, g_i, order)
    if best_dir is None:
        return []                                  # information spread over the scan
    most, u, g, order = best_dir
    idx = sub[np.sort(order[:min(MAX_POINTS, most)])]
    g = g[np.searchsorted(sub, idx)]
    Q = P[idx]
    k = WIDTH * ev.loss.c * ev.sigma                 # the probe's kernel (mm)
    # steps small for the points that move most (90th percentile), reach for the typical one
    ga = np.abs(g)
    step = k / (STEPS_PER_K * max(float(np.percentile(ga, 90)), 1e-300))
    n_steps = int(np.ceil(REACH * fit_distance / max(float(np.median(ga)), 1e-300) / step))
    if n_steps < 1:
        return []
    n_steps = min(n_steps, MAX_STEPS)

    def fit(s):
        dR = rodrigues(s * u[:3])
        Rs = dR @ R
        ts = dR @ (t - center) + center + s * u[3:]
        m = _irls.match(Q, prep, Rs, ts)
        u2 = np.where(m.valid, np.minimum((m.d / k) ** 2, 1.0), 1.0)
        return float(np.mean(1.0 - (1.0 - u2) ** 3)), (Rs, ts)   # Tukey rho / (k^2 / 6)

    f0, _ = fit(0.0)
    grid = np.arange(-n_steps, n_steps + 1)
    scores = [fit(j * step) if j else (f0, None) for j in grid]
    f = np.array([sc[0] for sc in scores])
    found = []
    for j in range(1, len(grid) - 1):
        if abs(grid[j]) <= 2 or not (f[j] <= f[j - 1] and f[j] <= f[j + 1]):
            continue                                 # the pose's own basin, or no minimum
        if f[j] <= max(CLOSE * f0, f0 + GAIN):
            found.append((f[j], int(grid[j]), scores[j][1]))
    found.sort(key=lambda x: (x[0], abs(x[1])))
    logger.debug("probe: %d points, f0 %.4f, other minima %s", Q.shape[0], f0,
                 [(round(a, 4), b) for a, b, _ in found[:CANDIDATES]])
    return [pose for _, _, pose in found[:CANDIDATES]]
