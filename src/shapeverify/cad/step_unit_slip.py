"""Geometric tolerance values written in inches with the millimetre unit (a CAD export's slip).

NIST CTC 03 in AP242 e1 gives every dimension in a conversion-based INCH unit (``0.438`` in)
but every geometric tolerance's magnitude as ``LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(10.E-03),
#61)``, ``#61`` the SI millimetre: 0.01 mm where the drawing (and the e2 export of the same
part) says 0.010 in = 0.254 mm.  Read as written, a perfect part fails its position and
profile tolerances.  :func:`unit_slip` recognises that slip from the file alone and only when
all of this holds:

* every length dimension's value is in a conversion-based INCH unit, and every geometric
  tolerance's magnitude is in an SI length unit (the file mixes the two systems: a drawing
  dimensioned in inches tolerances in inches too);
* no tolerance value, read as millimetres, is a whole number of 0.0001 in (0.00254 mm): a
  value converted from the drawing's inches would be (0.010 in is 0.254 mm), a slipped one
  is not (0.01 "mm");

then the tolerance values are read as inches (x 25.4), and each such tolerance says so in its
``unit_note`` (the plan carries it in ``pmi.unit_note``; ``shapeverify plan`` prints it).
"""
from __future__ import annotations

import re

from .step_text import GT_TYPES, step_text
from .step_units import _CONV, _MEAS, _si_mm

__all__ = ["unit_slip", "apply_unit_slip"]

_REF = re.compile(r"#(\d+)")


def _units(ents) -> tuple[set, set]:
    """(INCH conversion-based length units, SI length units) by entity id."""
    inch, si = set(), set()
    for k, body in ents.items():
        if "LENGTH_UNIT" not in body:
            continue
        conv = _CONV.search(body)
        if conv is not None:
            if conv.group(1).strip().upper() == "INCH":
                inch.add(k)
        elif _si_mm(body) is not None:
            si.add(k)
    return inch, si


def _dimension_units(ents) -> set:
    """Units of the dimensions' nominal values (``REPRESENTATION_ITEM('nominal value')``)."""
    out = set()
    for body in ents.values():
        if "'nominal value'" in body:
            m = _MEAS.search(body)
            if m:
                out.add(int(m.group(2)))
    return out


def _tolerance_units(st) -> set:
    """Units of the geometric tolerances' magnitudes (the third argument of a tolerance
    entity, or of the GEOMETRIC_TOLERANCE of a complex one)."""
    out = set()
    for k, body in st.entities.items():
        if "TOLERANCE" not in body:
            continue
        c = st.calls(k)
        args = c.get("GEOMETRIC_TOLERANCE") or next(
            (c[n] for n in GT_TYPES if n in c and len(c[n]) >= 4), None)
        if not args or len(args) < 3:
            continue
        ref = _REF.fullmatch(args[2].strip())
        if ref is None:
            continue
        m = _MEAS.search(st.entities.get(int(ref.group(1)), ""))
        if m:
            out.add(int(m.group(2)))
    return out


def unit_slip(path, tolerances) -> bool:
    """True when the file writes its geometric tolerance values in inches with the millimetre
    unit (the module docstring's two conditions)."""
    st = step_text(path)
    ents = st.entities
    inch, si = _units(ents)
    if not inch or not si or not tolerances:
        return False
    dims, gts = _dimension_units(ents), _tolerance_units(st)
    if not dims or not gts or not dims <= inch or not gts <= si:
        return False
    zones = [t["value"] for t in tolerances if t.get("value", 0.0) > 0.0]
    if not zones:
        return False
    steps = [z / 0.00254 for z in zones]           # in units of 0.0001 in
    return not any(abs(q - round(q)) < 1e-6 * max(q, 1.0) for q in steps)


def apply_unit_slip(path, tolerances) -> bool:
    """Read the tolerance values as inches when :func:`unit_slip` holds (in place); True if so."""
    if not unit_slip(path, tolerances):
        return False
    for t in tolerances:
        note = (f"the file writes {t['value']:g} with the millimetre unit while its dimensions "
                f"are in inches; read as inches: {t['value']:g} in (a drawing in inches "
                "tolerances in inches; a value converted to millimetres would be a whole "
                "number of 0.0001 in, this one is not)")
        for key in ("value", "max_value", "zone_modifier_value"):
            if t.get(key):
                t[key] = t[key] * 25.4
        t["unit_note"] = note
    return True
