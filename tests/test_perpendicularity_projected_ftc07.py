"""NIST FTC 07 GT4: perpendicularity ⌀0.381 Ⓟ 10.795 of the hole B (faces 191, 192: ⌀6.35
along y, 6.6 mm long) to datum A (the plane y = 12.7) -- "a Projected zone modifier" was
unsupported (only positions took Ⓟ).

The zone is a cylinder square to A holding the hole's axis extended 10.795 mm out of its
mouth: a straight axis tilted by theta from A's normal reads ``L tan(theta)`` whatever its
place (brute force, to 1e-6 mm on a noise-free scan whose hole points lie exactly on the
tilted cylinder: OpenCASCADE's tessellation of the faces, points uniform at 1 mm, the hole's
moved radially onto the CAD cylinder, then turned about z through the hole's centre), not the
hole's own length times it.  A perfect part with 0.02 mm noise passes.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

GZ = Path(__file__).parent / "data" / "nist_extra" / "nist_ftc_07_asme1_ap242-e2.stp.gz"
HOLE = (191, 192)
#: datum A (142, 7), the hole B, the hole C (187, 188) for the best fit
FACES = {142, 7, 191, 192, 187, 188}
CENTRE = np.array([-142.875, 8.89, 98.425])
L = 10.795


@pytest.fixture(scope="module")
def ftc07(tmp_path_factory):
    from independent_scans import random_points
    from nist_plans import one_tolerance_on_faces

    one = one_tolerance_on_faces(GZ, tmp_path_factory.mktemp("ftc07"), "GT4", FACES)
    data, prep, inv, V, T, F = one.data, one.prep, one.inv, one.V, one.T, one.F
    rng = np.random.default_rng(7)
    P, N, t = random_points(V, T, 1.0, rng, with_triangles=True)
    hole = np.isin(F[t], [inv[f] for f in HOLE])
    q = P[hole] - CENTRE                  # onto the CAD cylinder (radius 3.175, axis y)
    rad = q * [1.0, 0.0, 1.0]
    P[hole] = CENTRE + q * [0.0, 1.0, 0.0] + rad * (3.175 / np.linalg.norm(rad, axis=1))[:, None]
    return dict(data=data, prep=prep, P=P, N=N, hole=hole, rng=rng)


def _run(d, P):
    from shapeverify.characteristics import evaluate_plan

    (c,) = evaluate_plan(d["prep"], P, d["data"], init=np.eye(4)).characteristics
    return c


def _tilted(d, deg):
    t = np.radians(deg)
    R = np.array([[np.cos(t), -np.sin(t), 0.0], [np.sin(t), np.cos(t), 0.0], [0.0, 0.0, 1.0]])
    P = d["P"].copy()
    P[d["hole"]] = (P[d["hole"]] - CENTRE) @ R.T + CENTRE
    return P


@pytest.mark.slow
def test_ftc07_gt4_is_a_projected_perpendicularity_of_the_hole_axis(ftc07):
    (c,) = ftc07["data"]["characteristics"]
    assert c["type"] == "perpendicularity" and c["zone"] == "diameter"
    assert c["projected"] == pytest.approx(L) and c["datums"] == ["A"]
    assert sorted(c["faces"]) == ["face:191", "face:192"]


@pytest.mark.slow
@pytest.mark.parametrize("deg, verdict", [(0.0, "pass"), (1.5, "pass"), (2.5, "fail")])
def test_tilted_hole_reads_its_tilt_over_the_projected_length(ftc07, deg, verdict):
    c = _run(ftc07, _tilted(ftc07, deg))
    assert c.measured == pytest.approx(L * np.tan(np.radians(deg)), abs=1e-6), c.details
    assert c.details["projected"]["length"] == pytest.approx(L)
    assert c.verdict == verdict, c


@pytest.mark.slow
def test_perfect_ftc07_hole_with_noise_passes_its_projected_perpendicularity(ftc07):
    P = ftc07["P"] + ftc07["rng"].normal(0.0, 0.02, len(ftc07["P"]))[:, None] * ftc07["N"]
    c = _run(ftc07, P)
    assert c.verdict == "pass" and c.measured < 0.2, c


def test_projected_orientation_is_of_an_axis_and_its_direction_needs_its_length():
    """The plan's orientation took no projected zone; now it does, of axes only."""
    from shapeverify.characteristics.plan import load_plan

    base = {"name": "P", "type": "perpendicularity", "faces": ["face:1"], "tol": 0.381,
            "datums": ["A"]}
    plan = {"datums": {"A": {"faces": ["face:0"]}}}
    ok = load_plan({**plan, "characteristics": [{**base, "zone": "diameter",
                                                 "projected": 10.795}]})
    assert ok.characteristics[0].projected == 10.795
    for bad, word in (({"zone": "planes", "projected": 5.0}, "axis"),
                      ({"zone": "diameter", "projected_direction": [0, 1, 0]}, "without")):
        with pytest.raises(Exception, match=word):
            load_plan({**plan, "characteristics": [{**base, **bad}]})
