"""Issue 31 item 2 (the library's part): one name per concept.

``max_distance`` meant the search structure's reach in ``Prepared``, the inspection's evaluation
distance in ``Deviations``/``decide`` and in the plan YAML; ``tolerance`` meant a relative
convergence threshold in alignment and fitting; ``spacing`` was the model's in ``Prepared`` and
the scan's in ``InspectionResult``; ``rng=None`` was seed 0 in ``register`` and fresh randomness
in ``simulate``.  The old names keep working once, with a DeprecationWarning; our own code does
not use them (these tests turn DeprecationWarning into an error around our calls).
"""

from __future__ import annotations

import json
import logging
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

import shapeverify as sv
from shapeverify.cad.examples import wavy_panel


@pytest.fixture(scope="module")
def prep():
    return sv.prepare(wavy_panel(), spacing=4.0)


@pytest.fixture(scope="module")
def scan(prep):
    from shapeverify.simulate import virtual_scan

    return virtual_scan(prep, pixel=4.0, noise=0.02, rng=3).scan


def _strict():
    """A context in which any DeprecationWarning (our own code using an old name) is an error."""
    cm = warnings.catch_warnings()
    cm.__enter__()
    warnings.simplefilter("error", DeprecationWarning)
    return cm


# ----------------------------------------------------------------------------------- plan key
def test_plan_key_max_distance_still_read_and_warns(caplog):
    from shapeverify.characteristics.plan import PlanError, load_plan, parse_plan

    text = "units: mm\nalignment: {type: best_fit}\nmax_distance: 2.5\ncharacteristics: []\n"
    with caplog.at_level(logging.WARNING, logger="shapeverify.characteristics.plan"):
        with pytest.warns(DeprecationWarning, match="'max_distance' is now called "
                                                    "'evaluation_distance'"):
            old = parse_plan(text, source="plan.yaml")
    # the load log names the file and the line of the old key
    assert any("plan.yaml, line 3" in r.getMessage() and "evaluation_distance" in r.getMessage()
               for r in caplog.records)
    cm = _strict()
    try:
        new = parse_plan(text.replace("max_distance", "evaluation_distance"), "plan.yaml")
    finally:
        cm.__exit__(None, None, None)
    assert old.evaluation_distance == new.evaluation_distance == 2.5
    assert old.model_dump() == new.model_dump()
    assert "max_distance" not in new.model_dump()
    with pytest.warns(DeprecationWarning):
        assert load_plan({"max_distance": 1.5}).evaluation_distance == 1.5
    with pytest.raises(PlanError, match="line 3: give 'evaluation_distance' only"):
        parse_plan(text + "evaluation_distance: 1.0\n", "plan.yaml")


# ------------------------------------------------------------------------------------- reach
def test_prepared_reach_is_max_distance(prep, tmp_path):
    from shapeverify.nearest.prepared import default_max_distance, default_reach

    with pytest.warns(DeprecationWarning, match="Prepared.reach"):
        old = prep.max_distance
    assert old == prep.reach == default_reach(prep.model.size, prep.model_spacing)
    with pytest.raises(AttributeError):
        prep.max_distance = 1.0                                   # read-only
    with pytest.warns(DeprecationWarning, match="default_reach"):
        assert default_max_distance(360.0, 0.35) == default_reach(360.0, 0.35) == 5.25
    with pytest.warns(DeprecationWarning, match=r"prepare\(max_distance=\) is now called reach="):
        p2 = sv.prepare(wavy_panel(), spacing=4.0, max_distance=9.0)
    assert p2.reach == 9.0
    with pytest.raises(TypeError, match="give reach= only"):
        sv.prepare(wavy_panel(), spacing=4.0, max_distance=9.0, reach=9.0)
    # the protocol names reach; ExactSearch passes it on
    from shapeverify.nearest.protocol import PROTOCOL_ATTRIBUTES, ExactSearch

    assert "reach" in PROTOCOL_ATTRIBUTES and "max_distance" not in PROTOCOL_ATTRIBUTES
    assert ExactSearch(prep).reach == prep.reach


def test_svm_file_of_before_the_rename_still_loads(prep, tmp_path):
    """A .svm whose header names the reach only ``max_distance`` (files written before issue
    31) loads with that reach; a new file carries ``reach`` (and ``max_distance`` for old
    readers)."""
    path = tmp_path / "p.svm"
    prep.save(path)
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(bytes(arrays["meta"]).decode())
    assert meta["reach"] == meta["max_distance"] == prep.reach
    del meta["reach"]
    meta["max_distance"] = 7.25
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    old = tmp_path / "old.svm"
    with open(old, "wb") as fh:
        np.savez(fh, **arrays)
    cm = _strict()
    try:
        back = sv.load_prepared(old)
    finally:
        cm.__exit__(None, None, None)
    assert back.reach == 7.25 and back.model_spacing == prep.model_spacing


# --------------------------------------------------------------------- evaluation distance
def test_deviations_max_distance_is_a_deprecated_read_only_property(prep, scan):
    cm = _strict()
    try:
        dev = sv.deviations(scan, prep, None, evaluation_distance=1.25)
    finally:
        cm.__exit__(None, None, None)
    with pytest.warns(DeprecationWarning, match="Deviations.evaluation_distance"):
        assert dev.max_distance == 1.25
    with pytest.raises(AttributeError):
        dev.max_distance = 2.0
    with pytest.warns(DeprecationWarning):
        old = sv.deviations(scan, prep, None, max_distance=1.25)
    np.testing.assert_array_equal(old.values, dev.values)
    assert old.evaluation_distance == 1.25


def test_decide_reads_evaluation_distance_not_max_distance():
    """``decide`` reads ``deviations.evaluation_distance``: a deviations object without the old
    name works, and the reason quotes the value."""
    from shapeverify.inspection.verdict import Verdict, decide

    reg = SimpleNamespace(converged=True, inlier_fraction=1.0, iterations=5, message="",
                          scale=0.02)
    dev = SimpleNamespace(n=100, n_evaluated=0, evaluation_distance=3.75, n_too_far=100,
                          n_on_boundary=0)
    verdict, reasons, rule = decide(reg, dev, [], None)
    assert (verdict, rule) == (Verdict.ERROR, "no_data")
    assert "within 3.75 mm (the evaluation distance)" in reasons[0]


def test_inspection_uses_no_old_name_itself(prep, scan):
    """A whole inspection (registration, deviations, verdict, JSON) hits no deprecated alias."""
    cm = _strict()
    try:
        res = sv.inspect(prep, scan, tolerance=0.2, evaluation_distance=1.5)
        d = res.to_dict()
    finally:
        cm.__exit__(None, None, None)
    assert res.evaluation_distance == res.deviations.evaluation_distance == 1.5
    assert d["evaluation_distance"] == 1.5
    # scan_spacing: the scan's, measured on the evaluated feet; spacing is its older name
    from shapeverify.inspection.regions import surface_spacing

    feet = res.deviations.foot_points[res.deviations.evaluated]
    assert res.scan_spacing == res.spacing == surface_spacing(feet)
    assert d["scan_spacing"] == d["spacing"] == pytest.approx(res.scan_spacing)
    assert 0.5 * 4.0 < res.scan_spacing < 2.0 * 4.0       # a 4 mm pixel, not the model's
    assert prep.model_spacing == prep.spacing == 4.0


def test_html_report_reads_a_record_with_only_the_old_spacing_key(prep, scan):
    """Records stored before ``scan_spacing`` existed carry only ``spacing``: the HTML report
    (also the service's redraw of a stored record) shows the same spacing row."""
    from shapeverify.report.html import render_html

    res = sv.inspect(prep, scan, tolerance=0.2)

    class Old:                     # a stored record of before: its summary has no scan_spacing
        def __getattr__(self, k):
            return getattr(res, k)

        def to_dict(self, per_face=True):
            d = res.to_dict(per_face)
            del d["scan_spacing"]
            return d

    def row(text):
        i = text.index("point spacing [mm]")
        return text[i:text.index("</tr>", i)]

    new_row, old_row = row(render_html(res, prep.model)), row(render_html(Old(), prep.model))
    assert new_row == old_row and f"{res.scan_spacing:.2f}"[:3] in new_row


# ------------------------------------------------------------------------------------ rtol
@pytest.mark.parametrize("name", ["fit_line", "fit_plane", "fit_sphere", "fit_circle",
                                  "fit_cylinder"])
def test_fitting_tolerance_is_now_rtol(name):
    from shapeverify import fitting
    from shapeverify._warmup_commands import element_points

    fn = getattr(fitting, name)
    x = element_points(name[4:], n=200, rng=4)
    cm = _strict()
    try:
        new = fn(x, rtol=1e-9)
    finally:
        cm.__exit__(None, None, None)
    with pytest.warns(DeprecationWarning, match=rf"{name}\(tolerance=\) is now called rtol="):
        old = fn(x, tolerance=1e-9)
    assert repr(old) == repr(new)
    with pytest.raises(TypeError, match="give rtol= only"):
        fn(x, rtol=1e-9, tolerance=1e-9)


@pytest.mark.parametrize("name", ["best_fit", "constrained_fit", "rps_alignment"])
def test_alignment_tolerance_is_now_rtol(name):
    import inspect

    from shapeverify.characteristics import alignment

    fn = getattr(alignment, name)
    params = inspect.signature(fn).parameters
    assert "rtol" in params and "tolerance" not in params
    with pytest.raises(TypeError, match="give rtol= only"):
        fn(None, None, rtol=0.1, tolerance=0.1)


# ------------------------------------------------------------------------------------- rng
def test_rng_none_means_the_same_everywhere(prep):
    """``rng=None`` is the fixed seed 0 in registration, sampling and the simulated scanner
    alike (it was fresh randomness in ``simulate``)."""
    from shapeverify.simulate import random_motion, virtual_scan

    a = virtual_scan(prep, pixel=4.0, noise=0.02, motion=(1.0, 2.0), rng=None)
    b = virtual_scan(prep, pixel=4.0, noise=0.02, motion=(1.0, 2.0), rng=None)
    c = virtual_scan(prep, pixel=4.0, noise=0.02, motion=(1.0, 2.0), rng=0)
    np.testing.assert_array_equal(a.scan, b.scan)
    np.testing.assert_array_equal(a.scan, c.scan)
    np.testing.assert_array_equal(random_motion(2.0, 1.0), random_motion(2.0, 1.0, rng=0))
    fresh = virtual_scan(prep, pixel=4.0, noise=0.02, motion=(1.0, 2.0),
                         rng=np.random.default_rng())
    assert fresh.scan.shape != a.scan.shape or not np.array_equal(fresh.scan, a.scan)
    r0 = sv.register(a.scan, prep, rng=0)
    rn = sv.register(a.scan, prep, rng=None)
    np.testing.assert_array_equal(r0.T_model_scan, rn.T_model_scan)
