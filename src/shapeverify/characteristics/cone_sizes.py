"""The angle of a cone (issue 28 item 3, NIST CTC 04 ``Size_Angular``: the 90° ±1° of its 30
countersinks): characteristic ``cone_angle``.

Definitions (degrees)
---------------------
* **CAD cone** of faces (:func:`cad_cone`): closed form from a grid of points ``X`` and unit
  normals ``N`` of the faces (several faces: one cone, e.g. two half-cones).  A cone's normals
  make one angle with its axis, so the axis ``a`` is the normal of the plane the normal vectors
  span (least squares); every generator runs through the apex ``A``, perpendicular to the
  surface normal, so ``N_i . A = N_i . X_i`` (least squares, 3 unknowns); the half angle ``psi``
  is the mean of ``atan2(rho, h)`` (``h = (X - A) . a``, ``rho`` the distance from the axis)
  over the points not at the apex.
  ``err``: the largest distance of the grid points from that cone (a cone when ~0).
* **measured**: the half angle of the Tukey least-squares cone of the kept scan points of the
  faces (:func:`shapeverify.fitting.fit_cone`, orthogonal distances, axis started at the
  CAD's); ``angle: included`` reports ``2 psi`` (a countersink's angle, as ASME Y14.5 draws
  it), ``half`` reports ``psi`` (an angle to the axis).  Deviation = measured - the CAD's angle
  (the limits are about the drawing's nominal, which the plan checked against the CAD's).
* Uncertainty (k): the sandwich covariance of the linearised fit (axis point 2, tilt 2, radius,
  half angle) from the weighted residuals.
"""
from __future__ import annotations

import numpy as np

__all__ = ["cad_cone", "cached_cad_cone", "cone_fit_angle", "half_angle_sd", "cone_covariance", "eval_cone_angle"]


def cad_cone(model, faces) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(apex (3,), unit axis (3,) towards the opening, half angle (rad), err (mm)) of the CAD
    faces ``faces`` taken as one cone (module docstring)."""
    from .features import _face_grid

    grids = [_face_grid(model.faces[f]) for f in faces]
    return cone_from_normals(np.concatenate([g[0] for g in grids]),
                             np.concatenate([g[1] for g in grids]))


def cone_from_normals(X, N) -> tuple[np.ndarray, np.ndarray, float, float]:
    """:func:`cad_cone` of points ``X`` (n, 3) on a surface with unit normals ``N``."""
    X, N = np.asarray(X, np.float64), np.asarray(N, np.float64)
    a = np.linalg.svd(N - N.mean(axis=0), full_matrices=False)[2][2]
    A = np.linalg.lstsq(N, np.einsum("ij,ij->i", N, X), rcond=None)[0]
    q = X - A
    h = q @ a
    if np.mean(h) < 0:
        a, h = -a, -h
    rho = np.linalg.norm(q - np.outer(h, a), axis=1)
    # a grid point at the apex has no angle (atan2(0, 0): NIST FTC 07's drill points read
    # 58.47 deg for 59 and were "not one cone")
    r = np.hypot(rho, h)
    away = r > 1e-9 * max(float(r.max()), 1.0)
    psi = float(np.mean(np.arctan2(rho[away], h[away])))
    err = float(np.max(np.abs(rho * np.cos(psi) - h * np.sin(psi))))
    return A, a, psi, err


def cone_fit_angle(P, axis=None, loss: str = "tukey"):
    """The cone fitted to ``P`` (:func:`shapeverify.fitting.fit_cone`) and its half angle (rad)."""
    from ..fitting import fit_cone

    f = fit_cone(P, loss=loss, axis=axis)
    return f, float(f.half_angle)


def half_angle_sd(P, f) -> float:
    """Standard uncertainty (rad) of the half angle of the cone fit ``f`` of ``P``
    (:func:`cone_covariance`)."""
    return float(np.sqrt(max(cone_covariance(P, f)[5, 5], 0.0)))


def cone_covariance(P, f) -> np.ndarray:
    """(6, 6) covariance of the cone fit ``f`` of ``P`` in (axis point 2, tilt 2, R at
    ``f.point``, half angle): sandwich covariance of the orthogonal distance
    ``d = (rho - R) cos psi - h sin psi`` linearised by central differences."""
    from .holes import plane_basis

    p0, a0 = np.asarray(f.point, float), np.asarray(f.axis, float)
    e1, e2 = plane_basis(a0)

    def dist(t):
        p = p0 + t[0] * e1 + t[1] * e2
        a = a0 + t[2] * e1 + t[3] * e2
        a = a / np.linalg.norm(a)
        q = P - p
        h = q @ a
        rho = np.linalg.norm(q - np.outer(h, a), axis=1)
        return (rho - t[4]) * np.cos(t[5]) - h * np.sin(t[5])

    t0 = np.array([0.0, 0.0, 0.0, 0.0, float(f.radius), float(f.half_angle)])
    J = np.empty((len(P), 6))
    for k, step in enumerate((1e-6, 1e-6, 1e-7, 1e-7, 1e-6, 1e-7)):
        dt = np.zeros(6)
        dt[k] = step
        J[:, k] = (dist(t0 + dt) - dist(t0 - dt)) / (2 * step)
    w, r = np.asarray(f.weights, float), np.asarray(f.residuals, float)
    try:
        Hinv = np.linalg.inv((J * w[:, None]).T @ J)
    except np.linalg.LinAlgError:
        return np.full((6, 6), np.inf)
    Jb = J * (w * r)[:, None]
    return Hinv @ (Jb.T @ Jb) @ Hinv


def cached_cad_cone(c, ctx, fl) -> tuple[np.ndarray, np.ndarray, float]:
    """(apex, axis, half angle) of :func:`cad_cone` of the model faces ``fl``, kept in the
    evaluation's cache; ValueError when the faces are not one cone."""
    key = ("cad_cone", tuple(fl))
    if key not in ctx.cache:
        ctx.cache[key] = cad_cone(ctx.prep.model, fl)
    apex, axis0, psi0, err = ctx.cache[key]
    if not err <= 1e-6 * max(float(ctx.prep.model.size), 1.0) + 1e-9:
        raise ValueError(f"{c.name}: the faces {fl} are not one cone (CAD points {err:.3g} mm "
                         "off the cone of their normals)")
    return apex, axis0, psi0


def eval_cone_angle(c, ctx):
    """cone_angle (module docstring)."""
    from .alignment import face_indices
    from .evaluate import CharacteristicResult, _not_measured
    from .zones import decide

    fl = face_indices(ctx.prep.model, c.faces).tolist()
    apex, axis0, psi0 = cached_cad_cone(c, ctx, fl)
    m = ctx.S.on(fl)
    n = int(np.count_nonzero(m))
    if n < 20:
        return _not_measured(c, f"only {n} scan points on faces {fl}")
    P = ctx.S.X[m]
    f, psi = cone_fit_angle(P, axis0)
    scale = 2.0 if c.angle == "included" else 1.0
    cad = scale * float(np.degrees(psi0))
    meas = scale * float(np.degrees(psi))
    dev = meas - cad
    U = ctx.k * scale * float(np.degrees(half_angle_sd(P, f)))
    lo, hi = float(c.lower), float(c.upper)
    nominal = cad if c.nominal is None else float(c.nominal)
    return CharacteristicResult(c.name, c.type, nominal, meas, dev, lo, hi, U,
                                decide(dev, lo, hi, U),
                                {"faces": fl, "angle": c.angle, "n": n, "cad": cad,
                                 "unit": "deg", "rms": float(f.rms),
                                 "apex": np.asarray(f.apex, float).tolist(),
                                 "axis": np.asarray(f.axis, float).tolist(),
                                 "excluded": ctx.S.excluded(fl),
                                 "definition": "angle of the least-squares cone"})
