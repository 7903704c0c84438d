"""Datum-feature alignment: primary plane A, secondary axis/plane B, tertiary axis/plane C.

The datum frame is built the same way from the CAD features and from the elements fitted on the
scan (robust fits of :mod:`shapeverify.fitting`, Tukey loss; holes by
:func:`.holes.measure_hole`); the pose maps the measured frame onto the CAD's.  A fixes 3 DOFs
(its normal and offset), B 2, C 1.  The covariance propagates each datum's fit uncertainty
through the frame construction.
"""
from __future__ import annotations

import numpy as np

from ..registration.losses import MAD_TO_SIGMA
from ..registration.rigid import apply_transform, invert_transform, make_transform, pose_error
from .alignment import AlignmentResult, _check_T
from .features import find_feature, model_features
from .holes import measure_hole

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


def _measure_datum(f, X, cl, prep, feats, sigma):
    """(kind, point, direction, rms or u, one-sigma error modes [(dpoint, ddirection), ...])."""
    from ..fitting import fit_cylinder, fit_plane
    from .holes import plane_basis

    if f.kind == "hole":
        hm = measure_hole(X, f.center, f.axis, f.diameter)
        e1, e2 = plane_basis(f.axis)
        z = np.zeros(3)
        return "axis", hm.center, f.axis, hm.u_center, [(hm.u_center * e1, z),
                                                         (hm.u_center * e2, z)]
    m = (cl.face == f.face) & ~cl.on_boundary & (np.abs(cl.distances) <= max(1.0, 8 * sigma))
    if np.count_nonzero(m) < 10:
        raise ValueError(f"datum {f.id}: only {int(np.count_nonzero(m))} scan points on it")
    if f.kind == "plane":
        pl = fit_plane(X[m], loss="tukey")
        n = pl.normal if pl.normal @ f.axis > 0 else -pl.normal
        inl = pl.weights > 0
        return "plane", pl.point, n, pl.rms, _modes_plane(X[m][inl], n, pl.rms)
    if f.kind == "cylinder":
        cy = fit_cylinder(X[m], loss="tukey", axis=f.axis)
        a = cy.axis if cy.axis @ f.axis > 0 else -cy.axis
        e1, e2 = plane_basis(a)
        k = max(int(np.count_nonzero(cy.weights > 0)), 2)
        s_ax = max(float(np.std((X[m] - cy.point) @ a)), 1e-9)
        up = cy.rms * np.sqrt(2.0 / k)
        modes = [(up * e1, np.zeros(3)), (up * e2, np.zeros(3)),
                 (np.zeros(3), up / s_ax * e1), (np.zeros(3), up / s_ax * e2)]
        return "axis", cy.point, a, cy.rms, modes
    raise ValueError(f"datum {f.id} is a {f.kind} face; datums are planes, holes or cylinders")


def _pierce(kind, p, a, zp, z):
    """Point where an axis meets the primary plane (zp, z); planes pass through."""
    if kind != "axis":
        return p
    s = ((zp - p) @ z) / (a @ z)
    return p + s * a


def datum_alignment(scan, prep, primary, secondary, tertiary=None, init=None,
                    iterations: int = 3) -> AlignmentResult:
    """Datum-feature alignment: plane A, then axis or plane B, then axis or plane C.

    The datum frame: z = A's normal; the origin where B's axis meets A (B a plane: the corner of
    A, B and C, or A and B with C an axis); x towards C's axis (or along B's/C's normal).  The
    same frame is built from the CAD features and from the elements fitted on the scan (in the
    model frame of the current pose); the pose maps the measured frame onto the nominal one.
    Repeated ``iterations`` times (the point selection follows the pose).

    Parameters
    ----------
    primary, secondary, tertiary : str
        Feature ids ('face:0', 'hole:1', 'cylinder:3').

    Returns
    -------
    AlignmentResult
        ``residuals``: RMS of each datum's fit (mm) (a hole: its centre's uncertainty).
        ``covariance``: the datums' fit uncertainties (a plane's offset and tilt from its
        residual RMS, point count and extent; a hole's centre; a cylinder's axis) propagated
        through the frame construction (one-sigma perturbations).
    """
    from ..registration import register

    model = prep.model
    feats = model_features(model)
    refs = [r for r in (primary, secondary, tertiary) if r is not None]
    F = [find_feature(feats, r, kind="face" if i else "plane") for i, r in enumerate(refs)]
    if F[0].kind != "plane":
        raise ValueError(f"the primary datum {F[0].id} must be a plane, it is a {F[0].kind}")
    T = register(scan, prep).T_model_scan if init is None else _check_T(init)
    P = np.asarray(scan, np.float64)
    z_nom, zp_nom = F[0].axis, F[0].center

    def nominal(f):
        if f.kind == "plane":
            return "plane", f.center, f.axis
        return "axis", _pierce("axis", f.center, f.axis, zp_nom, z_nom), f.axis

    Fn = _frame(z_nom, zp_nom, [nominal(f) for f in F[1:]])
    def measured_frame(fits):
        _, zp, z, _, _ = fits[0]
        z = z / np.linalg.norm(z)
        elems = [(k, _pierce(k, p, a / np.linalg.norm(a), zp, z), a / np.linalg.norm(a))
                 for k, p, a, _, _ in fits[1:]]
        return _frame(z, zp, elems)

    fits, T_prev = [], T
    for _ in range(iterations):
        X = apply_transform(T, P)
        cl = prep.closest(X, exact=True)
        sigma = MAD_TO_SIGMA * float(np.median(np.abs(cl.distances)))
        fits = [_measure_datum(f, X, cl, prep, feats, sigma) for f in F]
        T_prev = T
        T = Fn @ invert_transform(measured_frame(fits)) @ T
    # covariance: each datum's one-sigma error modes propagated through the frame construction
    cov = np.zeros((6, 6))
    for i, (k, p, a, u, modes) in enumerate(fits):
        for dp, da in modes:
            pert = list(fits)
            pert[i] = (k, p + dp, a + da, u, modes)
            Tk = Fn @ invert_transform(measured_frame(pert)) @ T_prev
            e = pose_error(Tk, T)
            cov += np.outer(e, e)
    res = np.array([f[3] for f in fits])
    dof = ["A: tz rx ry", "B: " + ("tx ty" if F[1].kind != "plane" else "tx rz")]
    if len(F) > 2:
        dof.append("C: " + ("rz" if F[1].kind != "plane" else "ty"))
    return AlignmentResult(T, cov, res, float(np.sqrt(np.mean(res ** 2))), tuple(dof),
                           (), "datums", {"datums": [f.id for f in F]})
