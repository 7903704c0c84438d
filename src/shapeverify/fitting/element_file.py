"""Fit one geometric element (sphere, cylinder, cone, plane, line, circle) to a points file and
write the result as JSON: ``shapeverify fit POINTS --element sphere [--loss tukey] [--unit m]``.

A laser-scanner sphere (the NIST TLS spheres, metres, stray points beside the ball) is the
typical case: ``--loss tukey`` gives the 50 mm ball where least squares is pulled to ~67 mm.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np

from .cylinders_cones import fit_cone, fit_cylinder
from .lines_planes import fit_line, fit_plane
from .spheres_circles import fit_circle, fit_sphere

logger = logging.getLogger(__name__)

__all__ = ["ELEMENTS", "fit_element_file", "element_summary"]

#: element name -> fitting function (all take ``points, loss=...``)
ELEMENTS = {"sphere": fit_sphere, "cylinder": fit_cylinder, "cone": fit_cone,
            "plane": fit_plane, "line": fit_line, "circle": fit_circle}

# the result fields that are lengths or points (mm), and those that are directions (unit)
_FIELDS = {"sphere": ("center", "radius"), "circle": ("center", "radius", "normal"),
           "cylinder": ("point", "axis", "radius"), "cone": ("point", "axis", "radius", "half_angle"),
           "plane": ("point", "normal"), "line": ("point", "direction")}


def element_summary(fit, element: str) -> dict:
    """The JSON-ready fields of a fit result (lists and floats; ``half_angle`` in radians)."""
    out = {}
    for name in _FIELDS[element]:
        v = getattr(fit, name)
        out[name] = np.asarray(v, dtype=float).tolist() if np.ndim(v) else float(v)
    w = np.asarray(fit.weights) > 0
    r = np.asarray(fit.residuals)
    # a robust fit's rms counts the rejected stray points too; the inliers' rms is the fit's own
    out.update(rms=float(fit.rms),
               rms_inliers=float(np.sqrt(np.mean(r[w] ** 2))) if w.any() else float("nan"),
               inlier_fraction=float(np.mean(w)) if w.size else 1.0,
               loss=fit.loss, iterations=int(fit.iterations), converged=bool(fit.converged))
    return out


def fit_element_file(points_path, out_path, element: str, loss: str = "l2",
                     unit: str | None = None) -> dict:
    """Fit ``element`` to the points of a file and write the result as JSON.

    Parameters
    ----------
    points_path : str or os.PathLike
        Any format of :func:`shapeverify.io.points.read_points`.
    out_path : str or os.PathLike
        ``.json``: ``{"element": ..., "fit": {...}}``.
    element : {"sphere", "cylinder", "cone", "plane", "line", "circle"}
    loss : str
        ``"l2"`` (least squares) or a robust loss (``"tukey"``, ``"huber"``, ...; see
        :func:`shapeverify.fitting.fit_sphere`).
    unit : str, optional
        The unit of the points file (``m``, ``in``, ... :mod:`shapeverify.units`); the result is
        then in mm.  Default: the file's own units.

    Returns
    -------
    dict
        ``element``, ``points``, the element's fields (e.g. ``center``, ``radius``), ``rms``
        (all points), ``rms_inliers`` (points of non-zero weight), ``inlier_fraction``, ``loss``, ``iterations``, ``converged``, ``units``, ``output``.

    Raises
    ------
    ValueError
        Unknown element or loss, an output that is not ``.json``, degenerate points (all the
        same, on a line), or a fit that fails.
    """
    from ..io.points import read_points

    key = str(element).strip().lower()
    if key not in ELEMENTS:
        raise ValueError(f"unknown element {element!r}; use one of {', '.join(ELEMENTS)}")
    out = Path(out_path)
    if out.suffix.lower() != ".json":
        raise ValueError(f"output {out.name!r}: a fitted {key} is written as .json")
    x = read_points(points_path)
    if unit is not None:
        from ..units import scale_points
        x = scale_points(x, unit)
    fit = ELEMENTS[key](x, loss=loss)
    summary = {"element": key, "points": int(len(x)), **element_summary(fit, key),
               "units": "mm" if unit is not None else "input units", "output": str(out)}
    out.write_text(json.dumps({"element": key, "fit": summary}, indent=1))
    logger.info("fitted %s to %d points: rms %.4g -> %s", key, len(x), fit.rms, out)
    return summary
