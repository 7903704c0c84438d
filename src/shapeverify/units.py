"""Length units of files that carry none.

CAD files (STEP, IGES) declare their unit and are converted to millimetres at import.  STL, PLY,
OBJ and point-cloud files carry no unit: they are taken to be in millimetres unless the user says
otherwise (``--model-unit`` / ``--scan-unit`` on the command line, :func:`scale_points` and
:func:`scale_model` in Python).  When a scan and its model differ in size by about a unit factor
(10, 25.4 or 1000), :func:`unit_hint` names the factor that fits.

>>> unit_factor("in"), unit_factor("cm"), unit_factor("mm")
(25.4, 10.0, 1.0)
>>> unit_hint(scan_size=36.0, model_size=360.0)[:58]
'the scan is 10 times smaller than the model: if the scan i'
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

# the table itself is a leaf (cad.rescale reads it; this module reads cad.rescale)
from .unit_table import UNITS, unit_factor

__all__ = ["UNITS", "MIXUPS", "unit_factor", "scale_points", "scale_model", "unit_hint",
           "fitting_factor"]

#: Unit mix-ups: (millimetres per unit, name, short name) of the unit a file is probably in.
MIXUPS = ((1000.0, "metres", "m"), (25.4, "inches", "in"), (10.0, "centimetres", "cm"),
          (1e-3, "micrometres", "um"))


def fitting_factor(ratio: float, factors, lo: float, hi: float, target: float):
    """``(score, factor, name, short)`` of the ``factors`` entry that brings ``ratio * factor``
    into ``[lo, hi]`` nearest to ``target`` on a log scale (score ``|log(ratio f / target)|``),
    or None when none does.  The one search behind :func:`unit_hint` and the scan check of
    :func:`shapeverify.inspection.check_scan`."""
    fits = [(abs(math.log(ratio * f / target)), f, name, short) for f, name, short in factors
            if lo <= ratio * f <= hi]
    return min(fits) if fits else None


def scale_points(points, unit: str) -> np.ndarray:
    """``points`` given in ``unit``, in millimetres."""
    return np.asarray(points, dtype=np.float64) * unit_factor(unit)


def scale_model(model, unit: str):
    """A mesh or point-cloud model read as millimetres but really in ``unit``, in millimetres;
    a CAD model as if its file had declared ``unit`` instead of its own (a warning names both
    units and the resulting size: :func:`shapeverify.cad.rescale.with_declared_unit`).

    Raises
    ------
    ValueError
        An unknown unit; a CAD file whose declared unit has no known size.
    """
    f = unit_factor(unit)
    if getattr(model, "kind", "cad") == "cad":
        from shapeverify.cad.rescale import with_declared_unit
        return with_declared_unit(model, unit)
    if f == 1.0:
        return model
    changes = {"scale_to_mm": float(model.scale_to_mm) * f, "unit": str(unit)}
    if model.vertices is not None:
        changes["vertices"] = np.asarray(model.vertices, dtype=np.float64) * f
    return dataclasses.replace(model, **changes)


def unit_hint(scan_size: float, model_size: float) -> str | None:
    """A sentence naming the unit factor that would make a scan fit its model, or None.

    A scan usually spans 20-120 % of its part (``scan_size`` and ``model_size`` are bounding-box
    diagonals, mm).  When the ratio lies outside 15-300 % but a unit factor (10, 25.4, 1000) brings
    it to 30-150 %, that factor is named.
    """
    if not (scan_size > 0 and model_size > 0):
        return None
    ratio = scan_size / model_size
    if 0.15 <= ratio <= 3.0:
        return None
    common = [m for m in MIXUPS if m[0] > 1.0]               # cm, inch, m vs mm
    # the scan in a larger unit: ratio * f in [0.3, 1.5]; the model: ratio / f there, i.e.
    # (1 / ratio) * f in [1 / 1.5, 1 / 0.3] (same log score about 1 / 0.7)
    sides = (("scan", "--scan-unit", fitting_factor(ratio, common, 0.3, 1.5, 0.7)),
             ("model", "--model-unit", fitting_factor(1.0 / ratio, common, 1 / 1.5, 1 / 0.3, 1 / 0.7)))
    found = [(fit, side, flag) for side, flag, fit in sides if fit is not None]
    if not found:
        return None
    (_, mul, name, short), smaller, flag = min(found, key=lambda x: x[0][0])
    times = ratio if ratio > 1 else 1 / ratio
    bigger_or_smaller = "smaller" if ratio < 1 else "larger"
    return (f"the scan is {times:.3g} times {bigger_or_smaller} than the model: if the {smaller} is "
            f"in {name}, multiply it by {mul:g} ({flag} {short})")
