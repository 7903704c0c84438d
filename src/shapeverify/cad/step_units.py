"""The length unit a STEP file declares, read from its text: the fallback when OpenCASCADE's
``FileUnits`` returns no name (NIST CTC 05 writes its inch as the complex entity
``(CONVERSION_BASED_UNIT('inch',#m) LENGTH_UNIT() NAMED_UNIT(#d))``, which it reports as '').

>>> text = ("#1=(CONVERSION_BASED_UNIT('inch',#2) LENGTH_UNIT() NAMED_UNIT(#3));\\n"
...         "#2=MEASURE_WITH_UNIT(LENGTH_MEASURE(25.4),#4);\\n"
...         "#4=(LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.));")
>>> length_unit_of_text(text)
('inch', 25.4)
"""
from __future__ import annotations

import re

from .step_text import StepText, step_text

__all__ = ["length_unit_of_text", "length_unit_of_file"]

#: millimetres per metre for each SI prefix STEP writes (``.MILLI.``; ``$``: none)
_PREFIX_MM = {"$": 1e3, "EXA": 1e21, "PETA": 1e18, "TERA": 1e15, "GIGA": 1e12, "MEGA": 1e9,
              "KILO": 1e6, "HECTO": 1e5, "DECA": 1e4, "DECI": 1e2, "CENTI": 10.0, "MILLI": 1.0,
              "MICRO": 1e-3, "NANO": 1e-6, "PICO": 1e-9, "FEMTO": 1e-12, "ATTO": 1e-15}

_SI = re.compile(r"SI_UNIT\s*\(\s*(\$|\.(\w+)\.)\s*,\s*\.METRE\.\s*\)")
_CONV = re.compile(r"CONVERSION_BASED_UNIT\s*\(\s*'([^']*)'\s*,\s*#(\d+)\s*\)")
_MEAS = re.compile(r"LENGTH_MEASURE\s*\(\s*([-+0-9.EeDd]+)\s*\)\s*\)?\s*,\s*#(\d+)")


def _si_mm(body: str) -> float | None:
    m = _SI.search(body)
    if m is None:
        return None
    return _PREFIX_MM.get("$" if m.group(1) == "$" else m.group(2).upper())


_GLOBAL = re.compile(r"GLOBAL_UNIT_ASSIGNED_CONTEXT\s*\(\s*\(([^()]*)\)")


def length_unit_of_text(text: str) -> tuple[str, float] | None:
    """(name, millimetres per unit) of the length unit the STEP ``text`` declares, or None.

    A conversion-based length unit is followed to its measure and SI base unit; an SI length
    unit gives its prefix.  The unit the geometric context assigns
    (``GLOBAL_UNIT_ASSIGNED_CONTEXT``) wins, else a conversion-based one (the SI unit it is
    based on is declared too, often first: NIST FTC 07 declares millimetre, then its inch), else
    the first.

    >>> length_unit_of_text("#3=(LENGTH_UNIT()NAMED_UNIT(*)SI_UNIT(.MILLI.,.METRE.));\\n"
    ...     "#4=LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(25.4),#3);\\n"
    ...     "#6=(CONVERSION_BASED_UNIT('INCH',#4)LENGTH_UNIT()NAMED_UNIT(#5));\\n"
    ...     "#7=(GEOMETRIC_REPRESENTATION_CONTEXT(3)GLOBAL_UNIT_ASSIGNED_CONTEXT((#6,#8,#9))"
    ...     "REPRESENTATION_CONTEXT('',''));")
    ('INCH', 25.4)
    """
    return _length_unit(StepText(text))


def _length_unit(st: StepText) -> tuple[str, float] | None:
    ents = st.entities
    assigned = [int(r) for m in _GLOBAL.finditer(st.data)
                for r in re.findall(r"#(\d+)", m.group(1))]
    first = [k for k in assigned if k in ents] + sorted(
        ents, key=lambda k: ("CONVERSION_BASED_UNIT" not in ents[k], k))
    for k in first:
        body = ents[k]
        if "LENGTH_UNIT" not in body:
            continue
        conv = _CONV.search(body)
        if conv is None:
            mm = _si_mm(body)
            if mm is not None:
                return ("metre" if mm == 1e3 else "millimetre" if mm == 1.0 else "SI metre"), mm
            continue
        meas = _MEAS.search(ents.get(int(conv.group(2)), ""))
        if meas is None:
            continue
        base = _si_mm(ents.get(int(meas.group(2)), ""))
        if base is None:
            continue
        return conv.group(1), float(meas.group(1).replace("D", "E").replace("d", "e")) * base
    return None


def length_unit_of_file(path) -> tuple[str, float] | None:
    """:func:`length_unit_of_text` of a STEP file's DATA section (read as latin-1, once:
    :func:`.step_text.step_text`; the answer is kept with it)."""
    st = step_text(path)
    if "length_unit" not in st.memo:
        st.memo["length_unit"] = _length_unit(st)
    return st.memo["length_unit"]
