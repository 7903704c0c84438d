"""Position with a zone other than a cylinder (ASME Y14.5 §10, ISO 1101 §18.12): two parallel
planes about the true centre plane of a width feature (a slot or a tab), and a sphere about the
true centre of a spherical feature.  Lengths in mm, in the characteristic's datum reference
frame (:mod:`.drf`) when it names ``datums``, else in the plan's alignment.

* ``zone: planes``: ``faces`` are the two opposite planar sides of a width feature (outward
  normals ``+u`` / ``-u``).  Its derived centre plane is that of the actual mating envelope
  held in the CAD orientation (the DRF fixes the zone's orientation): for a slot (the sides
  face each other) the two parallel planes as far apart as the points allow, for a tab the
  two as close as they allow -- each plane through the extreme point of its side along ``u``.
  The value is ``2 |centre - true centre|`` (the zone of width ``t`` centred on the true
  position holds the centre plane iff the value ``<= t``).
* ``zone: sphere``: ``faces`` are the spherical faces of one sphere; its centre is the
  least-squares sphere's (:func:`shapeverify.fitting.fit_sphere`; the CAD's own centre the same
  fit of the faces' points), the value ``2 |centre - true centre|`` (the spherical zone of
  diameter ``t``).

Uncertainty (k): a centre plane through two extreme points moves with each extreme's noise,
the k-level quantile ``z_n sigma`` of the largest of n noisy deviations
(:func:`.support.extreme_quantile`): ``U = sqrt(2) z_n sigma`` on ``2 |offset|``; a
least-squares sphere centre moves by ``sigma sqrt(3 / n)`` per direction: ``U = 2 k sigma
sqrt(3 / n)``; each combined with the datum planes' shift (as position of an axis).
"""
from __future__ import annotations

import numpy as np

__all__ = ["width_centre", "sphere_centre", "eval_position_zone", "width_sides",
           "sphere_of_faces"]


def width_centre(A: np.ndarray, B: np.ndarray, u: np.ndarray, slot: bool) -> float:
    """Offset along unit ``u`` of the centre plane of the mating envelope of side ``A`` (low
    side along ``u``) and side ``B`` in the orientation ``u``: a slot's sides are held by the
    widest gap (``max A.u``, ``min B.u``), a tab's by the narrowest band (``min A.u``,
    ``max B.u``)."""
    a, b = A @ u, B @ u
    return 0.5 * ((a.max() + b.min()) if slot else (a.min() + b.max()))


def sphere_centre(X: np.ndarray) -> tuple[np.ndarray, float]:
    """(centre, radius) of the least-squares sphere of the points."""
    from ..fitting import fit_sphere

    f = fit_sphere(np.asarray(X, float))
    return np.asarray(f.center, float), float(f.radius)


def width_sides(feats, faces) -> tuple[list, list, np.ndarray, float, float, bool]:
    """(faces of side A, of side B, u, true offset of the centre plane along u, CAD width,
    slot?) of a width feature given by its planar faces; ValueError naming what is wrong."""
    kinds = {feats[f].kind for f in faces}
    if kinds != {"plane"}:
        raise ValueError(f"a position in two parallel planes takes the planar sides of a width "
                         f"feature; faces {faces} are {', '.join(sorted(kinds))}")
    n0 = np.asarray(feats[faces[0]].axis, float)
    side = {f: float(np.asarray(feats[f].axis, float) @ n0) for f in faces}
    if any(abs(abs(s) - 1.0) > 1e-6 for s in side.values()):
        raise ValueError(f"the faces {faces} are not parallel planes (a width feature's sides)")
    one = [f for f in faces if side[f] > 0]
    two = [f for f in faces if side[f] < 0]
    if not one or not two:
        raise ValueError(f"the faces {faces} face one way only: a width feature has two "
                         "opposite sides")
    s1 = [float(np.asarray(feats[f].center) @ n0) for f in one]
    s2 = [float(np.asarray(feats[f].center) @ n0) for f in two]
    tol = 1e-6 * max(1.0, max(map(abs, s1 + s2)))
    if np.ptp(s1) > tol or np.ptp(s2) > tol:
        raise ValueError(f"the sides of faces {faces} are not two planes (each side coplanar)")
    # u = n0, from side A (lower along u) to side B (a tab's sides, whose outward normals
    # part, gave u = -n0 here: a negative width and 'slot')
    A, B, u = (one, two, n0) if s2[0] > s1[0] else (two, one, n0)
    a, b = float(np.asarray(feats[A[0]].center) @ u), float(np.asarray(feats[B[0]].center) @ u)
    slot = bool(np.asarray(feats[A[0]].axis, float) @ u > 0)   # A's outward normal faces B
    return A, B, u, 0.5 * (a + b), b - a, slot


def sphere_of_faces(model, faces) -> tuple[np.ndarray, float, float]:
    """(centre, radius, largest residual) of the least-squares sphere of the CAD faces' grid
    points; ValueError when they are not one sphere (residual over 1e-6 of the radius)."""
    from .features import _face_grid

    X = np.concatenate([_face_grid(model.faces[f])[0] for f in faces])
    c, r = sphere_centre(X)
    err = float(np.abs(np.linalg.norm(X - c, axis=1) - r).max())
    if not err <= 1e-6 * r + 1e-9:
        raise ValueError(f"the faces {faces} are not one sphere (points {err:.3g} mm off the "
                         "best sphere)")
    return c, r, err


def eval_position_zone(c, ctx):
    """position_zone (module docstring)."""
    from .alignment import face_indices
    from .evaluate import _not_measured
    from .datum_noise import datum_u
    from .gdt import _frame_points, _result
    from .support import extreme_quantile

    fidx = face_indices(ctx.prep.model, c.faces)
    fl = fidx.tolist()
    X, m, drf = _frame_points(c, ctx, fl)
    if X.shape[0] == 0:
        return _not_measured(c, "no scan points on the feature's faces")
    F = np.asarray(ctx.S.face)[m]
    if c.zone == "planes":
        A, B, u, true, width, slot = width_sides(ctx.feats, fl)
        inA, inB = np.isin(F, A), np.isin(F, B)
        if inA.sum() < 3 or inB.sum() < 3:
            return _not_measured(c, f"fewer than 3 scan points on a side (faces {A}: "
                                    f"{int(inA.sum())}, {B}: {int(inB.sum())})")
        centre = width_centre(X[inA], X[inB], u, slot)
        value = 2.0 * abs(centre - true)
        # the datums' noise moves the sides along u (:mod:`.datum_noise`)
        Ud = datum_u(drf, ctx, X[inA | inB], np.asarray(u, float)[None])
        zq = extreme_quantile(int(min(inA.sum(), inB.sum())), ctx.k)
        U = float(np.hypot(np.sqrt(2.0) * zq * ctx.S.noise, Ud))
        details = {"direction": u.tolist(), "centre_offset": float(centre - true),
                   "feature": "slot" if slot else "tab", "cad_width": width,
                   "sides": {"A": A, "B": B}, "n": [int(inA.sum()), int(inB.sum())],
                   "noise": ctx.S.noise, "extreme_quantile": zq}
    else:
        key = ("sphere", tuple(fl))
        if key not in ctx.cache:
            ctx.cache[key] = sphere_of_faces(ctx.prep.model, fl)
        c0, r0, _ = ctx.cache[key]
        if X.shape[0] < 10:
            return _not_measured(c, f"{X.shape[0]} scan points on the sphere (10 needed)")
        cm, rm = sphere_centre(X)
        value = 2.0 * float(np.linalg.norm(cm - c0))
        Ud = datum_u(drf, ctx, cm[None], np.eye(3))
        U = float(np.hypot(2.0 * ctx.k * ctx.S.noise * np.sqrt(3.0 / X.shape[0]), Ud))
        details = {"centre": cm.tolist(), "cad_centre": c0.tolist(), "diameter": 2.0 * rm,
                   "cad_diameter": 2.0 * r0, "n": int(X.shape[0]), "noise": ctx.S.noise}
    details["faces"], details["u_datums"] = fl, Ud
    return _result(c, ctx, value, U, details, drf, 0.0, float(c.tol))
