"""Alignments the way parts are fixtured: best fit on faces, constrained, RPS, datum features.

Every alignment returns an :class:`AlignmentResult`: the pose ``T_model_scan`` (model = R @ scan
+ t), its covariance in the parameterisation of :class:`shapeverify.registration.Registration`
(``e = (rotation vector rad, translation mm)`` acting on the left, model frame, about the model
origin), its residuals, and which degrees of freedom it determined (``dof_fitted``) or held at
the start pose (``dof_locked``).

* :func:`best_fit` -- robust point-to-plane Gauss-Newton (IRLS, Tukey by default, scale
  ``1.4826 median |r|``) on the points whose exact closest CAD point lies on the named faces.
* :func:`constrained_fit` -- the same in the free degrees of freedom only.  The pose is
  ``T = M(p) @ T0`` with ``M(p) = [R(p), c + t - R(p) c]``, ``R(p) = Rz(rz) Ry(ry) Rx(rx)``
  about the centre ``c`` and ``t = (tx, ty, tz)``; the locked parameters are exactly 0, so the
  locked coordinates do not move (e.g. ``free: [tz, rz]`` keeps x, y and the tilt of the start).
* :func:`rps_alignment` -- reference points (RPS): each locks one to three model axes at a point;
  a point at a hole locks the hole's measured centre (:func:`.holes.measure_hole`) to the CAD
  hole's centre, any other point the scan's surface there: the mean deviation (along the CAD
  normal n) of the scan within ``radius`` of the CAD point q nearest to the point, divided by
  ``n . axis``, must vanish.  The six (or more)
  lock equations are solved by Gauss-Newton; residuals are the remaining differences (zero for
  exactly six independent locks, the 3-2-1 rule).
* :func:`.datums.datum_alignment` -- datum features A (plane), B (hole/cylinder axis or plane), C
  (hole/cylinder axis or plane) fitted on the scan (robust fits of :mod:`shapeverify.fitting`,
  Tukey loss) define a frame; the pose maps the measured frame onto the CAD's.  A fixes 3 DOFs
  (its normal and offset), B 2, C 1.

Starts and convergence (issue 27).  A fixture-like alignment needs the right *placement* of the
scan on the part first (an upside-down plate fits its datum plane and holes as well as the right
one): RPS and datums, and a best fit without a trusted free registration, start from the
placement the whole scan fits best among the caller's start and the global search's
(:mod:`.placement`, the search :func:`shapeverify.register` makes with no start); RPS and datums
are solved at each placement and pick among those that fit alike by their own fit (lock or datum
misfit); two that fit alike give a warning (``details['warnings']``).  The Gauss-Newton fits stop when the step still
to take is small against the pose's own standard deviation or the noise (:func:`best_fit`'s
``rtol``), as the registration does: a clean scan converges.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from .._renamed import renamed_keywords
from ..registration.losses import MAD_TO_SIGMA, get_loss
from ..registration.rigid import apply_transform, compose_step, make_transform, rotation_vector
from .features import faces_named, find_feature, model_features
from .holes import measure_hole
from .plan import DOF_NAMES

__all__ = ["AlignmentResult", "best_fit", "constrained_fit", "rps_alignment", "euler_pose",
           "face_indices", "align", "m_estimator_sandwich"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False, repr=False)
class AlignmentResult:
    """Result of an alignment.

    Attributes
    ----------
    T_model_scan : (4, 4) float64
    covariance : (6, 6) float64
        Pose covariance (e = (omega rad, tau mm), left, model frame, about the origin); zero in
        the locked directions (the fixture's own uncertainty is not known).
    residuals : (k,) float64
        Per point (best fit: signed distances of the weighted points), per lock (RPS) or per
        datum (RMS of its fit), mm.
    rms : float
        RMS of ``residuals`` (best fit: of the inliers), mm.
    dof_fitted, dof_locked : tuple of str
        Degrees of freedom the data determined / held at the start pose.
    kind : str
        'best_fit', 'constrained', 'rps' or 'datums'.
    details : dict
        Alignment-specific facts (JSON-ready): iterations, points used, lock residuals...
    """

    T_model_scan: np.ndarray
    covariance: np.ndarray
    residuals: np.ndarray
    rms: float
    dof_fitted: tuple
    dof_locked: tuple
    kind: str
    details: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"type": self.kind, "T_model_scan": self.T_model_scan.tolist(),
                "rms": float(self.rms), "dof_fitted": list(self.dof_fitted),
                "dof_locked": list(self.dof_locked),
                "pose_std": [float(np.sqrt(max(v, 0.0))) if np.isfinite(v) else None
                             for v in np.diag(self.covariance)],
                **self.details}

    def __repr__(self) -> str:
        return (f"AlignmentResult(kind={self.kind!r}, rms={self.rms:.4g}, "
                f"dof_fitted={list(self.dof_fitted)}, dof_locked={list(self.dof_locked)})")


# ------------------------------------------------------------------------------ poses
def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _drot(p):
    """R(p) and its derivatives dR/drx, dR/dry, dR/drz (R = Rz Ry Rx)."""
    X, Y, Z = _rx(p[0]), _ry(p[1]), _rz(p[2])
    K = [np.array([[0, 0, 0], [0, 0, -1], [0, 1, 0]]), np.array([[0, 0, 1], [0, 0, 0], [-1, 0, 0]]),
         np.array([[0, -1, 0], [1, 0, 0], [0, 0, 0]])]
    R = Z @ Y @ X
    return R, (Z @ Y @ X @ K[0], Z @ Y @ K[1] @ X, Z @ K[2] @ Y @ X)


def euler_pose(p, center=(0.0, 0.0, 0.0)) -> np.ndarray:
    """``M(p)`` (4, 4) for ``p = (rx, ry, rz, tx, ty, tz)`` (rad, mm): rotation
    ``Rz Ry Rx`` about ``center``, then translation."""
    p = np.asarray(p, np.float64)
    c = np.asarray(center, np.float64)
    R, _ = _drot(p)
    return make_transform(R, c + p[3:] - R @ c)


def _p_to_e(p, center, free) -> np.ndarray:
    """(6, k): d e / d p_free at p (e the left, origin-based pose perturbation)."""
    R, dR = _drot(p)
    c = np.asarray(center, np.float64)
    t = p[3:]
    cols = []
    for j in free:
        if j < 3:
            W = dR[j] @ R.T
            w = np.array([W[2, 1], W[0, 2], W[1, 0]])
            cols.append(np.r_[w, np.cross(c + t, w)])
        else:
            cols.append(np.r_[np.zeros(3), np.eye(3)[j - 3]])
    return np.array(cols).T


def face_indices(model, faces) -> np.ndarray | None:
    """Face indices of a plan's ``faces`` entry ('all' -> None; ids, ints or CAD face names --
    a name stands for every face that carries it)."""
    if faces is None or faces == "all":
        return None
    feats = model_features(model) if getattr(model, "kind", None) == "cad" else []
    out = []
    for f in faces:
        if isinstance(f, (int, np.integer)):
            ks = [int(f)]
        else:
            named = faces_named(feats, str(f))
            ks = [g.face for g in named] if named else [find_feature(feats, f, kind="face").face]
        for k in ks:
            if not 0 <= k < len(model.faces):
                raise ValueError(f"face {f} does not exist: the model has {len(model.faces)} "
                                 f"faces (0..{len(model.faces) - 1})")
        out.extend(ks)
    return np.unique(np.array(out, np.int64))


# ------------------------------------------------------------------------------ best fits
def m_estimator_sandwich(J, psi, dpsi) -> np.ndarray:
    """``n / (n - p) H^-1 B H^-1`` with ``H = sum psi' J^T J``, ``B = sum psi^2 J^T J``.

    The covariance of an M-estimate with Jacobian J (n, p) of the residuals, influence
    ``psi`` (n,) and its derivative ``dpsi`` (n,) (Huber 1981, §7.6; the same estimator as
    :func:`shapeverify.registration.rigid.pose_covariance`).  When ``H`` is not positive
    definite (a redescending psi' < 0 on many points) Huber's homogeneous bread
    ``mean(psi') J^T J`` is used.  Pseudo-inverse in directions J does not determine.
    """
    n, k = J.shape
    H = (J * dpsi[:, None]).T @ J
    lam = np.linalg.eigvalsh(H)
    if lam[0] <= -1e-12 * max(abs(lam[-1]), 1e-300):
        H = max(float(np.mean(dpsi)), 1e-12) * (J.T @ J)
    Hinv = np.linalg.pinv(H, rcond=1e-12, hermitian=True)
    Jb = J * psi[:, None]
    C = Hinv @ (Jb.T @ Jb) @ Hinv
    return C * (n / (n - k) if n > k else 1.0)


#: a step that moves no scan point by more than this many noise sigmas ends the iterations
MOVE_SIGMA = 0.05
#: scan points (an even subset) each placement is refined on before their fits are compared
_REFINE_POINTS = 20_000
#: placements told apart by fewer of the whole fit's points than this fit alike (a warning)
_ALIKE_POINTS = 10


def _gauss_newton(scan, prep, T0, free, center, faces, loss, max_iterations, tol, reach,
                  degenerate_ok=False):
    P = np.asarray(scan, np.float64)
    lossobj = get_loss(loss)
    X0 = apply_transform(T0, P)
    c = np.asarray(center, np.float64)
    p = np.zeros(6)
    free = list(free)
    size = float(getattr(prep.model, "size", 1.0))
    floor = 1e-6 * max(size, 1.0)
    Q = X0 - c
    # the columns of Q (no (N, 3) @ (3, 3) products: BLAS threads for a 3-wide product cost
    # more than the product)
    qx, qy, qz = (np.ascontiguousarray(Q[:, i]) for i in range(3))

    def rows(M, a, b, _=None):
        """The three columns of ``Q @ M.T + b`` (plus ``a`` per column)."""
        return [qx * M[i, 0] + qy * M[i, 1] + qz * M[i, 2] + (a[i] + b[i]) for i in range(3)]

    def linearise(p, check):
        """Closest points at pose ``p``: residuals, valid points, scale, weights, Jacobian."""
        R, dR = _drot(p)
        X = np.column_stack(rows(R, c, p[3:], None))
        cl = prep.closest(X, exact=True)
        r = cl.distances
        valid = ~cl.on_boundary & (np.abs(r) <= reach)
        if faces is not None:
            valid &= np.isin(cl.face, faces)
        if check and np.count_nonzero(valid) < 2 * len(free) + 3:
            raise ValueError(f"only {int(np.count_nonzero(valid))} scan points lie on the "
                             "alignment faces within reach; check the face list and the start pose")
        sigma = max(MAD_TO_SIGMA * float(np.median(np.abs(r[valid]))), floor)
        w = np.where(valid, lossobj.weight(r, sigma), 0.0)
        J = np.empty((P.shape[0], len(free)))
        nx, ny, nz = (cl.normals[:, i] for i in range(3))
        zero = np.zeros(3)
        for k, j in enumerate(free):
            if j < 3:
                dx, dy, dz = rows(dR[j], zero, zero, None)
                J[:, k] = nx * dx + ny * dy + nz * dz
            else:
                J[:, k] = cl.normals[:, j - 3]
        return r, valid, sigma, w, J

    it, converged = 0, False
    mscale = np.array([size if j < 3 else 1.0 for j in free])
    rot = np.array([j < 3 for j in free])
    arm = float(np.sqrt(np.max(np.sum((X0 - c) ** 2, axis=1))))   # farthest point from c
    state = None
    for it in range(1, max_iterations + 1):
        state = linearise(p, True)
        r, valid, sigma, w, J = state
        Jw = J * w[:, None]
        H = Jw.T @ J
        g = Jw.T @ r
        # geometric scaling (rotation columns are lengths times the model size): a direction
        # the faces do not determine keeps a tiny eigenvalue (diagonal scaling would hide it)
        scale = mscale * np.sqrt(max(float(w.sum()), 1.0))
        Hs = H / np.outer(scale, scale)
        lam, V = np.linalg.eigh(Hs)
        det = lam > 1e-8 * lam[-1]
        if not det.all() and not degenerate_ok:
            names = [DOF_NAMES[j] for j in free]
            raise ValueError(f"the alignment faces do not determine the free degrees of freedom "
                             f"{names} (flat or cylindrical geometry); lock some or add faces")
        inv = np.where(det, 1.0 / np.where(det, lam, 1.0), 0.0)   # no step where undetermined
        step = -(V * inv) @ (V.T @ (g / scale)) / scale
        # converged when the step still to take is small against the pose's own uncertainty
        # (sigma^2 H^-1: its length in standard deviations) or moves no scan point by more
        # than a small share of the noise -- the registration's rule (register's Notes); the
        # pose stays where the residuals were taken (the step is below the noise)
        n_std = float(np.sqrt(max(step @ H @ step, 0.0))) / sigma
        moved = float(np.linalg.norm(step[rot]) * arm + np.linalg.norm(step[~rot]))
        if n_std < tol or moved < MOVE_SIGMA * sigma:
            converged = True
            break
        p[free] += step
        state = None
    if state is None:              # stopped after a step: the state at the final p
        state = linearise(p, False)
    r, valid, sigma, w, J = state
    # sandwich covariance in p at the final state
    # M-estimator sandwich (Huber 1981, §7.6), the estimator of
    # registration.rigid.pose_covariance in the free parameters: psi' in the bread (with the
    # IRLS weights there a redescending loss is reported ~1.46x too precise)
    Jv, rv = J[valid], r[valid]
    hh = 1e-6 * sigma

    def psi(x):
        return lossobj.weight(x, sigma) * x

    Cp = m_estimator_sandwich(Jv, psi(rv), (psi(rv + hh) - psi(rv - hh)) / (2 * hh))
    A = _p_to_e(p, c, free)
    cov = A @ Cp @ A.T
    T = euler_pose(p, c) @ T0
    inl = valid & (np.abs(r) <= lossobj.c * sigma)
    rms = float(np.sqrt(np.mean(r[inl] ** 2))) if inl.any() else float("nan")
    return T, 0.5 * (cov + cov.T), r[valid], rms, p, it, converged, int(valid.sum()), sigma


def _reach(prep, reach):
    if reach is not None:
        return float(reach)
    return float(max(getattr(prep, "reach", 1.0), 3.0 * prep.spacing))


@renamed_keywords(tolerance="rtol")
def best_fit(scan, prep, faces=None, init=None, loss: str = "tukey", max_iterations: int = 50,
             rtol: float = 0.1, reach: float | None = None, rng=None,
             degenerate_ok: bool = False) -> AlignmentResult:
    """Free 6-DOF robust best fit, on all faces or on the faces named.

    Parameters
    ----------
    scan : (N, 3) float64
        Scan points (scan frame, mm).
    prep : Prepared
    faces : None, 'all' or sequence of face ids ('face:3', 3, a face name)
        Only points whose exact closest CAD point lies on these faces count.
    init : (4, 4) or None
        Start pose; None: the placement the whole scan fits best of the global search's
        (:mod:`.placement`, the search :func:`shapeverify.register` makes with no start).
    loss : str
        Robust loss of :mod:`shapeverify.registration.losses`.
    reach : float, optional
        Points farther than this from the CAD are ignored (default: ``prep.reach``).
    rtol : float
        Convergence, judged against the scan's noise as :func:`shapeverify.register` judges
        it: the Gauss-Newton step still to take is shorter than ``rtol`` standard
        deviations of the pose (``sqrt(s^T H s) / sigma``, ``H`` the weighted normal matrix,
        ``sigma`` the robust residual scale), or moves no scan point by more than
        :data:`MOVE_SIGMA` sigma.  The pose is the one where the residuals were taken.
    degenerate_ok : bool
        False: faces that leave a pose direction undetermined (one plane, one cylinder) are an
        error.  True: no step in those directions (they keep ``init``'s value).

    Returns
    -------
    AlignmentResult

    Raises
    ------
    ValueError
        Too few points on the faces, or undetermined directions (unless ``degenerate_ok``).
    """
    fidx = face_indices(prep.model, faces)
    if init is None:
        T0 = _best_start(scan, prep, None, 0 if rng is None else rng)[0]
    else:
        T0 = _check_T(init)
    T, cov, res, rms, p, it, ok, n, sigma = _gauss_newton(
        scan, prep, T0, range(6), np.zeros(3), fidx, loss, max_iterations, rtol,
        _reach(prep, reach), degenerate_ok)
    return AlignmentResult(T, cov, res, rms, DOF_NAMES, (), "best_fit",
                           {"iterations": it, "converged": ok, "n_points": n, "scale": sigma,
                            "faces": "all" if fidx is None else fidx.tolist()})


@renamed_keywords(tolerance="rtol")
def constrained_fit(scan, prep, free, init=None, center=(0.0, 0.0, 0.0), faces=None,
                    loss: str = "tukey", max_iterations: int = 50, rtol: float = 0.1,
                    reach: float | None = None) -> AlignmentResult:
    """Best fit in the free degrees of freedom only; the locked ones stay at ``init``.

    Parameters
    ----------
    free : sequence of {'rx', 'ry', 'rz', 'tx', 'ty', 'tz'}
        Rotations about the model axes through ``center``, translations along them.
    init : (4, 4) or None
        The fixture's pose (None: identity, the scan is already in the model frame).
    center : (3,)
        Centre of the rotations (model frame, mm).
    rtol : float
        Convergence against the pose's standard deviation and the noise, as :func:`best_fit`.

    Returns
    -------
    AlignmentResult
        ``details['parameters']``: the six parameters of ``M(p)`` (locked ones exactly 0).

    Raises
    ------
    ValueError
        Unknown DOF names, or free DOFs the faces do not determine.
    """
    names = list(free)
    bad = [f for f in names if f not in DOF_NAMES]
    if bad or not names:
        raise ValueError(f"free must name degrees of freedom from {DOF_NAMES}, got {names}")
    idx = sorted(DOF_NAMES.index(f) for f in set(names))
    T0 = np.eye(4) if init is None else _check_T(init)
    fidx = face_indices(prep.model, faces)
    T, cov, res, rms, p, it, ok, n, sigma = _gauss_newton(
        scan, prep, T0, idx, center, fidx, loss, max_iterations, rtol, _reach(prep, reach))
    locked = tuple(d for d in DOF_NAMES if DOF_NAMES.index(d) not in idx)
    return AlignmentResult(T, cov, res, rms, tuple(DOF_NAMES[j] for j in idx), locked,
                           "constrained",
                           {"iterations": it, "converged": ok, "n_points": n, "scale": sigma,
                            "parameters": dict(zip(DOF_NAMES, map(float, p))),
                            "center": [float(x) for x in center]})


def _check_T(T) -> np.ndarray:
    T = np.asarray(T, np.float64)
    if T.shape != (4, 4) or not np.isfinite(T).all():
        raise ValueError(f"a pose must be a finite (4, 4) matrix, got shape {T.shape}")
    R = T[:3, :3]
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
        raise ValueError("a pose must be rigid (orthonormal rotation, det +1)")
    return T


# ------------------------------------------------------------------------------ RPS
@renamed_keywords(tolerance="rtol")
def rps_alignment(scan, prep, points, init=None, radius: float = 4.0, max_iterations: int = 20,
                  rtol: float = 1e-10, rng=0) -> AlignmentResult:
    """RPS (reference point system) alignment; 3-2-1 is six single locks.

    Parameters
    ----------
    scan : (N, 3); prep : Prepared
    points : sequence of plan ``RpsPoint`` (or dicts with ``at``, ``lock`` and optionally
        ``feature``, ``radius``, ``name``)
        ``lock``: the model axes ('x', 'y', 'z') whose coordinate the point fixes.
    init : (4, 4) or None
        A start pose.  The locks are solved from every placement of the scan: ``init`` and the
        global search's (:mod:`.placement`); the result the whole scan fits best is taken, and
        among those that fit alike the one whose locks fit best (RMS of residual over
        uncertainty; ``init``'s when it fits alike on both counts).  Two that fit alike on
        both counts give a warning in ``details['warnings']``.
    radius : float
        Default neighbourhood radius of a surface point (mm).

    Returns
    -------
    AlignmentResult
        ``residuals``: one per lock (measured - nominal coordinate, mm);
        ``details['locks']``: name, axis, residual and the uncertainty of each lock.

    Raises
    ------
    ValueError
        Fewer than six independent locks (the message names the undetermined directions), a
        lock along a surface (a surface point can only lock an axis across it), or points not
        scanned.
    """

    pts = [p if isinstance(p, dict) else p.model_dump() for p in points]
    feats = model_features(prep.model) if prep.model.kind == "cad" else []
    P = np.asarray(scan, np.float64)
    spec = []
    for k, p in enumerate(pts):
        at = np.asarray(p["at"], np.float64)
        hole = None
        if p.get("feature"):
            hole = find_feature(feats, p["feature"], kind="hole")
        else:
            holes = [f for f in feats if f.kind == "hole"]
            if holes:
                h = find_feature(holes, near=at, kind="hole", strict=False)
                q = at - h.center
                if np.linalg.norm(q - (q @ h.axis) * h.axis) <= 0.5 * h.diameter:
                    hole = h
        spec.append((p.get("name") or f"P{k + 1}", at, [("xyz".index(a)) for a in p["lock"]],
                     hole, float(p.get("radius") or radius)))
    n_locks = sum(len(s[2]) for s in spec)
    feet = prep.closest(np.array([s[1] for s in spec]), exact=True)
    T, where, warns, it, J, Wh, r, unc, info = _rps_at_placements(
        P, prep, spec, n_locks, feet, None if init is None else _check_T(init), rng,
        max_iterations, rtol)
    Js = J * Wh[:, None]
    cov = np.linalg.pinv(Js.T @ Js)
    locks = [{"point": nm, "axis": ax, "kind": kd, "residual": float(v), "uncertainty": float(u)}
             for (nm, ax, kd), v, u in zip(info, r, unc)]
    return AlignmentResult(T, 0.5 * (cov + cov.T), r, float(np.sqrt(np.mean(r * r))), DOF_NAMES,
                           (), "rps", {"iterations": it, "locks": locks, "warnings": warns,
                                       "placement": where})


def _rps_at_placements(P, prep, spec, n_locks, feet, init, rng, max_iterations, rtol):
    """The RPS locks solved from every placement of the scan (:mod:`.placement`: the caller's
    start and the global search's poses); judged by the whole scan's fit at the result, and
    among those that fit alike by the locks' misfit (RMS of residual / uncertainty); the
    caller's start when it fits alike on both counts.  Two that fit alike on both counts and
    are distinct give a warning.  A placement where a lock cannot be solved (a point not
    scanned there) is left out; when every one fails, the error of the best-fitting one."""
    from .placement import ALIKE, placements, scan_noise_of, whole_fit

    noise = scan_noise_of(P)
    tried, failed = [], []
    for name, T0 in placements(P, prep, init, rng):
        try:
            out = _rps_solve(P, prep, spec, n_locks, feet, T0, max_iterations, rtol)
        except ValueError as exc:
            failed.append((whole_fit(P, prep, T0, noise), name, exc))
            continue
        r, unc = out[4], out[5]
        tried.append({"name": name, "out": out, "fit": whole_fit(P, prep, out[0], noise),
                      "misfit": float(np.sqrt(np.mean((np.asarray(r) / np.asarray(unc)) ** 2)))})
    if not tried:
        failed.sort(key=lambda f: -f[0])
        raise failed[0][2]
    best = max(t["fit"] for t in tried)
    alike = sorted([t for t in tried if t["fit"] >= ALIKE * best], key=lambda t: t["misfit"])
    ch = alike[0]
    st = next((t for t in alike if t["name"] == "start"
               and t["misfit"] <= 1.2 * ch["misfit"] + 0.5), None)
    ch = st or ch
    warns = []
    if init is not None and st is None:
        f0 = next((t["fit"] for t in tried if t["name"] == "start"), None)
        if f0 is not None:
            warns.append(f"the given start fits the scan worse than the global search's "
                         f"placement (whole fit {f0:.3f} vs {ch['fit']:.3f}): started from "
                         "the latter")
    T = ch["out"][0]
    for t in ([] if st is not None else alike):
        if t is ch:
            continue
        D = t["out"][0] @ np.linalg.inv(T)
        ang = float(np.degrees(np.linalg.norm(rotation_vector(D[:3, :3]))))
        if (ang > 1.0 or np.linalg.norm(D[:3, 3]) > 0.01 * prep.model.size) and \
                t["misfit"] <= 1.2 * ch["misfit"] + 0.5:
            warns.append(f"another placement of the scan ({t['name']}) fits it and the RPS "
                         f"locks alike (whole fit {t['fit']:.3f} vs {ch['fit']:.3f}, lock misfit "
                         f"{t['misfit']:.2f} vs {ch['misfit']:.2f}, {ang:.1f} deg away): the "
                         "pose may be a symmetric copy; give init= to choose")
    return (T, ch["name"], warns, *ch["out"][1:])


def _rps_solve(P, prep, spec, n_locks, feet, T, max_iterations, rtol):
    """Gauss-Newton on the RPS locks from the pose T: (T, iterations, J, weights, residuals,
    uncertainties, lock info)."""
    rows, res, unc, info = None, None, None, []
    for it in range(1, max_iterations + 1):
        X = apply_transform(T, P)
        cl = prep.closest(X, exact=True)
        ok = ~cl.on_boundary & (np.abs(cl.distances) <= _reach(prep, None))
        rows, res, unc, info = [], [], [], []
        for i, (name, at, axes, hole, rad) in enumerate(spec):
            if hole is not None:
                hm = measure_hole(X, hole.center, hole.axis, hole.diameter,
                                  face=prep.model.faces[hole.face], deviations=cl.distances,
                                  normals=cl.normals)
                c = hm.center
                for k in axes:
                    e = np.eye(3)[k]
                    rows.append(np.r_[np.cross(c, e), e])
                    res.append((c - hole.center)[k])
                    unc.append(max(hm.u_center, 1e-6))
                    info.append((name, "xyz"[k], "hole"))
                continue
            # a surface point: the scan's mean deviation (along the CAD normal) around the CAD
            # point q nearest to `at`, turned into a shift along the locked axis
            q, n, fc = feet.points[i], feet.normals[i], feet.face[i]
            m = ok & (cl.face == fc) & (np.linalg.norm(cl.points - q, axis=1) <= rad)
            if np.count_nonzero(m) < 3:
                raise ValueError(f"only {int(np.count_nonzero(m))} scan points within {rad:g} mm "
                                 f"of the RPS point {name} {np.round(q, 3).tolist()}; is that "
                                 "area scanned?")
            dm = cl.distances[m]
            u = max(float(dm.std()) / np.sqrt(dm.size), 1e-6)
            for k in axes:
                a = np.eye(3)[k]
                na = n @ a
                if abs(na) < 0.2:
                    raise ValueError(f"RPS point {name} locks {'xyz'[k]}, which runs along the "
                                     "surface there (|normal . axis| < 0.2); lock the axis "
                                     "across the surface or use a hole")
                rows.append(np.r_[np.cross(q, n), n] / na)
                res.append(float(dm.mean()) / na)
                unc.append(u / abs(na))
                info.append((name, "xyz"[k], "surface"))
        J = np.array(rows)
        r = np.array(res)
        Wh = 1.0 / np.array(unc)
        Js = J * Wh[:, None]
        # geometric conditioning: rotation columns scaled by the model size (all lengths)
        size = max(float(prep.model.size), 1e-9)
        Jg = J / np.r_[[size] * 3, [1.0] * 3]
        sv = np.linalg.svd(Jg, compute_uv=False)
        if Js.shape[0] < 6 or sv[-1] <= 1e-2 * sv[0]:
            _, _, Vt = np.linalg.svd(Jg)
            raise ValueError(f"the {n_locks} RPS locks do not fix all six degrees of freedom "
                             f"(undetermined pose direction e = {np.round(Vt[-1], 3).tolist()}); "
                             "3-2-1: lock z at three points, x and y at a hole, y at another")
        delta, *_ = np.linalg.lstsq(Js, -r * Wh, rcond=None)
        R, t = compose_step(T[:3, :3], T[:3, 3], delta, np.zeros(3))
        T = make_transform(R, t)
        if np.max(np.abs(delta[3:])) + prep.model.size * np.max(np.abs(delta[:3])) < rtol * \
                max(prep.model.size, 1.0):
            break
    return T, it, J, Wh, np.array(res), np.array(unc), info


def _best_start(scan, prep, init, rng):
    """Of ``init`` (if any), the global search's placements and the global pose's half turns
    (:mod:`.placement`), each refined by a short best fit, the pose the whole scan fits best:
    ``(T, name, warnings)``; a warning names each distinct placement that fits alike (within
    :data:`.placement.ALIKE` and told apart by fewer than ``_ALIKE_POINTS`` of 20,000 points).
    Chamfered plate, 1 mm, random poses: the 180-degree copy was taken silently in 5 of 40
    runs; now the right pose (a near-symmetric part's copies are refined before they are
    compared)."""
    from .placement import ALIKE, TRY_SHARE, placements, scan_noise_of, whole_fit

    P = np.asarray(scan, np.float64)
    noise = scan_noise_of(P)
    # each placement is refined (a short best fit on an even subset) before the whole fits are
    # compared: the global search's poses are rough (a tenth of a mm), the truncated fit is
    # sharp (3 noise sigmas), and a part told from its symmetric copy by a small feature (the
    # chamfered plate: 0.3 % of its area) was judged by the roughness of the poses -- the
    # copy won 5 of 40 random starts, and the right pose was not even "alike" to warn
    sub = P[np.linspace(0, P.shape[0] - 1, min(P.shape[0], _REFINE_POINTS)).astype(np.int64)]
    tried = [(nm, T0, whole_fit(P, prep, T0, noise))
             for nm, T0 in placements(P, prep, init, rng, turns=True)]
    best0 = max(f for _, _, f in tried)
    cands = []
    for nm, T0, f0 in tried:
        if f0 < TRY_SHARE * best0 and nm != "start":
            continue
        try:
            T1 = best_fit(sub, prep, init=T0, max_iterations=30).T_model_scan
        except ValueError:
            T1 = T0
        cands.append((nm, T1, whole_fit(P, prep, T1, noise, n=_REFINE_POINTS)))
    cands.sort(key=lambda c: -c[2])
    best = cands[0][2]
    # alike: within ALIKE of the best, and fewer than _ALIKE_POINTS of the fit's points tell
    # them apart (refined copies of a symmetric part score the same points alike; the plate's
    # chamfer: about 0.005 of them, 65 of 13,000)
    m = min(P.shape[0], _REFINE_POINTS)
    alike = [c for c in cands if c[2] >= ALIKE * best and (best - c[2]) * m < _ALIKE_POINTS]
    # the caller's start, when it fits alike, is the caller's choice among symmetric copies
    chosen = next((c for c in alike if c[0] == "start"), alike[0])
    nm, T, f0 = chosen
    if nm == "start":
        return T, nm, []
    warns = [f"another placement of the scan ({n2}) fits it alike (whole fit {f:.3f} vs "
             f"{f0:.3f}): the pose may be a symmetric copy; give init= to choose"
             for n2, T2, f in alike if n2 != nm
             and np.degrees(np.linalg.norm(rotation_vector(T2[:3, :3] @ T[:3, :3].T))) > 1.0]
    if init is not None:
        warns.append(f"the given start fits the scan worse than the global search's placement "
                     f"(whole fit {[c[2] for c in cands if c[0] == 'start'][0]:.3f} vs {f0:.3f}):"
                     " started from the latter")
    return T, nm, warns


def align(scan, prep, alignment, init=None, rng=None, registration=None) -> AlignmentResult:
    """Run a plan's alignment (a plan alignment model or a dict with ``type``).

    ``registration``: the free registration ``init`` comes from (:func:`shapeverify.register`).
    A best fit starts from it unless it carries warnings of a wrong minimum
    (``Registration.warnings``); otherwise (no registration, or one with warnings) from the
    placement the whole scan fits best of ``init`` and the global search's (:mod:`.placement`;
    ``init`` when it fits alike).  Datums and RPS always look at the placements.
    """
    a = alignment if isinstance(alignment, dict) else alignment.model_dump()
    kind = a["type"]
    if kind == "best_fit":
        warns, start = [], init
        if registration is None or getattr(registration, "warnings", ()):
            start, where, warns = _best_start(scan, prep, None if init is None else _check_T(init),
                                              0 if rng is None else rng)
        res = best_fit(scan, prep, faces=a.get("faces"), init=start, loss=a.get("loss", "tukey"),
                       rng=rng)
        if warns:
            res.details["warnings"] = warns
        return res
    if kind == "constrained":
        return constrained_fit(scan, prep, a["free"], init=init, center=a.get("center", (0, 0, 0)),
                               faces=a.get("faces"), loss=a.get("loss", "tukey"))
    if kind == "rps":
        return rps_alignment(scan, prep, a["points"], init=init, rng=0 if rng is None else rng)
    if kind == "datums":
        from .datums import datum_alignment

        return datum_alignment(scan, prep, a["primary"], a["secondary"], a.get("tertiary"),
                               init=init, rng=0 if rng is None else rng)
    raise ValueError(f"unknown alignment type {kind!r}")
