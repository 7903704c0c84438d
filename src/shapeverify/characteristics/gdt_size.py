"""Dimensions between features (issue 28 item 3, size): the distance and the angle between two
planar faces, each with ± limits (the dimensions ``Location_LinearDistance`` and
``Location_Angular`` of AP242 PMI).

Definitions (lengths in mm, angles in degrees)
----------------------------------------------
Each face is associated with its **least-squares plane** (total least squares: the plane
through the points' centroid normal to the direction of least spread; ISO 14405-2 leaves the
association of a dimension between two features to the drawing, least squares is its
default for derived features).  The points of a face are its kept scan points inside its
edges (:func:`.gdt._on`).

* **distance** (two parallel planar faces, either facing: a step or a width): the mean of
  the two one-sided distances, face 2's points' mean distance from face 1's plane and face
  1's points' from face 2's (:func:`plane_distance`); deviation = measured - nominal
  (``nominal``: the drawing's, else the CAD's distance).
* **angle** (two planar faces): the angle between the two least-squares normals, taken the
  way the drawing measures it: the angle between the CAD normals or its supplement,
  whichever is the nominal (:func:`plane_angle`).

Uncertainty (k): a least-squares plane of ``n`` points with noise ``sigma`` is offset by
``sigma / sqrt(n)`` at its centroid and tilted by ``sigma / (sqrt(n) s)`` about each of its
in-plane axes (``s`` the points' RMS spread along the other axis); the distance combines the
offsets of both planes, the angle their tilts about the line where the planes meet.
"""
from __future__ import annotations

import numpy as np

from .evaluate import CharacteristicResult, EvalContext, _not_measured
from .zones import decide

__all__ = ["lsq_plane", "plane_distance", "plane_angle", "eval_distance", "eval_angle"]


def lsq_plane(points, direction=None):
    """(centroid (3,), unit normal (3,)) of the total-least-squares plane of ``points`` (N >= 3);
    the normal turned to agree with ``direction`` when given."""
    P = np.asarray(points, np.float64)
    if P.ndim != 2 or P.shape[1] != 3 or P.shape[0] < 3:
        raise ValueError(f"a least-squares plane needs (N, 3) points, N >= 3; got {P.shape}")
    c = P.mean(axis=0)
    n = np.linalg.svd(P - c, full_matrices=False)[2][2]
    if direction is not None and n @ np.asarray(direction, float) < 0:
        n = -n
    return c, n


def plane_distance(points1, points2) -> float:
    """The distance between two (nearly) parallel faces: the mean of face 2's points' mean
    distance from face 1's least-squares plane and face 1's points' from face 2's."""
    c1, n1 = lsq_plane(points1)
    c2, n2 = lsq_plane(points2)
    P1, P2 = np.asarray(points1, float), np.asarray(points2, float)
    return 0.5 * (abs(float(np.mean((P2 - c1) @ n1))) + abs(float(np.mean((P1 - c2) @ n2))))


def plane_angle(points1, points2, normal1, normal2, nominal: float | None = None) -> float:
    """The angle (degrees) between the least-squares planes of two faces.

    ``normal1``, ``normal2``: the faces' CAD outward normals (orient the fitted ones).  With
    ``nominal`` (degrees), the angle between the normals or its supplement, whichever the
    CAD's is closer to ``nominal`` (a drawing dimensions the angle inside or outside the
    material); without it the angle between the outward normals."""
    _, n1 = lsq_plane(points1, normal1)
    _, n2 = lsq_plane(points2, normal2)
    ang = float(np.degrees(np.arccos(np.clip(n1 @ n2, -1.0, 1.0))))
    if nominal is not None and _supplement(normal1, normal2, nominal):
        ang = 180.0 - ang
    return ang


def _cad_angle(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.degrees(np.arccos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b),
                                              -1.0, 1.0))))


def _supplement(normal1, normal2, nominal: float) -> bool:
    """True when the drawing's angle ``nominal`` is the supplement of the CAD normals'."""
    cad = _cad_angle(normal1, normal2)
    return abs(180.0 - cad - nominal) < abs(cad - nominal)


def _tilt_sd(P, n, noise) -> np.ndarray:
    """One-sigma tilt vector components of a least-squares plane: (2, 3) rows ``axis x sd``
    (rotations about its two in-plane principal axes, rad)."""
    Q = P - P.mean(axis=0)
    Q = Q - np.outer(Q @ n, n)
    _, sv, vt = np.linalg.svd(Q, full_matrices=False)
    m = P.shape[0]
    out = []
    for k in range(2):
        spread = max(sv[k] / np.sqrt(m), 1e-9)
        # a tilt towards vt[k] is a rotation about n x vt[k]
        out.append(np.cross(n, vt[k]) * noise / (np.sqrt(m) * spread))
    return np.array(out)


def _side(ctx: EvalContext, ref, c, what: str) -> list[int]:
    """The model faces of one side of a two-plane dimension: a face, or several coplanar
    planar faces (a list, or a CAD name that several faces carry) taken as one plane."""
    from .alignment import face_indices

    fl = face_indices(ctx.prep.model, ref if isinstance(ref, list) else [ref]).tolist()
    feats = [ctx.feats[i] for i in fl]
    if any(f.kind != "plane" for f in feats):
        raise ValueError(f"{c.name}: {what} needs planar faces, got {ref} "
                         f"({[f.kind for f in feats]})")
    a = feats[0]
    size = max(float(ctx.prep.model.size), 1.0)
    for f in feats[1:]:
        if abs(abs(f.axis @ a.axis) - 1.0) > 1e-6 or abs((f.center - a.center) @ a.axis) \
                > 1e-6 * size + 1e-6:
            raise ValueError(f"{c.name}: the faces {ref} of one side of the {what} are not "
                             "coplanar in the CAD; name one plane per side")
    return fl


def _two_planes(c, ctx: EvalContext, what: str):
    """(sides: two lists of model faces, points of side 1, of side 2) or a 'not measured'
    result.  A side is one planar face or several coplanar ones (fitted as one plane)."""
    from .gdt import _on

    if len(c.faces) != 2:
        raise ValueError(f"{c.name}: {what} needs two sides, got {c.faces}")
    sides = [_side(ctx, ref, c, what) for ref in c.faces]
    P1, P2 = ctx.S.X[_on(ctx, sides[0])], ctx.S.X[_on(ctx, sides[1])]
    if len(P1) < 3 or len(P2) < 3:
        return sides, None, _not_measured(c, f"fewer than 3 scan points on a side of the "
                                             f"{what} ({len(P1)}, {len(P2)})")
    return sides, (P1, P2), None


def _flat(sides):
    """Two sides as before sides existed: [face 1, face 2] when each is one face."""
    return [s[0] if len(s) == 1 else s for s in sides]


def _dim_result(c, nominal, value, U, details):
    dev = value - nominal
    return CharacteristicResult(c.name, c.type, nominal, value, dev, float(c.lower),
                                float(c.upper), U, decide(dev, c.lower, c.upper, U), details)


def eval_distance(c, ctx: EvalContext):
    """distance between two parallel planar faces (module docstring); to the circle where a
    hole's wall meets its drill point: :func:`.drill_point.eval_depth_to_circle`."""
    if not isinstance(c.faces[1], (str, int, list)):
        from .drill_point import eval_depth_to_circle

        return eval_depth_to_circle(c, ctx)
    fidx, pts, bad = _two_planes(c, ctx, "distance")
    if bad is not None:
        return bad
    f1, f2 = ctx.feats[fidx[0][0]], ctx.feats[fidx[1][0]]
    if abs(abs(f1.axis @ f2.axis) - 1.0) > 1e-6:
        raise ValueError(f"{c.name}: faces {c.faces} are not parallel in the CAD "
                         f"({_cad_angle(f1.axis, f2.axis):.4f} deg apart); a distance is "
                         "between parallel planes")
    cad = float(abs((f2.center - f1.center) @ f1.axis))
    nominal = float(c.nominal) if c.nominal is not None else cad
    P1, P2 = pts
    value = plane_distance(P1, P2)
    U = ctx.k * float(ctx.S.noise) * float(np.sqrt(1.0 / len(P1) + 1.0 / len(P2)))
    return _dim_result(c, nominal, value, U,
                       {"faces": _flat(fidx), "n": [len(P1), len(P2)], "cad_distance": cad,
                        "noise": ctx.S.noise,
                        "definition": "mean distance between the least-squares planes"})


def eval_angle(c, ctx: EvalContext):
    """angle between two planar faces (module docstring)."""
    fidx, pts, bad = _two_planes(c, ctx, "angle")
    if bad is not None:
        return bad
    f1, f2 = ctx.feats[fidx[0][0]], ctx.feats[fidx[1][0]]
    cad = _cad_angle(f1.axis, f2.axis)
    nominal = float(c.nominal) if c.nominal is not None else cad
    sup = _supplement(f1.axis, f2.axis, nominal)
    if min(abs(cad - nominal), abs(180.0 - cad - nominal)) > 1e-3:
        raise ValueError(f"{c.name}: the nominal angle {nominal:g} deg is neither the CAD "
                         f"faces' angle {cad:.4f} nor its supplement")
    P1, P2 = pts
    value = plane_angle(P1, P2, f1.axis, f2.axis, nominal)
    # the tilts that change the angle: rotations about the line where the planes meet
    _, n1 = lsq_plane(P1, f1.axis)
    _, n2 = lsq_plane(P2, f2.axis)
    line = np.cross(n1, n2)
    line = line / np.linalg.norm(line) if np.linalg.norm(line) > 1e-12 else line
    s = np.sqrt(sum(float(np.sum((_tilt_sd(P, n, ctx.S.noise) @ line) ** 2))
                    for P, n in ((P1, n1), (P2, n2))))
    U = ctx.k * float(np.degrees(s))
    return _dim_result(c, nominal, value, U,
                       {"faces": _flat(fidx), "n": [len(P1), len(P2)], "cad_angle": cad,
                        "supplement": bool(sup), "noise": ctx.S.noise, "unit": "deg",
                        "definition": "angle between the least-squares planes"})
