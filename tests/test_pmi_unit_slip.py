"""Tolerance values a CAD export writes in inches with the millimetre unit (NIST CTC 03 e1:
dimensions in a conversion-based INCH unit, geometric tolerances ``LENGTH_MEASURE(10.E-03)``
in the SI millimetre; a perfect part failed its 0.01 "mm" zones).  The slip is recognised
from the file alone (:mod:`shapeverify.cad.step_unit_slip`) and only then."""
from __future__ import annotations

from shapeverify.cad.step_unit_slip import apply_unit_slip, unit_slip

HEAD = "ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\n"
UNITS = ("#61=(LENGTH_UNIT()NAMED_UNIT(*)SI_UNIT(.MILLI.,.METRE.));\n"
         "#70=LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(2.54E+01),#61);\n"
         "#71=(CONVERSION_BASED_UNIT('INCH',#70)LENGTH_UNIT()NAMED_UNIT(#72));\n"
         "#80=(LENGTH_MEASURE_WITH_UNIT()MEASURE_REPRESENTATION_ITEM()MEASURE_WITH_UNIT("
         "POSITIVE_LENGTH_MEASURE(0.438),#71)REPRESENTATION_ITEM('nominal value'));\n")


def _file(tmp_path, value: str, unit: int = 61):
    p = tmp_path / f"t{value}-{unit}.stp"
    p.write_text(HEAD + UNITS
                 + f"#90=LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE({value}),#{unit});\n"
                 + "#91=POSITION_TOLERANCE('Position.1','',#90,#95);\nENDSEC;\n"
                 + "END-ISO-10303-21;\n")
    return p


def _tol(v):
    return [{"value": v, "max_value": 0.0, "zone_modifier_value": 0.0}]


def test_inch_numbers_in_a_millimetre_measure_are_read_as_inches(tmp_path):
    p = _file(tmp_path, "10.E-03")
    t = _tol(0.01)
    assert apply_unit_slip(p, t)
    assert abs(t[0]["value"] - 0.254) < 1e-12
    assert "read as inches: 0.01 in" in t[0]["unit_note"]


def test_inches_converted_to_millimetres_are_left_alone(tmp_path):
    # 0.010 in written as 0.254 mm: a whole number of 0.0001 in
    assert not unit_slip(_file(tmp_path, "0.254"), _tol(0.254))


def test_tolerances_in_the_inch_unit_are_left_alone(tmp_path):
    assert not unit_slip(_file(tmp_path, "0.01", unit=71), _tol(0.254))


def test_a_metric_file_is_left_alone(tmp_path):
    p = tmp_path / "metric.stp"
    p.write_text(HEAD + UNITS.replace("#71)REPRESENTATION_ITEM", "#61)REPRESENTATION_ITEM")
                 + "#90=LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(0.01),#61);\n"
                 + "#91=POSITION_TOLERANCE('Position.1','',#90,#95);\nENDSEC;\n")
    assert not unit_slip(p, _tol(0.01))
