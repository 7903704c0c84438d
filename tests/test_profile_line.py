"""Profile of a line (issue 28 item 3, ASME Y14.5 §11): the line elements of a surface in
sections parallel to a plane, each within a 2-D zone; the value is the largest over the
sections of 2 max |d| of the points within a slab about each section plane."""
from __future__ import annotations

import numpy as np
import pytest

import shapeverify as sv
from shapeverify.characteristics.profile_line import section_offsets, sections_profile


def _brute(X, d, n, offsets, slab, min_points=3):
    """Point by point: each section's largest |d| over the points within slab of its plane."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    best = []
    for o in offsets:
        big, cnt = 0.0, 0
        for p, e in zip(X, d):
            if abs(float(p[0] * n[0] + p[1] * n[1] + p[2] * n[2]) - o) <= slab:
                cnt += 1
                big = max(big, abs(float(e)))
        best.append(2.0 * big if cnt >= min_points else None)
    return best


def test_sections_profile_is_the_point_by_point_largest_section_zone():
    rng = np.random.default_rng(0)
    X = rng.uniform(-50, 50, (3000, 3))
    d = rng.normal(0, 0.05, 3000)
    n = np.array([1.0, 2.0, -0.5])
    offsets = [-40.0, -3.3, 0.0, 17.0, 49.0, 120.0]          # the last: no point
    value, at, per = sections_profile(X, d, n, offsets, 0.7)
    want = _brute(X, d, n, offsets, 0.7)
    for p, w in zip(per, want):
        assert (p["value"] is None) == (w is None)
        assert w is None or abs(p["value"] - w) < 1e-12
    vals = [w for w in want if w is not None]
    assert value == pytest.approx(max(vals), abs=1e-12)
    assert per[at]["value"] == value and per[-1]["value"] is None and per[-1]["n"] == 0


def test_section_offsets_span_the_extent_inset_by_the_slab():
    s = np.array([2.0, 10.0, 7.0])
    assert section_offsets(s, 5, 0.5) == pytest.approx([2.5, 4.25, 6.0, 7.75, 9.5])
    assert section_offsets(s, 1, 0.5) == pytest.approx([6.0])


@pytest.fixture(scope="module")
def bracket_scan():
    from shapeverify.characteristics.parts import bracket

    prep = sv.prepare(bracket(), spacing=1.0)
    pts = prep.model.sample(0.7, rng=np.random.default_rng(2))
    P, N, F = np.asarray(pts.points), np.asarray(pts.normals), np.asarray(pts.face)
    return prep, P, N, F


def _dented(P, N, F, centre, depth, radius):
    """A dent of ``depth`` (cos^2 profile, ``radius``) into face 0 (the base plate, z = 0)."""
    r = np.linalg.norm(P[:, :2] - np.asarray(centre)[None, :], axis=1)
    h = np.where((F == 0) & (r < radius), depth * np.cos(np.pi * r / (2 * radius)) ** 2, 0.0)
    return P - h[:, None] * N, h


def _plan(tol, sections, datums=None):
    c = {"name": "LP", "type": "line_profile", "faces": ["face:0"], "tol": tol,
         "normal": [1.0, 0.0, 0.0], "sections": sections, "slab": 0.5}
    plan = {"alignment": {"type": "best_fit"}, "characteristics": [c]}
    if datums:
        c["datums"] = datums
        plan["datums"] = {"A": {"faces": ["face:0"]}, "B": {"faces": ["face:1"]},
                          "C": {"faces": ["face:2"]}}
    return plan


@pytest.mark.slow
def test_line_profile_through_a_dent_fails_and_equals_the_brute_force_zone(bracket_scan):
    from shapeverify.characteristics import evaluate_plan

    prep, P, N, F = bracket_scan
    X, h = _dented(P, N, F, (50.0, 60.0), 0.3, 6.0)
    X = X + np.random.default_rng(4).normal(0, 0.005, len(X))[:, None] * N
    res = evaluate_plan(prep, X, _plan(0.2, [20.0, 50.0]))
    lp = res["LP"]
    per = lp.details["sections"]
    # section x = 50 crosses the dent: its zone is 2 x the dent's depth there (the best fit
    # moves the plate by a little); x = 20 is clear of it
    assert per[1]["value"] == pytest.approx(2 * h[np.abs(X[:, 0] - 50) <= 0.5].max(), abs=0.03)
    assert per[0]["value"] < 0.05
    assert lp.measured == per[1]["value"] and lp.verdict == "fail"
    # brute force on the plan's own aligned points and deviations: the kept points of face 0
    # in the slab, away from its edges (the plate's rim x, y in [0, 100] x [0, 80], the walls)
    d, Q, ok = res.deviations, res.points, res.evaluated & (res.face == 0)
    far = ok & (Q[:, 0] > 1.0) & (Q[:, 1] > 1.0) & (Q[:, 1] < 79.0)
    for p in per:
        m = far & (np.abs(Q[:, 0] - p["offset"]) <= 0.5)
        assert p["value"] == pytest.approx(2 * np.abs(d[m]).max(), abs=1e-9)
    # the same dent is a pass for a section clear of it
    ok_res = evaluate_plan(prep, X, _plan(0.2, [20.0]))
    assert ok_res["LP"].verdict == "pass"


@pytest.mark.slow
def test_line_profile_in_a_datum_frame_of_a_perfect_part_passes(bracket_scan):
    from shapeverify.characteristics import evaluate_plan

    prep, P, N, F = bracket_scan
    rng = np.random.default_rng(5)
    X = P + rng.normal(0, 0.005, len(P))[:, None] * N
    res = evaluate_plan(prep, X, _plan(0.2, None, ["A", "B", "C"]))
    lp = res["LP"]
    assert lp.verdict == "pass", lp
    assert len(lp.details["sections"]) == 10 and lp.details["skipped_sections"] == 0
    assert lp.measured < 0.1 and lp.details["drf"]
