"""Lengths, areas and points as text in the unit that keeps three significant digits.

A 1 mm part's dent region printed "area 0.0 mm²", a 40 m part's "12345678.9 mm²" (issue 32):
the reports and the verdict's reasons write areas in µm², mm² or m² and lengths in µm, mm or m,
whichever shows the value with three significant digits and no exponent.  A leaf module: the
inspection's reasons and the reports both read it.
"""

from __future__ import annotations

import math

__all__ = ["area_text", "length_text", "number_text", "point_text"]


def number_text(v: float, signed: bool = False) -> str:
    """``v`` with three significant digits (more for values of 1000 and up, never an exponent).

    >>> [number_text(x) for x in (0.0012345, 0.5, 12.345, 1234.5, 0.0)]
    ['0.00123', '0.5', '12.3', '1,234', '0']
    >>> number_text(0.25, signed=True)
    '+0.25'
    """
    v = float(v)
    sign = "+" if signed else ""
    if not math.isfinite(v):
        return str(v)
    if abs(v) >= 1000:
        return f"{v:{sign},.0f}"
    if v == 0:
        return f"{0:{sign}}"
    digits = max(0, 2 - int(math.floor(math.log10(abs(v)))))
    text = f"{v:{sign}.{digits}f}"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return text


def area_text(mm2: float) -> str:
    """An area given in mm², in µm² below 0.01 mm², in m² from 1 m² on.

    >>> [area_text(a) for a in (0.0012345, 0.5, 255.0, 12_345_678.9)]
    ['1,234 µm²', '0.5 mm²', '255 mm²', '12.3 m²']
    """
    a = float(mm2)
    if a != 0 and abs(a) < 0.01:
        return f"{number_text(a * 1e6)} µm²"
    if abs(a) >= 1e6:
        return f"{number_text(a / 1e6)} m²"
    return f"{number_text(a)} mm²"


def length_text(mm: float, signed: bool = False) -> str:
    """A length given in mm, in µm below 0.01 mm, in m from 10 m on.

    >>> [length_text(x) for x in (0.0042, 0.393, 1234.5, 40_000.0)]
    ['4.2 µm', '0.393 mm', '1,234 mm', '40 m']
    >>> length_text(-0.0042, signed=True)
    '-4.2 µm'
    """
    v = float(mm)
    if v != 0 and abs(v) < 0.01:
        return f"{number_text(v * 1e3, signed)} µm"
    if abs(v) >= 10_000:
        return f"{number_text(v / 1e3, signed)} m"
    return f"{number_text(v, signed)} mm"


def point_text(xyz) -> str:
    """A point's coordinates (mm) in one unit (:func:`length_text`'s, from the largest), with the
    decimals that give its largest coordinate three significant digits.

    >>> point_text((0.8123, 0.0331, 0.305)), point_text((-2316.3, 18882.8, -5006.9))
    ('(0.812, 0.033, 0.305) mm', '(-2.3, 18.9, -5) m')
    >>> point_text((0.0012, -0.0004, 0.0))
    '(1.2, -0.4, 0) µm'
    """
    v = [float(c) for c in xyz]
    big = max((abs(c) for c in v if math.isfinite(c)), default=0.0)
    unit, f = ("µm", 1e3) if 0 < big < 0.01 else ("m", 1e-3) if big >= 10_000 else ("mm", 1.0)
    v = [c * f for c in v]
    big *= f
    digits = 0 if big == 0 or big >= 100 else max(0, 2 - int(math.floor(math.log10(big))))

    def one(c):
        if not math.isfinite(c):
            return str(c)
        t = f"{c:.{digits}f}"
        t = t.rstrip("0").rstrip(".") if "." in t else t
        return "0" if t in ("-0", "") else t

    return f"({', '.join(one(c) for c in v)}) {unit}"
