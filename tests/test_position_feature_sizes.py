"""Position of features of different sizes under one frame (a counterbored hole: the hole
and its counterbore, NIST FTC 07 GT15/GT16): ``feature_sizes`` gives each entry of
``features`` its own size limits for its bonus.  The plan and the evaluation on an
independent scan: tests/test_nist_extra_plans.py."""
from __future__ import annotations

import pytest


def _pos(**kw):
    from shapeverify.characteristics.schema import Position

    base = {"name": "p", "type": "position", "features": ["face:1", "face:2"], "tol": 0.5}
    return Position(**{**base, **kw})


HOLE = {"nominal": 7.1374, "lower": -0.0254, "upper": 0.1524}
CBORE = {"nominal": 11.1252, "lower": -0.254, "upper": 0.254}


def test_feature_sizes_give_each_feature_its_own_mmc_bonus():
    from shapeverify.characteristics.gdt import _bonus

    c = _pos(material="M", feature_sizes=[HOLE, CBORE])
    # a hole's bonus: its mating size less its own MMC (nominal + lower)
    assert _bonus(c, True, 7.15, float("nan"), 7.1374, c.feature_sizes[0])[0] == \
        pytest.approx(7.15 - 7.112)
    assert _bonus(c, True, 11.05, float("nan"), 11.1125, c.feature_sizes[1])[0] == \
        pytest.approx(11.05 - 10.8712)
    # below its own MMC: no bonus (the other feature's MMC would have given one)
    b, note = _bonus(c, True, 11.0, float("nan"), 11.1125, c.feature_sizes[0])
    assert b == pytest.approx(11.0 - 7.112)
    b, note = _bonus(c, True, 10.8, float("nan"), 11.1125, c.feature_sizes[1])
    assert b == 0.0 and "outside the size limits" in note


@pytest.mark.parametrize("kw", [
    {"material": "M", "feature_sizes": [HOLE]},                     # one per feature
    {"feature_sizes": [HOLE, CBORE]},                                # needs a material
    {"material": "M", "size": HOLE, "feature_sizes": [HOLE, CBORE]},  # instead of size
])
def test_feature_sizes_one_per_feature_with_a_material_modifier(kw):
    with pytest.raises(ValueError):
        _pos(**kw)
