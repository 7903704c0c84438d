"""PMI attached to edges on NIST CTC 02 (issue 28): the position (GT22), perpendicularity (GT4)
and diameters (DIM1, DIM2) of holes and the datums E, F point at a hole's rim circle; the
profile of a line GT18 at a line drawn on face 0.  Each becomes a plan entry on the feature the
edge bounds, marked ``pmi.attached``; checked against the edges' own geometry read
independently here with OCP."""
from __future__ import annotations

import numpy as np
import pytest

NAME = "nist_ctc_02_asme1_ap242-e1.stp"
pytestmark = [pytest.mark.slow, pytest.mark.shared]


@pytest.fixture(scope="module")
def ctc02(shared_data):
    from model_cache import cached_model, cached_pmi

    from shapeverify.characteristics.features import model_features
    from shapeverify.characteristics.pmi_plan import pmi_plan

    path = shared_data / "cad" / "nist" / NAME
    # load_model and read_pmi, once per suite run for every NIST module (tests/model_cache.py)
    model = cached_model(path, features=True)
    pmi = cached_pmi(path)
    r = pmi_plan(path, model=model, pmi=pmi)
    m = getattr(model, "model", model)
    return dict(path=path, model=model, pmi=pmi, plan=r, feats=model_features(m))


def _entries(r, pmi_id):
    return [c for c in r.data["characteristics"] if c["pmi"]["id"] == pmi_id]


@pytest.mark.parametrize("pmi_id", ["GT4", "GT22", "DIM1", "DIM2"])
def test_edge_attached_item_becomes_an_entry_on_the_cylinder_its_rim_circle_bounds(ctc02,
                                                                                 pmi_id):
    item = next(it for it in ctc02["pmi"]["tolerances"] + ctc02["pmi"]["dimensions"]
                if it["id"] == pmi_id)
    (rec,) = item["edges"]
    assert rec["curve"] == "Circle"
    (entry,) = _entries(ctc02["plan"], pmi_id)
    assert entry["pmi"]["attached"].startswith("circular edge")
    # the entry's faces: the model's cylinder(s) whose axis passes through the circle's
    # centre along its axis, with its radius
    refs = (entry.get("faces") or [f for g in entry.get("features", []) for f in g]
            or [entry["feature"]])
    feats = ctc02["feats"]
    c, a, r = np.array(rec["centre"]), np.array(rec["axis"]), rec["radius"]
    for ref in refs:
        kind, k = ref.split(":")
        f = feats[int(k)] if kind == "face" else next(x for x in feats if x.id == ref)
        assert f.diameter == pytest.approx(2 * r, rel=1e-6)
        assert np.linalg.norm(np.cross(f.axis, a)) < 1e-6
        q = c - f.center
        assert np.linalg.norm(q - (q @ f.axis) * f.axis) < 1e-6


def test_datums_e_and_f_on_rim_circles_are_the_hole_axes(ctc02):
    datums = {d["name"]: d for d in ctc02["pmi"]["datums"]}
    for name in "EF":
        assert datums[name]["attached"].startswith("circular edge")
        assert len(datums[name]["faces"]) == 1
    table = ctc02["plan"].data["datums"]
    assert table["E"]["kind"] == "axis"


def test_profile_of_a_line_drawn_on_face_0_sections_across_the_line(ctc02):
    from shapeverify.characteristics.pmi_plan import pmi_plan

    item = next(it for it in ctc02["pmi"]["tolerances"] if it["id"] == "GT18")
    (rec,) = item["edges"]
    assert rec["curve"] == "Line" and rec["faces"] == [] and rec["on_faces"] == [0]
    # its datums A|B|C are set up from datum targets: the plan's entry is on face 0, with them
    (with_drf,) = _entries(ctc02["plan"], "GT18")
    assert with_drf["type"] == "line_profile" and with_drf["faces"] == ["face:0"]
    assert with_drf.get("datums") == ["A", "B", "C"]
    # without the datums, the same entry: sections parallel to the plane of the line
    pmi = dict(ctc02["pmi"])
    pmi["tolerances"] = [{**it, "datums": []} if it["id"] == "GT18" else it
                         for it in pmi["tolerances"]]
    r = pmi_plan(ctc02["path"], model=ctc02["model"], pmi=pmi)
    (e,) = _entries(r, "GT18")
    assert e["type"] == "line_profile" and e["faces"] == ["face:0"] and e["tol"] == 0.25
    n = np.array(e["normal"])
    P = np.array(rec["points"])
    assert np.abs((P - P[0]) @ n).max() < 1e-9          # the line lies in a section plane
    assert abs(n[0]) == pytest.approx(1.0, abs=1e-6)    # the drawn line is at x = 180
