"""Reverse engineering: fit a NURBS curve or surface to a points file and write it out.

``.json`` holds our own NURBS data (:func:`nurbs_to_dict`); ``.step`` / ``.stp`` / ``.igs`` /
``.iges`` go through OpenCASCADE (:func:`shapeverify.cad.occ_write.write_nurbs`) so the result
opens in CAD software.  Used by ``shapeverify fit POINTS [--surface] [--ctrl NU NV] [--degree]
-o OUT``.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np

from ..cad.nurbs import NurbsCurve, NurbsSurface
from .curves import SLIDE_STIFFNESS, FitSolver, fit_curve
from .surfaces import fit_surface

logger = logging.getLogger(__name__)

__all__ = ["fit_points_file", "nurbs_to_dict", "nurbs_from_dict"]

_SUFFIXES = (".json", ".step", ".stp", ".igs", ".iges")


def nurbs_to_dict(shape) -> dict:
    """JSON-ready dict of a NurbsCurve or NurbsSurface (lists of floats; weights None if polynomial)."""
    if isinstance(shape, NurbsSurface):
        return {"type": "NurbsSurface", "degree_u": shape.degree_u, "degree_v": shape.degree_v,
                "knots_u": shape.knots_u.tolist(), "knots_v": shape.knots_v.tolist(),
                "control": shape.control.tolist(),
                "weights": None if shape.weights is None else shape.weights.tolist()}
    if isinstance(shape, NurbsCurve):
        return {"type": "NurbsCurve", "degree": shape.degree, "knots": shape.knots.tolist(),
                "control": shape.control.tolist(),
                "weights": None if shape.weights is None else shape.weights.tolist()}
    raise TypeError(f"expected a NurbsCurve or NurbsSurface, got {type(shape).__name__}")


def nurbs_from_dict(data: dict):
    """Inverse of :func:`nurbs_to_dict` (validated by the NURBS constructors).

    Raises
    ------
    ValueError
        Unknown ``type`` or invalid NURBS data.
    """
    kind = data.get("type")
    if kind == "NurbsSurface":
        return NurbsSurface(data["degree_u"], data["degree_v"], data["knots_u"], data["knots_v"],
                            data["control"], data.get("weights"))
    if kind == "NurbsCurve":
        return NurbsCurve(data["degree"], data["knots"], data["control"], data.get("weights"))
    raise ValueError(f"unknown NURBS type {kind!r} (expected 'NurbsCurve' or 'NurbsSurface')")


def fit_points_file(points_path, out_path, surface: bool = False, ctrl=None, degree: int = 3,
                    method: str = "odr", smoothing: float = 0.0, max_iterations: int = 100,
                    slide_stiffness: float = SLIDE_STIFFNESS) -> dict:
    """Fit a NURBS curve (ordered points) or surface to a points file and write it.

    Parameters
    ----------
    points_path : str or os.PathLike
        Any format of :func:`shapeverify.io.points.read_points` (.ply .xyz .txt .csv .npy .pcd).
        For a curve the points must be ordered along it (file order).
    out_path : str or os.PathLike
        ``.json`` (NURBS data + fit summary), ``.step`` / ``.stp`` or ``.igs`` / ``.iges``.
    surface : bool
        Fit a surface (scattered points, parametrised over their best-fit plane) instead of a curve.
    ctrl : int or (int, int), optional
        Control points: a count for a curve, ``(nu, nv)`` (or one int for both) for a surface.
        Default: curve ``min(N // 5, 50)``; surface ``clip(sqrt(N / 20), degree + 1, 30)`` per direction.
    degree : int
        Degree (both directions for a surface).
    method : {"odr", "varpro", "fixed"}
    smoothing : float
        See :func:`fit_curve` / :func:`fit_surface` (needed when the points leave parts of the
        parameter rectangle empty).
    max_iterations : int
    slide_stiffness : float
        See :func:`fit_curve` (0: the plain orthogonal-distance objective).

    Returns
    -------
    dict with ``kind``, ``points``, ``ctrl``, ``degree``, ``method``, ``rms``, ``max_error``,
    ``iterations``, ``converged``, ``output`` (the written path), ``units`` ("input units", mm
    for project data).

    Raises
    ------
    ValueError
        Unknown output suffix, bad ``ctrl``/``degree``, or any fitting error.
    """
    from ..io.points import read_points

    out = Path(out_path)
    if out.suffix.lower() not in _SUFFIXES:
        raise ValueError(f"output {out.name!r}: use one of {', '.join(_SUFFIXES)}")
    x = read_points(points_path)
    N = x.shape[0]
    if surface:
        if ctrl is None:
            k = int(np.clip(int(np.sqrt(N / 20.0)), degree + 1, 30))
            ctrl = (k, k)
        elif isinstance(ctrl, (int, np.integer)):
            ctrl = (int(ctrl), int(ctrl))
        else:
            ctrl = tuple(int(c) for c in ctrl)
            if len(ctrl) != 2:
                raise ValueError(f"ctrl for a surface must be one or two integers, got {ctrl}")
        fit = fit_surface(x, degrees=(degree, degree), n_ctrl=ctrl, method=method,
                          smoothing=smoothing, solver=FitSolver(
                              max_iterations=max_iterations, slide_stiffness=slide_stiffness))
        shape = fit.surface
    else:
        if ctrl is not None and not isinstance(ctrl, (int, np.integer)):
            vals = tuple(ctrl)
            if len(vals) != 1:
                raise ValueError(f"ctrl for a curve must be one integer, got {ctrl}")
            ctrl = int(vals[0])
        fit = fit_curve(x, degree=degree, n_ctrl=ctrl, method=method, smoothing=smoothing,
                        solver=FitSolver(max_iterations=max_iterations,
                                         slide_stiffness=slide_stiffness))
        shape = fit.curve
        ctrl = int(shape.control.shape[0])
    summary = {"kind": "surface" if surface else "curve", "points": int(N),
               "ctrl": list(ctrl) if surface else ctrl, "degree": int(degree), "method": method,
               "rms": fit.rms, "max_error": fit.max_error, "iterations": fit.iterations,
               "converged": fit.converged, "output": str(out), "units": "input units"}
    if out.suffix.lower() == ".json":
        out.write_text(json.dumps({"nurbs": nurbs_to_dict(shape), "fit": summary}, indent=1))
    else:
        from ..cad.occ_write import write_nurbs
        write_nurbs(shape, out)
    logger.info("fitted %s to %d points: rms %.4g, max %.4g -> %s", summary["kind"], N, fit.rms,
                fit.max_error, out)
    return summary
