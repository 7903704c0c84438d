"""Signs that a registration's final pose is not the right minimum (``Registration.warnings``,
:func:`pose_warnings`): few inliers, a robust scale broad against the fit distance or against
the scan's own noise (:mod:`._noise`), rejected points that would move the pose, a systematic
mean residual, and a global-search runner-up that fits about as well."""

from __future__ import annotations

import numpy as np

from . import _irls

#: below this inlier fraction the pose is flagged (it may be a wrong minimum)
WARN_INLIERS = 0.5
#: rejected points holding more than this many times the kept points' information in some
#: pose direction are flagged
WARN_REJECTED_INFO = 2.0
#: a robust scale beyond this many fit distances is flagged
WARN_SCALE = 2.0
#: a weighted mean residual beyond this many sigma is flagged as systematic
WARN_MEAN_SIGMA = 0.5
#: another global hypothesis with at least this share of the best fit is flagged
WARN_RUNNER_UP = 0.97
#: a robust scale beyond this many times the scan's own noise (:func:`._noise.scan_noise`) is
#: flagged: right poses measured 1.0-1.1 x on simulated scans (panel with 5 % outliers,
#: impeller), 3.0 x on the real bunny scans (against another noisy scan as the reference);
#: wrong impeller minima 43-62 x
WARN_NOISE = 5.0


def _rejected_information(ev, w, radius) -> float:
    """Largest ratio ``v^T H_rej v / v^T H_w v`` over the eigenvectors v of the weighted
    point-to-plane information H_w (rotation scaled by the scan's radius), H_rej the
    unweighted information of the valid points with weight 0."""
    rej = ev.valid & (w == 0)
    if not rej.any():
        return 0.0
    c = _irls.centroid(ev.X, w)
    r = radius
    D = np.outer(*(2 * [np.r_[[1.0 / r] * 3, [1.0] * 3]]))
    Hw, _ = _irls.system(ev.Y, ev.Y, ev.N, w, c)
    Hr, _ = _irls.system(ev.Y, ev.Y, ev.N, rej.astype(np.float64), c)
    lam, V = np.linalg.eigh(Hw * D)
    ok = lam > 1e-4 * max(lam[-1], 1e-300)   # not the undetermined directions
    if not ok.any():
        return 0.0
    V, lam = V[:, ok], lam[ok]
    return float(np.max(np.einsum("ij,ik,kj->j", V, Hr * D, V) / lam))


def _free_spin(D, undet, tol, radius) -> bool:
    """The relative pose D (4, 4) is a rotation about an undetermined spin axis (a turned
    part's spin copies: the deviations are the same) -- D moves two points of that axis, one
    radius apart, by less than ``tol``."""
    for e in undet:
        om = np.linalg.norm(e[:3])
        if om < 1e-9:
            continue                                   # a slide, not a spin
        a, c = e[:3] / om, np.cross(e[:3] / om, e[3:] / om)  # the axis point nearest the origin
        ends = np.stack([c, c + radius * a])
        if np.max(np.linalg.norm(ends @ D[:3, :3].T + D[:3, 3] - ends, axis=1)) <= tol:
            return True
    return False


def close_runner_up(ga, T, undet, tau, radius) -> bool:
    """The global search's runner-up fits nearly as well as its best (at least
    :data:`WARN_RUNNER_UP` of its fit) and is not a free spin of the final pose T (None: not
    checked): the pose may be a symmetric copy of the true one."""
    return (ga is not None and ga.runner_up is not None
            and ga.runner_up[0] >= WARN_RUNNER_UP * ga.fit
            and not (T is not None and ga.runner_up_pose is not None and _free_spin(
                ga.runner_up_pose @ np.linalg.inv(T), undet, tau, radius)))


def pose_warnings(ev, w, ga, tau, radius, T=None, undet=(), noise=float("nan")):
    """Signs that the final pose is not the right minimum (see ``Registration.warnings``);
    with the final pose T and its undetermined directions, a global runner-up that is only
    a free spin of T is no sign."""
    inl = float(ev.inliers.mean())
    if inl < WARN_INLIERS:
        yield (f"only {100 * inl:.0f} % of the scan points are inliers at the final pose: it "
               "may be a wrong minimum, or the scan shows much that is not on the model")
    if tau is not None and ev.sigma > WARN_SCALE * tau:
        yield (f"the robust residual scale is {ev.sigma:.3g} mm, more than {WARN_SCALE:g} x "
               f"the fit distance {tau:.3g} mm (4 model point spacings or 0.5 % of the size): "
               "the pose is likely a wrong minimum (or the scan is very noisy)")
    elif noise > 0 and ev.sigma > WARN_NOISE * noise:
        yield (f"the robust residual scale is {ev.sigma:.3g} mm, {ev.sigma / noise:.0f} x the "
               f"scan's own noise ({noise:.3g} mm, its scatter about local quadrics): the pose "
               "is likely a wrong minimum, or the part differs from the model far beyond the "
               "sensor's noise everywhere")
    share = _rejected_information(ev, w, radius)
    if share > WARN_REJECTED_INFO:
        yield (f"the scan points the robust loss rejected hold {share:.2g} x the information "
               "of the points it kept in the least determined pose direction: the pose rests "
               "on the points that fit and ignores those that would move it (a wrong minimum, "
               "e.g. a blade locked onto its neighbour)")
    sw = float(w.sum())
    if sw > 0:
        mean = float(w @ ev.d) / sw
        if abs(mean) > WARN_MEAN_SIGMA * ev.sigma:
            yield (f"the weighted mean residual is {mean:+.3g} mm ({mean / ev.sigma:+.2g} "
                   "sigma): the scan lies systematically on one side of the model (wrong "
                   "minimum, wrong scale or units, or a part that differs everywhere)")
    if close_runner_up(ga, T, undet, tau, radius):
        f, ang, dn = ga.runner_up
        yield (f"another start fits nearly as well (fit {f:.3f} vs {ga.fit:.3f}, {ang:.1f} deg "
               f"away, moving the scan {dn:.3g} mm RMS along the normals): the pose may be a "
               "symmetric copy of the true one; give init= to choose")
