"""`sv.inspect(prep, scan, plan=...)` and `shapeverify inspect --plan --pdf` (issue 17): the plan's
characteristics join the verdict, the JSON carries them in the documented form."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import shapeverify as sv
from shapeverify.cad.examples import PANEL_HOLE, example_part_step
from shapeverify.simulate import ScanEffects, virtual_scan

pytestmark = pytest.mark.slow

X, Y, R = PANEL_HOLE
PLAN = f"""units: mm
alignment: {{type: best_fit}}
characteristics:
  - {{name: H1, type: hole, near: [{X}, {Y}, 0], diameter: {{tol: 0.5}}, position: {{tol: 0.6}}}}
  - {{name: SKIN, type: surface_profile, faces: all, tol: 0.4}}
"""


@pytest.fixture(scope="module")
def panel(tmp_path_factory):
    d = tmp_path_factory.mktemp("plan")
    prep = sv.prepare(sv.load_model(example_part_step(d / "panel.step")), spacing=1.0)
    prep.save(d / "panel.svm")
    (d / "plan.yaml").write_text(PLAN)
    return prep, d


def test_plan_characteristics_in_the_result_and_json(panel):
    prep, d = panel
    scan = virtual_scan(prep, pixel=1.0, noise=0.02,
                        effects=ScanEffects(outlier_fraction=0.02), motion=(1.0, 2.0), rng=4)
    res = sv.inspect(prep, scan.scan, tolerance=0.2, plan=d / "plan.yaml")
    names = [c.name for c in res.characteristics]
    assert names == ["H1", "SKIN"]
    js = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    h1 = next(c for c in js["characteristics"] if c["name"] == "H1")
    assert {"name", "type", "nominal", "measured", "deviation", "uncertainty", "verdict"} <= set(h1)
    assert np.allclose(h1["nominal"]["center"][:2], [X, Y], atol=1e-6)
    assert abs(h1["measured"]["diameter"] - 2 * R) < 0.2
    assert np.linalg.norm(np.subtract(h1["measured"]["center"][:2], [X, Y])) < 0.1
    skin = next(c for c in js["characteristics"] if c["name"] == "SKIN")
    # isolated outliers do not decide the profile: twice the largest inlier deviation
    assert skin["measured"] < 0.2 and skin["verdict"] == "pass"
    assert js["alignment"]["type"] == "best_fit"
    assert res.verdict == "pass", res.reasons


def test_failing_characteristic_fails_the_part(panel):
    prep, d = panel
    scan = virtual_scan(prep, pixel=1.0, noise=0.02,
                        effects=ScanEffects(dents=[(0.3, 12.0)]), motion=(1.0, 2.0), rng=5)
    res = sv.inspect(prep, scan.scan, tolerance=0.35, plan=PLAN.replace("tol: 0.4", "tol: 0.3"))
    assert res.verdict == "fail" and res.rule == "characteristics"
    assert "SKIN" in res.reasons[0]


def test_cli_plan_and_pdf(panel, tmp_path):
    from shapeverify.io.points import write_ply

    prep, d = panel
    scan = virtual_scan(prep, pixel=1.0, noise=0.02, motion=(1.0, 2.0), rng=6)
    write_ply(tmp_path / "scan.ply", scan.scan)
    out = subprocess.run([sys.executable, "-m", "shapeverify.cli", "inspect", str(d / "panel.svm"),
                          str(tmp_path / "scan.ply"), "--tolerance", "0.2", "--plan",
                          str(d / "plan.yaml"), "--pdf", str(tmp_path / "r.pdf"), "--report",
                          str(tmp_path / "r.html"), "--json",
                          str(tmp_path / "r.json"), "--part", "P-1"],
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "Characteristics" in out.stdout and "H1" in out.stdout
    assert (tmp_path / "r.pdf").read_bytes()[:5] == b"%PDF-"
    page = (tmp_path / "r.html").read_text()
    assert "Characteristics (mm)" in page and ">H1<" in page and "ISO 14253-1" in page
    js = json.loads((tmp_path / "r.json").read_text())
    assert [c["name"] for c in js["characteristics"]] == ["H1", "SKIN"]


def test_pdf_without_a_plan_draws_the_inspections_own_pose_and_deviations(panel, tmp_path,
                                                                          monkeypatch):
    """No plan: the PDF shows the inspection's registration, deviations and verdict; nothing
    aligns the scan again (the best fits are made to fail if called)."""
    import shutil

    from shapeverify.characteristics import alignment as al
    from shapeverify.characteristics.pdf import ReportLabels, write_pdf_report
    from shapeverify.inspection.plan_link import plan_result_of

    prep, _ = panel
    scan = virtual_scan(prep, pixel=1.0, noise=0.02,
                        effects=ScanEffects(dents=[(0.3, 12.0)]), motion=(1.0, 2.0),
                        rng=7)
    res = sv.inspect(prep, scan.scan, tolerance=0.2)

    def no_realignment(*a, **k):
        raise AssertionError("the scan was aligned again")

    monkeypatch.setattr(al, "_gauss_newton", no_realignment)
    pr = plan_result_of(res)
    assert np.array_equal(pr.alignment.T_model_scan, res.registration.T_model_scan)
    assert np.array_equal(pr.alignment.covariance, res.registration.covariance)
    dev = res.deviations
    assert np.array_equal(pr.evaluated, dev.evaluated)
    assert np.array_equal(pr.deviations[dev.evaluated], dev.values[dev.evaluated])
    assert np.isnan(pr.deviations[~dev.evaluated]).all()
    assert pr.verdict == res.verdict == "fail" and pr.characteristics == ()
    # evaluate_plan without a plan takes the registration as its (free best fit) alignment
    from shapeverify.characteristics import evaluate_plan

    ev = evaluate_plan(prep, scan.scan, None, registration=res.registration)
    assert np.array_equal(ev.alignment.T_model_scan, res.registration.T_model_scan)
    both = ev.evaluated & dev.evaluated
    assert both.sum() > 0.95 * dev.evaluated.sum()
    np.testing.assert_allclose(ev.deviations[both], dev.values[both], atol=1e-9)
    out = write_pdf_report(pr, tmp_path / "free.pdf", prep, tolerance=0.2,
                           labels=ReportLabels(part="P-2", scan_file="scan.ply", date="2026-12-01"))
    assert out.read_bytes()[:5] == b"%PDF-"
    if shutil.which("pdftoppm"):
        subprocess.run(["pdftoppm", "-png", "-r", "40", str(out), str(tmp_path / "page")],
                       check=True, timeout=60)
        pages = sorted(tmp_path.glob("page*.png"))
        assert len(pages) == 2
        from PIL import Image
        img = np.asarray(Image.open(pages[0]).convert("L"))
        assert img.shape[0] > img.shape[1] and img.std() > 5     # portrait, not blank


def test_characteristic_whose_evaluation_raises_is_not_measured_and_the_part_not_passed(
        panel, monkeypatch):
    """An evaluator that raised anything but ValueError (an IndexError on a part's geometry
    the suite never met) stopped the whole inspection: no verdict, no other characteristic.
    It is now that characteristic's 'not measured' reason; the others stand, and the part,
    with a characteristic not measured, does not pass."""
    from shapeverify.characteristics import registry

    prep, d = panel
    scan = virtual_scan(prep, pixel=1.0, noise=0.02, motion=(1.0, 2.0), rng=4)
    good = sv.inspect(prep, scan.scan, tolerance=0.2, plan=d / "plan.yaml")
    assert good.verdict == "pass", good.reasons

    def broken(c, ctx):
        raise IndexError("index 7 is out of bounds for axis 0 with size 7")

    monkeypatch.setitem(registry._EVALUATORS, "hole", broken)
    res = sv.inspect(prep, scan.scan, tolerance=0.2, plan=d / "plan.yaml")
    h1, skin = res.characteristics
    assert h1.verdict == "undecided" and h1.measured is None
    assert "IndexError: index 7 is out of bounds" in h1.details["reason"]
    g_skin = good.characteristics[1]
    assert (skin.measured, skin.verdict) == (g_skin.measured, g_skin.verdict)
    assert res.verdict != "pass", res.reasons
