"""Signs that a registration's final pose is not the right minimum (``Registration.warnings``,
:func:`pose_warnings`): few inliers, a robust scale broad against the fit distance or against
the scan's own noise (:mod:`._noise`), rejected points that would move the pose, a systematic
mean residual, and a global-search runner-up that fits about as well.

Each warning is a :class:`PoseWarning`: a ``str`` (as before) with a ``kind``.  Two kinds say that
the scan fits better elsewhere than at the pose (``wrong_minimum``; the verdict turns them into
``error (registration)``, never ``incomplete (coverage)``):

* ``scale``: the robust residual scale is beyond twice the fit distance *and* beyond
  :data:`WARN_NOISE` times the scan's own noise (a very noisy depth camera's right pose -- 1.5 mm
  of noise on a 120 mm box, fit distance 0.6 mm -- is not a wrong minimum);
* ``noise``: the scale is beyond :data:`WARN_NOISE` times the noise but under the fit-distance
  bar, *and* the scan's own local surface lies across the model's (:func:`surface_tilt`).  Issue
  30: the residual against the noise alone warned on every right pose of a micro gear, whose
  form deviation (10-20 um) is far above its sensor's noise (0.7 um) -- which is what a part under
  inspection looks like.  What the part could deviate is judged by the fit of a local surface to
  the scan: a part that deviates in form lies along its model (its local planes parallel to the
  model's tangent planes, whatever the offset); a wrong minimum lays the scan across it.

``symmetric-copy`` is no doubt: the global search found other poses that fit alike and are
exact symmetric copies of this one (the model maps onto itself under the motion between them,
:func:`.global_search.is_symmetry`): every one is an equally right answer (a gear's pitch).
"""

from __future__ import annotations

import numpy as np
from shapeverify._lazy import cKDTree

from . import _irls


class PoseWarning(str):
    """One warning of :func:`pose_warnings`: its text (a ``str``, as before), and ``kind``, what
    it says -- ``'inliers'``, ``'scale'``, ``'noise'``, ``'rejected'``, ``'mean'``,
    ``'runner-up'`` or ``'symmetric-copy'``.  ``wrong_minimum`` is True for the kinds that say
    the scan fits better elsewhere than at this pose (:data:`WRONG_MINIMUM`)."""

    kind: str

    def __new__(cls, text: str, kind: str):
        obj = super().__new__(cls, text)
        obj.kind = kind
        return obj

    def __reduce__(self):
        return PoseWarning, (str(self), self.kind)

    @property
    def wrong_minimum(self) -> bool:
        return self.kind in WRONG_MINIMUM


#: the kinds of warning that say the pose is a wrong minimum (the scan fits better elsewhere):
#: the verdict turns them into ``error (registration)``
WRONG_MINIMUM = frozenset({"scale", "noise", "better-elsewhere"})

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
#: ... and is flagged only where the scan's local planes lie across the model's tangent planes
#: by more than this many times the sine their own scatter explains (median over the points,
#: :func:`surface_tilt`): a part that deviates in form (a micro gear's 10-20 um against a
#: sensor noise of 1 um) lies along its model; a wrong minimum lays the scan across it
#: (right poses measured: the real bunny views against the merged cloud of the others 2.9-3.3 x,
#: 3.6-3.8 deg -- a cloud reference's own normals are noisy; a tilt of 8 deg: far beyond)
WARN_TILT = 5.0
#: ... and by more than this angle (deg, median): the slopes of a real part's form deviation
#: (20 um over a 0.4 mm flank: 3 deg) are no sign of a wrong pose on a low-noise sensor
WARN_TILT_DEG = 5.0
#: a robust scale beyond this many times the scan's own noise (:func:`._noise.scan_noise`) is
#: flagged: right poses measured 1.0-1.1 x on simulated scans (panel with 5 % outliers,
#: impeller), 3.0 x on the real bunny scans (against another noisy scan as the reference);
#: wrong impeller minima 43-62 x
WARN_NOISE = 5.0


def surface_tilt(ev, k: int = 24, points: int = 1000) -> tuple[float, float]:
    """How the scan's own local surface lies against the model's at the pose: (median sine of the
    angle between each scan point's local plane -- PCA of its ``k`` nearest scan points -- and the
    model's tangent plane at its closest point, median of that sine over the sine the scan's own
    scatter about its plane explains), over up to ``points`` weighted points (evenly spaced);
    (nan, nan) with fewer than 50.

    A part that deviates from its model in form (a smooth offset of some 10 um over a band of
    a micro gear) leaves its surface nearly parallel to the model's: the ratio stays near 1
    however large the offset is against the noise.  A wrong minimum lays the scan across the
    model's surfaces (a spin, a tilt, flanks on the neighbouring teeth): the planes disagree.
    """
    idx = np.flatnonzero(ev.valid & (ev.w > 0))
    if idx.shape[0] < max(50, k + 1) or ev.X.shape[0] < k + 1:
        return float("nan"), float("nan")
    sel = idx[np.linspace(0, idx.shape[0] - 1, min(points, idx.shape[0])).astype(np.int64)]
    _, nb = cKDTree(ev.X).query(ev.X[sel], k=k + 1)
    Q = ev.X[nb] - ev.X[nb].mean(axis=1, keepdims=True)
    lam, V = np.linalg.eigh(np.einsum("nki,nkj->nij", Q, Q))
    sine = np.linalg.norm(np.cross(V[:, :, 0], ev.N[sel]), axis=1)
    lam = np.maximum(lam, 1e-300)
    explained = np.sqrt(lam[:, 0] / (k - 2) * (1.0 / lam[:, 1] + 1.0 / lam[:, 2]))
    return float(np.median(sine)), float(np.median(sine / np.maximum(explained, 1e-12)))


#: a pose from a given start (no global search ran) with fewer inliers than this is checked
#: against the global search (:func:`better_elsewhere`)
CHECK_INLIERS = 0.9
#: ... and flagged when the global search's best pose fits the scan at least this many times
#: better (truncated fit at the sharp fit distance) and is neither this pose nor a symmetric copy
BETTER = 1.1


def better_elsewhere(ev, prep, rng=0):
    """(fit here, fit there, rotation deg, shift mm) when the global search, run on the scan
    as placed (``ev.X``), finds a pose that fits clearly better (:data:`BETTER`) and is neither
    this one nor an exact symmetric copy of it; else None.

    Issue 30 proxies: one side of a box given 120 deg off ended 90 deg off, lying flat on the
    wrong faces with its residual at the noise level (1.4 x), planes parallel, converged: no
    other sign tells it; the scan fits far better elsewhere.
    """
    from .global_search import _distinct, _model_side, _sharp_fits, global_alignment, is_symmetry

    X = np.asarray(ev.X, np.float64)
    side = _model_side(prep)
    ga = global_alignment(X, prep, rng=rng)
    S = X[np.linspace(0, X.shape[0] - 1, min(400, X.shape[0])).astype(np.int64)]
    (f0, f1), tau = _sharp_fits(side, S, [np.eye(4), ga.T_model_scan])
    if not f1 > BETTER * f0:
        return None
    ang, dn = _distinct(np.eye(4), ga.T_model_scan, S, side, full=True)
    if dn <= tau and ang <= 5.0:
        return None
    if is_symmetry(side, ga.T_model_scan, float(np.clip(tau, 2.0 * side.spacing, side.tau))):
        return None
    return f0, f1, ang, dn


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


def pose_warnings(ev, w, ga, tau, radius, T=None, undet=(), noise=float("nan"), prep=None):
    """Signs that the final pose is not the right minimum (see ``Registration.warnings``);
    with the final pose T and its undetermined directions, a global runner-up that is only
    a free spin of T is no sign.  With ``prep`` and no global search (``ga`` None: a given
    start), a final pose with few inliers is checked by one (:func:`better_elsewhere`)."""
    inl = float(ev.inliers.mean())
    if ga is None and prep is not None and T is not None and inl < CHECK_INLIERS:
        better = better_elsewhere(ev, prep)
        if better is not None:
            f0, f1, ang, dn = better
            yield PoseWarning(
                f"the scan fits better elsewhere: the global search places it {ang:.1f} deg "
                f"away (moving it {dn:.3g} mm RMS along the normals) with a fit of {f1:.3f} "
                f"against {f0:.3f} here: the pose is a wrong minimum of the given start",
                "better-elsewhere")
    if inl < WARN_INLIERS:
        yield PoseWarning(
            f"only {100 * inl:.0f} % of the scan points are inliers at the final pose: it may "
            "be a wrong minimum, or the scan shows much that is not on the model", "inliers")
    excess = noise > 0 and ev.sigma > WARN_NOISE * noise
    if tau is not None and ev.sigma > WARN_SCALE * tau and (excess or not noise > 0):
        yield PoseWarning(
            f"the robust residual scale is {ev.sigma:.3g} mm, more than {WARN_SCALE:g} x the fit "
            f"distance {tau:.3g} mm (4 model point spacings or 0.5 % of the size): the pose is "
            "likely a wrong minimum (or the scan is very noisy)", "scale")
    elif excess and T is None:
        # the registration's own check whether to try restarts (a restart is kept only where
        # it fits better): the residual against the noise alone, as before issue 30
        yield PoseWarning(
            f"the robust residual scale is {ev.sigma:.3g} mm, {ev.sigma / noise:.0f} x the "
            f"scan's own noise ({noise:.3g} mm): the pose may be a wrong minimum", "noise")
    elif excess:
        sine, ratio = surface_tilt(ev)
        if ratio > WARN_TILT and sine > np.sin(np.radians(WARN_TILT_DEG)):
            yield PoseWarning(
                f"the robust residual scale is {ev.sigma:.3g} mm, {ev.sigma / noise:.0f} x the "
                f"scan's own noise ({noise:.3g} mm, its scatter about local quadrics), and the "
                f"scan's surface lies across the model's (its local planes tilted "
                f"{np.degrees(np.arcsin(min(sine, 1.0))):.1f} deg from the model's tangent "
                f"planes, median; {ratio:.1f} x what its scatter explains): the pose is likely a "
                "wrong minimum (a part that only deviates in form lies along its model)", "noise")
    share = _rejected_information(ev, w, radius)
    if share > WARN_REJECTED_INFO:
        yield PoseWarning(
            f"the scan points the robust loss rejected hold {share:.2g} x the information of "
            "the points it kept in the least determined pose direction: the pose rests on the "
            "points that fit and ignores those that would move it (a wrong minimum, e.g. a "
            "blade locked onto its neighbour)", "rejected")
    sw = float(w.sum())
    if sw > 0:
        mean = float(w @ ev.d) / sw
        if abs(mean) > WARN_MEAN_SIGMA * ev.sigma:
            yield PoseWarning(
                f"the weighted mean residual is {mean:+.3g} mm ({mean / ev.sigma:+.2g} sigma): "
                "the scan lies systematically on one side of the model (wrong minimum, wrong "
                "scale or units, or a part that differs everywhere)", "mean")
    if close_runner_up(ga, T, undet, tau, radius):
        f, ang, dn = ga.runner_up
        sym = tuple(getattr(ga, "symmetric", ()) or ())
        if sym and sym[0]:
            k = sum(1 for (fo, _), s in zip(ga.others, sym) if s and fo >= WARN_RUNNER_UP * ga.fit)
            yield PoseWarning(
                f"the part maps onto itself: {k} other pose{'s' if k > 1 else ''} that fit the "
                f"scan alike (the nearest {ang:.1f} deg away, fit {f:.3f} vs {ga.fit:.3f}) "
                f"{'are' if k > 1 else 'is'} an exact symmetric copy of this one (the model is "
                "unchanged by the motion between them): every copy is an equally right answer",
                "symmetric-copy")
            return
        yield PoseWarning(
            f"another start fits nearly as well (fit {f:.3f} vs {ga.fit:.3f}, {ang:.1f} deg "
            f"away, moving the scan {dn:.3g} mm RMS along the normals): the pose may be a "
            "symmetric copy of the true one; give init= to choose", "runner-up")
