"""Rigid-body steps of ICP: weighted point-to-point (SVD) and point-to-plane (linearised LS).

Poses are 4x4 homogeneous matrices ``T_model_scan``: ``model = R @ scan + t``.
A small pose change is a 6-vector ``e = (omega, tau)`` -- a rotation vector (rad) and a
translation (mm) -- acting on the left, in model coordinates, about the model origin:
``T_true = exp(e) @ T_est``, to first order ``x -> x + omega x x + tau``.  Covariances and the
Fisher information of this module are expressed in that parameterisation, so that
``e = pose_error(T_est, T_true)`` can be compared with them directly.

References
----------
Bergström (2011), thesis §5.2.1 eq. 7-10 (rigid body movement by SVD with the determinant
correction) and §5.2.2 eq. 11-13 (point-to-plane, linearised six-parameter least squares).
Chen & Medioni (1992); Besl & McKay (1992).
"""
from __future__ import annotations

import numpy as np

__all__ = [
    "rodrigues", "rotation_vector", "make_transform", "apply_transform", "invert_transform",
    "weighted_rigid_fit", "point_to_plane_system", "solve_step", "compose_step",
    "pose_covariance", "fisher_information", "pose_error", "undetermined_directions",
    "DEGENERATE_RTOL",
]

#: Relative eigenvalue (of the information matrix, rotation scaled by the scan's radius)
#: under which a pose direction counts as undetermined by the geometry (flat or cylindrical scan).
DEGENERATE_RTOL = 1e-6


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def rodrigues(omega) -> np.ndarray:
    """Exact rotation matrix (3, 3) of a rotation vector omega (3,) (Rodrigues' formula).

    Series expansions are used for tiny angles, so the result is orthonormal to rounding.
    """
    w = np.asarray(omega, np.float64)
    th2 = float(w @ w)
    K = _skew(w)
    if th2 < 1e-12:
        a = 1.0 - th2 / 6.0
        b = 0.5 - th2 / 24.0
    else:
        th = np.sqrt(th2)
        a = np.sin(th) / th
        b = (1.0 - np.cos(th)) / th2
    return np.eye(3) + a * K + b * (K @ K)


def rotation_vector(R) -> np.ndarray:
    """Rotation vector (3,) (axis * angle, angle in [0, pi]) of a rotation matrix (3, 3)."""
    R = np.asarray(R, np.float64)
    c = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    th = float(np.arccos(c))
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if th < 1e-6:
        return 0.5 * v * (1.0 + th * th / 6.0)
    if np.pi - th > 1e-4:
        return v * (th / (2.0 * np.sin(th)))
    # near pi: axis from the symmetric part
    B = (R + np.eye(3)) / 2.0
    i = int(np.argmax(np.diag(B)))
    axis = B[:, i] / np.sqrt(max(B[i, i], 1e-300))
    axis /= np.linalg.norm(axis)
    if axis @ v < 0:
        axis = -axis
    return axis * th


def make_transform(R, t) -> np.ndarray:
    """4x4 homogeneous transform from R (3, 3) and t (3,)."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def apply_transform(T, X) -> np.ndarray:
    """Apply a 4x4 transform to points X (N, 3): ``X @ R.T + t``."""
    T = np.asarray(T, np.float64)
    return np.asarray(X, np.float64) @ T[:3, :3].T + T[:3, 3]


def invert_transform(T) -> np.ndarray:
    """Inverse of a rigid 4x4 transform (exact: uses R^T)."""
    T = np.asarray(T, np.float64)
    R = T[:3, :3]
    return make_transform(R.T, -R.T @ T[:3, 3])


def weighted_rigid_fit(P, Y, w=None) -> tuple[np.ndarray, np.ndarray]:
    """Weighted rigid body movement: ``argmin_{R in SO(3), t} sum w_k |R p_k + t - y_k|^2``.

    Thesis eq. 7-10 with weights: weighted centroids, weighted cross-covariance
    ``S = sum w (y - mu_Y)(p - mu_P)^T = U Sigma V^T`` and
    ``R = U diag(1, 1, det(U V^T)) V^T`` (the determinant correction keeps det R = +1),
    ``t = mu_Y - R mu_P``.

    Parameters
    ----------
    P, Y : (N, 3) float64
        Points to move and their targets.
    w : (N,) float64 >= 0 or None
        Weights (at least three non-collinear points must carry weight).

    Returns
    -------
    R : (3, 3), t : (3,)
    """
    P = np.asarray(P, np.float64)
    Y = np.asarray(Y, np.float64)
    w = np.ones(P.shape[0]) if w is None else np.asarray(w, np.float64)
    sw = w.sum()
    mp = (w @ P) / sw
    my = (w @ Y) / sw
    S = ((Y - my) * w[:, None]).T @ (P - mp)
    U, _, Vt = np.linalg.svd(S)
    d = np.sign(np.linalg.det(U @ Vt)) or 1.0
    R = U @ np.diag([1.0, 1.0, d]) @ Vt
    return R, my - R @ mp


def point_to_plane_system(X, Y, N, w, center) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weighted normal equations of the linearised point-to-plane problem (thesis eq. 12-13).

    The residual of point k after a small motion ``x -> x + omega x (x - c) + tau`` about the
    centre c is ``r_k + J_k theta`` with ``r_k = n_k . (x_k - y_k)``,
    ``J_k = [((x_k - c) x n_k)^T, n_k^T]`` and ``theta = (omega, tau)``.

    Parameters
    ----------
    X : (N, 3) current (transformed) scan points; Y : (N, 3) closest model points;
    N : (N, 3) unit model normals at Y; w : (N,) weights; center : (3,)

    Returns
    -------
    H : (6, 6) ``sum w J^T J``;  g : (6,) ``sum w r J``;  r : (N,) residuals
    """
    Q = X - center
    r = np.einsum("ij,ij->i", N, X - Y)
    J = np.empty((X.shape[0], 6))
    J[:, :3] = np.cross(Q, N)
    J[:, 3:] = N
    Jw = J * w[:, None]
    return Jw.T @ J, Jw.T @ r, r


def _scaled(H: np.ndarray, g: np.ndarray, radius: float):
    D = np.array([1.0 / radius] * 3 + [1.0] * 3)
    return H * np.outer(D, D), g * D, D


def solve_step(H, g, radius: float, rtol: float = DEGENERATE_RTOL, null=None):
    """Solve ``H theta = -g`` in the directions the geometry determines.

    The rotation part is scaled by the scan's radius so that all six unknowns are lengths; the
    eigen-directions of the scaled H with eigenvalue below ``rtol * max`` are undetermined
    (a flat or cylindrical scan) and get no step.

    ``null`` (k, 6): directions (scaled coordinates) known to be undetermined from elsewhere
    (e.g. exact model points); they are removed before solving.

    Returns
    -------
    theta : (6,) (omega rad, tau mm);  undetermined : (k, 6) unit eigen-directions (scaled
    coordinates: rotation * radius, translation), k = 0 for a well-posed problem.
    """
    Hs, gs, D = _scaled(H, g, radius)
    if null is not None and len(null):
        U = np.linalg.qr(np.asarray(null, np.float64).T)[0]
        Pr = np.eye(6) - U @ U.T
        Hs = Pr @ Hs @ Pr
        gs = Pr @ gs
    lam, V = np.linalg.eigh(Hs)
    lmax = max(float(lam[-1]), 1e-300)
    ok = lam > rtol * lmax
    inv = np.zeros_like(lam)
    inv[ok] = 1.0 / lam[ok]
    theta_s = -(V * inv) @ (V.T @ gs)
    return theta_s * D, V[:, ~ok].T.copy()


def compose_step(R, t, theta, center) -> tuple[np.ndarray, np.ndarray]:
    """Compose a step (omega, tau) about ``center`` exactly onto the pose (R, t).

    The step is the rigid map ``x -> R0 (x - c) + c + tau`` with ``R0 = rodrigues(omega)``
    (exact rotation, so R stays orthonormal); the new pose is ``R <- R0 R``, ``t <- R0 t + t0``
    with ``t0 = c + tau - R0 c`` (thesis Algorithm 2).
    """
    R0 = rodrigues(theta[:3])
    t0 = center + theta[3:] - R0 @ center
    Rn = R0 @ R
    # re-orthonormalise against accumulated rounding (polar factor, a no-op to ~1e-16)
    U, _, Vt = np.linalg.svd(Rn)
    return U @ Vt, R0 @ t + t0


def _center_to_origin(center) -> np.ndarray:
    # e_origin = A e_center: tau_o = tau_c + c x omega
    A = np.eye(6)
    A[3:, :3] = _skew(np.asarray(center, np.float64))
    return A


def undetermined_directions(undet_scaled, center, radius: float) -> np.ndarray:
    """Convert directions from :func:`solve_step` (scaled, about ``center``) to unit vectors
    ``e = (omega, tau)`` in the model-origin parameterisation, (k, 6)."""
    U = np.atleast_2d(np.asarray(undet_scaled, np.float64)).reshape(-1, 6)
    if U.shape[0] == 0:
        return np.zeros((0, 6))
    A = _center_to_origin(center)
    D = np.array([1.0 / radius] * 3 + [1.0] * 3)
    B = ((U * D) @ A.T).T                      # (6, k) basis in e coordinates
    # canonical basis of the same subspace: pure translations first, then rotations whose
    # translation part has no component along those translations (a screw axis, no slide)
    W, sv, Zt = np.linalg.svd(B[:3], full_matrices=True)
    B = B @ Zt.T
    rot = np.zeros(B.shape[1], bool)
    rot[:min(3, B.shape[1])] = sv[:B.shape[1]] * radius > 1e-6 * np.linalg.norm(B[:, :len(sv)],
                                                                               axis=0)[:len(sv)]
    Tr = B[3:, ~rot]
    if Tr.shape[1]:
        Tq = np.linalg.qr(Tr)[0]
        B[3:, rot] -= Tq @ (Tq.T @ B[3:, rot])
        B[:3, ~rot] = 0.0
        B[3:, ~rot] = Tq
    E = B.T
    n = np.linalg.norm(E, axis=1, keepdims=True)
    return E / np.where(n > 0, n, 1.0)


def pose_covariance(X, N, r, w, center, radius: float, undetermined=None, *, loss=None,
                    sigma: float | None = None) -> np.ndarray:
    """Covariance (6, 6) of the pose from an IRLS fit, in the (omega, tau) model-origin frame.

    The M-estimator sandwich (Huber 1981, §7.6; the heteroscedastic form)::

        C = n / (n - 6) * H^-1 B H^-1,   H = sum psi'(r_i) J_i^T J_i,   B = sum psi(r_i)^2 J_i^T J_i

    with ``psi(r) = w(r) r`` the loss' influence function, ``psi'`` its derivative (by central
    differences of ``loss.weight``), ``J_i = [((x_i - c) x n_i)^T, n_i^T]`` and n the points
    that take part (``w > 0``).  For least squares it is ``sigma^2 (J^T J)^-1``.  The bread
    must use ``psi'``, not the IRLS weights ``w = psi / r``: for a redescending or bounded loss
    ``psi' < w`` (Tukey: ``(1 - u^2)(1 - 5 u^2)`` against ``(1 - u^2)^2``), and with ``w`` in
    the bread the covariance comes out too small by ``(E w / E psi')^2`` -- 1.46 for Tukey,
    1.36 Huber, 1.50 Welsch, 1.58 Cauchy on Gaussian residuals at their 95 %-efficiency
    constants (computed from 2 million normal draws).  When ``H`` is not positive definite
    (a redescending ``psi'`` is negative beyond ``k / sqrt(5)``; possible in small samples)
    Huber's homogeneous form ``mean(psi') J^T J`` over the same points is used instead.

    Parameters
    ----------
    X : (N, 3) points in model coordinates (final pose); N : (N, 3) model normals;
    r : (N,) residuals (mm); w : (N,) final weights (0: the point takes no part; a factor
    beyond the loss' weight, ``w = f * loss.weight(r)``, scales psi and psi' alike);
    center, radius : centring used for conditioning.
    undetermined : (k, 6) or None
        Directions (model-origin ``e`` coordinates) the data do not determine: the entries of
        the covariance they touch are set to ``inf``.
    loss : Loss or str, optional
        The loss of the fit, with ``sigma`` (its scale, mm): gives ``psi'``.  Without it the
        IRLS weights stand in for ``psi'`` (exact for least squares only; too small by the
        factors above for robust losses).
    sigma : float, optional
        Scale of ``loss`` (``k = loss.c * sigma``); required with ``loss``.

    Raises
    ------
    ValueError
        ``loss`` given without a positive ``sigma``.

    References
    ----------
    Huber, P. J. (1981), Robust Statistics, §7.6 (covariance of regression M-estimates).
    """
    X = np.asarray(X, np.float64)
    r = np.asarray(r, np.float64)
    w = np.asarray(w, np.float64)
    Q = X - center
    J = np.empty((X.shape[0], 6))
    J[:, :3] = np.cross(Q, N)
    J[:, 3:] = N
    used = w > 0
    n = int(np.count_nonzero(used))
    if loss is not None:
        if not (sigma is not None and np.isfinite(sigma) and sigma > 0):
            raise ValueError(f"pose_covariance: loss {loss!r} needs its positive scale sigma "
                             f"(mm), got {sigma!r}")
        from ..robust import get_loss
        L = get_loss(loss) if isinstance(loss, str) else loss
        h = 1e-6 * float(sigma)
        dpsi = (L.weight(r + h, sigma) * (r + h) - L.weight(r - h, sigma) * (r - h)) / (2 * h)
        # a per-point factor in the weights beyond the loss' (e.g. an overlap weight) scales
        # psi and so psi' alike
        lw = L.weight(r, sigma)
        dpsi = np.where(used & (lw > 0), dpsi * w / np.where(lw > 0, lw, 1.0), 0.0)
    else:
        dpsi = w
    D = np.array([1.0 / radius] * 3 + [1.0] * 3)

    def inverse(H):
        lam, V = np.linalg.eigh(H * np.outer(D, D))
        ok = lam[0] > -1e-12 * max(lam[-1], 1e-300)
        lam = np.maximum(lam, 1e-16 * max(lam[-1], 1e-300))
        return ((V / lam) @ V.T) * np.outer(D, D), ok

    Hinv, ok = inverse((J * dpsi[:, None]).T @ J)
    if not ok:  # psi' < 0 on too many points: Huber's homogeneous bread
        Ju = J[used]
        Hinv, _ = inverse(max(float(dpsi[used].mean()) if n else 1.0, 1e-12) * (Ju.T @ Ju))
    Jb = J * (w * r)[:, None]
    B = Jb.T @ Jb
    C = Hinv @ B @ Hinv
    if loss is not None and n > 6:
        C *= n / (n - 6.0)
    A = _center_to_origin(center)
    C = A @ C @ A.T
    C = 0.5 * (C + C.T)
    if undetermined is not None and len(undetermined):
        touched = np.any(np.abs(np.asarray(undetermined)) > 1e-9, axis=0)
        C[np.ix_(touched, touched)] = np.inf
    return C


def fisher_information(points, normals, sigma: float) -> np.ndarray:
    """Fisher information (6, 6) of point-to-plane residuals: ``F = sum J_i^T J_i / sigma^2``.

    ``J_i = [(p_i x n_i)^T, n_i^T]`` with p_i in model coordinates and n_i the model normal, in the
    (omega, tau) model-origin parameterisation of this module.  For an efficient estimator,
    ``e^T F e`` with ``e = pose_error(T_est, T_true)`` is chi-square with 6 degrees of freedom
    (the Cramér-Rao bound).
    """
    P = np.asarray(points, np.float64)
    Nn = np.asarray(normals, np.float64)
    J = np.hstack([np.cross(P, Nn), Nn])
    return (J.T @ J) / float(sigma) ** 2


def pose_error(T_est, T_true) -> np.ndarray:
    """Pose error e = (rotation vector rad, translation mm) (6,) with ``T_est = exp(e) T_true``.

    Computed exactly from ``dT = T_est @ inv(T_true)`` (a map model -> model).
    """
    dT = np.asarray(T_est, np.float64) @ invert_transform(T_true)
    return np.concatenate([rotation_vector(dT[:3, :3]), dT[:3, 3]])
