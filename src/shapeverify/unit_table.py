"""Millimetres per length unit: the one table (a leaf: :mod:`shapeverify.units` and
:mod:`shapeverify.cad.rescale` both read it, and ``units`` reads ``cad.rescale``).

>>> unit_factor("inch")
25.4
"""

from __future__ import annotations

__all__ = ["UNITS", "unit_factor"]

#: Millimetres per unit, by the names accepted.
UNITS = {"mm": 1.0, "millimetre": 1.0, "millimeter": 1.0, "cm": 10.0, "centimetre": 10.0,
         "centimeter": 10.0, "m": 1000.0, "metre": 1000.0, "meter": 1000.0, "in": 25.4,
         "inch": 25.4, "inches": 25.4, "um": 1e-3, "micrometre": 1e-3, "micrometer": 1e-3}


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
