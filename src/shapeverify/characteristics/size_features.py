"""Size of a radius or a sphere (issue 28 item 3, NIST FTC 06 ``Size_Radius``,
``Size_SphericalDiameter``, ``Size_SphericalRadius``; FTC 11's fillet ``Size_Radius``): the
two-point-free, least-squares size (ISO 14405-1 (GG)) of one feature -- a group of coaxial
cylindrical faces of one radius, the spherical faces of one sphere, or a torus's faces (a
fillet about an axis: its tube's radius) -- against the drawing's ± limits.

``shape: cylinder``: the Tukey least-squares cylinder of the feature's kept points, its axis
started at the CAD's (:func:`shapeverify.fitting.fit_cylinder`); ``shape: sphere``: the
Tukey least-squares sphere (:func:`shapeverify.fitting.fit_sphere`); ``shape: torus``: the
Tukey least-squares torus started at the CAD's (:func:`shapeverify.fitting.torus.fit_torus`),
its minor radius.  ``size: radius`` reports the radius, ``diameter`` twice it; the nominal is
the CAD's (the same fit of the faces' own grid points), the deviation ``measured - nominal``
within ``[lower, upper]``.  Uncertainty (k): the linearised least-squares covariance of the
radius from the weighted residuals (a partial arc or cap -- a fillet's quarter tube -- is
poorly conditioned and says so in a large U)."""
from __future__ import annotations

import numpy as np

__all__ = ["eval_feature_size", "radius_uncertainty", "cad_size", "cad_torus"]


def radius_uncertainty(P: np.ndarray, centre, axis, residuals, weights,
                       major: float | None = None) -> float:
    """Standard uncertainty of a fitted radius (sandwich covariance of the linearised fit):
    a sphere (``axis`` None: centre 3 + radius), a cylinder (axis point 2, tilt 2, radius) or,
    with ``major`` (the spine's radius), a torus's minor radius (centre 3, tilt 2, R, r)."""
    q = P - np.asarray(centre, float)
    if major is not None:
        from ..fitting.torus import torus_jacobian

        J = torus_jacobian(P, centre, axis, major)[1]
    elif axis is None:
        rn = np.linalg.norm(q, axis=1)
        ud = q / np.where(rn > 0, rn, 1.0)[:, None]
        J = np.column_stack([-ud, -np.ones(len(P))])
    else:
        from .holes import plane_basis

        a = np.asarray(axis, float)
        h = q @ a
        radial = q - np.outer(h, a)
        rn = np.linalg.norm(radial, axis=1)
        ud = radial / np.where(rn > 0, rn, 1.0)[:, None]
        e1, e2 = plane_basis(a)
        J = np.column_stack([-(ud @ e1), -(ud @ e2), -(ud @ e1) * h, -(ud @ e2) * h,
                             -np.ones(len(P))])
    w, r = np.asarray(weights, float), np.asarray(residuals, float)
    try:
        Hinv = np.linalg.inv((J * w[:, None]).T @ J)
    except np.linalg.LinAlgError:
        return float("inf")
    Jb = J * (w * r)[:, None]
    return float(np.sqrt(max((Hinv @ (Jb.T @ Jb) @ Hinv)[-1, -1], 0.0)))


def _fit(P, shape, axis=None, torus=None):
    from ..fitting import fit_cylinder, fit_sphere

    if shape == "torus":
        from ..fitting.torus import fit_torus

        f = fit_torus(P, start=torus, loss="tukey")
        return f, np.asarray(f.center, float), np.asarray(f.axis, float), float(f.minor_radius)
    if shape == "sphere":
        f = fit_sphere(P, loss="tukey")
        return f, np.asarray(f.center, float), None, float(f.radius)
    f = fit_cylinder(P, loss="tukey", axis=axis)
    return f, np.asarray(f.point, float), np.asarray(f.axis, float), float(f.radius)


def cad_size(model, faces, shape) -> tuple[float, np.ndarray | None, float]:
    """(CAD radius, axis or None, largest residual) of the faces' grid points fitted as one
    cylinder or sphere (least squares); of a torus, (minor radius, the CAD's
    :class:`~shapeverify.fitting.torus.TorusFit`, largest residual)."""
    from ..fitting import fit_cylinder, fit_sphere
    from .features import _face_grid

    if shape == "torus":        # its own grid points, fitted from the surface's torus
        t = cad_torus(model, faces)
        if t is None:
            return float("nan"), None, float("inf")
        return t.minor_radius, t, float(np.abs(t.residuals).max())
    X = np.concatenate([_face_grid(model.faces[f])[0] for f in faces])
    if shape == "sphere":
        f = fit_sphere(X)
        return float(f.radius), None, float(np.abs(f.residuals).max())
    f = fit_cylinder(X)
    return float(f.radius), np.asarray(f.axis, float), float(np.abs(f.residuals).max())


def cad_torus(model, faces):
    """The one torus of the faces (their grid points fitted from the first face's torus,
    :func:`shapeverify.fitting.torus.torus_of_surface`), or None."""
    from ..fitting.torus import fit_torus, torus_of_surface
    from .features import _face_grid

    f0 = model.faces[faces[0]]
    t = torus_of_surface(f0.surface, f0.uv_bounds)
    if t is None or len(faces) == 1:
        return t
    X = np.concatenate([_face_grid(model.faces[f])[0] for f in faces])
    try:
        return fit_torus(X, start=t)
    except ValueError:
        return None


def eval_feature_size(c, ctx):
    """feature_size (module docstring)."""
    from .alignment import face_indices
    from .evaluate import CharacteristicResult, _not_measured
    from .zones import decide

    fl = face_indices(ctx.prep.model, c.faces).tolist()
    key = ("cad_size", c.shape, tuple(fl))
    if key not in ctx.cache:
        ctx.cache[key] = cad_size(ctx.prep.model, fl, c.shape)
    r0, axis0, err = ctx.cache[key]
    if not err <= 1e-5 * r0 + 1e-9:
        raise ValueError(f"{c.name}: the faces {fl} are not one {c.shape} (CAD points {err:.3g} "
                         "mm off its best fit)")
    m = ctx.S.on(fl)
    n = int(np.count_nonzero(m))
    if n < 20:
        return _not_measured(c, f"only {n} scan points on faces {fl}")
    P = ctx.S.X[m]
    if c.shape == "torus":
        f, centre, axis, r = _fit(P, c.shape, torus=axis0)
        u_r = radius_uncertainty(P, centre, axis, f.residuals, f.weights, f.major_radius)
    else:
        f, centre, axis, r = _fit(P, c.shape, axis0)
        u_r = radius_uncertainty(P, centre, axis, f.residuals, f.weights)
    scale = 2.0 if c.size == "diameter" else 1.0
    nominal = scale * r0 if c.nominal is None else float(c.nominal)
    meas = scale * r
    dev = meas - scale * r0          # the limits are about the drawing's nominal = the CAD's
    U = ctx.k * scale * u_r
    lo, hi = float(c.lower), float(c.upper)
    return CharacteristicResult(c.name, c.type, nominal, meas, dev, lo, hi, U,
                                decide(dev, lo, hi, U),
                                {"faces": fl, "shape": c.shape, "size": c.size, "n": n,
                                 "cad": scale * r0, "rms": float(f.rms),
                                 "excluded": ctx.S.excluded(fl)})
