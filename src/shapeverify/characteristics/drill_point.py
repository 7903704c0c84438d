"""A drilled hole's depth to its point (issue 28 item 3, NIST FTC 06 DIM49 and DIM50: 12.7
±1.27 from a planar face to the circle where the ⌀6.35 hole's wall meets its drill point): a
``distance`` whose second side is that circle, ``{cylinder: face, cone: face}`` (either may be
a list of faces of one cylinder or one cone).

Definition (mm)
---------------
* the **plane**: the least-squares plane of the first side's kept scan points inside its edges
  (as for a distance between planes, :mod:`.gdt_size`);
* the **circle**: the Tukey least-squares cylinder of the hole wall's kept scan points
  (radius ``R``) and the Tukey least-squares cone of the drill point's (``fit_cone``: radius
  ``Rk`` at its axis point ``p``, unit axis ``a``, half angle ``psi``); the circle lies where
  the cone's radius equals the cylinder's, ``h = (R - Rk) / tan psi`` along the cone's axis
  from ``p``: its centre ``c = p + h a`` (:func:`junction_centre`);
* the **value**: the distance from the plane to that centre along the plane's normal
  (:func:`depth_to_circle`).  The nominal is the same construction on the CAD (the CAD
  cylinder's radius, :func:`.cone_sizes.cad_cone`, the face's plane); the CAD plane must be
  square to the cone's axis within ``SQUARE_DEG`` (else the plan keeps the dimension
  unsupported).

Uncertainty (k): linear propagation of the fits' covariances, which are independent (disjoint
points): the cone's sandwich covariance in (axis point 2, tilt 2, Rk, psi)
(:func:`.cone_sizes.cone_covariance`), the cylinder radius's
(:func:`.size_features.radius_uncertainty`), and the plane's offset ``sigma / sqrt(n)`` and
tilts (:func:`.gdt_size._tilt_sd`) over the lever from its centroid to the circle's centre.
"""
from __future__ import annotations

import numpy as np

__all__ = ["SQUARE_DEG", "junction_centre", "depth_to_circle", "eval_depth_to_circle"]

#: largest angle (degrees) between the plane's normal and the hole's axis in the CAD
SQUARE_DEG = 0.1


def junction_centre(R, point, axis, cone_radius, psi) -> np.ndarray:
    """(3,) the centre of the circle where a cone (radius ``cone_radius`` at ``point``,
    ``cone_radius + h tan psi`` at ``h`` along the unit ``axis``) has the radius ``R``."""
    h = (float(R) - float(cone_radius)) / np.tan(float(psi))
    return np.asarray(point, float) + h * np.asarray(axis, float)


def depth_to_circle(plane_point, normal, centre) -> float:
    """Distance (mm, unsigned) from the plane through ``plane_point`` normal to ``normal``
    to the point ``centre``, along the normal."""
    n = np.asarray(normal, float)
    return abs(float((np.asarray(centre, float) - plane_point) @ n / np.linalg.norm(n)))


def _side(ctx, ref):
    from .alignment import face_indices

    return face_indices(ctx.prep.model, ref if isinstance(ref, list) else [ref]).tolist()


def _cone_gradient(f, R, c_pl, n) -> np.ndarray:
    """d value / d (cone chart parameters of :func:`.cone_sizes.cone_covariance`)."""
    from .holes import plane_basis

    p0, a0 = np.asarray(f.point, float), np.asarray(f.axis, float)
    e1, e2 = plane_basis(a0)

    def v(t):
        a = a0 + t[2] * e1 + t[3] * e2
        c = junction_centre(R, p0 + t[0] * e1 + t[1] * e2, a / np.linalg.norm(a), t[4], t[5])
        return float((c - c_pl) @ n)

    t0 = np.array([0.0, 0.0, 0.0, 0.0, float(f.radius), float(f.half_angle)])
    g = np.empty(6)
    for k, step in enumerate((1e-6, 1e-6, 1e-7, 1e-7, 1e-6, 1e-7)):
        dt = np.zeros(6)
        dt[k] = step
        g[k] = (v(t0 + dt) - v(t0 - dt)) / (2 * step)
    return g


def eval_depth_to_circle(c, ctx):
    """distance from a plane to the circle where a hole's wall meets its drill point (module
    docstring)."""
    from ..fitting import fit_cylinder
    from .cone_sizes import cached_cad_cone, cone_covariance, cone_fit_angle
    from .evaluate import _not_measured
    from .gdt import _on
    from .gdt_size import _dim_result, _tilt_sd, lsq_plane
    from .gdt_size import _side as plane_side
    from .size_features import radius_uncertainty

    circle = c.faces[1]
    fp = plane_side(ctx, c.faces[0], c, "distance")       # planar, coplanar faces
    fy, fk = _side(ctx, circle.cylinder), _side(ctx, circle.cone)
    planes, cyls = [ctx.feats[f] for f in fp], [ctx.feats[f] for f in fy]
    if any(q.kind != "cylinder" for q in cyls):
        raise ValueError(f"{c.name}: the wall of a hole to its drill point is cylinder faces, "
                         f"got {circle.cylinder} ({[q.kind for q in cyls]})")
    apex0, a0, psi0 = cached_cad_cone(c, ctx, fk)
    pl0, R0 = planes[0], 0.5 * float(cyls[0].diameter)
    n0 = np.asarray(pl0.axis, float)
    if np.degrees(np.arccos(min(1.0, abs(float(n0 @ a0))))) > SQUARE_DEG:
        raise ValueError(f"{c.name}: the plane {c.faces[0]} is not square to the axis of the "
                         f"cone {circle.cone} (within {SQUARE_DEG} deg)")
    centre0 = junction_centre(R0, apex0, a0, 0.0, psi0)
    side = 1.0 if (centre0 - pl0.center) @ n0 >= 0 else -1.0
    cad = depth_to_circle(pl0.center, n0, centre0)
    nominal = float(c.nominal) if c.nominal is not None else cad
    Pp, Py, Pk = ctx.S.X[_on(ctx, fp)], ctx.S.X[ctx.S.on(fy)], ctx.S.X[ctx.S.on(fk)]
    if len(Pp) < 3 or len(Py) < 20 or len(Pk) < 20:
        return _not_measured(c, f"too few scan points: {len(Pp)} on the plane {fp}, {len(Py)} "
                                f"on the wall {fy}, {len(Pk)} on the drill point {fk}")
    c_pl, n = lsq_plane(Pp, n0)
    cy = fit_cylinder(Py, loss="tukey", axis=a0)
    f, psi = cone_fit_angle(Pk, a0)
    centre = junction_centre(cy.radius, f.point, f.axis, f.radius, psi)
    value = side * float((centre - c_pl) @ n)
    # uncertainty: cone (sandwich covariance), cylinder radius, plane offset and tilts
    g = _cone_gradient(f, cy.radius, c_pl, side * n)
    var = float(g @ cone_covariance(Pk, f) @ g)
    u_r = radius_uncertainty(Py, cy.point, cy.axis, cy.residuals, cy.weights)
    var += (side * float(np.asarray(f.axis) @ n) / np.tan(psi) * u_r) ** 2
    tilts = _tilt_sd(Pp, n, ctx.S.noise)
    var += float(ctx.S.noise) ** 2 / len(Pp) + sum(float(np.cross(w, n) @ (centre - c_pl)) ** 2
                                                    for w in tilts)
    U = ctx.k * float(np.sqrt(max(var, 0.0)))
    return _dim_result(c, nominal, value, U,
                       {"faces": [fp, {"cylinder": fy, "cone": fk}],
                        "n": [len(Pp), len(Py), len(Pk)], "cad_distance": cad,
                        "centre": centre.tolist(), "diameter": 2.0 * float(cy.radius),
                        "angle": float(np.degrees(2 * psi)), "noise": ctx.S.noise,
                        "excluded": ctx.S.excluded(fy + fk),
                        "definition": "distance from the least-squares plane to the centre of "
                                      "the circle where the least-squares cone's radius is "
                                      "the least-squares cylinder's"})
