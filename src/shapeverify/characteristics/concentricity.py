"""Concentricity (ASME Y14.5-2009 section 7.6.4): all median points of diametrically opposed
elements of a surface of revolution lie within a cylindrical zone (diameter ``tol``) whose
axis is the datum axis.

On a scan (in the DRF's frame, where the datum axis sits on its nominal one): the feature's
points are cut into sections along the axis (a tenth of its length each); in a section each
point at angle ``theta`` and radius ``r`` has its opposed element at ``theta + pi``, whose
radius is interpolated linearly (periodically in the angle) between the section's points
next to that angle -- when both lie within :data:`MAX_GAP` of it (else the point has no
opposed element in the scan and is left out).  The median point of the two lies on the line
through the axis at ``theta``, ``(r(theta) - r(theta + pi)) / 2`` from the axis; the value
is twice the largest such distance, ``max |r(theta) - r(theta + pi)|`` (the diameter of the
smallest zone about the datum axis holding every median point).

Lengths in mm, angles in radians.
"""
from __future__ import annotations

import numpy as np

__all__ = ["MAX_GAP", "median_offsets", "eval_concentricity"]

#: an opposed element is interpolated between scan points at most this far (rad) from it
MAX_GAP = np.radians(5.0)


def median_offsets(theta, r, max_gap: float = MAX_GAP) -> tuple[np.ndarray, np.ndarray]:
    """(signed distances ``(r_i - r(theta_i + pi)) / 2`` of the median points from the axis,
    indices of the points that have them) of one section's points (angles ``theta``, radii
    ``r``).

    Example
    -------
    >>> import numpy as np
    >>> t = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    >>> m, i = median_offsets(t, 10 + 0.1 * np.cos(t), max_gap=1.0)
    >>> round(float(np.abs(m).max()), 9)       # r(t) - r(t + pi) = 0.2 cos t: 0.1
    0.1
    """
    th = np.mod(np.asarray(theta, np.float64), 2 * np.pi)
    r = np.asarray(r, np.float64)
    if th.size < 2:
        return np.zeros(0), np.zeros(0, np.int64)
    o = np.argsort(th)
    ts, rs = th[o], r[o]
    tp = np.concatenate([ts - 2 * np.pi, ts, ts + 2 * np.pi])
    rp = np.concatenate([rs, rs, rs])
    want = np.mod(th + np.pi, 2 * np.pi)
    k = np.searchsorted(tp, want)              # tp[k-1] <= want < tp[k]
    lo, hi = tp[k - 1], tp[k]
    ok = (want - lo <= max_gap) & (hi - want <= max_gap)
    w = np.where(hi > lo, (want - lo) / np.where(hi > lo, hi - lo, 1.0), 0.0)
    r_opp = rp[k - 1] + w * (rp[k] - rp[k - 1])
    idx = np.flatnonzero(ok)
    return 0.5 * (r[idx] - r_opp[idx]), idx


def eval_concentricity(c, ctx):
    """concentricity of a surface of revolution about the DRF's datum axis (module
    docstring)."""
    from .datum_noise import datum_u
    from .gdt import (_check_revolution, _cylinder_points, _datum_feature, _faces,
                      _frame_points, _result, _sections)
    from .evaluate import _not_measured
    from .support import extreme_quantile

    fidx = _faces(c, ctx)
    X, m, drf = _frame_points(c, ctx, fidx)
    nom = None
    for d in drf.datums:
        if d.kind == "axis":
            nom = _datum_feature(d.name, ctx.plan.datums[d.name], ctx)
            break
    if nom is None:
        raise ValueError(f"{c.name}: concentricity needs an axis datum (a hole or boss); "
                         f"{'|'.join(c.datums)} has none")
    p0 = np.asarray(nom.point, float)
    a0 = np.asarray(nom.direction, float) / np.linalg.norm(nom.direction)
    for i in fidx:
        _check_revolution(c, ctx.feats[i], p0, a0, float(ctx.prep.model.size))
    if ctx.feats[fidx[0]].kind == "cylinder":
        X, _ = _cylinder_points(X, ctx.feats[fidx[0]])
    if X.shape[0] < 8:
        return _not_measured(c, f"only {X.shape[0]} scan points on faces {fidx}")
    e1 = np.cross(a0, np.eye(3)[int(np.argmin(np.abs(a0)))])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a0, e1)
    q = X - p0
    h = q @ a0
    th = np.arctan2(q @ e2, q @ e1)
    r = np.hypot(q @ e1, q @ e2)
    meds, n_med = [], 0
    for sec in _sections(h):
        if sec.size < 4:
            continue
        mo, _ = median_offsets(th[sec], r[sec])
        meds.append(np.abs(mo))
        n_med += mo.size
    if n_med < 4:
        return _not_measured(c, "fewer than 4 scan points with an opposed point (the scan "
                                "must see the feature on both sides of its axis)")
    value = 2.0 * float(np.concatenate(meds).max())
    zq = extreme_quantile(n_med, ctx.k)
    # a median distance is half the difference of two radii (each with the scan's noise):
    # sigma / sqrt(2); the value doubles it.  The datums' noise moves the median points
    # across the axis (:mod:`.datum_noise`)
    Ud = datum_u(drf, ctx, X, np.stack([e1, e2]))
    U = float(np.hypot(2.0 * zq * ctx.S.noise / np.sqrt(2.0), Ud))
    return _result(c, ctx, value, U,
                   {"faces": fidx, "n": int(X.shape[0]), "n_median_points": int(n_med),
                    "axis_point": p0.tolist(), "axis": a0.tolist(),
                    "definition": "median points of diametrically opposed elements (ASME "
                                  "Y14.5-2009 7.6.4): the diameter about the datum axis that "
                                  "holds them all",
                    "u_datum_axis": Ud, "noise": ctx.S.noise,
                    "excluded": ctx.S.excluded(fidx)}, drf)
