"""IRLS-ICP iterations (private to :mod:`shapeverify.registration`).

Two kinds of stage:

* :func:`stage_rematch` -- every iteration re-matches the scan points to the model
  (``prep.closest``), computes the robust scale and weights and takes one rigid step
  (point-to-plane, or point-to-point with Anderson acceleration).  Used on random subsets
  while the pose is still moving, and for point-to-point throughout.
* :func:`stage_final_plane` -- point-to-plane on every point: one matching gives each point
  its closest point and tangent plane; IRLS steps are iterated against these fixed planes
  (Gauss-Newton on the local surface model, thesis eq. 12-13) until the pose converges; then
  a fresh matching of a random subset (4,000 points) at the final pose checks that the planes
  are still the closest-point planes: the pose correction the subset's fresh residuals ask for
  must be below the tolerance, below 0.1 standard deviation of the subset's own estimate (the
  resolution of the piecewise tangent-patch closest points of ``exact=False``), or move no
  scan point by more than :data:`POSE_FRACTION` (0.05) x sigma while changing the objective by
  less than :data:`OBJECTIVE_RTOL` (1 %): the pose is then at a fixed point of ICP to a small
  fraction of the noise level.  If not, everything is matched again (at most 4 times; then
  ``converged`` is False and the message says how far the pose still moves).

Convergence (both), tested before each step with the step that would be taken: the pose
change still to come, in standard deviations of the pose, is below ``sqrt(tol * n_valid)`` (a
move that changes the objective by less than ``tol`` relative), and the objective -- at the
previous iteration's scale -- decreased by less than ``tol`` relative.  The step's length is
``m = sqrt(v^T H v) / sigma`` with ``H = sum w J^T J``; for point-to-plane (Gauss-Newton) the
change still to come is ``m / (1 - q)`` with ``q`` the observed contraction of successive
steps; for point-to-point, which converges linearly and slowly where the surface is nearly
flat or cylindrical, it is the first-order distance to the optimum ``H^-1 H_pt v`` (see
:func:`step`).  So a crawling iteration is never declared converged.

References
----------
Bergström (2011), thesis §5.2, §6.3 (Algorithms 1-3); Chen & Medioni (1992); Walker & Ni,
"Anderson acceleration for fixed-point iterations", SIAM J. Numer. Anal. 49 (2011);
Zhang, Yao, Deng, "Fast and robust iterative closest point", IEEE TPAMI 44 (2022).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from . import _kernels
from ._model_arrays import SPIN_DEG, ModelArrays, information_points, model_points, spin_direction  # noqa: F401,E501
from .losses import LOSSES, MAD_TO_SIGMA, Loss, robust_scale
from .options import Method, StageSettings
from .rigid import (
    DEGENERATE_RTOL, compose_step, rodrigues, rotation_vector, solve_step, weighted_rigid_fit,
)

from ..errors import RegistrationError

#: points re-matched to check the final stage's planes
VERIFY = 4000
#: the fast closest points are piecewise (tangent patches): re-matching may move the optimum
#: a little.  Corrections below this many standard deviations of the pose are accepted.
VERIFY_SIGMA = 0.1
#: converged: fresh closest points at the final pose ask for a pose increment that moves no
#: scan point by more than this fraction of the noise level sigma ...
POSE_FRACTION = 0.05
#: ... and change the objective (mean rho) by less than this, relative
OBJECTIVE_RTOL = 0.01
#: largest contraction factor used to extrapolate the remaining distance
_QMAX = 0.999


class IterationRecord(NamedTuple):
    """One IRLS-ICP iteration."""

    stage: str          # "coarse" | "final"
    loss: str
    n_points: int       # scan points used in this stage
    n_valid: int        # points with a closest point, not on the model's free boundary
    scale: float        # robust sigma (mm)
    objective: float    # mean rho of the valid residuals
    rms: float          # RMS residual of the inliers (|r| <= k), mm
    step_rotation: float     # rad, of the step taken after this evaluation (0: none)
    step_translation: float  # mm, at the weighted centroid
    step_sigma: float        # Mahalanobis length of the step (in standard deviations)
    matched: bool            # closest points were recomputed for this evaluation


@dataclass
class State:
    R: np.ndarray
    t: np.ndarray
    iterations: int = 0
    history: list = field(default_factory=list)


class Match(NamedTuple):
    """Closest points of the moved scan (:func:`match`)."""

    X: np.ndarray        # (n, 3) scan points in model coordinates
    Y: np.ndarray        # (n, 3) closest model points (X where invalid)
    N: np.ndarray        # (n, 3) model normals (0 where invalid)
    d: np.ndarray        # (n,) signed residuals (0 where invalid)
    valid: np.ndarray    # (n,) bool: a closest point, not on the model's free boundary
    index: np.ndarray    # (n,) nearest model point (-1 unknown)
    clamped: np.ndarray  # (n,) bool: foot clamped to a patch edge


@dataclass
class Eval:
    X: np.ndarray       # scan points in model coordinates
    Y: np.ndarray       # closest model points (X where invalid)
    N: np.ndarray       # model normals (0 where invalid)
    d: np.ndarray       # signed residuals (0 where invalid)
    valid: np.ndarray
    w: np.ndarray
    sigma: float
    objective: float
    rms: float
    inliers: np.ndarray
    loss: Loss
    index: np.ndarray   # nearest model point of each scan point (-1 unknown)
    clamped: np.ndarray  # foot clamped to a patch edge (distance to the foot point, not plane)

    @property
    def match(self) -> Match:
        """The closest points this evaluation weighed."""
        return Match(self.X, self.Y, self.N, self.d, self.valid, self.index, self.clamped)


def system(X, Y, N, w, center):
    """(H, g) of the point-to-plane step (numba form of rigid.point_to_plane_system)."""
    H = np.empty((6, 6))
    g = np.empty(6)
    _kernels.plane_system(X, Y, N, w, center, H, g)
    return H, g


def centroid(X, w) -> np.ndarray:
    return _kernels.weighted_centroid(X, w)


def match(P, prep, R, t) -> Match:
    """Closest points of the moved scan (scan points P moved by R, t): the fast tangent-patch
    feet (the exact refinement is the inspection's, after the pose is found)."""
    X = P @ R.T + t
    cl = prep.closest(X)
    d = np.asarray(cl.distances, np.float64)
    valid = np.isfinite(d) & ~np.asarray(cl.on_boundary, bool)
    Y = np.where(valid[:, None], np.asarray(cl.points, np.float64), X)
    N = np.where(valid[:, None], np.asarray(cl.normals, np.float64), 0.0)
    idx = np.asarray(getattr(cl, "index", np.full(X.shape[0], -1)))
    # feet clamped to a tangent patch's edge are not orthogonal projections: their distance is
    # to the foot point itself (remembered for the fixed-plane iterations)
    E = X - Y
    dn = np.einsum("ij,ij->i", E, N)
    tang2 = np.einsum("ij,ij->i", E, E) - dn * dn
    clamped = valid & (tang2 > (1e-6 * np.abs(d) + 1e-9) ** 2)
    return Match(X, Y, N, np.where(valid, d, 0.0), valid, idx, clamped)


#: partial overlap: the scale of the residuals near zero is used when it is below this share
#: of the MAD scale (see :func:`overlap_scale`)
OVERLAP_RATIO = 0.5
#: ... found by trimming at this many scales; tried only when at least this share of the valid
#: points lie within a quarter of the MAD scale
OVERLAP_TRIM = 3.0
OVERLAP_NEAR = 0.3


def overlap_scale(absd: np.ndarray, sigma: float, floor: float) -> float:
    """The robust scale of a partial overlap: ``sigma`` unless the residuals near zero say less.

    The MAD scale ``sigma = 1.4826 median|d|`` breaks down when half the valid points or more
    lie off the model (a partial view matched to a point cloud whose outline is not known:
    the points beyond the overlap are matched to the cloud's edge, mm away).  When at least
    :data:`OVERLAP_NEAR` of the points lie within sigma / 4 (19.7 % for Gaussian residuals), the
    fixed point ``s <- 1.4826 median(|d| : |d| <= 3 s)`` is iterated from sigma / 4: it settles
    on the scale of the mode at zero (for Gaussian residuals the median of |d| truncated at 3
    sigma is 0.2 % below the untruncated one).  It replaces sigma only when it is below
    :data:`OVERLAP_RATIO` x sigma, so unimodal residuals -- with or without a minority of
    outliers -- keep the MAD scale bit for bit (at the cost of one comparison).
    """
    if np.count_nonzero(absd <= 0.25 * sigma) < OVERLAP_NEAR * absd.shape[0]:
        return sigma                 # no dense mode below the MAD scale: it stands
    s = 0.25 * sigma
    for _ in range(30):
        near = absd[absd <= OVERLAP_TRIM * s]
        if near.shape[0] < 6:
            return sigma
        s_new = max(MAD_TO_SIGMA * float(np.median(near)), floor)
        if abs(s_new - s) <= 1e-3 * s:
            s = s_new
            break
        s = s_new
    return s if s < OVERLAP_RATIO * sigma else sigma


def weigh(m: Match, loss: Loss, scale, floor, overlap: bool = False) -> Eval:
    """Robust scale, weights, objective and inliers of the residuals of a matching.

    ``overlap``: the scale may drop to that of the mode at zero (:func:`overlap_scale`)."""
    X, Y, N, d, valid, idx, clamped = m
    nv = int(valid.sum())
    if nv < 6:
        raise RegistrationError(
            f"only {nv} scan points have a closest model point off the model's free boundary; "
            "give a better init (e.g. init='principal-axes') or check the model and units")
    code = _kernels.LOSS_CODES.get(loss.name) if LOSSES.get(loss.name) is loss else None
    if code is None:   # a loss of the caller's own: the numpy formulas
        sigma = float(scale) if scale is not None else robust_scale(d[valid], floor)
        if overlap and scale is None:
            sigma = overlap_scale(np.abs(d[valid]), sigma, floor)
        w = np.where(valid, loss.weight(d, sigma), 0.0)
        objective = float(loss.rho(d[valid], sigma).mean())
        inl = valid & (np.abs(d) <= loss.c * sigma)
        rms = float(np.sqrt(np.mean(d[inl] ** 2))) if inl.any() else float("nan")
        return Eval(X, Y, N, d, valid, w, sigma, objective, rms, inl, loss, idx, clamped)
    # the built-in losses in one numba pass (the same formulas as losses.py)
    if scale is not None:
        sigma = float(scale)
    else:
        absd = _kernels.abs_valid(d, valid)
        sigma = float(max(MAD_TO_SIGMA * np.median(absd), floor))
        if overlap:
            sigma = overlap_scale(absd, sigma, floor)
    w = np.empty(d.shape[0])
    inl = np.empty(d.shape[0], dtype=np.bool_)
    objective, rms, _ = _kernels.weigh_residuals(code, d, valid, loss.c * sigma, w, inl)
    return Eval(X, Y, N, d, valid, w, sigma, float(objective), float(rms), inl, loss, idx, clamped)


def evaluate(P, prep, R, t, cfg: StageSettings) -> Eval:
    return weigh(match(P, prep, R, t), cfg.loss, cfg.scale, cfg.floor, cfg.overlap)


def evaluate_fixed(P, R, t, m: Match, cfg: StageSettings) -> Eval:
    """Residuals against the fixed tangent planes (m.Y, m.N) of a matching at the pose (R, t)."""
    X = np.empty_like(P)
    d = np.empty(P.shape[0])
    _kernels.move_and_residuals(P, R, t, m.Y, m.N, m.valid, m.clamped, X, d)
    return weigh(m._replace(X=X, d=d), cfg.loss, cfg.scale, cfg.floor, cfg.overlap)


def _motion(R0, t0, R1, t1, center) -> np.ndarray:
    """The move from pose 0 to pose 1 as (rotation vector, translation of ``center``)."""
    dR = R1 @ R0.T
    dt = t1 - dR @ t0
    return np.concatenate([rotation_vector(dR), dR @ center + dt - center])


def _check_weights(w):
    if np.count_nonzero(w > 0) < 6:
        raise RegistrationError("fewer than 6 scan points carry weight; the robust loss "
                                "rejected almost everything (bad start or wrong model?)")


#: relative eigenvalue under which the tangent-patch feet are suspected of faking information
_SUSPECT = 1e-3
#: about this many points (a regular subset) give the exact-point information matrix
INFO_POINTS = 4000


def null_directions(ev: "Eval", mp, H, center, radius) -> np.ndarray:
    """Scaled-centred directions (k, 6) the geometry does not determine.

    Cheap test on H first; only when it shows a weak direction (relative eigenvalue below
    1e-3) is the information recomputed from the exact model points and tested against
    :data:`~shapeverify.registration.rigid.DEGENERATE_RTOL`.  A mesh's or a cloud's weak
    direction that is the spin about its model's axis of revolution (within :data:`SPIN_DEG`)
    is undetermined too: the symmetry is the part's, the information its facets'.
    """
    D = np.array([1.0 / radius] * 3 + [1.0] * 3)
    lam, V = np.linalg.eigh(H * np.outer(D, D))
    if lam[0] >= _SUSPECT * lam[-1]:
        return np.zeros((0, 6))
    if mp is not None and np.all(ev.index[ev.valid] >= 0):
        # a regular subset is enough for a relative eigenvalue test against 1e-6 (an exact
        # degeneracy stays exact); the full gather from the model's points cost 2 ms per 30k
        s = slice(None, None, max(1, ev.index.shape[0] // INFO_POINTS))
        i = np.where(ev.valid[s], ev.index[s], 0)
        M = mp[0][i]
        Hq, _ = system(M, M, mp[1][i], np.where(ev.valid[s], ev.w[s], 0.0), center)
    else:
        Hq, _ = system(ev.Y, ev.Y, ev.N, ev.w, center)
    lam, V = np.linalg.eigh(Hq * np.outer(D, D))
    null = V[:, lam <= DEGENERATE_RTOL * max(lam[-1], 1e-300)].T.copy()
    if null.shape[0] == 0 and lam[0] < _SUSPECT * lam[-1]:
        # a tessellated (or scanned) solid of revolution: its facets give the spin a weak,
        # spurious information (relative 1e-4 on a 14k-triangle turned part, against 0 on its
        # CAD), so the pose drifts along it and never settles; the part itself is symmetric
        spin = spin_direction(mp, center, radius)
        if spin is not None and abs(float(V[:, 0] @ spin)) >= np.cos(np.radians(SPIN_DEG)):
            null = V[:, :1].T.copy()
    return null


def _pinv_psd(H, radius):
    """Pseudo-inverse of an information matrix in the well-determined directions."""
    D = np.array([1.0 / radius] * 3 + [1.0] * 3)
    lam, V = np.linalg.eigh(H * np.outer(D, D))
    inv = np.where(lam > 1e-6 * max(lam[-1], 1e-300), 1.0 / np.where(lam > 0, lam, 1.0), 0.0)
    return ((V * inv) @ V.T) * np.outer(D, D)


def step(P, ev: Eval, R, t, method: str, radius: float, mp=None, null=None):
    """The plain rigid step from the pose (R, t) of the evaluation ``ev``.

    Returns the new (R, t), the step v = (omega, tau at the weighted centroid), its Mahalanobis
    length m, and ``far``: the Mahalanobis distance to the optimum predicted from this step.
    For point-to-plane the step itself is the Gauss-Newton step, so ``far = m`` (the caller
    extrapolates with the observed contraction).  Point-to-point converges linearly: its step
    solves ``H_pt v = -g`` where point-to-plane would solve ``H_pl v* = -g``, so the remaining
    distance is ``v* = H_pl^-1 H_pt v`` (first order).  ``null``: undetermined directions
    (scaled, see :func:`null_directions`), computed here when None.
    """
    w = ev.w
    _check_weights(w)
    center = centroid(ev.X, w)
    H, g = system(ev.X, ev.Y, ev.N, w, center)
    if null is None:
        null = null_directions(ev, mp, H, center, radius)
    if method == Method.POINT_TO_PLANE:
        theta, _ = solve_step(H, g, radius, null=null)
        Rn, tn = compose_step(R, t, theta, center)
    else:
        Rn, tn = weighted_rigid_fit(P, ev.Y, w)
    v = _motion(R, t, Rn, tn, center)
    m = float(np.sqrt(max(v @ H @ v, 0.0))) / ev.sigma
    if method == Method.POINT_TO_PLANE:
        return Rn, tn, v, m, m
    q = ev.X - center
    S = (q * w[:, None]).T @ q
    Hpt = np.zeros((6, 6))
    Hpt[:3, :3] = np.trace(S) * np.eye(3) - S
    Hpt[3:, 3:] = w.sum() * np.eye(3)
    vstar = _pinv_psd(H, radius) @ (Hpt @ v)
    far = float(np.sqrt(max(vstar @ H @ vstar, 0.0))) / ev.sigma
    return Rn, tn, v, m, max(far, m)


class Anderson:
    """Anderson acceleration of the point-to-point fixed-point map pose -> ICP(pose).

    Poses are mapped to 6-vectors ``x = (rotvec(R R_ref^T) * radius, R c + t)`` (c: the scan's
    centroid), smooth around the stage's start.  With the last m+1 pairs (x_i, g_i = G(x_i)),
    the accelerated point is ``g_k - dG gamma`` with ``gamma = argmin |f_k - dF gamma|``,
    ``f = g - x`` (Walker & Ni 2011; for ICP: Pavlov et al. 2018, Zhang et al. 2021).  The caller
    keeps it only if the objective decreases (otherwise the plain step is taken and the history
    is cleared), so it never does worse than plain ICP.
    """

    def __init__(self, R_ref, c_scan, radius, m: int = 5):
        self.R_ref, self.c, self.radius, self.m = R_ref, c_scan, radius, m
        self.X, self.G = [], []

    def _x(self, R, t):
        return np.concatenate([rotation_vector(R @ self.R_ref.T) * self.radius, R @ self.c + t])

    def _pose(self, x):
        R = rodrigues(x[:3] / self.radius) @ self.R_ref
        return R, x[3:] - R @ self.c

    def reset(self):
        self.X, self.G = [], []

    def __call__(self, R, t, Rg, tg):
        self.X = (self.X + [self._x(R, t)])[-(self.m + 1):]
        self.G = (self.G + [self._x(Rg, tg)])[-(self.m + 1):]
        if len(self.X) < 2:
            return None
        X, G = np.array(self.X), np.array(self.G)
        F = G - X
        gamma = np.linalg.lstsq(np.diff(F, axis=0).T, F[-1], rcond=1e-10)[0]
        x = G[-1] - np.diff(G, axis=0).T @ gamma
        return self._pose(x) if np.all(np.isfinite(x)) else None


class _Criterion:
    """Step-length and objective test of the module docstring."""

    def __init__(self, tol, method):
        self.tol, self.plane, self.prev_m = tol, method == Method.POINT_TO_PLANE, None

    def done(self, prev, ev: Eval, m, far) -> bool:
        """prev: (sigma, objective) before the last step or None; m, far: from :func:`step`."""
        if self.plane:   # Gauss-Newton steps: extrapolate with the observed contraction
            q = 0.0 if not self.prev_m else min(m / self.prev_m, _QMAX)
            far = m / (1.0 - q)
        self.prev_m = m
        if prev is None:
            return False
        obj = _mean_rho(ev, prev[0])
        return (prev[1] - obj <= self.tol * prev[1]
                and far <= np.sqrt(self.tol * ev.valid.sum()))


def _record(st, name, loss, n, ev, v=None, m=0.0, matched=True):
    st.history.append(IterationRecord(
        name, loss.name, n, int(ev.valid.sum()), ev.sigma, ev.objective, ev.rms,
        0.0 if v is None else float(np.linalg.norm(v[:3])),
        0.0 if v is None else float(np.linalg.norm(v[3:])), float(m), matched))


def _anneal(ev: Eval, prev_sigma, anneal, cfg: StageSettings) -> Eval:
    """Graduated scale: sigma may fall by at most the factor ``anneal`` per iteration."""
    if anneal is None or cfg.scale is not None or prev_sigma is None:
        return ev
    lo = anneal * prev_sigma
    if ev.sigma >= lo:
        return ev
    return weigh(ev.match, ev.loss, lo, cfg.floor)


def stage_rematch(name, P, prep, st: State, cfg: StageSettings, first=None,
                  anneal=None) -> tuple[Eval, bool, str]:
    """Iterate re-matching + one step until converged or ``max_it`` steps (module docstring).

    ``first(d, valid)`` optionally checks the first matching (e.g. the reach test).
    ``anneal`` (e.g. 0.7): the robust scale may fall by at most this factor per iteration
    (graduated non-convexity: the points that fit only once the pose is right -- a few blades
    that fix an impeller's spin, while its hub fits at once -- keep their pull until the pose
    has moved; Black & Rangarajan 1996, Yang et al. 2020).
    Returns the final evaluation, whether it converged, and why not ('' when it did).
    """
    method, loss, radius, max_it = cfg.method, cfg.loss, cfg.radius, cfg.max_iterations
    m0 = match(P, prep, st.R, st.t)
    if first is not None:
        first(m0.d, m0.valid)
    ev = weigh(m0, loss, cfg.scale, cfg.floor, cfg.overlap)
    aa = Anderson(st.R.copy(), P.mean(axis=0), radius) if method == Method.POINT_TO_POINT else None
    mp = model_points(prep)
    crit = _Criterion(cfg.tolerance, method)
    prev = None   # (sigma, objective) before the last step
    plain = None  # the plain step's pose when the last step was accelerated
    for k in range(max_it + 1):
        if plain is not None and _mean_rho(ev, prev[0]) > prev[1]:
            st.R, st.t = plain       # the accelerated step made it worse: plain step
            aa.reset()
            ev = evaluate(P, prep, st.R, st.t, cfg)
        plain = None
        Rn, tn, v, m, far = step(P, ev, st.R, st.t, method, radius, mp)
        if crit.done(prev, ev, m, far):
            _record(st, name, loss, P.shape[0], ev)
            return ev, True, ""
        if k == max_it:
            break
        if aa is not None:
            fast = aa(st.R, st.t, Rn, tn)
            if fast is not None:
                plain = (Rn, tn)
                Rn, tn = fast
                v = _motion(st.R, st.t, Rn, tn, centroid(ev.X, ev.w))
        _record(st, name, loss, P.shape[0], ev, v, m)
        prev = (ev.sigma, ev.objective)
        st.R, st.t = Rn, tn
        st.iterations += 1
        ev = _anneal(evaluate(P, prep, st.R, st.t, cfg), ev.sigma, anneal, cfg)
    _record(st, name, loss, P.shape[0], ev)
    return ev, False, f"stage {name!r} hit max_iterations={max_it}"


def _mean_rho(ev: Eval, sigma: float) -> float:
    """The objective of an evaluation at another scale (the previous iteration's)."""
    if sigma == ev.sigma:
        return float(ev.objective)
    return float(np.mean(ev.loss.rho(ev.d[ev.valid], sigma)))


def pose_increment(theta, radius: float) -> float:
    """Length (mm) of a pose step theta = (omega rad, tau mm at the centroid):
    ``|omega| * radius + |tau|``, the largest displacement it gives a point of the scan."""
    return float(np.linalg.norm(theta[:3]) * radius + np.linalg.norm(theta[3:]))


def _verify(P, prep, st: State, ev: Eval, cfg: StageSettings, rng, mp):
    """Re-match a random subset at the final pose: are the fixed planes still right?

    Returns (ok, delta, dobj): ``ok`` when the correction the fresh closest points ask for is
    below the tolerance, below 0.1 standard deviation of the subset's own estimate, or moves no
    scan point by more than :data:`POSE_FRACTION` x sigma; ``delta`` that correction (mm, see
    :func:`pose_increment`); ``dobj`` the relative change of the subset's objective between the
    fixed planes and the fresh matching.
    """
    radius, tol = cfg.radius, cfg.tolerance
    n = P.shape[0]
    S = np.arange(n) if n <= VERIFY else np.sort(rng.choice(n, VERIFY, replace=False))
    fresh = match(P[S], prep, st.R, st.t)
    df, vf = fresh.d, fresh.valid
    if np.mean(vf == ev.valid[S]) < 0.999:
        return False, np.inf, np.inf
    both = vf & ev.valid[S]
    delta = np.where(both, df - ev.d[S], 0.0)
    w = np.where(both, ev.w[S], 0.0)
    if np.count_nonzero(w) < 6:
        return False, np.inf, np.inf
    center = centroid(ev.X, ev.w)
    XS = ev.X[S]
    Hs, gs = system(XS, XS - delta[:, None] * ev.N[S], ev.N[S], w, center)
    H, _ = system(ev.X, ev.Y, ev.N, ev.w, center)
    theta, _ = solve_step(Hs, gs, radius, null=null_directions(ev, mp, H, center, radius))
    # the correction the re-matched subset asks for, in standard deviations of the subset's
    # own estimate (a pure noise-like correction does not grow with the subset's size)
    m = float(np.sqrt(max(theta @ Hs @ theta, 0.0))) / ev.sigma
    inc = pose_increment(theta, radius)
    if m <= max(np.sqrt(tol * both.sum()), VERIFY_SIGMA):
        return True, inc, 0.0
    rho = ev.loss.rho
    o_fix = float(np.mean(rho(ev.d[S][both], ev.sigma)))
    o_new = float(np.mean(rho(df[both], ev.sigma)))
    dobj = abs(o_new - o_fix) / max(o_fix, 1e-300)
    return inc <= POSE_FRACTION * ev.sigma and dobj <= OBJECTIVE_RTOL, inc, dobj


def stage_final_plane(P, prep, st: State, cfg: StageSettings, rng,
                      rounds: int = 4) -> tuple[Eval, bool, str]:
    """Point-to-plane on every point against fixed tangent planes, verified (module docstring).

    ``cfg.method`` is ignored (always point-to-plane)."""
    loss, radius, max_it = cfg.loss, cfg.radius, cfg.max_iterations
    steps = 0
    ev = None
    mp = model_points(prep)
    for _ in range(rounds):
        m0 = match(P, prep, st.R, st.t)
        ev = weigh(m0, loss, cfg.scale, cfg.floor, cfg.overlap)
        crit = _Criterion(cfg.tolerance, Method.POINT_TO_PLANE)
        prev = None
        matched = True
        null = None   # the geometry of this matching: its undetermined directions are fixed
        while True:
            if null is None:
                c0 = centroid(ev.X, ev.w)
                null = null_directions(ev, mp, system(ev.X, ev.Y, ev.N, ev.w, c0)[0], c0,
                                       radius)
            Rn, tn, v, m, far = step(P, ev, st.R, st.t, Method.POINT_TO_PLANE, radius, mp, null)
            if crit.done(prev, ev, m, far):
                _record(st, "final", loss, P.shape[0], ev, matched=matched)
                break
            if steps == max_it:
                _record(st, "final", loss, P.shape[0], ev, matched=matched)
                return ev, False, f"stage 'final' hit max_iterations={max_it}"
            _record(st, "final", loss, P.shape[0], ev, v, m, matched)
            matched = False
            prev = (ev.sigma, ev.objective)
            st.R, st.t = Rn, tn
            st.iterations += 1
            steps += 1
            ev = evaluate_fixed(P, st.R, st.t, m0, cfg)
        ok, inc, dobj = _verify(P, prep, st, ev, cfg, rng, mp)
        if ok:
            return ev, True, ""
    return ev, False, (f"the pose is still moving after {rounds} re-matchings of all points: "
                       f"fresh closest points ask for a further {inc:.3g} mm "
                       f"({inc / ev.sigma:.2g} sigma; converged means <= {POSE_FRACTION} sigma) "
                       f"and change the objective by {100 * dobj:.2g} %")
