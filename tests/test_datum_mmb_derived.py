"""A datum referenced at MMB/LMB whose feature has no toleranced size (NIST FTC 10 GT23's
E-F-G): the boundary from its nominal and the tolerances holding it to the higher-precedence
datums (ASME Y14.5-2009 4.11.6; :func:`shapeverify.characteristics.pmi_datums.
derived_boundary`).  Which tolerance counts is pinned here on a small PMI (the cylinder
grouping stood in); the FTC 10 numbers and a brute-force check of the pattern's worst case are
in tests/test_nist_extra_plans.py."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest


def _ctx(monkeypatch, tolerances, side="hole", kinds=None):
    from shapeverify.characteristics import pmi_plan

    def cylinders(feats, model, faces):
        return [[list(faces), np.zeros(3), np.array([0.0, 0.0, 1.0]), 3.5, side]], []

    monkeypatch.setattr(pmi_plan, "_cylinders", cylinders)
    pmi = {"datums": [{"name": "E", "faces": [1, 2]}, {"name": "F", "faces": [3, 4]}],
           "dimensions": [{"id": "DIM11", "type": "Size_Diameter", "faces": [1, 2],
                           "nominal": 3.5, "lower": None, "upper": None}],
           "tolerances": tolerances}
    specs = {n: {"kind": k} for n, k in (kinds or {"D": "plane", "B": "axis"}).items()}
    return SimpleNamespace(pmi=pmi, fmap={i: i for i in range(1, 5)}, feats=None, model=None,
                           datum_specs=specs)


def _tol(id_, type_, value, frame, faces=(1, 2), mods=None, zone="Diameter"):
    return {"id": id_, "type": type_, "value": value, "value_type": zone, "faces": list(faces),
            "datums": [{"name": n, "order": k + 1, "modifiers": (mods or {}).get(n, [])}
                       for k, n in enumerate(frame)]}


POS = _tol("GT17", "Position", 0.8, "DBC")
PERP = _tol("GT18", "Perpendicularity", 0.12, "D")


@pytest.mark.parametrize("before, pattern, tols, want", [
    # a pattern secondary to plane D: only the position holds the holes' spacing
    (["D"], True, [POS, PERP], 3.5 - 0.8),
    # one hole secondary to plane D: square to D is all that locates it (location free)
    (["D"], False, [POS, PERP], 3.5 - 0.12),
    # tertiary after D|B: the orientation to D alone does not hold it to B; the position does
    (["D", "B"], False, [POS, PERP], 3.5 - 0.8),
    # a primary hole: its MMC (no form tolerance at MMC here)
    ([], False, [POS, PERP], 3.5),
    # a position in another frame (A|D) does not hold it to D as the primary
    (["D"], True, [_tol("GT1", "Position", 0.3, "AD")], 3.5),
    # a position whose D is itself at MMB holds nothing fixed to D
    (["D"], True, [_tol("GT1", "Position", 0.3, "DBC", mods={"D": ["M"]})], 3.5),
    # a zone of two parallel planes bounds the axis one way only
    (["D"], False, [_tol("GT1", "Perpendicularity", 0.05, "D", zone="None")], 3.5),
    # the tightest of several candidates
    (["D"], True, [POS, _tol("GT2", "Position", 0.5, "DB")], 3.5 - 0.5),
])
def test_mmb_of_a_datum_without_size_limits_uses_the_tolerance_holding_it_to_earlier_datums(
        monkeypatch, before, pattern, tols, want):
    from shapeverify.characteristics.pmi_datums import derived_boundary

    got = derived_boundary("E", _ctx(monkeypatch, tols), before, pattern)
    assert got["nominal"] == 3.5
    assert got["mmb"] == pytest.approx(want, abs=1e-12)
    assert got["lmb"] == pytest.approx(7.0 - want, abs=1e-12)     # nominal + t
    assert "4.11.6" in got["rule"] and "DIM11" in got["rule"]


def test_mmb_of_a_boss_without_size_limits_lies_outside_its_nominal(monkeypatch):
    from shapeverify.characteristics.pmi_datums import derived_boundary

    got = derived_boundary("E", _ctx(monkeypatch, [POS], side="boss"), ["D"], True)
    assert (got["mmb"], got["lmb"]) == (pytest.approx(4.3), pytest.approx(2.7))


def test_shift_allowance_uses_the_derived_boundary_and_refuses_a_size_without_either():
    from shapeverify.characteristics.datum_shift import shift_allowance
    from shapeverify.characteristics.schema import DatumSize

    t = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    X = np.column_stack([1.75 * np.cos(t), 1.75 * np.sin(t), np.repeat([0.0, 5.0], 45)])
    size = DatumSize(nominal=3.5, mmb=2.7, lmb=4.3)
    r, det = shift_allowance(X, [0, 0, 0], [0, 0, 1], True, "M", size)
    assert det["boundary_diameter"] == 2.7 and r == pytest.approx(1.75 - 1.35)
    r, det = shift_allowance(X, [0, 0, 0], [0, 0, 1], True, "L", size)
    assert det["boundary_diameter"] == 4.3 and r == pytest.approx(2.15 - 1.75)
    with pytest.raises(ValueError):
        DatumSize(nominal=3.5)
    with pytest.raises(ValueError):
        DatumSize(nominal=3.5, lower=-0.1)
