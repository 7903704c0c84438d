"""The lower segment of a composite feature control frame (ASME Y14.5-2009 §7.5.1 composite
positional tolerancing, §8.3.1 composite profile): the feature-relating tolerance zone
framework (FRTZF).

The upper segment (pattern-locating, PLTZF) is an ordinary tolerance, located to all its
datums.  The lower segment's datums only **orient** its zone framework: the framework may
translate as a whole in every direction, and rotate about the axes the datums leave free (a
primary plane alone: about its normal; a plane and an axis perpendicular to it: about that
axis; no datums: any rotation); the features are checked against the framework in its best
place, so the lower segment controls the features' relation to each other and their
orientation to the datums, not their location.

The best place (the characteristic's ``details['composite']`` gives the motion):

* **position** (:func:`best_pattern_fit`): the rigid motion ``x -> R (x - p) + p + t``
  (``R`` a rotation about the free axes, ``p`` the centroid of the true positions, ``t`` any
  translation) of the features' measured axis ends minimising the largest distance of an end
  from its true axis; value = twice that distance (the zone diameter the worst feature needs).
  A small smooth minimax problem in epigraph form (minimise ``q`` with ``q >= dist^2`` for
  every end), solved by SLSQP from the identity.  Features whose zones differ (each its own
  bonus at MMC/LMC, e.g. a counterbored hole's hole and counterbore): the largest excess
  ``dist - r_i`` over each one's own zone radius is minimised instead (``(q + r_i)^2 >=
  dist^2``, ``q + r_i >= 0``).
* **profile of a surface** (:func:`best_profile_fit`): the rigid motion in the same set
  minimising the largest ``|deviation|``: a linear programme in the small motion (each
  deviation changes by ``n . (omega x (x - p) + t)``, HiGHS), the points moved by the exact
  motion and their deviations taken again from the CAD; repeated until the largest
  ``|deviation|`` improves by less than 1e-9 mm (at most 8 times); never worse than the start.
"""
from __future__ import annotations

import numpy as np

__all__ = ["lower_rotations", "best_pattern_fit", "best_profile_fit", "rotation_matrix"]


def lower_rotations(drf) -> np.ndarray:
    """(k, 3) unit axes about which a lower segment's framework may turn: those the DRF leaves
    free (:meth:`.drf.DRF.free_rotations`); all three without datums."""
    if drf is None:
        return np.eye(3)
    return drf.free_rotations()


def rotation_matrix(w) -> np.ndarray:
    """Rotation by the vector ``w`` (Rodrigues)."""
    from .drf import rigid_exp

    return rigid_exp(np.r_[np.asarray(w, float), 0.0, 0.0, 0.0])[:3, :3]


def _move(X, w, t, p):
    return (np.asarray(X, float) - p) @ rotation_matrix(w).T + p + t


def best_pattern_fit(ends, centres, axes, rotations, scale: float | None = None,
                     radii=None) -> dict:
    """The best place of a pattern's true positions (module docstring).

    Parameters
    ----------
    ends : list of (m_i, 3)    measured axis end points of each feature (the DRF's frame)
    centres, axes : (n, 3)     each feature's true axis: a point on it and its direction
    rotations : (k, 3)         free rotation axes (:func:`lower_rotations`), k in 0..3
    scale : float, optional    lever (mm) of rotations against translations (default: the
                               pattern's extent)
    radii : (n,), optional     each feature's own zone radius (features of different sizes
                               at MMC/LMC: each zone ``tol + its bonus``): the best place then
                               minimises the largest ``distance - radius`` (the largest
                               excess over its own zone), not the largest distance

    Returns
    -------
    dict: ``value`` (twice the largest end distance at the best place), ``located`` (the same
    without moving), ``rotation`` (rad, vector), ``translation`` (mm), ``pivot``,
    ``per_feature`` (twice each feature's largest end distance at the best place)
    """
    from scipy.optimize import minimize

    C = np.asarray(centres, float)
    A = np.asarray(axes, float)
    A = A / np.linalg.norm(A, axis=1, keepdims=True)
    B = np.asarray(rotations, float).reshape(-1, 3)
    E = [np.atleast_2d(np.asarray(e, float)) for e in ends]
    idx = np.concatenate([np.full(len(e), i) for i, e in enumerate(E)])
    P = np.vstack(E)
    p = C.mean(axis=0)
    L = float(scale or max(np.ptp(np.vstack([C, P]), axis=0).max(), 1.0))
    k = B.shape[0]

    def dist2(x):
        Q = _move(P, (x[:k] / L) @ B, x[k:k + 3], p) - C[idx]
        along = np.einsum("ij,ij->i", Q, A[idx])
        return np.einsum("ij,ij->i", Q, Q) - along ** 2

    d0 = dist2(np.zeros(k + 3))
    if radii is None:       # epigraph: q >= dist^2 for every end
        x0 = np.r_[np.zeros(k + 3), d0.max()]
        cons = [{"type": "ineq", "fun": lambda x: x[-1] - dist2(x[:-1])}]

        def top(x):
            return dist2(x).max()
    else:                   # q >= dist - r_i, i.e. (q + r_i)^2 >= dist^2 with q + r_i >= 0
        rr = np.asarray(radii, float)[idx]

        def top(x):
            return float((np.sqrt(np.maximum(dist2(x), 0.0)) - rr).max())

        x0 = np.r_[np.zeros(k + 3), top(np.zeros(k + 3))]
        cons = [{"type": "ineq", "fun": lambda x: (x[-1] + rr) ** 2 - dist2(x[:-1])},
                {"type": "ineq", "fun": lambda x: x[-1] + rr}]
    best = x0
    for _ in range(3):       # restart from the answer: SLSQP's Hessian estimate starts again
        r = minimize(lambda x: x[-1], best, jac=lambda x: np.r_[np.zeros(k + 3), 1.0],
                     constraints=cons, method="SLSQP",
                     options={"ftol": 1e-16, "maxiter": 500})
        x = r.x.copy()
        x[-1] = top(x[:-1])
        if x[-1] < best[-1] - 1e-15:
            best = x
        else:
            break
    d = np.sqrt(np.maximum(dist2(best[:-1]), 0.0))
    per = [2.0 * float(d[idx == i].max()) for i in range(len(E))]
    return {"value": 2.0 * float(d.max()), "located": 2.0 * float(np.sqrt(d0.max())),
            "rotation": ((best[:k] / L) @ B).tolist() if k else [0.0, 0.0, 0.0],
            "translation": best[k:k + 3].tolist(), "pivot": p.tolist(), "per_feature": per}


def best_profile_fit(X, deviations, rotations, max_iterations: int = 8) -> dict:
    """The best place of a profile's zone (module docstring).

    Parameters
    ----------
    X : (N, 3)               the points (the DRF's frame)
    deviations : callable    ``Y -> (d (N,), normals (N, 3))``: signed deviations of points
                             ``Y`` from the CAD and the CAD normals at their feet
    rotations : (k, 3)       free rotation axes (:func:`lower_rotations`)

    Returns
    -------
    dict: ``d`` (deviations at the best place), ``value`` (largest ``|d|``), ``located`` (the
    same unmoved), ``rotation``, ``translation``, ``pivot``, ``iterations``
    """
    from scipy.optimize import linprog

    X = np.asarray(X, float)
    B = np.asarray(rotations, float).reshape(-1, 3)
    p = X.mean(axis=0)
    L = float(max(np.ptp(X, axis=0).max(), 1.0))
    w, t = np.zeros(3), np.zeros(3)
    d, Nn = deviations(X)
    d, Nn = np.asarray(d, float), np.asarray(Nn, float)
    ok = np.isfinite(d)
    located = float(np.abs(d[ok]).max())
    best = (located, d, w, t)
    it = 0
    for it in range(1, max_iterations + 1):
        Y = _move(X, w, t, p)
        ok = np.isfinite(d)
        # d(w + dw, t + dt) ~ d + n . (dw x (Y - p) + dt): columns for s (dw = s B / L), dt
        G = np.hstack([np.cross(Y[ok] - p, Nn[ok]) @ B.T / L, Nn[ok]])
        one = np.ones((G.shape[0], 1))
        m = G.shape[1]
        res = linprog(np.r_[np.zeros(m), 1.0],
                      A_ub=np.vstack([np.hstack([G, -one]), np.hstack([-G, -one])]),
                      b_ub=np.r_[-d[ok], d[ok]], bounds=[(None, None)] * m + [(0, None)],
                      method="highs")
        if res.status != 0:
            break
        s, dt = res.x[:m - 3], res.x[m - 3:m]
        dw = (s / L) @ B if len(s) else np.zeros(3)
        # compose: the new small rotation about p after the current one
        R = rotation_matrix(dw) @ rotation_matrix(w)
        w_new = _rotvec(R)
        t_new = rotation_matrix(dw) @ t + dt
        d_new, N_new = deviations(_move(X, w_new, t_new, p))
        d_new, N_new = np.asarray(d_new, float), np.asarray(N_new, float)
        v = float(np.nanmax(np.abs(d_new)))
        gain = best[0] - v
        if v < best[0]:
            best = (v, d_new, w_new, t_new)
        w, t, d, Nn = w_new, t_new, d_new, N_new
        if gain < 1e-9:
            break
    return {"d": best[1], "value": best[0], "located": located, "rotation": best[2].tolist(),
            "translation": best[3].tolist(), "pivot": p.tolist(), "iterations": it}


def _rotvec(R) -> np.ndarray:
    """The rotation vector of the rotation matrix R (angle < pi)."""
    c = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    th = float(np.arccos(c))
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if th < 1e-12:
        return v / 2.0
    return v * th / (2.0 * np.sin(th))
