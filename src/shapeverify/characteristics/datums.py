"""Datum-feature alignment: primary plane A, secondary axis/plane B, tertiary axis/plane C.

The datum frame is built the same way from the CAD features and from the elements fitted on the
scan (robust fits of :mod:`shapeverify.fitting`, Tukey loss; holes by
:func:`.holes.measure_hole`); the pose maps the measured frame onto the CAD's.  A fixes 3 DOFs
(its normal and offset), B 2, C 1.  The covariance propagates each datum's fit uncertainty
through the frame construction.
"""
from __future__ import annotations

import numpy as np

from ..registration.rigid import apply_transform, invert_transform, make_transform, pose_error
from .alignment import AlignmentResult, _check_T
from .features import find_feature, model_features
from .holes import hole_reach, measure_hole

__all__ = ["datum_alignment"]


def _frame(z, zp, elems) -> np.ndarray:
    """Right-handed datum frame (4, 4): primary plane (normal z through zp), then elements.

    ``elems``: the secondary and tertiary datums as (kind, point, direction): ('axis', the
    point where the axis meets plane A, axis) or ('plane', a point on it, its normal).
    B an axis: origin where it meets A; x towards C's axis point (C a plane: along C's normal).
    B a plane: x along B's normal (in A); origin on the line A-B where plane C cuts it, or
    nearest to C's axis point (no C: nearest to B's point).
    """
    z = z / np.linalg.norm(z)
    (k2, p2, n2), rest = elems[0], elems[1:]
    c3 = rest[0] if rest else None
    if k2 == "axis":
        O = p2
        if c3 is None:
            x = np.eye(3)[int(np.argmin(np.abs(z)))]
        else:
            x = (c3[1] - O) if c3[0] == "axis" else c3[2]
    else:
        x = n2
    x = x - (x @ z) * z
    if np.linalg.norm(x) < 1e-9:
        raise ValueError("the secondary/tertiary datums do not fix the rotation about the "
                         "primary plane's normal (parallel to it, or coincident)")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    if k2 == "plane":
        if c3 is not None and c3[0] == "plane":
            third_n, third_p = c3[2], c3[1]
        else:
            third_n, third_p = y, (p2 if c3 is None else c3[1])
        A = np.array([z, n2, third_n])
        O = np.linalg.solve(A, np.array([z @ zp, n2 @ p2, third_n @ third_p]))
    return make_transform(np.column_stack([x, y, z]), O)


def _modes_plane(Xp, n, rms):
    """One-sigma error modes (dpoint, dnormal) of a least-squares plane through Xp."""
    c = Xp.mean(axis=0)
    Q = Xp - c
    Q = Q - np.outer(Q @ n, n)
    _, sv, vt = np.linalg.svd(Q, full_matrices=False)
    m = len(Xp)
    out = [(rms / np.sqrt(m) * n, np.zeros(3))]
    for k in range(2):
        spread = max(sv[k] / np.sqrt(m), 1e-9)
        out.append((np.zeros(3), rms / (np.sqrt(m) * spread) * vt[k]))
    return out


def _near_datum(f, X, prep, reach):
    """Indices of the scan points (model frame X) whose exact closest CAD point lies on the
    datum face ``f`` within ``reach``: a cheap geometric preselection (a slab about a plane, a
    shell about a cylinder; an even subset of about 2 x :data:`MAX_DATUM_POINTS` of it), then
    the exact closest points of those only."""
    q = X - f.center
    if f.kind == "plane":
        pre = np.flatnonzero(np.abs(q @ f.axis) <= reach)
    else:
        radial = q - np.outer(q @ f.axis, f.axis)
        pre = np.flatnonzero(np.abs(np.linalg.norm(radial, axis=1) - 0.5 * f.diameter) <= reach)
    if pre.size == 0:
        return pre
    pre = pre[::max(1, pre.size // (2 * MAX_DATUM_POINTS))]      # an even subset of a big face
    cl = prep.closest(X[pre], exact=True)
    m = (np.asarray(cl.face) == f.face) & ~np.asarray(cl.on_boundary, bool) & \
        (np.abs(cl.distances) <= reach)
    return pre[m]


def _measure_datum(f, X, prep, reach):
    """(kind, point, direction, rms or u, one-sigma error modes [(dpoint, ddirection), ...],
    points used)."""
    from ..fitting import fit_cylinder, fit_plane
    from .holes import plane_basis

    if f.kind == "hole":
        try:
            hm = _measure_datum_hole(f, X, prep)
        except ValueError as exc:
            raise ValueError(f"datum {f.id} (hole, diameter {f.diameter:g} mm) was not seen: "
                             f"{exc}") from None
        e1, e2 = plane_basis(f.axis)
        z = np.zeros(3)
        # the diameter misfit beyond what the edge detection may be off (two spacings)
        return ("axis", hm.center, f.axis, hm.u_center,
                [(hm.u_center * e1, z), (hm.u_center * e2, z)], hm.n_wall or hm.n_edge,
                max(abs(hm.diameter - f.diameter) - 2.0 * hm.spacing, 0.0))
    if f.kind not in ("plane", "cylinder"):
        raise ValueError(f"datum {f.id} is a {f.kind} face; datums are planes, holes or "
                         "cylinders")
    idx = _near_datum(f, X, prep, reach)
    if idx.size < MIN_DATUM_POINTS:
        raise ValueError(f"datum {f.id} ({f.kind}) was not seen: only {idx.size} scan points lie "
                         f"on it (at least {MIN_DATUM_POINTS} are needed); scan that face or "
                         "choose another datum")
    Xm = X[idx]
    if f.kind == "plane":
        pl = fit_plane(Xm, loss="tukey")
        n = pl.normal if pl.normal @ f.axis > 0 else -pl.normal
        inl = pl.weights > 0
        return ("plane", pl.point, n, pl.rms, _modes_plane(Xm[inl], n, pl.rms), idx.size, 0.0)
    cy = fit_cylinder(Xm, loss="tukey", axis=f.axis)
    # the axis is located at its points' mid-height (cy.point) and oriented by the primary
    # plane (ISO 5459 / ASME Y14.5: a secondary or tertiary datum feature simulator is
    # oriented to the primary), i.e. it keeps the CAD direction in the model frame of the
    # current pose, like a hole's; the fitted tilt of a short wall, extrapolated to plane A,
    # would move the frame's origin by tilt x distance (FTC 08: 1.5e-3 rad over 43 mm, 0.064
    # mm, 3 noise sigmas)
    a = np.asarray(f.axis, float) / np.linalg.norm(f.axis)
    e1, e2 = plane_basis(a)
    k = max(int(np.count_nonzero(cy.weights > 0)), 2)
    up = cy.rms * np.sqrt(2.0 / k)
    z = np.zeros(3)
    modes = [(up * e1, z), (up * e2, z)]
    return "axis", cy.point, a, cy.rms, modes, idx.size, abs(2.0 * cy.radius - f.diameter)


def _measure_datum_hole(f, X, prep):
    """:func:`.holes.measure_hole` of a datum hole with the CAD's closest points of the scan
    points around it, so that a hole with a scanned wall is the wall's cylinder (its centre to
    the wall's noise over its points) and not only the circle its rim's points trace (FTC 10's
    datum holes B and C at 1 mm spacing: 28 rim points each, a centre uncertain by 0.2-0.3 mm,
    which made every position tolerance referencing them undecided)."""
    a = np.asarray(f.axis, float) / np.linalg.norm(f.axis)
    q = X - f.center
    t = q @ a
    radial = np.linalg.norm(q - np.outer(t, a), axis=1)
    near = np.flatnonzero(radial < hole_reach(f.diameter) + 1.0)
    if near.size == 0:
        return measure_hole(X, f.center, f.axis, f.diameter)
    cl = prep.closest(X[near], exact=True)
    d = np.asarray(cl.distances, np.float64)
    try:
        hm = measure_hole(X[near], f.center, f.axis, f.diameter,
                          face=prep.model.faces[f.face], deviations=d,
                          normals=np.asarray(cl.normals, np.float64))
    except ValueError:
        hm = None
    if hm is not None and hm.n_wall > 0:
        return hm
    # no wall seen (a thin sheet, a sparse scan): the rim's circle of all the points, as before
    # (CTC 03 e1 at 1.5 mm: the rim measured without the wall candidates set aside moved the
    # frame 0.54 mm over three iterations, against 0.009 mm this way)
    return measure_hole(X, f.center, f.axis, f.diameter)


def _pierce(kind, p, a, zp, z):
    """Point where an axis meets the primary plane (zp, z); planes pass through."""
    if kind != "axis":
        return p
    s = ((zp - p) @ z) / (a @ z)
    return p + s * a


#: fewest scan points on a datum plane or cylinder
MIN_DATUM_POINTS = 30
#: a datum plane or cylinder is fitted to an even subset of about this many of its points at
#: most (their fit's uncertainty, in the covariance, is that of the points used)
MAX_DATUM_POINTS = 20_000
#: a datum plane or cylinder whose fit RMS exceeds this many noise sigmas fits badly
BAD_FIT = 5.0
#: a datum hole or cylinder whose measured diameter is off by more than this share of its
#: nominal is not the datum (another hole, or not seen)
BAD_DIAMETER = 0.05
#: the frame iterations stop when the pose moves no point by more than this many noise sigmas
MOVE_SIGMA = 0.01


def _frame_cov(fits, Fn, T_prev, T):
    """Covariance (6, 6) of the pose: each datum's one-sigma error modes propagated through
    the frame construction."""
    cov = np.zeros((6, 6))
    for i, (k, p, a, u, modes, _, _) in enumerate(fits):
        for dp, da in modes:
            pert = list(fits)
            pert[i] = (k, p + dp, a + da, u, modes, 0, 0.0)
            e = pose_error(Fn @ invert_transform(_measured_frame(pert)) @ T_prev, T)
            cov += np.outer(e, e)
    return cov


def _fit_frame(P, prep, F, Fn, T, noise, iterations):
    """Datum fits and pose from the start T: ``(T, fits, cov, iterations, converged)``.

    Converged when an iteration moves no point (``|omega| size + |tau|``) by more than
    :data:`MOVE_SIGMA` noise sigmas or half the frame's own standard deviation (a hole's edge
    points change with the pose: its centre moves within its uncertainty)."""
    size = float(prep.model.size)
    nz = noise if np.isfinite(noise) else 0.0
    reach = max(1.0, 8.0 * nz)
    fits, cov, it, ok = [], np.zeros((6, 6)), 0, False
    for it in range(1, iterations + 1):
        X = apply_transform(T, P)
        fits = [_measure_datum(f, X, prep, reach) for f in F]
        T_prev = T
        T = Fn @ invert_transform(_measured_frame(fits)) @ T
        cov = _frame_cov(fits, Fn, T_prev, T)
        e = pose_error(T, T_prev)
        sd = np.sqrt(max(np.trace(cov[:3, :3]), 0.0)) * size + np.sqrt(max(np.trace(cov[3:, 3:]),
                                                                          0.0))
        if np.linalg.norm(e[:3]) * size + np.linalg.norm(e[3:]) <= max(
                MOVE_SIGMA * nz, 0.5 * sd, 1e-9 * size):
            ok = True
            break
    return T, fits, cov, it, ok


def _measured_frame(fits):
    _, zp, z = fits[0][:3]
    z = z / np.linalg.norm(z)
    elems = [(k, _pierce(k, p, a / np.linalg.norm(a), zp, z), a / np.linalg.norm(a))
             for k, p, a in (f[:3] for f in fits[1:])]
    return _frame(z, zp, elems)


def _badness(F, fits, noise) -> str | None:
    """Why a datum fits badly (None: all fit)."""
    for f, fit in zip(F, fits):
        if f.kind != "hole" and np.isfinite(noise) and fit[3] > BAD_FIT * max(noise, 1e-9):
            return (f"datum {f.id} ({f.kind}) fits badly: its points scatter {fit[3]:.3g} mm RMS "
                    f"about the fitted {f.kind}, {fit[3] / noise:.1f} x the scan's noise "
                    f"({noise:.3g} mm); is it the right face, deformed, or partly another face?")
        if f.kind != "plane" and fit[6] > BAD_DIAMETER * f.diameter:
            return (f"datum {f.id} ({f.kind}, diameter {f.diameter:g} mm) fits badly: the scan "
                    f"there measures its diameter {fit[6]:.3g} mm off (beyond two point "
                    "spacings); it was not seen whole, or another feature lies where it should be")
    return None


def datum_alignment(scan, prep, primary, secondary, tertiary=None, init=None,
                    iterations: int = 8, rng=0) -> AlignmentResult:
    """Datum-feature alignment: plane A, then axis or plane B, then axis or plane C.

    The datum frame: z = A's normal; the origin where B's axis meets A (B a plane: the corner of
    A, B and C, or A and B with C an axis); x towards C's axis (or along B's/C's normal).  The
    same frame is built from the CAD features and from the elements fitted on the scan (in the
    model frame of the current pose); the pose maps the measured frame onto the nominal one,
    repeated until it moves no point by more than :data:`MOVE_SIGMA` noise sigmas (at most
    ``iterations`` times; the point selection follows the pose).

    Where it starts (:mod:`.placement`): from every placement of the scan the global search
    finds (its best pose and the poses that fit nearly as well, and ``init`` when given); the
    result of each is judged by the whole scan's fit, and among those that fit alike by the
    datums' own fit (RMS in noise sigmas, diameter misfit).  Two that fit alike on both counts
    (a symmetric part whose datum features allow several placements) give a warning in
    ``details['warnings']``.  A datum that was not seen or fits badly (:data:`BAD_FIT`,
    :data:`BAD_DIAMETER`) at every placement leaves ``details['converged']`` False with the
    reason in ``details['reason']`` (an inspection then says 'error', its characteristics
    'undecided'): never a silent wrong frame.

    Parameters
    ----------
    primary, secondary, tertiary : str
        Feature ids ('face:0', 'hole:1', 'cylinder:3').
    init : (4, 4), optional
        A start pose (e.g. the free registration's); tried with the global search's placements.

    Returns
    -------
    AlignmentResult
        ``residuals``: RMS of each datum's fit (mm) (a hole: its centre's uncertainty).
        ``covariance``: the datums' fit uncertainties (a plane's offset and tilt from its
        residual RMS, point count and extent; a hole's centre; a cylinder's axis) propagated
        through the frame construction (one-sigma perturbations).
        ``details``: ``placements`` (each tried: name, whole fit, datum RMS in sigmas, angle
        from the chosen pose, or why it failed), ``converged``, ``reason``, ``warnings``.
    """
    from .placement import ALIKE, placements, scan_noise_of, whole_fit

    model = prep.model
    feats = model_features(model)
    refs = [r for r in (primary, secondary, tertiary) if r is not None]
    F = [find_feature(feats, r, kind="face" if i else "plane") for i, r in enumerate(refs)]
    if F[0].kind != "plane":
        raise ValueError(f"the primary datum {F[0].id} must be a plane, it is a {F[0].kind}")
    P = np.asarray(scan, np.float64)
    T_init = None if init is None else _check_T(init)
    z_nom, zp_nom = F[0].axis, F[0].center

    def nominal(f):
        if f.kind == "plane":
            return "plane", f.center, f.axis
        return "axis", _pierce("axis", f.center, f.axis, zp_nom, z_nom), f.axis

    Fn = _frame(z_nom, zp_nom, [nominal(f) for f in F[1:]])
    noise = scan_noise_of(P)
    tried, failed = [], []
    for name, T0 in placements(P, prep, T_init, rng):
        try:
            T, fits, cov, it, conv = _fit_frame(P, prep, F, Fn, T0, noise, iterations)
        except ValueError as exc:
            failed.append({"placement": name, "reason": str(exc), "T": T0,
                           "fit": whole_fit(P, prep, T0, noise)})
            continue
        rms = [f[3] / max(noise, 1e-9) for f, d in zip(fits, F) if d.kind != "hole"]
        tried.append({"placement": name, "T": T, "cov": cov, "fits": fits,
                      "iterations": it, "converged": conv, "bad": _badness(F, fits, noise),
                      "fit": whole_fit(P, prep, T, noise),
                      "datum_rms": float(np.sqrt(np.mean(np.square(rms)))) if rms else 0.0,
                      "diameter_misfit": float(sum(f[6] for f in fits))})
    failed.sort(key=lambda f: -f["fit"])
    best_fit = max([t["fit"] for t in tried + failed] or [0.0])
    if not tried or max(t["fit"] for t in tried) < ALIKE * best_fit:
        # the placement the scan fits best has no datum frame (a datum not seen there): a
        # worse-fitting copy that has one would be a silent wrong frame
        why = failed[0]["reason"] if failed else "no placement of the scan was found"
        return _untrusted(P, F, failed[0]["T"] if failed else (T_init if T_init is not None
                          else np.eye(4)), why, failed)
    # the placement is the whole scan's (a wrong copy fits the datums as well); among those
    # that fit alike, the datums' own fit decides (ones that fit badly last)
    alike = [t for t in tried if t["fit"] >= ALIKE * best_fit]
    alike.sort(key=lambda t: (t["bad"] is not None, t["datum_rms"], t["diameter_misfit"],
                              -t["fit"]))
    ch = alike[0]
    # the caller's start, when it fits alike on both counts, is the caller's choice
    st = next((t for t in alike if t["placement"] == "start" and t["bad"] is None
               and t["datum_rms"] <= 1.2 * ch["datum_rms"] + 0.2), None)
    ch = st or ch
    warns = []
    for t in ([] if st is not None else alike):
        if t is ch:
            continue
        ang = np.degrees(np.linalg.norm(pose_error(t["T"], ch["T"])[:3]))
        if ang > 1.0 or np.linalg.norm(pose_error(t["T"], ch["T"])[3:]) > 0.01 * model.size:
            if t["datum_rms"] <= 1.2 * ch["datum_rms"] + 0.2:
                warns.append(f"the datum features allow another placement of the scan that fits "
                             f"alike (whole fit {t['fit']:.3f} vs {ch['fit']:.3f}, datum RMS "
                             f"{t['datum_rms']:.2f} vs {ch['datum_rms']:.2f} noise sigmas, "
                             f"{ang:.1f} deg away): the frame may be a symmetric copy; give "
                             "init= to choose")
    T, fits, cov = ch["T"], ch["fits"], ch["cov"]
    lost = [f for f in failed if f["fit"] >= ALIKE * ch["fit"]]
    if lost:
        # a placement the scan fits as well has no datum frame: the frame found may be a
        # symmetric copy standing in for a datum that was not seen
        ch = {**ch, "bad": f"{lost[0]['reason']} (at a placement of the scan that fits it as "
                           f"well as the one with a datum frame, whole fit {lost[0]['fit']:.3f} "
                           f"vs {ch['fit']:.3f}: that frame may be a symmetric copy)"}
    res = np.array([f[3] for f in fits])
    dof = ["A: tz rx ry", "B: " + ("tx ty" if F[1].kind != "plane" else "tx rz")]
    if len(F) > 2:
        dof.append("C: " + ("rz" if F[1].kind != "plane" else "ty"))
    reason = ch["bad"] or (None if ch["converged"] else
                           f"the datum frame still moved after {ch['iterations']} iterations")
    details = {"datums": [f.id for f in F], "iterations": ch["iterations"],
               "converged": reason is None, "noise": noise, "placement": ch["placement"],
               "placements": _placement_rows(tried, failed, T), "warnings": warns,
               "n_points": [int(f[5]) for f in fits]}
    if reason:
        details["reason"] = reason
    return AlignmentResult(T, cov, res, float(np.sqrt(np.mean(res ** 2))), tuple(dof),
                           (), "datums", details)


def _placement_rows(tried, failed, T) -> list:
    rows = []
    for t in tried:
        e = pose_error(t["T"], T)
        rows.append({"placement": t["placement"], "whole_fit": float(t["fit"]),
                     "datum_rms_sigma": float(t["datum_rms"]),
                     "degrees_from_chosen": float(np.degrees(np.linalg.norm(e[:3]))),
                     "mm_from_chosen": float(np.linalg.norm(e[3:])),
                     **({"fits_badly": t["bad"]} if t["bad"] else {})})
    rows += [{"placement": f["placement"], "whole_fit": float(f["fit"]), "failed": f["reason"]}
             for f in failed]
    return rows


def _untrusted(P, F, T, why, failed) -> AlignmentResult:
    """No datum frame: the start pose, flagged (inspection 'error', characteristics
    'undecided'), with the reason."""
    return AlignmentResult(T, np.full((6, 6), np.inf), np.zeros(0), float("nan"), (), (),
                           "datums", {"datums": [f.id for f in F], "converged": False,
                                      "reason": why, "iterations": 0, "warnings": [],
                                      "placements": _placement_rows([], failed, T)})
