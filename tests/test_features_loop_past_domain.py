"""A trim loop that runs a little past its surface's parameter domain (NIST FTC 10: a hole's
cylinder face with v up to 8e-6 beyond +-23) no longer stops `shapeverify plan` with
'v must lie in the domain'; and a zero geometric tolerance (FTC 10's positions 0 at MMC / LMC)
is listed as unsupported instead of making an invalid plan (tol must be > 0)."""
from __future__ import annotations

import numpy as np
import pytest

from shapeverify.cad.model import Face, Model
from shapeverify.cad.nurbs import cylinder
from shapeverify.characteristics.features import model_features


def test_a_hole_wall_whose_loop_runs_past_the_v_domain_is_still_a_hole():
    surf = cylinder(radius=5.0, height=20.0)      # u around, v in [0, 1] along z
    over = 4e-7                                   # 8e-6 mm on the 20 mm wall; the surface
    loop = np.array([[0, -over], [1, -over], [1, 1 + over], [0, 1 + over]], float)
    with pytest.raises(ValueError, match="v must lie in the domain"):
        surf.evaluate(loop[:, 0], loop[:, 1])     # itself still rejects such parameters
    wall = Face(surf, (loop,), (np.zeros(4, bool),), True)   # normals inwards: a hole
    feats = model_features(Model((wall,)))
    holes = [f for f in feats if f.kind == "hole"]
    assert len(holes) == 1
    assert holes[0].diameter == pytest.approx(10.0, rel=1e-9)


def test_a_zero_tolerance_without_a_material_modifier_is_unsupported_not_an_invalid_plan():
    """NIST FTC 10's Position.12 / .19 are 0 at LMC / MMC (all bonus: planned since, see
    tests/test_position_max_projected.py); a zero zone without a material modifier has no
    bonus to come from and stays unsupported, with the reason, rather than an invalid plan."""
    from shapeverify.characteristics.pmi_plan import _tolerance

    item = {"type": "Position", "value": 0.0, "material": None, "faces": [1], "id": "GT1"}
    entries, reason = _tolerance(item, None, None, "")
    assert entries == []
    assert reason.startswith("a tolerance of 0:") and "MMC or LMC" in reason
