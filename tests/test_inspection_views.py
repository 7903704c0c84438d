"""Several views of one part (issue 30 item 2): each view placed from no start, the union
inspected, a view that fits nowhere named and left out, disagreeing views named."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import shapeverify as sv
from shapeverify.cad.examples import wavy_panel


@pytest.fixture(scope="module")
def prep():
    return sv.prepare(wavy_panel(), spacing=1.0)


def _random_pose(rng):
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rng.normal(size=3) * 0.8).as_matrix()
    T[:3, 3] = rng.normal(size=3) * 40
    return T


def _views(prep, rng, dent=None, n_views=3, noise=0.02):
    """Overlapping bands across the part's longest axis, each moved into its own sensor frame,
    noise along the normal; returns the views and their true T_model_scan."""
    near = prep.closest(prep.points.points)
    pts, nrm = near.points, near.normals
    if dent is not None:           # (centre, radius, depth): a smooth dent into the material
        c, r, depth = dent
        d = np.linalg.norm(pts - c, axis=1)
        pts = pts - nrm * (depth * 0.5 * (1 + np.cos(np.pi * np.minimum(d / r, 1.0))))[:, None]
    axis = int(np.argmax(np.ptp(pts, axis=0)))
    lo, hi = pts[:, axis].min(), pts[:, axis].max()
    edges = np.linspace(lo, hi, n_views + 1)
    pad = 0.12 * (hi - lo)
    covers = np.stack([(pts[:, axis] >= edges[k] - pad) & (pts[:, axis] <= edges[k + 1] + pad)
                       for k in range(n_views)])
    # each surface point is measured by one of the views that see it (drawn at random), so the
    # overlaps are sampled as densely as the rest, by both views, with no repeated points
    owner = np.array([rng.choice(np.flatnonzero(c)) for c in covers.T])
    views, truths = [], []
    for k in range(n_views):
        m = owner == k
        p = pts[m] + nrm[m] * rng.normal(scale=noise, size=(m.sum(), 1))
        T_scan_model = _random_pose(rng)
        views.append(p @ T_scan_model[:3, :3].T + T_scan_model[:3, 3])
        truths.append(np.linalg.inv(T_scan_model))
    return views, truths


def test_views_from_no_start_merge_to_one_covered_passing_part(prep):
    views, truths = _views(prep, np.random.default_rng(1))
    res = sv.inspect(prep, views, tolerance=0.2, min_coverage=0.9)
    assert str(res.verdict) == "pass", res.reasons
    assert res.coverage.fraction >= 0.9
    assert [v.used for v in res.views] == [True, True, True]
    for v, T in zip(res.views, truths):
        dR = Rotation.from_matrix(v.T_model_scan[:3, :3] @ T[:3, :3].T).magnitude()
        assert np.degrees(dR) < 0.05 and np.linalg.norm(v.T_model_scan[:3, 3] - T[:3, 3]) < 0.1
        assert v.verdict == "incomplete" and v.coverage < 0.9     # each alone is not enough
        assert all(d < 0.05 for d in v.disagreement.values()) and v.disagreement
    d = res.to_dict()
    assert len(d["views"]) == 3 and d["views"][0]["coverage"] < d["coverage"]["fraction"]


def test_a_dent_seen_in_one_view_fails_the_merged_part(prep):
    c = prep.points.points[len(prep.points.points) // 2]
    views, _ = _views(prep, np.random.default_rng(2), dent=(c, 12.0, 0.6))
    res = sv.inspect(prep, views, tolerance=0.2, min_coverage=0.9)
    assert str(res.verdict) == "fail" and res.rule == "regions", res.reasons
    worst = res.regions[0]
    assert worst.kind == "deviation" and -0.7 < worst.extreme < -0.45
    assert np.linalg.norm(np.asarray(worst.centroid) - c) < 6.0


def test_a_view_that_fits_nowhere_is_named_and_left_out(prep):
    rng = np.random.default_rng(3)
    views, _ = _views(prep, rng)
    junk = rng.uniform(-500, 500, size=(2000, 3))          # not a view of this part
    res = sv.inspect(prep, views + [junk], tolerance=0.2, min_coverage=0.9)
    assert [v.used for v in res.views] == [True, True, True, False]
    assert any(r.startswith("view view 4 left out") for r in res.reasons), res.reasons
    assert str(res.verdict) == "pass"


def test_views_with_given_poses_and_a_view_moved_off_is_named(prep):
    views, truths = _views(prep, np.random.default_rng(4))
    res = sv.inspect_views(prep, views, tolerance=0.2, poses=truths, min_coverage=0.9) \
        if hasattr(sv, "inspect_views") else sv.inspection.inspect_views(
            prep, views, tolerance=0.2, poses=truths, min_coverage=0.9)
    assert str(res.verdict) == "pass"
    with pytest.raises(ValueError, match="2 poses for 3 views"):
        sv.inspection.inspect_views(prep, views, poses=truths[:2])


@pytest.mark.slow
def test_cli_inspects_several_view_files_and_an_e57_with_several_scans(prep, tmp_path):
    import json

    from typer.testing import CliRunner

    from shapeverify.cli import app
    from shapeverify.io.points import write_ply

    views, truths = _views(prep, np.random.default_rng(5))
    prep.save(tmp_path / "panel.svm")
    files = []
    for i, v in enumerate(views):
        files.append(str(tmp_path / f"view{i + 1}.ply"))
        write_ply(files[-1], v)
    runner = CliRunner()
    res = runner.invoke(app, ["inspect", str(tmp_path / "panel.svm"), *files, "--tolerance",
                              "0.2", "--min-coverage", "0.9", "--json",
                              str(tmp_path / "r.json")])
    assert res.exit_code == 0, res.output
    d = json.loads((tmp_path / "r.json").read_text())
    assert [v["name"] for v in d["views"]] == ["view1.ply", "view2.ply", "view3.ply"]
    assert d["inputs"]["scan"] == "view1.ply, view2.ply, view3.ply"
    assert "Views (mm)" in res.output
    one = runner.invoke(app, ["inspect", str(tmp_path / "panel.svm"), files[0], "--tolerance",
                              "0.2", "--min-coverage", "0.9"])
    assert one.exit_code == 3, one.output          # one view alone: incomplete
    # the same views in one E57 file, each with its pose into a common frame
    pytest.importorskip("pye57", reason="the scanners extra (pye57) is not installed")
    from shapeverify.io.e57 import write_e57
    common = _random_pose(np.random.default_rng(9))     # the scanner software's frame
    write_e57(tmp_path / "views.e57", views, [common @ T for T in truths])
    res = runner.invoke(app, ["inspect", str(tmp_path / "panel.svm"), str(tmp_path / "views.e57"),
                              "--tolerance", "0.2", "--min-coverage", "0.9", "--json",
                              str(tmp_path / "e.json")])
    assert res.exit_code == 0, res.output
    d = json.loads((tmp_path / "e.json").read_text())
    assert len(d["views"]) == 3 and all(v["used"] for v in d["views"])
