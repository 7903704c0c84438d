"""Datum feature shift: a datum feature of size referenced at its maximum or least material
boundary (MMB ``M`` / LMB ``L``; ASME Y14.5-2018 section 7.11.7, ISO 5459 / ISO 2692 "MMR
applied to a datum").

The datum feature simulator of an MMB hole is a fixed pin of the hole's MMB diameter (its
smallest size limit), of an MMB boss a fixed ring of its largest size limit; at LMB the
boundaries are the least material ones (a hole's largest, a boss's smallest size).  A real
feature that departs from that boundary can move on the simulator: the datum reference frame
may shift by that much, and the characteristic is met if it is met in some pose within the
shift.

How it is evaluated here
------------------------
* **The allowed shift** of datum k: its axis (fitted by :mod:`.drf`, sitting on the nominal
  one in the DRF) may move across its direction by up to ``r_k``, at both ends of the feature
  (so a primary axis may also tilt): a hole at MMB ``r = r_mate - D_MMB / 2`` (``r_mate`` the
  radius of the largest inscribed cylinder about the fitted axis: the smallest radial distance
  of its points); a boss at MMB ``r = D_MMB / 2 - r_mate`` (the largest); a hole at LMB ``r =
  D_LMB / 2 - r_out`` (the largest radial distance: the hole must stay inside the LMB
  cylinder); a boss at LMB ``r = r_in - D_LMB / 2``.  A negative ``r`` (the feature violates
  its boundary) allows no shift and is reported.  The disc of radius ``r`` about the fitted
  axis is a conservative stand-in for the set of simulator positions (it lies inside it).
* **Which motions**: only the degrees of freedom the shifted datum constrained in the DRF
  (:attr:`.drf.DRF.constrained`); higher-precedence datums at RMB stay as fitted.
* **The best pose** (:func:`best_profile_shift`): the motion ``xi = (omega, t)`` in that
  subspace minimising the profile's largest ``|deviation|``, each deviation changing to first
  order by ``n . (omega x x + t)`` (the CAD normal at the point's foot); each shift disc is
  replaced by its inscribed regular 64-gon (conservative: ``1 - cos(pi/64) = 0.12 %`` of the
  radius lost), which makes it a linear programme (scipy's HiGHS).  The caller then moves the
  points by that motion and takes their deviations again from the CAD (exact closest points).

Lengths in mm.
"""
from __future__ import annotations

import numpy as np

__all__ = ["POLYGON", "Infeasible", "shift_allowance", "best_profile_shift", "motion_of",
           "profile_with_shift", "pattern_shift_limits", "shift_limits", "best_position_shift"]

#: sides of the regular polygon inscribed in each shift disc
POLYGON = 64


def shift_allowance(points, point, axis, hole: bool, material: str, size) -> tuple[float, dict]:
    """(radius the datum axis may shift, details) of a datum feature of size.

    Parameters
    ----------
    points : (m, 3)   the datum feature's scan points (in the DRF's frame)
    point, axis       its fitted axis (in the DRF: the nominal one)
    hole : bool       a hole (True) or a boss
    material : 'M' or 'L'
    size              nominal, lower, upper (mm) of its diameter, or the boundary's diameter
                      ``mmb`` / ``lmb`` itself (an object with attributes)
    """
    X = np.asarray(points, float)
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    q = X - np.asarray(point, float)
    rad = np.linalg.norm(q - np.outer(q @ a, a), axis=1)
    r_in, r_out = float(rad.min()), float(rad.max())
    if material not in ("M", "L"):
        raise ValueError(f"datum modifier {material!r}: M (MMB) or L (LMB)")
    what = "MMB" if material == "M" else "LMB"
    bound = getattr(size, "mmb" if material == "M" else "lmb", None)
    if bound is None:           # the size's MMC (a hole's smallest, a boss's largest) / LMC
        if getattr(size, "lower", None) is None:
            raise ValueError(f"datum size {size}: no limits and no {what} diameter")
        lo, hi = size.nominal + size.lower, size.nominal + size.upper
        bound = (lo if hole else hi) if material == "M" else (hi if hole else lo)
    if material == "M":
        r = r_in - bound / 2 if hole else bound / 2 - r_out
    else:
        r = bound / 2 - r_out if hole else r_in - bound / 2
    det = {"boundary": what, "boundary_diameter": bound, "r_in": r_in, "r_out": r_out,
           "shift_radius": max(r, 0.0)}
    if r < 0:
        det["violates_boundary"] = -r
    return max(r, 0.0), det


class Infeasible(ValueError):
    """The datum features do not fit their simulators at MMB/LMB in any pose."""


def _skew_rows(e) -> np.ndarray:
    """(3, 6): the displacement of the point e under the small motion (omega, t)."""
    e = np.asarray(e, float)
    K = np.array([[0, e[2], -e[1]], [-e[2], 0, e[0]], [e[1], -e[0], 0]])   # omega x e = K omega
    return np.hstack([K, np.eye(3)])


def motion_of(S, y) -> np.ndarray:
    """The small motion (6,) ``S y``."""
    return np.asarray(S, float) @ np.asarray(y, float)


def best_profile_shift(X, normals, d, S, datums, polygon: int = POLYGON):
    """The motion within the datum shifts that minimises ``max |d_i + n_i . (omega x x_i +
    t)|`` (see the module docstring).

    Parameters
    ----------
    X, normals : (N, 3)   the profile's points and the CAD normals at their feet
    d : (N,)              their signed deviations
    S : (6, m)            the motions the shifted datums constrained
    datums : list of (ends (k, 3), axis (3,), r[, offsets (k, 3)])
                          each shifted datum feature: points of its axis where the shift is
                          bounded, its direction, its shift radius, and where the feature's
                          axis is off its simulator's at those points (a feature of a pattern
                          datum: the pattern is placed by least squares; default none) --
                          ``|offset + motion(end)| <= r`` across the axis

    Returns
    -------
    (value: the linearised min of max |d'|, xi (6,), y (m,))
    """
    X, Nn, d = (np.asarray(v, float) for v in (X, normals, d))
    S = np.asarray(S, float)
    m = S.shape[1]
    if m == 0 or all(float(x[2]) <= 0 for x in datums):
        return float(np.abs(d).max()), np.zeros(6), np.zeros(m)
    G = np.hstack([np.cross(X, Nn), Nn]) @ S                   # d' = d + G y
    one = np.ones((len(d), 1))
    A = [np.hstack([G, -one]), np.hstack([-G, -one])]
    b = [-d, d]
    ang = 2 * np.pi * (np.arange(polygon) + 0.5) / polygon
    for item in datums:
        ends, axis, r = item[:3]
        ends = np.atleast_2d(np.asarray(ends, float))
        offs = (np.atleast_2d(np.asarray(item[3], float)) if len(item) > 3
                else np.zeros_like(ends))
        a = np.asarray(axis, float) / np.linalg.norm(axis)
        e1 = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(a, e1)
        U = np.outer(np.cos(ang), e1) + np.outer(np.sin(ang), e2)     # (polygon, 3)
        for e, o in zip(ends, offs):
            A.append(np.hstack([U @ _skew_rows(e) @ S, np.zeros((polygon, 1))]))
            b.append(np.full(polygon, max(float(r), 0.0) * np.cos(np.pi / polygon)) - U @ o)
    return _min_excess(A, b, S, m, (0, None))


def shift_limits(c, ctx, drf):
    """(S (6, m): the motions the shifted datums constrained, datums for
    :func:`best_profile_shift`, details per datum) of ``c.datum_modifiers``.

    Raises
    ------
    ValueError
        A modified datum is not a hole or boss axis (or a pattern of them), or the plan gives
        it no size limits.
    """
    from .gdt import _datum_feature

    S_parts, datums, det = [], [], {}
    for name, mat in sorted(c.datum_modifiers.items()):
        k = drf.names.index(name)
        spec, fit = ctx.plan.datums[name], drf.datums[k]
        what = "MMB" if mat == "M" else "LMB"
        if fit.kind == "pattern":
            got, dd = _pattern_shift(c, name, spec, ctx, drf, k, mat)
            datums.extend(got)
            S_parts.append(drf.constrained[k])
            det[name] = dd
            continue
        if fit.kind != "axis":
            raise ValueError(f"{c.name}: datum {name} at {what} is a {fit.kind}; a datum "
                             "feature shift is applied to hole and boss axes and patterns of "
                             "them only")
        if spec.size is None:
            raise ValueError(f"{c.name}: datum {name} at {what} needs its size limits (give "
                             f"datums: {{{name}: {{size: {{nominal, lower, upper}}}}}})")
        feat = _datum_feature(name, spec, ctx)
        P = drf.apply(feat.points)
        r, dd = shift_allowance(P, fit.point, fit.direction, feat.hole, mat, spec.size)
        h = (P - fit.point) @ fit.direction
        ends = fit.point + np.outer([h.min(), h.max()], fit.direction)
        datums.append((ends, fit.direction, r))
        S_parts.append(drf.constrained[k])
        det[name] = dd
    S = np.hstack(S_parts)
    return S, datums, det


def profile_with_shift(c, ctx, X, drf, d, normals):
    """(deviations of the profile's points ``X`` (DRF frame) at the best pose within the
    shifts of ``c.datum_modifiers``, details) -- the motion from :func:`best_profile_shift`,
    the deviations then taken again from the CAD (exact closest points); the original ones if
    those are no better (the linearisation never makes a part worse).

    Raises
    ------
    ValueError
        A modified datum is not a hole or boss axis, or the plan gives it no size limits.
    """
    from .drf import rigid_exp

    S, datums, det = shift_limits(c, ctx, drf)
    ok = np.isfinite(d)
    try:
        lin, xi, _ = best_profile_shift(X[ok], normals[ok], d[ok], S, datums)
    except Infeasible as e:
        return d, {"datums": det, "applied": False, "reason": str(e),
                   "max_before": float(np.nanmax(np.abs(d)))}
    T = rigid_exp(xi)
    d2 = np.asarray(ctx.prep.closest(X @ T[:3, :3].T + T[:3, 3], exact=True).distances, float)
    better = np.nanmax(np.abs(d2)) < np.nanmax(np.abs(d))
    out = {"datums": det, "motion": xi.tolist(), "linearised_max": lin,
           "max_before": float(np.nanmax(np.abs(d))), "max_after": float(np.nanmax(np.abs(d2))),
           "applied": bool(better)}
    return (d2 if better else d), out


def pattern_shift_limits(groups, sizes, material: str, N) -> tuple[list, list]:
    """The shift limits of a pattern (or common) datum referenced at MMB/LMB: the pattern's
    simulator is rigid -- each feature's boundary (a pin of a hole's MMB diameter ...) at its
    basic place relative to the others -- so the whole pattern may move (translate and turn)
    as long as every feature still holds (or stays within) its boundary.

    Parameters
    ----------
    groups : list of (p0, d0, points (m, 3), hole)
        Each feature: its nominal axis (a point, the direction) and its scan points, in the
        DRF's frame (where the simulators sit on their nominal axes).
    sizes : list
        Each feature's size limits (``nominal``, ``lower``, ``upper``).
    material : 'M' or 'L'
    N : (6, k)
        The motions free before the pattern datum (its axes' fits turn only in those, as in
        :func:`.drf.fit_drf`).

    Returns
    -------
    (datums, details): datums for :func:`best_profile_shift` -- per feature (its axis' two
    ends, its direction, the shift radius, the axis' offsets from the simulator's axis at the
    ends) -- and per feature :func:`shift_allowance`'s details with its ``offset``.
    """
    from .drf import DatumFeature, _fit

    out, det = [], []
    for k, ((p0, d0, P, hole), size) in enumerate(zip(groups, sizes)):
        p0 = np.asarray(p0, float)
        d0 = np.asarray(d0, float) / np.linalg.norm(d0)
        fit, _, _ = _fit(DatumFeature(f"[{k + 1}]", "axis", p0, d0, P, hole=hole), P, N)
        c, a = fit.point, fit.direction
        r, dd = shift_allowance(P, c, a, hole, material, size)
        h = (P - c) @ a
        ends = c + np.outer([h.min(), h.max()], a)
        offs = []
        for e in ends:
            q = e - p0
            offs.append(q - (q @ d0) * d0)        # the axis' end off the simulator's axis
        offs = np.array(offs)
        dd["offset"] = float(np.linalg.norm(offs, axis=1).max())
        out.append((ends, a, r, offs))
        det.append(dd)
    return out, det


def _pattern_shift(c, name, spec, ctx, drf, k, mat):
    """(datums for :func:`best_profile_shift`, details) of the pattern datum ``name`` (the
    k-th of the DRF) at MMB/LMB: its features' sizes from ``spec.size`` (all alike) or
    ``spec.face_sizes`` (per face)."""
    from .alignment import face_indices
    from .datum_targets import pattern_feature

    what = "MMB" if mat == "M" else "LMB"
    if spec.size is None and spec.face_sizes is None:
        raise ValueError(f"{c.name}: the pattern datum {name} at {what} needs its features' size "
                         f"limits (datums: {{{name}: {{size: ...}}}} or face_sizes: [...])")
    feat = pattern_feature(name, spec, ctx)
    fidx = face_indices(ctx.prep.model, spec.faces).tolist()
    groups, sizes = [], []
    for p0, d0, idx, hole in feat.groups:
        P = drf.apply(feat.points[idx])
        if spec.face_sizes is None:
            size = spec.size
        else:       # the size of the group's faces: the face nearest its axis' points
            cyl = [i for i in fidx if abs(abs(np.asarray(ctx.feats[i].axis) @ d0) - 1) < 1e-4
                   and np.linalg.norm(np.cross(ctx.feats[i].center - p0, d0)) < 1e-4
                   * ctx.feats[i].diameter + 1e-6]
            got = {spec.face_sizes[fidx.index(i)] for i in cyl}
            if len(got) != 1:
                raise ValueError(f"{c.name}: datum {name}: the faces of one of its features "
                                 f"have {len(got)} sizes in face_sizes (one each)")
            size = got.pop()
        groups.append((p0, d0, P, hole))
        sizes.append(size)
    N = np.hstack(list(drf.constrained[k:]) + [drf.free_basis])
    datums, det = pattern_shift_limits(groups, sizes, mat, N)
    return datums, {"boundary": what, "features": det}


def best_position_shift(axes, S, datums, polygon: int = POLYGON):
    """The motion within the datum shifts that minimises the largest excess of a pattern of
    axes over their position zones: ``max_j max_e (|P_j (e + omega x e + t - c_j)| - z_j / 2)``
    over each axis j's ends e (``P_j`` across its nominal direction, ``c_j`` on its nominal
    axis, ``z_j`` its zone's diameter with any bonus); each zone circle replaced by its
    inscribed regular ``polygon``-gon (conservative), each datum's shift disc as in
    :func:`best_profile_shift`: a linear programme.

    Parameters
    ----------
    axes : list of (ends (k, 3), centre (3,), direction (3,), zone diameter)
    S, datums : as for :func:`best_profile_shift`

    Returns
    -------
    (the linearised min of the largest excess, xi (6,), y (m,))
    """
    S = np.asarray(S, float)
    m = S.shape[1]
    ang = 2 * np.pi * (np.arange(polygon) + 0.5) / polygon
    cosp = np.cos(np.pi / polygon)

    def ring(a):
        a = np.asarray(a, float) / np.linalg.norm(a)
        e1 = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(a, e1)
        return np.outer(np.cos(ang), e1) + np.outer(np.sin(ang), e2)

    A, b = [], []
    for ends, c0, a, z in axes:
        U = ring(a)
        for e in np.atleast_2d(np.asarray(ends, float)):
            q = e - np.asarray(c0, float)
            # U_k . (q + motion(e)) <= cos(pi/P) (z/2 + s): inside the excess-grown polygon
            A.append(np.hstack([U @ _skew_rows(e) @ S, -cosp * np.ones((polygon, 1))]))
            b.append(cosp * 0.5 * float(z) - U @ q)
    for item in datums:
        ends, axis, r = item[:3]
        ends = np.atleast_2d(np.asarray(ends, float))
        offs = (np.atleast_2d(np.asarray(item[3], float)) if len(item) > 3
                else np.zeros_like(ends))
        U = ring(axis)
        for e, o in zip(ends, offs):
            A.append(np.hstack([U @ _skew_rows(e) @ S, np.zeros((polygon, 1))]))
            b.append(np.full(polygon, max(float(r), 0.0) * cosp) - U @ o)
    return _min_excess(A, b, S, m, (None, None))


def _min_excess(A, b, S, m: int, bound: tuple):
    """The LP of the datum shift: minimise the last variable (the largest excess, bounded by
    ``bound``) over ``m`` motion coordinates ``y`` (the motion ``S @ y``) subject to
    ``A [y, t] <= b``.  Returns (excess, motion, y); :class:`Infeasible` when no pose fits."""
    from scipy.optimize import linprog

    c = np.r_[np.zeros(m), 1.0]
    res = linprog(c, A_ub=np.vstack(A), b_ub=np.concatenate(b),
                  bounds=[(None, None)] * m + [bound], method="highs")
    if res.status == 2:
        raise Infeasible("no pose of the part fits its datum features on their simulators "
                         "(a feature is off its place by more than its departure from the "
                         "boundary allows)")
    if res.status != 0:
        raise ValueError(f"the datum shift optimisation failed: {res.message}")
    y = res.x[:m]
    return float(res.x[m]), S @ y, y
