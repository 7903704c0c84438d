"""Scan points on a file's supplemental geometry are not the part (issue 28: a perfect part
fails no characteristic).

NIST FTC 10 (bundled, ``tests/data/nist_extra``) holds 18 supplemental faces 1.25-1.69 mm off
its solid.  A scan made from OpenCASCADE's tessellation of the whole file (as an independent
sampler makes it) has points on them; the planned profile GT10 (1.5 mm to A|B|C, faces
177-180) read 2.88 mm on every perfect scan: **fail**.  Those points are now left out
(``excluded: on_supplemental_geometry``); a real bump on the same faces still fails.
"""
from __future__ import annotations


import numpy as np
import pytest

pytestmark = pytest.mark.slow           # FTC 10's import, features and plan (cached per run)

NOISE = 0.02


@pytest.fixture(scope="module")
def ftc10(tmp_path_factory):
    from nist_plans import ftc10_gt10_scan

    return ftc10_gt10_scan(tmp_path_factory.mktemp("ftc10"), NOISE)


def test_the_points_found_on_supplemental_faces_are_those_sampled_there(ftc10):
    from shapeverify.characteristics.supplemental_points import on_supplemental

    prep, X, _, truth, _ = ftc10
    assert set(prep.model.supplemental) == set(range(264, 282)) and truth.sum() > 100
    cl = prep.closest(X, exact=True)
    d = np.asarray(cl.distances, np.float64)
    near = np.isfinite(d) & (np.abs(d) <= 3.0)
    found = on_supplemental(prep.model, X, d, near, float(prep.model_spacing), NOISE)
    # no point of the part is taken (the triangle each point was drawn on says where it is)
    assert not (found & ~truth).any()
    # and the supplemental points within 3 mm of the part, but off it, are found: all of
    # them (140), those on the curved faces too (133 of 140 by the tangent planes of samples)
    want = truth & near & (np.abs(d) >= 0.3)
    assert want.sum() > 100 and found[want].all(), (found[want].sum(), want.sum())


def test_ftc10_gt10_passes_on_a_perfect_scan_of_the_whole_file(ftc10):
    from shapeverify.characteristics import evaluate_plan

    prep, X, _, _, plan = ftc10
    c, = evaluate_plan(prep, X, plan, init=np.eye(4)).characteristics
    assert c.verdict == "pass", (c.measured, c.uncertainty, c.details)
    assert c.details["excluded"]["on_supplemental_geometry"] > 100
    assert c.measured < 0.5


def _bumped(ftc10, face, height):
    """The scan with a bump ``height cos^2(pi r / 6)`` (6 mm across) in the middle of ``face``:
    every scan point within 0.3 mm of the face is pushed along its normal, those sampled on a
    supplemental face lying on it too (as on a real part: one surface)."""
    prep, X, N, truth, plan = ftc10
    cl = prep.closest(X, exact=True)
    on = (np.asarray(cl.face) == face) & (np.abs(np.asarray(cl.distances)) < 0.3)
    mid = X[on].mean(axis=0)
    c0 = X[on][np.argmin(np.linalg.norm(X[on] - mid, axis=1))]
    r = np.linalg.norm(X - c0, axis=1)
    bump = on & (r < 3.0)
    assert bump.sum() >= 15
    Y = X.copy()
    Y[bump] += (height * np.cos(np.pi * r[bump] / 6.0) ** 2)[:, None] * \
        np.asarray(cl.normals)[bump]
    return Y


@pytest.mark.parametrize("face", [177, 178, 179, 180])
def test_ftc10_gt10_still_fails_with_a_bump_on_its_faces(ftc10, face):
    """A 1 mm bump (6 mm across) in the middle of each of GT10's faces is measured whole:
    2 max |d| about 2 mm.  The outlier rule once left out most of a bump this steep at this
    spacing (face 178: 1.21 mm, pass; ``tests/test_steep_small_bump_is_not_an_outlier.py``)."""
    from shapeverify.characteristics import evaluate_plan

    prep, X, N, truth, plan = ftc10
    c, = evaluate_plan(prep, _bumped(ftc10, face, 1.0), plan, init=np.eye(4)).characteristics
    assert c.verdict == "fail", (c.measured, c.details)
    assert c.measured == pytest.approx(2.0, abs=0.12), c.details["excluded"]


def test_a_point_on_a_curved_supplemental_face_is_found_beside_a_1_5_mm_bump(ftc10):
    """A 1.5 mm bump on face 177 read 4.12 mm, not 2 x 1.5: one scan point sampled on a curved
    supplemental face 2.06 mm off the part was not found (the tangent plane of the nearest
    sample of those faces is off by up to spacing^2 x curvature / 8 there), and the outlier
    rescue kept it, within the bump's range.  The exact distance to the supplemental faces
    finds it."""
    from shapeverify.characteristics import evaluate_plan

    prep, X, N, truth, plan = ftc10
    c, = evaluate_plan(prep, _bumped(ftc10, 177, 1.5), plan, init=np.eye(4)).characteristics
    assert c.verdict == "fail", (c.measured, c.details)
    assert 2.7 <= c.measured <= 3.3, (c.measured, c.uncertainty, c.details["excluded"])
