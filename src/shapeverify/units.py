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

__all__ = ["UNITS", "unit_factor", "scale_points", "scale_model", "unit_hint"]

#: Millimetres per unit, by the names accepted.
UNITS = {"mm": 1.0, "millimetre": 1.0, "millimeter": 1.0, "cm": 10.0, "centimetre": 10.0,
         "centimeter": 10.0, "m": 1000.0, "metre": 1000.0, "meter": 1000.0, "in": 25.4,
         "inch": 25.4, "inches": 25.4, "um": 1e-3, "micrometre": 1e-3, "micrometer": 1e-3}

# the factors a unit mix-up produces, with the unit the smaller file is probably in
_MIXUPS = ((10.0, "centimetres", "cm"), (25.4, "inches", "in"), (1000.0, "metres", "m"))


def unit_factor(unit: str) -> float:
    """Millimetres per ``unit`` (``"mm"``, ``"cm"``, ``"m"``, ``"in"``, ``"um"`` and long names).

    Raises
    ------
    ValueError
        For an unknown unit (the message lists the known ones).
    """
    key = str(unit).strip().lower()
    if key not in UNITS:
        raise ValueError(f"unknown length unit {unit!r}; use one of mm, cm, m, in, um")
    return UNITS[key]


def scale_points(points, unit: str) -> np.ndarray:
    """``points`` given in ``unit``, in millimetres."""
    return np.asarray(points, dtype=np.float64) * unit_factor(unit)


def scale_model(model, unit: str):
    """A mesh or point-cloud model read as millimetres but really in ``unit``, in millimetres.

    Raises
    ------
    ValueError
        For a CAD model: STEP and IGES files declare their unit, which import already applied.
    """
    f = unit_factor(unit)
    if f == 1.0:
        return model
    if getattr(model, "kind", "cad") == "cad":
        raise ValueError(f"{getattr(model, 'source', 'the model')}: a CAD file declares its own unit "
                         f"({getattr(model, 'unit', '?')}), already converted to mm at import; "
                         "--model-unit is for STL, PLY, OBJ and point-cloud references")
    changes = {"scale_to_mm": float(model.scale_to_mm) * f, "unit": str(unit)}
    for name in ("vertices",):
        v = getattr(model, name, None)
        if v is not None:
            changes[name] = np.asarray(v, dtype=np.float64) * f
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
    best = None
    for f, name, short in _MIXUPS:
        for r, smaller, flag, mul in ((ratio * f, "scan", "--scan-unit", f),
                                      (ratio / f, "model", "--model-unit", f)):
            if 0.3 <= r <= 1.5:
                score = abs(math.log(r / 0.7))
                if best is None or score < best[0]:
                    best = (score, smaller, name, short, flag, mul)
    if best is None:
        return None
    _, smaller, name, short, flag, mul = best
    times = ratio if ratio > 1 else 1 / ratio
    bigger_or_smaller = "smaller" if ratio < 1 else "larger"
    return (f"the scan is {times:.3g} times {bigger_or_smaller} than the model: if the {smaller} is "
            f"in {name}, multiply it by {mul:g} ({flag} {short})")
