"""NIST FTC 10 GT9: symmetry 0.5 of the tab between faces 183 and 185 (x = 45 .. 50) to A|J,
J the centre plane of the slot between faces 181 and 187 (x = 40 .. 55) -- "Symmetry ... is
not measured" before.

On an independent scan (OpenCASCADE's tessellation of the tab's sides and of the datum faces,
uniform points at 0.5 mm (the tab is a rib 1.9 mm high), 0.02 mm noise, the alignment a best fit of those faces and two faces
across z, started at the true pose): the perfect part passes; the tab moved 0.4 mm along x (its two sides' points) reads
twice that (brute force: the median points of two planes 0.4 mm off the datum centre plane lie
0.4 mm from it) and fails.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.slow

GZ = Path(__file__).parent / "data" / "nist_extra" / "nist_ftc_10_asme1_ap242-e2.stp.gz"
#: GT9's tab, datum A (y = 0), datum J's two sides (x = 40, 55); 178, 180 (z = 16, 31) fix
#: the best fit along z
FACES = {183, 185, 213, 181, 187, 178, 180}


@pytest.fixture(scope="module")
def ftc10(tmp_path_factory):
    from independent_scans import random_points
    from nist_plans import one_tolerance_on_faces

    from shapeverify.characteristics.plan import load_plan

    one = one_tolerance_on_faces(GZ, tmp_path_factory.mktemp("ftc10"), "GT9", FACES)
    data, prep, inv, V, T, F = one.data, one.prep, one.inv, one.V, one.T, one.F
    rng = np.random.default_rng(9)
    P, N, t = random_points(V, T, 0.5, rng, with_triangles=True)
    P = P + rng.normal(0.0, 0.02, len(P))[:, None] * N
    return dict(plan=load_plan(data), data=data, prep=prep, P=P, face=F[t], inv=inv)


def _run(d, P):
    from shapeverify.characteristics import evaluate_plan

    (c,) = evaluate_plan(d["prep"], P, d["plan"], init=np.eye(4)).characteristics
    return c


def test_ftc10_gt9_symmetry_is_planned_to_the_slot_centre_plane(ftc10):
    (c,) = ftc10["data"]["characteristics"]
    assert c["type"] == "symmetry" and c["datums"] == ["A", "J"]
    assert sorted(c["faces"]) == ["face:183", "face:185"]
    assert ftc10["data"]["datums"]["J"]["kind"] == "midplane"


def test_perfect_ftc10_tab_passes_its_symmetry_and_a_moved_one_fails(ftc10):
    c = _run(ftc10, ftc10["P"])
    assert c.verdict == "pass", c
    assert c.measured < 0.1 and c.details["n_median_points"] > 40, c
    assert c.details["feature"] == "tab" and c.details["true_centre"] == pytest.approx(
        47.5 * np.sign(c.details["direction"][0]), abs=1e-9)
    tab = np.isin(ftc10["face"], [ftc10["inv"][183], ftc10["inv"][185]])
    P = ftc10["P"].copy()
    P[tab] += [0.4, 0.0, 0.0]
    b = _run(ftc10, P)
    assert b.measured == pytest.approx(0.8, abs=c.measured + 0.02), (b, b.uncertainty)
    assert b.verdict == "fail", (b, b.uncertainty, c.uncertainty)
