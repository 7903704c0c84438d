"""The plan made from NIST FTC 08's semantic PMI, run on an independent scan (issue 28 "How
good"): OpenCASCADE's tessellation of the STEP file, points uniform by area at 1 mm, 0.02 mm
Gaussian noise along the triangles' normals, a rigid motion (``tests/independent_scans.py``).

* a perfect part fails no characteristic, and the plan's own D|B|C alignment converges (its
  datum holes B and C are their whole cylinder walls: fitted on the rims of one end, 19
  points, they put the frame 0.2 mm off and called hole B a bad fit, every characteristic
  'undecided');
* the wall of hole face 70 moved 0.3 mm sideways fails that hole's position (GT21, the
  ⌀0.508 MMC segment: about 0.62 against 0.508 with U about 0.06, the centre of a mating
  circle moving only with the difference of its extremes) and nothing else;
* face 4 tilted 0.2 degrees fails its parallelism tolerances (GT7, GT8) and nothing that does
  not control face 4.

The plan runs as ``shapeverify plan`` writes it: its ``datums`` alignment and every
characteristic.  Three characteristics of the perfect scan stay 'undecided' for reasons of
the scan itself: GT14 (profile 0.127 of 344 points with 0.02 mm noise: the extremes alone
make 0.145) and two hole diameters (the tessellation's chords make the scanned holes about
0.013 mm smaller, within U of the lower limit -0.0254).
"""
from __future__ import annotations

import numpy as np
import pytest

NAME = "nist_ftc_08_asme1_ap242-e1.stp"


@pytest.fixture(scope="module")
def ftc08(shared_data):
    from independent_scans import file_tessellation, random_points
    from model_cache import cached_model, cached_pmi, cached_prepared

    from shapeverify.characteristics.drf import rigid_exp
    from shapeverify.characteristics.features import model_features
    from shapeverify.characteristics.plan import load_plan
    from shapeverify.characteristics.pmi_plan import pmi_plan

    path = shared_data / "cad" / "nist" / NAME
    if not path.exists():
        pytest.skip(f"{path} not present (NIST MBE PMI test model)")
    # import, PMI, preparation and tessellation: once per suite run for every NIST module
    # (tests/model_cache.py: bitwise what load_model, read_pmi, prepare, tessellate give)
    model = cached_model(path, features=True)
    r = pmi_plan(path, model=model, pmi=cached_pmi(path))
    assert r.data["alignment"]["type"] == "datums"
    plan = load_plan(r.data)
    m = getattr(model, "model", model)
    prep = cached_prepared(path, spacing=1.0, features=True)
    V, T, F = file_tessellation(path, 0.01)
    rng = np.random.default_rng(0)
    P, N, t = random_points(V, T, 1.0, rng, with_triangles=True)
    P = P + rng.normal(0.0, 0.02, len(P))[:, None] * N
    M = rigid_exp([0.05, -0.03, 0.02, 3.0, -2.0, 1.0])
    return dict(plan=plan, prep=prep, P=P, face=F[t], M=M, feats=model_features(m))


def _run(d, P):
    from shapeverify.characteristics import evaluate_plan

    M = d["M"]
    res = evaluate_plan(d["prep"], P @ M[:3, :3].T + M[:3, 3], d["plan"], init=np.linalg.inv(M))
    assert res.alignment.details["converged"], res.alignment.details.get("reason")
    return {c.name: c for c in res.characteristics}


def _fails(res):
    return {n for n, c in res.items() if c.verdict == "fail"}


@pytest.mark.slow
def test_ftc08_perfect_scan_fails_no_characteristic(ftc08):
    res = _run(ftc08, ftc08["P"])
    assert not _fails(res), {n: (res[n].measured, res[n].upper) for n in _fails(res)}
    # 'undecided' only where the scan itself sits at the limit: GT14 (noise extremes) and hole
    # diameters (the tessellation's chords shrink the holes by about 0.013 mm)
    open_ = {n for n, c in res.items() if c.verdict != "pass"}
    diameters = {n for n, c in res.items() if c.type == "hole" and "diameter" in c.upper}
    assert open_ <= {"GT14_profile"} | diameters, open_
    assert len(open_) <= 6, open_


@pytest.mark.slow
def test_ftc08_hole_moved_0p3_mm_fails_exactly_its_position(ftc08):
    """Hole face 70 moved 0.3 mm.  GT20 (1.27) over GT21 (0.508) is a composite frame (the
    file's GEOMETRIC_TOLERANCE_RELATIONSHIP; it matched once the file's inch was read right):
    located, the hole reads twice the offset, about 0.6 mm; GT21, the lower segment over this
    one hole, floats its zone framework to the best place, where the moved axis fits: it reads
    only the hole's tilt (the noise's, within its U: a 3.4 mm hole of ~25 points), and GT20
    passes.  The hole is also datum K of the profile GT17
    (D|K(M)|L(M)): its frame moves with the hole, and a hole of its nominal size has no
    departure from its MMB size to shift it back (:mod:`shapeverify.characteristics.
    datum_shift`), so GT17 fails; nothing else fails."""
    h = ftc08["feats"][70]
    e = np.cross(h.axis, [1.0, 0.0, 0.0])
    e /= np.linalg.norm(e)
    P = ftc08["P"].copy()
    P[ftc08["face"] == 70] += 0.3 * e
    res = _run(ftc08, P)
    assert _fails(res) == {"GT17_profile"}
    r = res["GT21_position"]
    assert r.details["composite"]["segment"] == "lower"
    assert r.details["composite"]["located"] == pytest.approx(0.6, abs=0.1)
    assert 0.0 < r.measured <= r.uncertainty and r.verdict == "pass"
    assert res["GT20_position"].verdict == "pass"


@pytest.mark.slow
def test_ftc08_face_tilted_0p2_degrees_fails_its_parallelism(ftc08):
    from shapeverify.characteristics.drf import rigid_exp

    f4 = ftc08["feats"][4]
    sel = ftc08["face"] == 4
    P = ftc08["P"].copy()
    u = np.linalg.svd(np.eye(3) - np.outer(f4.axis, f4.axis))[0][:, 0]
    c = P[sel].mean(axis=0)
    R = rigid_exp(np.r_[np.radians(0.2) * u, 0.0, 0.0, 0.0])[:3, :3]
    P[sel] = (P[sel] - c) @ R.T + c
    res = _run(ftc08, P)
    fails = _fails(res)
    assert {"GT7_parallelism", "GT8_parallelism"} <= fails
    on_face_4 = {n for n, c in res.items() if 4 in (c.details.get("faces") or [])}
    assert fails <= on_face_4, fails - on_face_4
