"""``--model-unit`` for a CAD file: override the length unit the file declares (issue 30 item 6).

A STEP or IGES file declares its unit, and the import converts to millimetres with it; a file
that declares the wrong one (the bundled ``hammer.iges`` says MM and is then about 40.9 m across)
could not be corrected.  :func:`with_declared_unit` rescales the imported model as if the file
had declared ``unit``: every control point is multiplied by ``mm per unit / scale_to_mm`` (the
weights, knots and trimming loops, which live in parameter space, are unchanged), and a warning
names both units and the resulting size.  :func:`summary_with_declared_unit` does the same to
the figures ``shapeverify info`` shows.
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np

__all__ = ["with_declared_unit", "summary_with_declared_unit"]

logger = logging.getLogger(__name__)


def _factor(declared: str, scale_to_mm: float, unit: str, source: str) -> tuple[float, float]:
    """(mm per ``unit``, the factor to apply to coordinates already in mm)."""
    from shapeverify.unit_table import unit_factor

    f = unit_factor(unit)
    if not (math.isfinite(scale_to_mm) and scale_to_mm > 0):
        raise ValueError(f"{source}: the unit the file declares ({declared!r}) has no known size "
                         "in mm, so the coordinates OpenCASCADE converted cannot be taken back "
                         "to the file's numbers; export the file again with a standard unit")
    return f, f / scale_to_mm


def _warn(source, declared, scale_to_mm, unit, f, k, size_before):
    if k == 1.0:
        return
    logger.warning("%s: --model-unit %s overrides the unit the file declares (%s, %g mm): the "
                   "model's coordinates are multiplied by %g, so the part is %.4g mm across "
                   "(bounding-box diagonal) instead of %.4g mm", source, unit, declared,
                   scale_to_mm, k, size_before * k, size_before)


def with_declared_unit(model, unit: str):
    """The CAD ``model`` as if its file had declared ``unit``.

    Parameters
    ----------
    model : Model
        ``kind="cad"``, imported with the file's own unit (``unit``, ``scale_to_mm``).
    unit : str
        A unit of :data:`shapeverify.units.UNITS` (mm, cm, m, in, um, ...).

    Returns
    -------
    Model
        ``unit`` and ``scale_to_mm`` of the new unit; control points (and the bounds) scaled.

    Raises
    ------
    ValueError
        An unknown unit, or a file unit of unknown size (``scale_to_mm`` NaN).
    """
    from .model import Face
    from .nurbs import NurbsSurface

    f, k = _factor(model.unit, model.scale_to_mm, unit, model.source)
    size = model.size
    _warn(model.source, model.unit, model.scale_to_mm, unit, f, k, size)
    if k == 1.0:
        return dataclasses.replace(model, unit=str(unit), scale_to_mm=f)
    faces = tuple(Face(NurbsSurface(s.degree_u, s.degree_v, s.knots_u, s.knots_v, s.control * k,
                                    s.weights), fc.loops, fc.loop_free, fc.reversed)
                  for fc in model.faces for s in (fc.surface,))
    out = dataclasses.replace(model, faces=faces, unit=str(unit), scale_to_mm=f)
    b = np.array(model.bounds, dtype=np.float64) * k  # a scaling maps the box to the box
    b.setflags(write=False)
    out.__dict__["bounds"] = b
    return out


def summary_with_declared_unit(summary, unit: str, source: str = "the CAD file"):
    """:func:`with_declared_unit` for a :class:`~shapeverify.cad.summary.ModelSummary`
    (``source``: the file, named in the warning)."""
    f, k = _factor(summary.unit, summary.scale_to_mm, unit, source)
    _warn(source, summary.unit, summary.scale_to_mm, unit, f, k, summary.size)
    return dataclasses.replace(summary, unit=str(unit), scale_to_mm=f,
                               lo=tuple(x * k for x in summary.lo),
                               hi=tuple(x * k for x in summary.hi), size=summary.size * k)
