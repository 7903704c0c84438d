"""Issue 28 "How good", end to end on NIST FTC 08 and CTC 01: the plan generated from the file's
semantic PMI (``pmi_plan``), run as ``inspect --plan`` runs it on a scan made independently of
the project (OpenCASCADE's tessellation sampled uniformly by area, 0.02 mm noise along the
normal, random order and pose: ``benchmarks/check_nist_plans.py``, here at 2 mm, 1 mm on faces
under 300 mm^2, to stay within a minute of CPU per part; the plan's alignment starts at the
true pose, the registration from any pose is tests/test_plan_nist.py's):

* the perfect part fails no characteristic;
* one hole (or located width) moved 0.3 mm fails the position tolerances whose zone 0.6 mm
  exceeds and nothing that does not measure the moved faces;
* one face tilted 0.2 deg (about ``n x a``, ``a`` its datum's direction) fails its
  orientation tolerance when ``L tan 0.2 deg`` exceeds the zone (FTC 08's GT7/GT8, 1.07 mm
  over 305 mm), measures it otherwise (CTC 01's GT5: the wall leaning against datum A), and
  fails nothing else.  (CTC 01's tilted wall once failed the flatness of
  the floor at its foot, GT6, 0.53 mm: the wall's points beyond the moved edge were closest to
  the floor, and flatness did not leave out the edge band the other GD&T characteristics
  leave out; that band itself missed most of a long straight edge.)  Measured: 77 s CPU for
both parts (plan from the PMI, model cached by tests/model_cache.py).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

pytestmark = [pytest.mark.slow, pytest.mark.shared]

SPACING = 2.0
#: faces under 300 mm^2 (holes' walls) at 1 mm: at 2 mm FTC 08's 5.4 mm holes keep fewer than
#: the 8 points a position needs
FINE = 1.0


def _cases(shared_data, name):
    import check_nist_plans as cnp

    cnp.DATA = shared_data / "cad" / "nist"
    # the PMI, features and tessellation shared with the other NIST modules
    return cnp.run_file(name, SPACING, 0, True, fine=FINE, cached=True)


@pytest.fixture(scope="module")
def ftc08(shared_data):
    return _cases(shared_data, "nist_ftc_08_asme1_ap242-e1.stp")


@pytest.fixture(scope="module")
def ctc01(shared_data):
    return _cases(shared_data, "nist_ctc_01_asme1_ap242-e1.stp")


def _fails(case):
    return {k: v for k, v in case["rows"].items() if v["verdict"] == "fail"}


def _check(res):
    cases = res["cases"]
    for case in cases.values():       # the plan's alignment found the true pose
        assert case["alignment"]["rot_deg"] < 0.01 and case["alignment"]["trans_mm"] < 0.02
    assert not _fails(cases["perfect"]), _fails(cases["perfect"])
    for kind in ("hole", "tilt"):
        rows = cases[kind]["rows"]
        bad = {k: v for k, v in _fails(cases[kind]).items() if v["relation"] == "other"}
        assert not bad, (kind, cases[kind]["defect"], bad)
        missed = {k: v for k, v in rows.items()
                  if v["relation"] == "expected" and v["verdict"] != "fail"}
        assert not missed, (kind, cases[kind]["defect"], missed)
    return cases


def test_ftc08_plan_perfect_moved_hole_tilted_face(ftc08):
    cases = _check(ftc08)
    hole, tilt = cases["hole"], cases["tilt"]
    # the moved hole is one of the 10-hole pattern of the composite frame GT11 (1.016 at MMC,
    # upper: located) over GT12 (0.508, lower: the zone framework floats).  Located, the hole
    # reads 2 x 0.3 mm; the lower segment's best place splits the move: 0.3, in its zone
    assert hole["defect"]["characteristic"] in ("GT11_position", "GT12_position")
    assert hole["rows"]["GT12_position"]["verdict"] == "pass"
    assert 0.25 < hole["rows"]["GT12_position"]["measured"] < 0.4
    assert hole["rows"]["GT11_position"]["verdict"] == "pass"
    # face:4 tilted 0.2 deg over its 305 mm: parallelism to A = 1.07 mm (GT7 0.381, GT8 0.762)
    L = tilt["defect"]["length"]
    for g in ("GT7_parallelism", "GT8_parallelism"):
        r = tilt["rows"][g]
        assert r["verdict"] == "fail"
        assert abs(r["measured"] - L * np.tan(np.radians(0.2))) < r["uncertainty"] + 0.05, r


def test_ctc01_plan_perfect_moved_width_tilted_face(ctc01):
    cases = _check(ctc01)
    perfect, tilt = cases["perfect"], cases["tilt"]
    # the 35 mm holes whose nominal is a limit (-0.2/0, 0/+0.2) are rightly undecided
    for n in ("DIM4_diameter_hole7", "DIM5_diameter_hole8"):
        assert perfect["rows"][n]["verdict"] == "undecided"
    # face:24 leaning 0.2 deg against A over its height L: perpendicularity L tan 0.2 deg
    # (GT5, 1.5), and the floor at its foot (datum A's face:97) keeps its flatness
    g = tilt["rows"]["GT5_perpendicularity"]
    L = tilt["defect"]["length"]
    assert abs(g["measured"] - L * np.tan(np.radians(0.2))) < g["uncertainty"] + 0.05, g
    f0, f1 = perfect["rows"]["GT6_flatness"], tilt["rows"]["GT6_flatness"]
    assert f1["verdict"] != "fail" and abs(f1["measured"] - f0["measured"]) < 0.02, (f0, f1)
