"""Global registration: the pose of a scan given in any frame, with no start.

:func:`global_alignment` generates pose hypotheses from published methods and keeps the one
that fits best under one robust objective:

1. *principal axes*: the scan's centroid and principal axes matched with those of the model's
   points and of its "visible halves" (the model points facing each of the six directions
   along its principal axes), under all 24 proper axis permutations and sign flips
   (:mod:`shapeverify.registration.initial`);
2. *features*: FPFH descriptors (Rusu, Blodow, Beetz, "Fast Point Feature Histograms (FPFH)
   for 3D registration", ICRA 2009) of a voxel subsample of the scan and of the model points,
   nearest-descriptor correspondences, and RANSAC over correspondence triples with the
   edge-length pre-check of Zhou, Park, Koltun ("Fast global registration", ECCV 2016) -- the
   pipeline of Open3D's ``registration_ransac_based_on_feature_matching``;
3. *axis of revolution* (only for a model that is a solid of revolution, e.g. a turned part):
   the scan's own axis, read from its normal lines (Pottmann, Randrup 1998), put on the
   model's both ways up at the best height (:mod:`shapeverify.registration._revolution`);
4. *axis pairs* (only for a model with a near-symmetry axis that is not a solid of revolution,
   e.g. an impeller): the scan's axis direction put on the model's, and one scan point paired
   with one model point of like descriptor and like angle to the axis
   (:mod:`shapeverify.registration._axis_pairs`);
5. the identity (the scan may already be in the model's frame).

Every hypothesis is scored by the *fit* of a fixed subset of scan points: the mean over the
subset of ``max(0, 1 - (d / tau)^2)`` with ``d`` the point's distance to the model (0 for a
point whose closest model point is on the model's free boundary), ``tau`` the fit distance
(:func:`fit_distance`).  This is the truncated (Tukey-like) robust objective: 1 when every
point lies on the surface, the share of points within ``tau`` otherwise, blind to outliers.
All hypotheses are screened by this fit (kd-tree on a voxel subsample of the model, ``tau`` =
2 voxels); the best distinct ones are refined by a short Huber point-to-plane ICP on the subset
(kd-tree of all model points) and re-scored at a sharp fit distance, three times the smallest
robust residual scale among them (the right pose fits to the noise level; a wrong one that lays
the scan loosely over the surface does not); the best refined one wins.

What it cannot do: tell apart poses that the geometry itself cannot (a symmetric part's
symmetric copies fit equally well; the result says so in ``runner_up``).
"""
from __future__ import annotations

import logging
import time
import weakref
from dataclasses import dataclass

import numpy as np
from shapeverify._lazy import cKDTree

from .._random import generator
from . import _axis_pairs, _features, _irls, _revolution
from .losses import get_loss
from .rigid import make_transform, rotation_vector

from ..errors import RegistrationError

__all__ = ["global_alignment", "GlobalAlignment", "fit_score", "fit_distance"]

logger = logging.getLogger(__name__)

#: scan points scored per hypothesis (the first SCREEN_POINTS of them screen all hypotheses)
SCORE_POINTS = 400
SCREEN_POINTS = 300
#: voxels across the model's size for the feature subsample
VOXELS = 40
#: RANSAC triples tried
RANSAC_ITERATIONS = 30000
#: hypotheses refined by ICP
N_REFINE = 20
#: scan points (of the scored subset) the refinement uses
REFINE_POINTS = 400
#: hypotheses refined further after the first round
N_FINAL = 5


@dataclass(frozen=True, eq=False, repr=False)
class GlobalAlignment:
    """Result of :func:`global_alignment`.

    T_model_scan : (4, 4) the best refined pose; fit : its fit score in [0, 1] at the sharp fit
    distance (share of the scored scan points on the surface, see the module docstring); source : which hypothesis it
    came from ('identity', 'principal-axes', 'revolution-axis', 'axis-pairs',
    'fpfh-ransac'); n_hypotheses : poses scored;
    runner_up : (fit, rotation deg, normal displacement mm) of the best refined hypothesis that
    moves the scan differently (None if none); seconds : wall time; runner_up_pose : that
    hypothesis' pose (4, 4) or None; others : (fit, pose) of every refined hypothesis that
    moves the scan differently from the best, best fit first (the runner-up the first);
    symmetric : one bool per entry of ``others``: that pose is an exact symmetric copy of the
    best -- the model maps onto itself under the motion between them (:func:`is_symmetry`), so
    the two are equally right answers, not a doubt about the pose.
    """

    T_model_scan: np.ndarray
    fit: float
    source: str
    n_hypotheses: int
    runner_up: tuple | None
    seconds: float
    runner_up_pose: np.ndarray | None = None
    others: tuple = ()
    symmetric: tuple = ()

    def __repr__(self) -> str:
        return (f"GlobalAlignment(fit={self.fit:.3f}, source={self.source!r}, "
                f"n_hypotheses={self.n_hypotheses}, seconds={self.seconds:.3f})")


# ------------------------------------------------------------------------------ model side
_CACHE: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _model_size(prep) -> float:
    size = getattr(getattr(prep, "model", None), "size", None)
    if size is None or not np.isfinite(size) or size <= 0:
        mp = _irls.model_points(prep)
        size = float(np.linalg.norm(np.ptp(mp[0], axis=0)))
    return float(size)


def fit_distance(prep) -> float:
    """Fit distance tau (mm): ``max(4 x model point spacing, 0.005 x model size)``, the spacing
    of a CAD model taken at most ``size / 500``.

    Generous enough for depth-camera noise, small against the model, so a wrong pose fits
    only where surfaces happen to cross.  A mesh's or a cloud's model points are as sparse as
    its geometry (the fit cannot be sharper); a CAD model's are not, and its coarser default
    spacing for solid parts (up to 2 x ``size / 500``, :func:`~shapeverify.cad.sampling.needed_spacing`)
    leaves the fit distance as it was (it also sets the scale beyond which a pose is flagged).
    """
    sp = float(getattr(prep, "spacing", 0.0) or 0.0)
    size = _model_size(prep)
    if getattr(getattr(prep, "model", None), "kind", None) == "cad":
        sp = min(sp, size / 500.0)
    return max(4.0 * sp, 0.005 * size)


def _voxel_keys(X: np.ndarray, voxel: float) -> np.ndarray:
    """The voxel (side ``voxel``, from the points' lower corner) of each point, as one int64."""
    key = np.floor((X - X.min(axis=0)) / voxel).astype(np.int64)
    dims = key.max(axis=0) + 1
    return (key[:, 0] * dims[1] + key[:, 1]) * dims[2] + key[:, 2]


def _voxel_subsample(X: np.ndarray, voxel: float) -> np.ndarray:
    """Index of one point per occupied voxel (the first in scan order: deterministic)."""
    _, first = np.unique(_voxel_keys(X, voxel), return_index=True)
    return np.sort(first)


def _normals(X: np.ndarray, tree: cKDTree, k: int = 10) -> np.ndarray:
    """Unit PCA normals (n, 3) of X from its k nearest neighbours (unoriented)."""
    k = min(k, X.shape[0])
    _, nb = tree.query(X, k=k)
    Q = X[nb] - X[nb].mean(axis=1, keepdims=True)
    C = np.einsum("nki,nkj->nij", Q, Q)
    _, V = np.linalg.eigh(C)
    return np.ascontiguousarray(V[:, :, 0])


def _fpfh(X: np.ndarray, Nrm: np.ndarray, tree: cKDTree, radius: float, k: int = 48):
    k = min(k, X.shape[0])
    dist, nb = tree.query(X, k=k, distance_upper_bound=radius)
    nb = np.where(np.isfinite(dist), nb, X.shape[0]).astype(np.int64)
    dist = np.where(np.isfinite(dist), dist, 0.0)
    return _features.fpfh(X, Nrm, nb, dist)


class _ModelSide:
    """What the global search needs from the model, built once per Prepared object."""

    def __init__(self, prep):
        mp = _irls.model_points(prep)
        if mp is None:
            raise ValueError("global registration needs prep.points (model points and normals)")
        M, Nm = mp
        self.size = _model_size(prep)
        self.voxel = self.size / VOXELS
        self.tau = fit_distance(prep)
        self.spacing = float(getattr(prep, "spacing", 0.0) or self.size / 500.0)
        keep = _voxel_subsample(M, self.voxel)
        self.points = np.ascontiguousarray(M[keep])
        self.normals = np.ascontiguousarray(Nm[keep])
        self.tree = cKDTree(self.points)
        self.features = _fpfh(self.points, self.normals, self.tree, 5.0 * self.voxel)
        self.ftree = cKDTree(self.features)
        # every model point, for the refinement of the hypotheses
        self.all_points, self.all_normals = M, Nm
        self.all_tree = cKDTree(M)
        # all model points (about 5k, a regular subset) for the principal-axes hypotheses
        s = max(1, M.shape[0] // 5000)
        self.axes_points, self.axes_normals = M[::s], Nm[::s]


def _model_side(prep) -> _ModelSide:
    try:
        return _CACHE[prep]
    except KeyError:
        side = _CACHE[prep] = _ModelSide(prep)
        return side
    except TypeError:   # not weak-referenceable
        return _ModelSide(prep)


# ------------------------------------------------------------------------------ scoring
def fit_score(prep, S: np.ndarray, T: np.ndarray, tau: float) -> float:
    """Fit of the scan points S (n, 3) moved by T: mean of ``max(0, 1 - (d/tau)^2)``.

    ``d`` from ``prep.closest`` (fast mode); points whose closest model point is on the
    model's free boundary count 0.
    """
    X = S @ T[:3, :3].T + T[:3, 3]
    cl = prep.closest(X)
    d = np.asarray(cl.distances, np.float64)
    valid = np.isfinite(d) & ~np.asarray(cl.on_boundary, bool)
    return float(_features.truncated_fit(np.where(valid, d, 0.0), valid, tau))


def _distances(side, S, T):
    """Distances (n,) of the moved points S to the model: to the tangent plane of the nearest
    model point within 3 spacings of it, to the point itself farther away (all valid), inf
    beyond both 3 spacings and the fit distance (a far point fits at no sharp fit distance and
    moves no robust scale below it: the fits are the same, and a far-off hypothesis' kd-tree
    search stops early)."""
    X = S @ T[:3, :3].T + T[:3, 3]
    cap = max(side.tau, 3.0 * side.spacing)
    e, j = side.all_tree.query(X, distance_upper_bound=cap * (1.0 + 1e-12))
    j = np.minimum(j, side.all_points.shape[0] - 1)
    dn = np.abs(np.einsum("ij,ij->i", X - side.all_points[j], side.all_normals[j]))
    d = np.where(e <= 3.0 * side.spacing, dn, e)
    return d, np.ones(d.shape[0], bool)


def _sharp_fits(side, S, poses):
    """Fits of the poses at a sharp fit distance: three times the smallest robust residual
    scale among them (the right pose fits to the noise level; a wrong one that lays the scan
    loosely over the surface does not).  Returns (fits, tau)."""
    dists = [_distances(side, S, T) for T in poses]
    sig = [1.4826 * float(np.median(np.abs(d[v]))) if v.sum() >= 6 else np.inf
           for d, v in dists]
    tau = float(np.clip(3.0 * min(sig), 1e-9 * side.size, side.tau))
    return [float(_features.truncated_fit(d, v, tau)) for d, v in dists], tau


def _quick_fits(tree: cKDTree, S, poses, tau) -> np.ndarray:
    """Fits (k,) of the points S moved by each of the k poses (4, 4): the mean of
    ``max(0, 1 - (d / tau)^2)``, d the distance to the nearest point of ``tree`` (tau
    beyond it); all poses in one kd-tree query."""
    Y = np.concatenate([S @ T[:3, :3].T + T[:3, 3] for T in poses])
    d, _ = tree.query(Y, distance_upper_bound=tau)
    d = np.where(np.isfinite(d), d, tau).reshape(len(poses), S.shape[0])
    return np.mean(np.maximum(0.0, 1.0 - (d / tau) ** 2), axis=1)


def _quick_fit(tree: cKDTree, S, T, tau) -> float:
    return float(_quick_fits(tree, S, [T], tau)[0])


def refine(S, side: "_ModelSide", T, radius, max_it: int = 20) -> np.ndarray:
    """Short Huber point-to-plane ICP of the subset S from T against the model points.

    Nearest model points (kd-tree) with their normals, pairs farther than ``8 x tau`` left
    out: the cheap refinement of a hypothesis (the closest-point structure, slow for points
    far from the model, is kept for the final scoring).
    """
    from .rigid import compose_step, point_to_plane_system, solve_step

    R, t = T[:3, :3].copy(), T[:3, 3].copy()
    reach = 8.0 * side.tau
    huber = get_loss("huber")
    for _ in range(max_it):
        X = S @ R.T + t
        d, j = side.all_tree.query(X, distance_upper_bound=reach)
        ok = np.isfinite(d)
        if ok.sum() < 6:
            break
        X, Y, Nn = X[ok], side.all_points[j[ok]], side.all_normals[j[ok]]
        r = np.einsum("ij,ij->i", X - Y, Nn)
        sigma = max(1.4826 * float(np.median(np.abs(r))), 1e-9 * radius)
        w = huber.weight(r, sigma)
        c = X.mean(axis=0)
        H, g, _ = point_to_plane_system(X, Y, Nn, w, c)
        theta, _ = solve_step(H, g, radius)
        R, t = compose_step(R, t, theta, c)
        if np.linalg.norm(theta[:3]) * radius + np.linalg.norm(theta[3:]) < 1e-2 * side.tau:
            break
    return make_transform(R, t)


# ------------------------------------------------------------------------------ hypotheses
def _orient_towards_sensor(X: np.ndarray, Nrm: np.ndarray) -> np.ndarray:
    """Scan normals facing the scanner: towards the origin of the scan frame (the sensor, for a
    scan in the sensor's frame) when it lies outside the scan's box, else away from the scan's
    centroid."""
    lo, hi = X.min(axis=0), X.max(axis=0)
    outside = np.any((lo > 0.0) | (hi < 0.0))
    view = -X if outside else X - X.mean(axis=0)
    s = np.where(np.einsum("ij,ij->i", Nrm, view) < 0, -1.0, 1.0)
    return Nrm * s[:, None]


def scan_features(P: np.ndarray, side: _ModelSide):
    """(X, normals towards the sensor, FPFH) of the scan's voxel subsample; empty arrays with
    fewer than 10 voxels."""
    X = np.ascontiguousarray(P[_voxel_subsample(P, side.voxel)])
    if X.shape[0] < 10:
        return X, np.empty((0, 3)), np.empty((0, 33))
    tree = cKDTree(X)
    Nrm = _orient_towards_sensor(X, _normals(X, tree))
    return X, Nrm, _fpfh(X, Nrm, tree, 5.0 * side.voxel)


def feature_hypotheses(features, side: _ModelSide, rng_seed: int, top: int = 40):
    """Poses from FPFH correspondences + RANSAC, best inlier counts first (list of 4x4);
    ``features`` from :func:`scan_features`."""
    X, Nrm, F = features
    if X.shape[0] < 10:
        return []
    _, j = side.ftree.query(F, k=1)
    # mutual nearest descriptors, plus every scan point's nearest (if too few are mutual)
    _, back = cKDTree(F).query(side.features[j], k=1)
    mutual = back == np.arange(X.shape[0])
    sel = mutual if mutual.sum() >= 30 else np.ones_like(mutual)
    src = np.ascontiguousarray(X[sel])
    dst = np.ascontiguousarray(side.points[j[sel]])
    if src.shape[0] < 3:
        return []
    counts, poses = _features.ransac(src, dst, RANSAC_ITERATIONS, 1.5 * side.voxel, 0.9,
                                     rng_seed)
    order = np.argsort(-counts, kind="stable")[:top]
    out = []
    for i in order:
        R = poses[i, :9].reshape(3, 3)
        out.append(make_transform(R, poses[i, 9:]))
    return out


def axes_hypotheses(P: np.ndarray, side: _ModelSide):
    """The principal-axes poses (list of 4x4): see :mod:`.initial`."""
    from .initial import candidate_poses

    return candidate_poses(P, side.axes_points, side.axes_normals)


def _distinct(T1, T2, S, side, full: bool = False) -> tuple[float, float]:
    """(rotation deg, RMS normal displacement mm) between two poses on the points S.

    """
    dR = T2[:3, :3] @ T1[:3, :3].T
    ang = float(np.degrees(np.linalg.norm(rotation_vector(dR))))
    if ang > 5.0 and not full:     # apart anyway (see _apart): skip the displacement
        return ang, np.inf
    X1 = S @ T1[:3, :3].T + T1[:3, 3]
    X2 = S @ T2[:3, :3].T + T2[:3, 3]
    _, j = side.tree.query(X1)
    dn = np.einsum("ij,ij->i", X2 - X1, side.normals[j])
    return ang, float(np.sqrt(np.mean(dn ** 2)))


#: model points (a regular subset) moved by a candidate symmetry
SYMMETRY_POINTS = 20000


def is_symmetry(side, D, tol: float | None = None) -> bool:
    """The model maps onto itself under D (4, 4, model frame): every one of a regular subset of
    its points (:data:`SYMMETRY_POINTS`), moved by D, lies within ``tol`` (mm; default the fit
    distance) of the model (the distance to the nearest model point's tangent plane,
    :func:`_distances`).  The global search passes its sharp fit distance (three times the
    robust residual scale of the best pose, at least two model spacings): a motion that misses
    the nearest true symmetry by more than the scan's own fit is not one.

    Every point, not a share: a near-symmetric part (a plate whose one chamfered corner tells its
    ends apart) moves the points of that feature far off, and its copies are not equally right.
    """
    M = side.all_points[::max(1, side.all_points.shape[0] // SYMMETRY_POINTS)]
    d, _ = _distances(side, M, np.asarray(D, np.float64))
    tol = side.tau if tol is None else float(tol)
    return bool(np.all(np.isfinite(d) & (d <= tol)))


def _apart(dist, tq) -> bool:
    """Two hypotheses differ: 5 degrees apart, or moving the scan by tq along the normals."""
    return dist[0] > 5.0 or dist[1] > tq


def global_alignment(scan, prep, rng=0, extra=()) -> GlobalAlignment:
    """Find T_model_scan with no start (module docstring: hypotheses, objective, refinement).

    Parameters
    ----------
    scan : (N, 3) float64
        Scan points (mm) in any frame.
    prep : Prepared
        Uses ``prep.closest``, ``prep.points``, ``prep.spacing`` and ``prep.model.size``.
    rng : int or Generator
        Seeds the scored subset and RANSAC (fixed default: the same answer every run).
    extra : sequence of (name, (4, 4))
        More hypotheses (e.g. the identity refined by the caller).

    Returns
    -------
    GlobalAlignment
    """
    from .icp import _check_scan

    t0 = time.perf_counter()
    P = _check_scan(scan)
    rng = generator(rng)
    side = _model_side(prep)
    n = P.shape[0]
    S = P if n <= SCORE_POINTS else P[np.sort(rng.choice(n, SCORE_POINTS, replace=False))]
    radius = max(float(np.sqrt(np.mean(np.sum((P - P.mean(axis=0)) ** 2, axis=1)))), 1e-12)
    seed = int(rng.integers(2 ** 31))
    hyps = [("identity", np.eye(4))] + [(k, np.asarray(T, float)) for k, T in extra]
    hyps += [("principal-axes", T) for T in axes_hypotheses(P, side)]
    hyps += [("revolution-axis", T) for T in _revolution.hypotheses(P, side)]
    features = scan_features(P, side)
    hyps += [("axis-pairs", T) for T in _axis_pairs.hypotheses(P, side, S, radius, features)]
    hyps += [("fpfh-ransac", T) for T in feature_hypotheses(features, side, seed)]
    tq = 2.0 * side.voxel    # screening: kd-tree on the voxel subsample of the model
    Sq = S[:SCREEN_POINTS]
    quick = _quick_fits(side.tree, Sq, [T for _, T in hyps], tq)
    order = np.argsort(-quick, kind="stable")
    chosen = []
    for i in order:
        if len(chosen) == N_REFINE:
            break
        if all(_apart(_distinct(hyps[i][1], hyps[c][1], Sq, side), tq) for c in chosen):
            chosen.append(int(i))
    # refine: a few steps for every chosen hypothesis, more for the best few, each round
    # scored at the sharp fit distance
    poses = [hyps[i][1] for i in chosen]
    names = [hyps[i][0] for i in chosen]
    keep = list(range(len(poses)))
    for steps, n_keep in ((8, N_FINAL), (12, N_FINAL)):
        for i in keep:
            poses[i] = refine(S[:REFINE_POINTS], side, poses[i], radius, steps)
        fits, tau = _sharp_fits(side, S, [poses[i] for i in keep])
        order = np.argsort(-np.asarray(fits), kind="stable")[:n_keep]
        keep, fits = [keep[j] for j in order], [fits[j] for j in order]
    refined = [(f, names[i], poses[i]) for f, i in zip(fits, keep)]
    refined.sort(key=lambda r: -r[0])
    best_fit, best_src, best_T = refined[0]
    runner = runner_T = None
    others = []
    for f, _, T in refined[1:]:
        ang, dn = _distinct(best_T, T, S, side, full=True)
        if dn > tau:
            others.append((f, T))
            if runner is None:
                runner, runner_T = (f, ang, dn), T
    inv = np.linalg.inv(best_T)
    tol = float(np.clip(tau, 2.0 * side.spacing, side.tau))
    symmetric = tuple(is_symmetry(side, T @ inv, tol) for _, T in others)
    out = GlobalAlignment(best_T, best_fit, best_src, len(hyps), runner,
                          time.perf_counter() - t0, runner_T, tuple(others), symmetric)
    logger.info("global alignment: %r", out)
    return out
