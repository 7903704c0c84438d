"""Pose hypotheses for a part that is a solid of revolution: the scan's axis onto the model's.

Why: a partial view of a turned part (a shaft, a flange, a bushing) has principal axes that
say little about the part's axis (a side view of a stepped shaft: tilted 14-20 deg and shifted
13-20 mm from the truth), and its FPFH features repeat all around the part, so neither of the
global search's other generators starts near the right basin (a simulated turned part from
random sensor poses: 3-4 of 8 views ended 1.7-3.8 mm off, some "converged").  But every normal
line of a surface of revolution meets its axis, so the axis can be read from the scan itself.

How:

1. The axis of the normal lines (Pottmann, Randrup, "Rotational and helical surface
   approximation for reverse engineering", Computing 60 (1998) 307-322): a line with direction
   ``a`` (unit) and moment ``m = c x a`` meets the normal line of point ``p`` with normal ``n``
   iff ``a . (p x n) + m . n = 0``; the axis minimises the sum of squares of these over the
   points, with ``m`` eliminated in closed form (a 3 x 3 eigenproblem), re-weighted (Tukey) so
   that outliers and the parts of the scan that are not turned do not move it.  Normal lines
   parallel to the axis (plane faces across it) satisfy the condition for any position: they
   fix the direction only.
2. The model's axis comes from the same fit on its model points; the model counts as a solid
   of revolution when :data:`SHARE` of its normal lines meet the axis within 3 deg
   (:data:`SLOPE`) (checked once per prepared model).  The scan's axis is used when :data:`SCAN_SHARE` of
   its normal lines agree with it.
3. Hypotheses: the scan's axis onto the model's, both ways up, shifted along the axis to where
   the scan fits best (truncated fit at the global search's fit distance, in steps of it over
   every overlap of the two axial extents, then of a quarter of it around the best), at
   :data:`SPINS` spins and around the best of them (a feature that fixes the spin, as a
   keyway, judged by distances to tangent planes).  The best
   :data:`KEEP` join the global search's other hypotheses under the same objective.
"""
from __future__ import annotations

import weakref

import numpy as np
from shapeverify._lazy import cKDTree

from .rigid import make_transform, rodrigues

#: share of the model's normal lines that must meet its axis (a solid of revolution)
SHARE = 0.6
#: share of the scan's normal lines that must meet the axis read from them (noisy normals of a
#: depth camera's scan miss by more than 3 deg while the axis is right to 0.1-0.6 deg; a wrong
#: axis only costs the hypotheses' time: they are judged by the fit like the others)
SCAN_SHARE = 0.4
#: the scan's normals: PCA of this many neighbours on a voxel subsample of size / VOXELS
#: (the voxels dense enough to be surface: :func:`_dense_voxels`)
NEIGHBOURS, VOXELS = 20, 80.0
#: the scan's voxels that count: those holding at least this share of a typical point's voxel
DENSE = 0.1
#: "near": the normal misses the plane of its point and the axis by less than this sine (3 deg)
SLOPE = 0.05
#: the re-weighting's scale floor, as a share of the model's size
NEAR = 0.004
#: spins about the axis tried for each way up (15 deg apart; the best one moved to the best of
#: its neighbours 3.75 and 7.5 deg on either side): a keyway 6 mm wide on a 36 mm shaft spans
#: 19 deg; at 30 deg apart (before) one of 4 views of such a part ended 131 deg off
SPINS = 24
#: scan points the spins are judged on (a feature that fixes the spin is a few % of them)
SPIN_POINTS = 2000
#: hypotheses handed to the global search
KEEP = 4


def axis_of_normals(X: np.ndarray, N: np.ndarray, scale: float, iterations: int = 8):
    """The line (direction (3,), point (3,)) that the normal lines of X (n, 3) with unit
    normals N (n, 3) meet best (module docstring, step 1), and each normal's misfit (n,): the
    sine of the angle by which it misses the plane through its point and the axis (0 on a
    surface of revolution, for a normal along the axis too).  ``scale`` (mm): the floor of the
    re-weighting's scale (the misfit times the distance from the axis).

    >>> t = np.linspace(0, 2 * np.pi, 50, endpoint=False)
    >>> X = np.c_[3 + 10 * np.cos(t), -1 + 10 * np.sin(t), np.linspace(0, 20, 50)]
    >>> N = np.c_[np.cos(t), np.sin(t), 0 * t]
    >>> a, c, miss = axis_of_normals(X, N, 0.01)
    >>> np.round(np.abs(a), 6).tolist(), np.round(c[:2], 6).tolist(), float(miss.max()) < 1e-9
    ([0.0, 0.0, 1.0], [3.0, -1.0], True)
    """
    o = X.mean(axis=0)
    Y = X - o
    Mo = np.cross(Y, N)
    w = np.ones(X.shape[0])
    a = c = None
    miss = np.zeros(X.shape[0])
    for _ in range(iterations):
        W = w[:, None]
        A = (Mo * W).T @ Mo
        B = (Mo * W).T @ N
        C = (N * W).T @ N
        Cp = np.linalg.pinv(C, rcond=1e-9)
        K = A - B @ Cp @ B.T
        _, V = np.linalg.eigh(0.5 * (K + K.T))
        a = V[:, 0]
        m = -Cp @ B.T @ a
        m -= (m @ a) * a                     # Pluecker: the moment is normal to the direction
        c = np.cross(a, m)                   # the axis point nearest the scan's centroid
        miss, rho = normal_misfit(Y, N, a, c)
        r = miss * rho                       # the intersection condition's residual (mm)
        sig = max(1.4826 * float(np.median(r)), scale)
        u = r / (4.685 * sig)
        w = np.where(u < 1.0, (1.0 - u ** 2) ** 2, 0.0)
        if w.sum() < 6:
            break
    return a, c + o, miss


def axis_directions(X: np.ndarray, N: np.ndarray, scale: float, k: int = 2,
                    n_dirs: int = 600, max_points: int = 500) -> list[np.ndarray]:
    """Up to ``k`` directions (unit (3,), at least 10 deg apart) of lines that many normal lines
    of X (n, 3), unit normals N (n, 3), meet, best share first: for each of ``n_dirs``
    directions over a hemisphere (about 6 deg apart) the best position (a few Tukey re-weighted
    least-squares steps, vectorised), scored by the share of normals within :data:`SLOPE`; on
    at most ``max_points`` of the points (evenly spaced).

    Unlike :func:`axis_of_normals`, which starts from the fit of all normals and converges to
    the nearest minimum, this finds the axis of a near-axisymmetric part whose scan is mostly
    not turned (an impeller's blades: the fit of all normals ended 21-28 deg off on 4 of 8
    views, the search 1-4 deg off on 7).  The position is poorly fixed where the normals that
    meet the axis are along it (a hub's flat top): only the directions are returned.

    >>> t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    >>> X = np.c_[10 * np.cos(t), 10 * np.sin(t), np.linspace(0, 20, 60)]
    >>> N = np.c_[np.cos(t), np.sin(t), 0 * t]
    >>> a = axis_directions(X, N, 0.01)[0]
    >>> bool(abs(a[2]) > np.cos(np.radians(5)))     # the grid's directions are 6 deg apart
    True
    """
    if X.shape[0] > max_points:              # an evenly spaced subset (the scan's order)
        keep = np.linspace(0, X.shape[0] - 1, max_points).astype(np.int64)
        X, N = X[keep], N[keep]
    i = np.arange(n_dirs) + 0.5
    z, phi = i / n_dirs, np.pi * (1.0 + 5.0 ** 0.5) * i          # a Fibonacci hemisphere
    A = np.c_[np.sqrt(1.0 - z * z) * np.cos(phi), np.sqrt(1.0 - z * z) * np.sin(phi), z]
    o = X.mean(axis=0)
    Q = A @ np.cross(X - o, N).T             # (dirs, n): a . (p x n)
    NN = (N[:, :, None] * N[:, None, :]).reshape(-1, 9)
    w = np.ones_like(Q)
    for _ in range(4):                       # moment m per direction: the condition Q + m . n
        C = (w @ NN).reshape(-1, 3, 3) + 1e-9 * np.eye(3)
        m = np.linalg.solve(C, -((w * Q) @ N)[..., None])[..., 0]
        r = np.abs(Q + m @ N.T)
        sig = np.maximum(1.4826 * np.median(r, axis=1), scale)[:, None]
        u = r / (4.685 * sig)
        w = np.where(u < 1.0, (1.0 - u * u) ** 2, 0.0)
    m -= np.sum(m * A, axis=1)[:, None] * A
    # normal_misfit for every direction at once: |n . (a x R)| / |R|, R from the axis to the
    # point; a x R = a x Y for Y from the axis point (the part along a drops out)
    Y = (X - o)[None] - np.cross(A, m)[:, None]
    h = np.sum(Y * A[:, None], axis=2)
    rho = np.sqrt(np.maximum(np.sum(Y * Y, axis=2) - h * h, 0.0))
    miss = np.abs(np.sum(np.cross(A[:, None], Y) * N[None], axis=2)) / np.maximum(rho, 1e-300)
    share = np.mean(miss <= SLOPE, axis=1)
    out: list[np.ndarray] = []
    for d in np.argsort(-share, kind="stable"):
        if all(abs(A[d] @ b) < np.cos(np.radians(10.0)) for b in out):
            out.append(A[d])
            if len(out) == k:
                break
    return out


def normal_misfit(X: np.ndarray, N: np.ndarray, a: np.ndarray, c: np.ndarray):
    """(miss, rho), each (n,): the sine of the angle by which each unit normal N misses the
    plane through its point X and the axis (direction a, unit; through c), and the point's
    distance from the axis.  0 on a surface of revolution about that axis.

    >>> X = np.array([[2.0, 0, 0], [0, 3.0, 1.0]])
    >>> N = np.array([[1.0, 0, 0], [1.0, 0, 0]])
    >>> miss, rho = normal_misfit(X, N, np.array([0, 0, 1.0]), np.zeros(3))
    >>> miss.tolist(), rho.tolist()
    ([0.0, 1.0], [2.0, 3.0])
    """
    R = (X - c) - np.outer((X - c) @ a, a)           # from the axis to the point
    rho = np.linalg.norm(R, axis=1)
    et = np.cross(a, R) / np.maximum(rho, 1e-300)[:, None]  # the spin direction there
    return np.abs(np.einsum("ij,ij->i", N, et)), rho


def _agree(miss) -> float:
    """Share of the normals that meet the axis within SLOPE (about 3 deg)."""
    return float(np.mean(miss <= SLOPE))


_MODEL: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def model_axis(side):
    """(direction, point, (lo, hi) axial extent) of the model's axis of revolution, or None
    (module docstring, step 2); cached per global-search model side.  A model whose normals
    all lie along one direction (a flat plate: they meet any parallel line) has none."""
    try:
        return _MODEL[side]
    except (KeyError, TypeError):
        pass
    M, Nm = np.asarray(side.axes_points, float), np.asarray(side.axes_normals, float)
    out = None
    if M.shape[0] >= 20:
        a, c, miss = axis_of_normals(M, Nm, NEAR * side.size)
        around = np.mean(np.abs(Nm @ a) < 0.9) >= 0.1     # faces around the axis, not across
        if around and _agree(miss) >= SHARE:
            h = (M - c) @ a
            out = (a, c, (float(h.min()), float(h.max())))
    try:
        _MODEL[side] = out
    except TypeError:   # not weak-referenceable
        pass
    return out


def hypotheses(P: np.ndarray, side) -> list[np.ndarray]:
    """Up to :data:`KEEP` poses (4, 4) with the scan's axis on the model's (module docstring),
    best fit first; [] when the model is not a solid of revolution or the scan shows no axis."""
    from .global_search import _quick_fit

    ax = model_axis(side)
    if ax is None:
        return []
    am, cm, (lo, hi) = ax
    dense = scan_normals(P, side)
    if dense is None:
        return []
    X = dense[0]
    a, c, d = axis_of_normals(*dense, NEAR * side.size)
    if _agree(d) < SCAN_SHARE:
        return []
    hs = (X - c) @ a
    S = X[np.linspace(0, X.shape[0] - 1, min(400, X.shape[0])).astype(np.int64)]
    F = X[np.linspace(0, X.shape[0] - 1, min(SPIN_POINTS, X.shape[0])).astype(np.int64)]
    tau, tree = side.tau, side.all_tree     # nearest model points: a fit to the spacing
    out = []
    for up in (1.0, -1.0):
        R0 = _onto(up * a, am)
        # scan heights s map to model heights s + z: every overlap of [s0, s1] + z with [lo, hi]
        s0, s1 = sorted((up * hs.min(), up * hs.max()))
        # the height at spin 0 (a turned part's fit does not depend on the spin): steps of tau
        # on a third of the points, then of tau / 4 around the best; then the spins
        zs = np.arange(lo - s1, hi - s0 + tau, tau)
        fz = [_quick_fit(tree, S[::3], make_transform(R0, cm + z * am - R0 @ c), tau)
              for z in zs]
        zs = zs[int(np.argmax(fz))] + 0.25 * tau * np.arange(-4, 5)
        fz = [_quick_fit(tree, S, make_transform(R0, cm + z * am - R0 @ c), tau) for z in zs]
        z = zs[int(np.argmax(fz))]

        def spun(angle):
            R = rodrigues(am * angle) @ R0
            return make_transform(R, cm + z * am - R @ c)

        # the spins, judged by distances to the tangent planes (a feature that fixes the spin,
        # a keyway, is a few % of the points: the point-to-point fit's sampling noise hid it)
        step = 2.0 * np.pi / SPINS
        spins = step * np.arange(SPINS)
        fits = [_spin_fit(side, F, spun(a)) for a in spins]
        b = int(np.argmax(fits))       # the best spin, moved to the best of its neighbours
        fine = spins[b] + 0.25 * step * np.array([-2.0, -1.0, 1.0, 2.0])
        ff = [_spin_fit(side, F, spun(a)) for a in fine]
        if max(ff) > fits[b]:
            spins[b], fits[b] = fine[int(np.argmax(ff))], max(ff)
        out += [(f, spun(a)) for f, a in zip(fits, spins)]
    out.sort(key=lambda ft: -ft[0])
    return [T for _, T in out[:KEEP]]


def scan_normals(P: np.ndarray, side):
    """(X, unit normals) of the scan's dense voxels (:func:`_dense_voxels`, voxels of the
    model's size / :data:`VOXELS`), normals by PCA of :data:`NEIGHBOURS` neighbours; None
    with fewer points than that."""
    from .global_search import _normals

    X = P[_dense_voxels(P, side.size / VOXELS)]
    if X.shape[0] < NEIGHBOURS:
        return None
    return X, _normals(X, cKDTree(X), NEIGHBOURS)


def _spin_fit(side, F: np.ndarray, T: np.ndarray) -> float:
    """Fit of the points F moved by T (:func:`._features.truncated_fit` at the fit distance), d
    the distance to the nearest model point's tangent plane (:func:`.global_search._distances`)."""
    from . import _features
    from .global_search import _distances

    return float(_features.truncated_fit(*_distances(side, F, T), side.tau))


def _dense_voxels(P: np.ndarray, voxel: float) -> np.ndarray:
    """One point per voxel of ``voxel`` (the first in scan order), of the voxels where the scan
    is dense: whose cell holds at least :data:`DENSE` of the points a typical scan point's cell
    holds, and at least 3.

    Isolated outliers sit alone in their cells: one point per voxel gave 10 % outliers about
    half the subsample, and only 10-21 % of the normals met the axis (a turned part's views,
    noise 0.05 mm), against 70-75 % with the sparse voxels left out.  The cells are the voxels,
    or larger where a typical voxel holds fewer than 6 points (a coarse scan): then sized to
    hold about 12.

    >>> P = np.r_[np.repeat([[0.5, 0.5, 0.5], [1.5, 0.5, 0.5]], 10, axis=0), [[9.5, 9.5, 9.5]]]
    >>> _dense_voxels(P, 1.0).tolist()
    [0, 10]
    """
    from .global_search import _voxel_keys, _voxel_subsample

    def counts(cell):   # points in each point's cell
        _, inverse, count = np.unique(_voxel_keys(P, cell), return_inverse=True,
                                      return_counts=True)
        return count[inverse.ravel()]

    n = counts(voxel)
    typical = float(np.median(n))
    if typical < 6:
        n = counts(voxel * np.sqrt(12.0 / typical))
        typical = float(np.median(n))
    sub = _voxel_subsample(P, voxel)
    return sub[n[sub] >= max(3.0, DENSE * typical)]


def _onto(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The smallest rotation (3, 3) taking the unit vector u to the unit vector v."""
    w = np.cross(u, v)
    s, cth = np.linalg.norm(w), float(u @ v)
    if s < 1e-12:
        if cth > 0:
            return np.eye(3)
        p = np.eye(3)[np.argmin(np.abs(u))]
        w = np.cross(u, p)
        return rodrigues(np.pi * w / np.linalg.norm(w))
    return rodrigues(w / s * np.arctan2(s, cth))
