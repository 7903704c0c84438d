"""Plans from the semantic PMI of STEP AP242 files (``shapeverify plan``, ``plan_from_pmi``).

On the NIST MBE PMI test models (``../shared/data/cad/nist/*_ap242-e1.stp``) the plan is checked
against an independent reading of the file's PMI with OpenCASCADE's XCAF (a different walk of
the document: the children of the GD&T tool's base label, ``IsGeomTolerance``/``IsDatum``/
``IsDimension``), run in a child process.
"""
from __future__ import annotations

import functools
import json
import os
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
import yaml

from shapeverify.characteristics import load_plan
from shapeverify.characteristics.plan import PlanError

NIST = ["nist_ctc_01_asme1_ap242-e1.stp", "nist_ctc_02_asme1_ap242-e1.stp",
        "nist_ftc_06_asme1_ap242-e1.stp", "nist_ftc_08_asme1_ap242-e1.stp"]

SRC = str(Path(__file__).resolve().parents[1] / "src")

# the independent reader: XCAF document, GD&T on; every child label of the DimTol tool's base
# label that the tool calls a tolerance / datum / dimension; the type from the attribute's object
_READER = r"""
import json, sys
from OCP.Interface import Interface_Static
from OCP.STEPCAFControl import STEPCAFControl_Controller, STEPCAFControl_Reader
from OCP.TCollection import TCollection_ExtendedString
from OCP.TDF import TDF_AttributeIterator, TDF_ChildIterator
from OCP.TDocStd import TDocStd_Document
from OCP.XCAFDoc import XCAFDoc_Datum, XCAFDoc_DocumentTool, XCAFDoc_GeomTolerance
STEPCAFControl_Controller.Init_s()
Interface_Static.SetCVal_s("xstep.cascade.unit", "MM")
r = STEPCAFControl_Reader()
r.SetGDTMode(True)
assert r.ReadFile(sys.argv[1]).name == "IFSelect_RetDone"
doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
assert r.Transfer(doc)
tool = XCAFDoc_DocumentTool.DimTolTool_s(doc.Main())
tols, datums, dims = [], set(), 0
it = TDF_ChildIterator(tool.BaseLabel(), False)
while it.More():
    lab = it.Value(); it.Next()
    ai = TDF_AttributeIterator(lab)
    while ai.More():
        a = ai.Value(); ai.Next()
        if isinstance(a, XCAFDoc_GeomTolerance) and tool.IsGeomTolerance(lab):
            tols.append(a.GetObject().GetType().name.split("GeomToleranceType_")[1])
        elif isinstance(a, XCAFDoc_Datum) and tool.IsDatum(lab):
            datums.add(a.GetObject().GetName().ToCString())
    if tool.IsDimension(lab):
        dims += 1
print(json.dumps({"tolerances": tols, "datums": sorted(datums), "dimensions": dims}))
"""


def _env():
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([SRC] + [p for p in env.get("PYTHONPATH", "").split(
        os.pathsep) if p])
    return env


@functools.lru_cache(maxsize=None)
def _independent(path: Path) -> dict:
    """The independent reading of a file (once per file and process: two tests read CTC 01)."""
    res = subprocess.run([sys.executable, "-c", _READER, str(path)], capture_output=True,
                         text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    return json.loads(res.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def nist_plans(shared_data, tmp_path_factory):
    """{file name: (exit status, stderr, plan text or None)} of `shapeverify plan` per file.

    The first file (CTC 01, the smallest) runs the real command in its own process; the others
    run the same command in this process (typer's CliRunner) with its import and PMI read from
    the suite's cache (tests/model_cache.py: bitwise what load_model and read_pmi give, and
    the NIST modules import the same files), which saves a CAD import, a PMI read and a
    Python start per file."""
    from model_cache import load_model_stand_in, read_pmi_stand_in
    from typer.testing import CliRunner

    import shapeverify.cad.load
    import shapeverify.cad.pmi
    from shapeverify.cli import app

    d = shared_data / "cad" / "nist"
    out = {}
    tmp = tmp_path_factory.mktemp("pmi")
    for i, name in enumerate(NIST):
        if not (d / name).exists():
            continue
        target = tmp / (name + ".yaml")
        if i == 0:
            res = subprocess.run([sys.executable, "-m", "shapeverify", "plan", str(d / name),
                                  "-o", str(target)], capture_output=True, text=True,
                                 env=_env(), timeout=1500)
            status, err = res.returncode, res.stderr
        else:
            with pytest.MonkeyPatch.context() as mp:
                mp.setattr(shapeverify.cad.load, "load_model", load_model_stand_in)
                mp.setattr(shapeverify.cad.pmi, "read_pmi", read_pmi_stand_in)
                res = CliRunner().invoke(app, ["plan", str(d / name), "-o", str(target)])
            status, err = res.exit_code, res.stderr
            if res.exc_info is not None and status != 0:
                import traceback

                err += "".join(traceback.format_exception(*res.exc_info))
        out[name] = (status, err, target.read_text() if target.exists() else None, target)
    return out


def _file(shared_data, name) -> Path:
    p = shared_data / "cad" / "nist" / name
    if not p.exists():
        pytest.skip(f"{p} not present (NIST MBE PMI test model)")
    return p


@pytest.mark.slow
@pytest.mark.parametrize("name", NIST)
def test_plan_from_nist_pmi_holds_every_tolerance_and_datum_of_the_file(shared_data, nist_plans,
                                                                        name):
    path = _file(shared_data, name)
    status, err, text, target = nist_plans[name]
    assert status == 0, err[-2000:]
    plan = load_plan(target)                       # the project's own loader takes it
    data = yaml.safe_load(text)
    truth = _independent(path)

    in_chars = {}
    for c in plan.characteristics:
        assert c.pmi is not None, f"{c.name} does not say where it came from"
        in_chars.setdefault(c.pmi.id, c.pmi.type)
    unsupported = Counter(u.pmi.id for u in plan.unsupported)
    assert all(n == 1 for n in unsupported.values()), unsupported
    assert all(u.reason.strip() for u in plan.unsupported)
    assert not set(in_chars) & set(unsupported), "an item both checked and unsupported"

    # every geometric tolerance exactly once, by type as the file holds them
    kinds = {**{u.pmi.id: (u.pmi.kind, u.pmi.type) for u in plan.unsupported},
             **{c.pmi.id: (c.pmi.kind, c.pmi.type) for c in plan.characteristics}}
    gt = Counter(t for k, t in kinds.values() if k == "geometric_tolerance")
    assert gt == Counter(truth["tolerances"])
    assert sum(1 for k, _ in kinds.values() if k == "dimension") == truth["dimensions"]
    # the datums: in the alignment, in the datums table or unsupported, one entry per letter
    names = [u.pmi.model_extra["name"] for u in plan.unsupported if u.pmi.kind == "datum"]
    if plan.alignment.type == "datums":
        names += [p.model_extra["name"] for p in plan.alignment.pmi]
    # (a common datum E-F is one table entry for the letters E and F)
    names += [p for n in plan.datums for p in n.split("-") if p not in names]
    assert sorted(names) == truth["datums"]
    for n, spec in plan.datums.items():
        assert spec.pmi.model_extra["name"] == n
    # every datum letter a characteristic names is in the datums table (the plan checks it)
    for c in plan.characteristics:
        assert set(getattr(c, "datums", None) or []) <= set(plan.datums)
    assert data["unsupported"] == [u.model_dump(exclude_none=True) for u in plan.unsupported]


@pytest.mark.slow
def test_plan_from_pmi_ties_ctc01_diameters_to_the_holes_of_that_diameter(shared_data,
                                                                          nist_plans):
    """CTC 01's toleranced diameters become hole characteristics of `info --features` holes
    whose CAD diameter is the dimension's nominal, and the flatness is of a planar face."""
    from model_cache import cached_model

    from shapeverify.characteristics.features import find_feature, model_features

    path = _file(shared_data, NIST[0])
    plan = load_plan(nist_plans[NIST[0]][3])
    feats = model_features(cached_model(path, features=True))   # once per code version
    holes = [c for c in plan.characteristics if c.type == "hole" and c.diameter is not None]
    assert len(holes) >= 4
    for c in holes:
        f = find_feature(feats, c.feature, kind="hole")
        assert f.kind == "hole"
        assert f.diameter == pytest.approx(c.pmi.model_extra["nominal"], abs=1e-3)
    flat = [c for c in plan.characteristics if c.type == "flatness"]
    assert flat and all(find_feature(feats, c.feature, kind="flatness").kind == "plane"
                        for c in flat)


@pytest.mark.slow
def test_plan_from_pmi_checks_distances_angles_and_drawn_diameters_with_the_drawings_limits(
        shared_data, nist_plans):
    """Issue 28 item 3 (size): FTC 06's linear distances between two planes become ``distance``
    entries and CTC 01's 60 degree angle an ``angle`` entry, each with the dimension's nominal
    and limits; FTC 08's diameters drawn 6.0452 on holes modelled 6.0325 keep the drawing's
    limits as deviations from the CAD diameter (were unsupported)."""
    got = {}
    for name in (NIST[0], NIST[2], NIST[3]):
        _file(shared_data, name)
        got[name] = load_plan(nist_plans[name][3])
    dist = {c.pmi.id: c for c in got[NIST[2]].characteristics if c.type == "distance"}
    assert set(dist) == {"DIM35", "DIM40", "DIM43", "DIM44", "DIM47", "DIM48", "DIM49", "DIM50"}
    for c in dist.values():
        assert (c.lower, c.upper) == (c.pmi.model_extra["lower"], c.pmi.model_extra["upper"])
        assert c.nominal == pytest.approx(c.pmi.model_extra["nominal"], abs=1e-9)
    # DIM40 is drawn .56 +-.02 in (14.224 +-0.508 mm) between faces .5625 in apart: the CAD
    # lies within the drawing's limits, measured against the drawing's nominal (was unsupported)
    assert dist["DIM40"].nominal == 14.224
    assert dist["DIM40"].pmi.model_extra["cad_distance"] == pytest.approx(14.2875, abs=1e-9)
    assert all("cad_distance" not in c.pmi.model_extra for k, c in dist.items() if k != "DIM40")
    # DIM49, DIM50: a hole's depth, its second side the circle where the hole's wall meets
    # its drill point (were unsupported: "no characteristic for a distance to such a circle")
    circles = {k: c.faces[1] for k, c in dist.items() if not isinstance(c.faces[1], (str, list))}
    assert set(circles) == {"DIM49", "DIM50"}
    assert (circles["DIM49"].cylinder, circles["DIM49"].cone) == ("face:20", "face:18")
    assert not {"DIM49", "DIM50"} & {u.pmi.id for u in got[NIST[2]].unsupported}
    ang = [c for c in got[NIST[0]].characteristics if c.type == "angle"]
    assert [(c.pmi.id, c.nominal, c.lower, c.upper) for c in ang] == [("DIM3", 60.0, -0.5, 0.5)]
    drawn = [c for c in got[NIST[3]].characteristics
             if c.type == "hole" and c.pmi.id in ("DIM8", "DIM9", "DIM10")]
    assert {c.pmi.id for c in drawn} == {"DIM8", "DIM9", "DIM10"}     # one per hole
    for c in drawn:
        x = c.pmi.model_extra
        shift = x["nominal"] - x["cad_diameter"]
        assert x["cad_diameter"] == pytest.approx(6.0325, abs=1e-6)
        assert c.diameter.lower == pytest.approx(x["lower"] + shift, abs=1e-9)
        assert c.diameter.upper == pytest.approx(x["upper"] + shift, abs=1e-9)


def test_plan_schema_takes_pmi_sources_and_unsupported_items():
    text = """
units: mm
alignment: {type: datums, primary: face:1, secondary: hole:0,
            pmi: [{kind: datum, type: Datum, name: A}, {kind: datum, type: Datum, name: B}]}
characteristics:
  - {name: F, type: flatness, feature: face:1, tol: 0.1,
     pmi: {kind: geometric_tolerance, type: Flatness, id: GT1, value: 0.1}}
unsupported:
  - {pmi: {kind: geometric_tolerance, type: Perpendicularity, id: GT2}, reason: not yet}
"""
    plan = load_plan(text)
    assert plan.characteristics[0].pmi.type == "Flatness"
    assert plan.characteristics[0].pmi.model_extra["id"] == "GT1"
    assert plan.unsupported[0].reason == "not yet"
    with pytest.raises(PlanError, match="kind"):
        load_plan(text.replace("kind: geometric_tolerance, type: Perpendicularity",
                               "kind: tolerance, type: Perpendicularity"))
    with pytest.raises(PlanError, match="reason"):
        load_plan(text.replace(", reason: not yet", ""))


def test_read_pmi_rejects_an_iges_file_by_name(tmp_path):
    from shapeverify.cad.pmi import read_pmi
    from shapeverify.errors import UnsupportedFormatError

    p = tmp_path / "part.igs"
    p.write_text("x")
    with pytest.raises(UnsupportedFormatError, match="part.igs"):
        read_pmi(p)


def test_plan_from_a_step_file_without_pmi_is_an_empty_best_fit_plan(example_step):
    from shapeverify.characteristics import plan_from_pmi

    plan = plan_from_pmi(example_step)
    assert plan.alignment.type == "best_fit"
    assert plan.characteristics == [] and plan.unsupported == []


def test_plan_of_a_file_without_pmi_says_so_and_finds_no_features(example_step, tmp_path,
                                                                  monkeypatch):
    """NIST FTC 08's AP203 edition (no semantic PMI) took 92 s to say "0 characteristics":
    63 s went to classifying the faces no PMI item named, and nothing told the user why the
    plan was empty."""
    from typer.testing import CliRunner

    import shapeverify.characteristics.pmi_plan as pp
    from shapeverify.cli import app

    def no_features(model):
        raise AssertionError("features were found for a file without PMI")

    monkeypatch.setattr(pp, "model_features", no_features)
    res = CliRunner().invoke(app, ["plan", str(example_step), "-o", str(tmp_path / "p.yaml")])
    assert res.exit_code == 0, res.output
    text = " ".join(res.stderr.split())
    assert "holds no semantic PMI" in text and "AP242" in text
    assert yaml.safe_load((tmp_path / "p.yaml").read_text())["characteristics"] == []


@pytest.mark.slow
def test_info_pmi_lists_every_tolerance_of_ctc01_with_mm_headers(shared_data):
    path = _file(shared_data, NIST[0])
    res = subprocess.run([sys.executable, "-m", "shapeverify", "info", str(path), "--pmi"],
                         capture_output=True, text=True, env={**_env(), "COLUMNS": "250"},
                         timeout=1500)
    assert res.returncode == 0, res.stderr[-2000:]
    truth = _independent(path)
    assert "value (mm)" in res.stdout and "limits (mm)" in res.stdout
    rows = [ln for ln in res.stdout.splitlines() if ln.startswith("│ GT")]
    assert Counter(r.split("│")[3].strip() for r in rows) == Counter(truth["tolerances"])


def test_pmi_face_whose_vertices_are_not_on_the_model_face_is_an_error(example_step):
    """The face numbers of the PMI are checked against the model, not trusted."""
    from shapeverify.cad.pmi import read_pmi
    from shapeverify.characteristics.pmi_plan import pmi_plan
    from shapeverify.errors import CADImportError

    pmi = read_pmi(example_step)
    assert pmi["n_faces"] == 1 and pmi["tolerances"] == []
    pmi["face_vertices"] = {0: [[1e4, 1e4, 1e4]]}
    with pytest.raises(CADImportError, match="does not match model face 0"):
        pmi_plan(example_step, pmi=pmi)
    pmi["n_faces"] = 2
    with pytest.raises(CADImportError, match="2 faces"):
        pmi_plan(example_step, pmi=pmi)


def test_info_pmi_shows_unsupported_reasons_without_markup_and_angularity_in_mm():
    """CTC 03's table printed "[yellow]unsupported:[/yellow]" literally (its cells are plain
    text) and GT2's angularity zone as "1.016°" (the zone is a length)."""
    import io
    from types import SimpleNamespace

    from rich.console import Console

    from shapeverify.cli_plan import pmi_table

    rows = [dict(id="GT2", kind="geometric_tolerance", type="Angularity", value=1.016,
                 datums="A", faces=["face:110"], entries=["GT2_angularity"]),
            dict(id="GT10", kind="geometric_tolerance", type="Position", value=0.762,
                 datums="D|B|C", faces=["face:41"], entries=[],
                 reason="faces [41, 40] are cylinder"),
            dict(id="DIM3", kind="dimension", type="Location_Angular", value=30.0,
                 limits=(-0.5, 0.5), faces=["face:2"], entries=["DIM3_angle"])]
    res = SimpleNamespace(rows=rows, plan=SimpleNamespace(
        alignment=SimpleNamespace(type="best_fit")))
    c = Console(width=250, file=io.StringIO())
    c.print(pmi_table("part.stp", res))
    text = c.file.getvalue()
    assert "[yellow]" not in text and "unsupported: faces [41, 40] are cylinder" in text
    gt2 = next(ln for ln in text.splitlines() if "GT2 " in ln)
    assert "1.016 " in gt2 and "°" not in gt2
    dim3 = next(ln for ln in text.splitlines() if "DIM3" in ln)
    assert "30°" in dim3 and "-0.5° / +0.5°" in dim3
