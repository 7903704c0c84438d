"""A countersink's diameter at the surface it is cut in (issue 28 item 3, NIST CTC 04 DIM7:
"⌀20 ±0.3" attached to the circular edges where its 30 countersink cones meet the top face):
characteristic ``cone_diameter``.

Definition (mm): the diameter of the Tukey least-squares cone of the kept scan points of
``faces`` (:func:`.cone_sizes.cone_fit_angle`) where its axis meets the least-squares plane of
the kept scan points of ``at`` (the surface the countersink is cut in) within 1.5 times the
CAD diameter of the CAD axis (the surface around the countersink, not the whole face): ``2 (R
+ h tan psi)``, ``h`` the axial position of that point from the fitted cone's reference point.
The nominal is the same construction on the CAD (:func:`.cone_sizes.cad_cone` and the face's
plane); deviation = measured - the CAD's.  Uncertainty (k): the cone's covariance of (R, psi)
(:func:`.cone_sizes.cone_covariance`) and the plane's offset ``sigma / sqrt(n)`` along the
axis, propagated linearly.
"""
from __future__ import annotations

import numpy as np

__all__ = ["diameter_at_plane", "eval_cone_diameter"]


def diameter_at_plane(apex, axis, psi, c, n) -> tuple[float, float]:
    """(diameter, axial distance t from the apex) of the cone (apex, unit axis towards the
    opening, half angle psi rad) where its axis meets the plane through ``c`` normal to ``n``."""
    a, n = np.asarray(axis, float), np.asarray(n, float)
    t = float((np.asarray(c, float) - apex) @ n / (a @ n))
    return 2.0 * t * float(np.tan(psi)), t


def eval_cone_diameter(c, ctx):
    """cone_diameter (module docstring)."""
    from .alignment import face_indices
    from .cone_sizes import cached_cad_cone, cone_covariance, cone_fit_angle
    from .evaluate import CharacteristicResult, _not_measured
    from .gdt_size import lsq_plane
    from .zones import decide

    fl = face_indices(ctx.prep.model, c.faces).tolist()
    at = face_indices(ctx.prep.model, c.at).tolist()
    apex0, a0, psi0 = cached_cad_cone(c, ctx, fl)
    pl = [ctx.feats[f] for f in at]
    if any(f.kind != "plane" for f in pl):
        raise ValueError(f"{c.name}: at {c.at} must be planar faces")
    cad, _ = diameter_at_plane(apex0, a0, psi0, pl[0].center, pl[0].axis)
    m = ctx.S.on(fl)
    q = ctx.S.X - apex0
    off_axis = np.linalg.norm(q - np.outer(q @ a0, a0), axis=1)
    mp = ctx.S.on(at) & (off_axis <= 1.5 * cad)
    n, npl = int(np.count_nonzero(m)), int(np.count_nonzero(mp))
    if n < 20 or npl < 10:
        return _not_measured(c, f"only {n} scan points on the cone {fl} or {npl} on the "
                                f"surface {at} around it")
    P = ctx.S.X[m]
    f, psi = cone_fit_angle(P, a0)
    cp, npn = lsq_plane(ctx.S.X[mp], pl[0].axis)
    meas, t = diameter_at_plane(f.apex, f.axis, psi, cp, npn)
    # D = 2 (R + h tan psi), h the plane's axial position from f.point
    h = t - float(f.radius / np.tan(psi))
    g = np.array([2.0, 2.0 * h / np.cos(psi) ** 2])
    cov = cone_covariance(P, f)[4:, 4:]
    var = float(g @ cov @ g) + (2.0 * np.tan(psi)) ** 2 * ctx.S.noise ** 2 / npl \
        / float(abs(np.asarray(f.axis) @ npn)) ** 2
    dev = meas - cad
    U = ctx.k * float(np.sqrt(max(var, 0.0)))
    lo, hi = float(c.lower), float(c.upper)
    nominal = cad if c.nominal is None else float(c.nominal)
    return CharacteristicResult(c.name, c.type, nominal, meas, dev, lo, hi, U,
                                decide(dev, lo, hi, U),
                                {"faces": fl, "at": at, "n": [n, npl], "cad": cad,
                                 "angle": float(np.degrees(2 * psi)), "rms": float(f.rms),
                                 "excluded": ctx.S.excluded(fl),
                                 "definition": "diameter of the least-squares cone at the "
                                               "least-squares plane of the surface"})
