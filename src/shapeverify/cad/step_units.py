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

__all__ = ["length_unit_of_text", "length_unit_of_file"]

#: millimetres per metre for each SI prefix STEP writes (``.MILLI.``; ``$``: none)
_PREFIX_MM = {"$": 1e3, "EXA": 1e21, "PETA": 1e18, "TERA": 1e15, "GIGA": 1e12, "MEGA": 1e9,
              "KILO": 1e6, "HECTO": 1e5, "DECA": 1e4, "DECI": 1e2, "CENTI": 10.0, "MILLI": 1.0,
              "MICRO": 1e-3, "NANO": 1e-6, "PICO": 1e-9, "FEMTO": 1e-12, "ATTO": 1e-15}

_ENTITY = re.compile(r"#(\d+)\s*=\s*([^;]*);")
_SI = re.compile(r"SI_UNIT\s*\(\s*(\$|\.(\w+)\.)\s*,\s*\.METRE\.\s*\)")
_CONV = re.compile(r"CONVERSION_BASED_UNIT\s*\(\s*'([^']*)'\s*,\s*#(\d+)\s*\)")
_MEAS = re.compile(r"LENGTH_MEASURE\s*\(\s*([-+0-9.EeDd]+)\s*\)\s*\)?\s*,\s*#(\d+)")


def _si_mm(body: str) -> float | None:
    m = _SI.search(body)
    if m is None:
        return None
    return _PREFIX_MM.get("$" if m.group(1) == "$" else m.group(2).upper())


def length_unit_of_text(text: str) -> tuple[str, float] | None:
    """(name, millimetres per unit) of the length unit the STEP ``text`` declares, or None.

    A conversion-based length unit is followed to its measure and SI base unit; an SI length
    unit gives its prefix.  The first length unit of the file wins, less the SI units that are
    only the base of a conversion (NIST FTC 07 writes its millimetre, the inch's base, first).

    >>> length_unit_of_text("#3=(LENGTH_UNIT()NAMED_UNIT(*)SI_UNIT(.MILLI.,.METRE.));\\n"
    ...     "#4=LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(25.4),#3);\\n"
    ...     "#6=(CONVERSION_BASED_UNIT('INCH',#4)LENGTH_UNIT()NAMED_UNIT(#5));")
    ('INCH', 25.4)
    """
    ents = {int(k): v for k, v in _ENTITY.findall(text)}
    bases = set()
    for body in ents.values():
        conv = _CONV.search(body) if "LENGTH_UNIT" in body else None
        meas = _MEAS.search(ents.get(int(conv.group(2)), "")) if conv else None
        if meas is not None:
            bases.add(int(meas.group(2)))
    for k, body in ents.items():
        if "LENGTH_UNIT" not in body:
            continue
        if k in bases and _CONV.search(body) is None:
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
    """:func:`length_unit_of_text` of a STEP file's DATA section (read as latin-1)."""
    with open(path, "r", encoding="latin-1") as fh:
        text = fh.read()
    i = text.find("DATA;")
    return length_unit_of_text(text[i + 5:] if i >= 0 else text)
