"""A composite position's lower segment on a feature shorter than its diameter read exactly 0
(NIST FTC 08 GT19/21/24/26: 2e-8 on every scan): the lower segment's framework floats, so of
one feature it reads only the axis' tilt, and a short feature's mating fit kept the CAD
direction.  Its axis is now the least-squares cylinder's over the feature's length (as the
orientation tolerances of a short hole take it): the value is the tilt times the length."""
import numpy as np
import pytest

from shapeverify.characteristics import evaluate_plan
from shapeverify.characteristics.parts import bracket
from shapeverify.nearest import prepare
from shapeverify.simulate import virtual_scan

BOSS = (75.0, 58.0, 8.0, 5.0)        # 16 mm across, 5 mm tall: short
PLAN = """units: mm
alignment: {type: best_fit}
datums: {A: {faces: [face:0]}, B: {faces: [face:1]}, C: {faces: [face:2]}}
characteristics:
  - {name: POS_LOWER, type: position, features: [face:3], tol: 0.3, datums: [A, B, C],
     composite: lower}
"""


def _scan(prep, tilt: float):
    views = ([1.0, 1.0, 1.6], [-1.0, 1.0, 1.6], [1.0, -1.0, 1.6], [-1.0, -1.0, 1.6])
    P = np.vstack([virtual_scan(prep, view=v, pixel=0.7, noise=0.02, rng=5 + i).scan
                   for i, v in enumerate(views)])
    on = np.asarray(prep.closest(P, exact=True).face) == 3
    bx, by, _, h = BOSS
    c = np.array([bx, by, h / 2])
    ca, sa = np.cos(tilt), np.sin(tilt)
    R = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])     # about x through the boss' middle
    P[on] = (P[on] - c) @ R.T + c
    return P, int(on.sum())


@pytest.mark.parametrize("tilt", [0.0, 0.02])
def test_short_boss_lower_segment_reads_its_tilt_not_zero(tilt):
    prep = prepare(bracket(boss=BOSS), spacing=1.0)
    P, n = _scan(prep, tilt)
    assert n > 150
    c = evaluate_plan(prep, P, PLAN)["POS_LOWER"]
    row = c.details["features"][0]
    assert "least-squares" in row["axis_fit"]
    # the axis' ends on the boss' end planes (z = 0 and 5) are 5 tan(tilt) apart across it;
    # the least-squares tilt of ~250 points with 0.02 mm noise is known to ~0.0013 rad
    expected = BOSS[3] * np.tan(tilt)
    assert c.measured == pytest.approx(expected, abs=0.025)
    assert c.measured > 1e-4                     # a measurement, never 0 by construction
    assert abs(c.measured - expected) <= c.uncertainty
