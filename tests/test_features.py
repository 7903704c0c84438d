"""CAD features from the topology: holes (circular inner trim loops), planes, cylinders."""
from __future__ import annotations

import json

import numpy as np
import pytest

from shapeverify.cad.model import Face, Model
from shapeverify.cad.nurbs import NurbsSurface
from shapeverify.characteristics.features import features_table, find_feature, model_features
from shapeverify.characteristics.parts import BRACKET_BOSS, BRACKET_HOLES, bracket

N_LOOP = 512
# a polygon of N_LOOP vertices inscribed in the circle: the fitted radius lies between the
# apothem r cos(pi / N) and r
POLY = 1.0 - np.cos(np.pi / N_LOOP)


def _curved_sheet(hole=(40.0, 30.0, 7.0)):
    """A bicubic Bezier sheet over [0, 100] x [0, 80] with x = 100 u, y = 80 v exactly (equally
    spaced control points: linear precision) and a curved height, with a round hole along z."""
    xs, ys = np.linspace(0, 100, 4), np.linspace(0, 80, 4)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    Z = 8.0 * np.sin(X / 40.0) + 0.002 * (Y - 40) ** 2
    surf = NurbsSurface(3, 3, [0] * 4 + [1] * 4, [0] * 4 + [1] * 4, np.stack([X, Y, Z], -1))
    x0, y0, r = hole
    t = -np.linspace(0, 2 * np.pi, N_LOOP, endpoint=False)
    inner = np.column_stack([(x0 + r * np.cos(t)) / 100.0, (y0 + r * np.sin(t)) / 80.0])
    outer = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    return Model((Face(surf, (outer, inner), (np.ones(4, bool), np.ones(N_LOOP, bool))),)), surf


def test_bracket_faces_are_classified_and_its_holes_found_at_their_cad_positions():
    feats = model_features(bracket())
    kinds = {f.id: f.kind for f in feats}
    assert kinds == {"face:0": "plane", "face:1": "plane", "face:2": "plane",
                     "face:3": "cylinder", "hole:0": "hole", "hole:1": "hole"}
    normals = {f.id: f.axis for f in feats if f.kind == "plane"}
    np.testing.assert_allclose(normals["face:0"], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(normals["face:1"], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(normals["face:2"], [0, 1, 0], atol=1e-12)
    boss = find_feature(feats, "face:3")
    assert boss.diameter == pytest.approx(2 * BRACKET_BOSS[2], abs=1e-9)
    np.testing.assert_allclose(np.abs(boss.axis), [0, 0, 1], atol=1e-9)
    np.testing.assert_allclose(boss.center[:2], BRACKET_BOSS[:2], atol=1e-9)
    holes = [f for f in feats if f.kind == "hole"]
    for f, (x, y, r) in zip(holes, BRACKET_HOLES):
        np.testing.assert_allclose(f.center, [x, y, 0.0], atol=1e-9)
        np.testing.assert_allclose(f.axis, [0, 0, 1], atol=1e-12)   # the face's outward side
        assert 2 * r * (1 - POLY) - 1e-9 <= f.diameter <= 2 * r + 1e-9
        assert f.face == 0 and f.form_error < 1e-3


def test_hole_through_a_curved_sheet_lies_on_a_cylinder_and_its_centre_on_the_surface():
    model, surf = _curved_sheet()
    feats = model_features(model)
    assert [f.id for f in feats] == ["face:0", "hole:0"]
    assert feats[0].kind == "freeform"
    h = feats[1]
    # the loop is not planar (the sheet curves), so this came from the cylinder fit
    np.testing.assert_allclose(h.axis, [0, 0, 1], atol=1e-6)
    assert 14 * (1 - POLY) - 1e-6 <= h.diameter <= 14 + 1e-6
    z = surf.evaluate(np.array([0.4]), np.array([30 / 80]))[0]   # S(u, v) at the hole's centre
    np.testing.assert_allclose(h.center, z, atol=1e-6)


def test_near_picks_the_closest_feature_of_the_type_and_unknown_ids_list_what_exists():
    feats = model_features(bracket())
    assert find_feature(feats, near=[60, 25, 0], kind="hole").id == "hole:1"
    assert find_feature(feats, near=[33, 41, 5], kind="hole").id == "hole:0"
    assert find_feature(feats, near=[70, 60, 10], kind="cylinder").id == "face:3"
    with pytest.raises(ValueError, match=r"no feature 'hole:7'.*hole:0, hole:1"):
        find_feature(feats, "hole:7", kind="hole")
    with pytest.raises(ValueError, match="no cylinder"):
        find_feature(model_features(bracket(boss=None)), near=[0, 0, 0], kind="cylinder")


def test_features_table_is_json_ready_and_ids_are_stable():
    rows = features_table(bracket())
    text = json.dumps(rows)
    assert json.loads(text) == rows
    assert [r["id"] for r in rows] == [r["id"] for r in features_table(bracket())]
    assert {"id", "kind", "face", "name", "center", "axis", "diameter"} <= set(rows[0])


def test_mesh_models_have_no_features():
    mesh = Model(kind="mesh", vertices=np.eye(3), triangles=np.array([[0, 1, 2]]))
    with pytest.raises(ValueError, match="CAD model"):
        model_features(mesh)


# ------------------------------------------------------------------ face names from STEP files
def _name_by_position(c) -> str:
    """The name the test gives the face of the 40 x 30 x 10 block whose centre of mass is c."""
    x, y, z = c
    if abs(z - 10) < 1e-6:
        return "top"
    if abs(z) < 1e-6:
        return "bottom"
    if abs(x) < 1e-6 or abs(x - 40) < 1e-6:
        return "x_walls"                 # one name for two faces: a face group
    if abs(y) < 1e-6:
        return "front"
    if abs(y - 30) < 1e-6:
        return "NONE"                    # what exporters write for an unnamed face
    return "bore"


def _name_faces(tool, label, shape, name_of) -> None:
    """Name each face of ``shape`` (the shape of XCAF ``label``) ``name_of(centre)``; None
    leaves it unnamed."""
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDataStd import TDataStd_Name
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer

    exp = TopExp_Explorer(shape, TopAbs_FACE)
    while exp.More():
        props = GProp_GProps()
        BRepGProp.SurfaceProperties_s(exp.Current(), props)
        c = props.CentreOfMass()
        name = name_of((c.X(), c.Y(), c.Z()))
        if name is not None:
            TDataStd_Name.Set_s(tool.AddSubShape(label, exp.Current()),
                                TCollection_ExtendedString(name))
        exp.Next()


def _write_xcaf_step(doc, path) -> None:
    """Write an XCAF document to STEP with the names of its sub-shapes."""
    from OCP.Interface import Interface_Static
    from OCP.STEPCAFControl import STEPCAFControl_Writer
    from OCP.STEPControl import STEPControl_AsIs

    writer = STEPCAFControl_Writer()
    assert Interface_Static.SetIVal_s("write.stepcaf.subshapes.name", 1)
    writer.SetNameMode(True)
    assert writer.Transfer(doc, STEPControl_AsIs)
    writer.Write(str(path))


def _write_named_block(path):
    """A 40 x 30 x 10 mm block with a 10 mm through hole at (20, 15), its faces named through
    OCP's XCAF writer (sub-shape names), the face list of the shell then reversed in the text
    so that the importer meets the faces in another order than the file lists them."""
    import re

    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCylinder
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDocStd import TDocStd_Document
    from OCP.XCAFDoc import XCAFDoc_DocumentTool
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt

    block = BRepPrimAPI_MakeBox(40.0, 30.0, 10.0).Shape()
    pin = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(20, 15, -1), gp_Dir(0, 0, 1)), 5.0, 12.0).Shape()
    part = BRepAlgoAPI_Cut(block, pin).Shape()
    doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
    tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    label = tool.AddShape(part, False)
    _name_faces(tool, label, part, _name_by_position)
    _write_xcaf_step(doc, path)
    text = path.read_text()
    shell = re.search(r"CLOSED_SHELL\('([^']*)',\(([^)]*)\)\)", text)
    ids = [s.strip() for s in shell.group(2).split(",")]
    assert len(ids) == 7
    text = text.replace(shell.group(0), f"CLOSED_SHELL('{shell.group(1)}',({','.join(ids[::-1])}))")
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def named_step(tmp_path_factory):
    return _write_named_block(tmp_path_factory.mktemp("names") / "block.step")


def test_step_face_names_attach_to_the_faces_they_name_by_shape_not_by_file_order(named_step):
    import re

    from shapeverify.cad.occ_import import read_cad

    model = read_cad(named_step, isolated=False)   # (the CLI test reads through the importer)
    feats = model_features(model)
    faces = [f for f in feats if f.kind != "hole"]
    assert len(faces) == 7
    for f in faces:
        want = _name_by_position(f.center) if f.kind == "plane" else "bore"
        assert f.kind == ("cylinder" if want == "bore" else "plane")
        # the grid centroid of a face with the hole is not its centre of mass: name by the plane
        if f.kind == "plane":
            n = f.axis
            want = {(0, 0, 1): "top", (0, 0, -1): "bottom", (1, 0, 0): "x_walls",
                    (-1, 0, 0): "x_walls", (0, -1, 0): "front", (0, 1, 0): None}[
                tuple(int(round(v)) for v in n)]
        assert f.name == want, (f.id, f.axis, f.name)
    np.testing.assert_allclose(faces[[f.name for f in faces].index("bore")].diameter, 10.0,
                               atol=1e-6)
    # the file lists the names in another order than the faces are imported
    in_file = [m for m in re.findall(r"ADVANCED_FACE\('([^']*)'", named_step.read_text())]
    assert [n or "NONE" for n in model.face_names] != in_file
    # the hole of the top and bottom faces carries its face's name
    holes = [f for f in feats if f.kind == "hole"]
    assert sorted(h.name for h in holes) == ["bottom", "top"]


def test_face_names_change_nothing_else_and_a_file_without_names_has_none(named_step, tmp_path):
    import re

    from shapeverify.cad.occ_import import read_cad
    from shapeverify.cad.persist import model_to_arrays

    plain = tmp_path / "plain.step"
    plain.write_text(re.sub(r"ADVANCED_FACE\('[^']*'", "ADVANCED_FACE(''", named_step.read_text()))
    named, bare = read_cad(named_step, isolated=False), read_cad(plain, isolated=False)
    assert bare.face_names is None and named.face_names is not None
    a, b = model_to_arrays(named), model_to_arrays(bare)
    assert a.keys() == b.keys()
    for k in a:
        if k != "meta":
            assert np.array_equal(a[k], b[k]), k


def test_face_names_survive_svmodel_and_svm_files_and_old_files_load(named_step, tmp_path):
    import shapeverify as sv
    from shapeverify.cad.persist import load_saved_model, model_from_arrays, model_to_arrays

    from shapeverify.cad.occ_import import read_cad

    model = read_cad(named_step, isolated=False)
    model.save(tmp_path / "m.svmodel")
    assert load_saved_model(tmp_path / "m.svmodel").face_names == model.face_names
    prep = sv.prepare(model, spacing=2.0)
    prep.save(tmp_path / "m.svm")
    assert sv.load_prepared(tmp_path / "m.svm").model.face_names == model.face_names
    # a file written before names existed: its meta has no face_names
    arrays = model_to_arrays(model)
    meta = json.loads(bytes(arrays["meta"]).decode())
    del meta["face_names"]
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), np.uint8)
    assert model_from_arrays(arrays).face_names is None
    with pytest.raises(ValueError, match="face_names has 2 entries for 7 faces"):
        Model(model.faces, face_names=("a", "b"))


def test_a_plan_names_faces_by_their_cad_names():
    from shapeverify.characteristics.alignment import face_indices

    base = bracket()
    model = Model(base.faces, face_names=("plate", "walls", "walls", None))
    feats = model_features(model)
    assert find_feature(feats, "plate", kind="plane").id == "face:0"
    assert face_indices(model, ["walls"]).tolist() == [1, 2]           # a name is a face group
    assert face_indices(model, ["plate", "face:3"]).tolist() == [0, 3]
    with pytest.raises(ValueError, match=r"'walls' belongs to 2 faces \(face:1, face:2\)"):
        find_feature(feats, "walls", kind="plane")
    with pytest.raises(ValueError, match="'plate' names face:0, a plane face, but a hole"):
        find_feature(feats, "plate", kind="hole")
    with pytest.raises(ValueError, match="no feature 'wall'"):
        face_indices(model, ["wall"])
    assert [f.name for f in feats if f.kind == "hole"] == ["plate", "plate"]
    # the plan schema takes names where it takes face ids
    from shapeverify.characteristics.plan import PlanError, parse_plan

    plan = parse_plan("alignment: {type: datums, primary: plate, secondary: face:1, "
                      "tertiary: face:2}\ncharacteristics:\n"
                      "  - {name: F, type: flatness, feature: plate, tol: 0.1}\n"
                      "  - {name: W, type: surface_profile, faces: [walls], tol: 0.2}\n")
    assert plan.alignment.primary == "plate" and plan.characteristics[0].feature == "plate"
    with pytest.raises(PlanError, match="line 3"):
        parse_plan("alignment: {type: best_fit}\ncharacteristics:\n"
                   "  - {name: F, type: flatness, feature: 'hole:x', tol: 0.1}\n")


def test_info_features_lists_the_step_face_names(named_step, tmp_path):
    from typer.testing import CliRunner

    from shapeverify.cli import app

    out = tmp_path / "features.json"
    res = CliRunner().invoke(app, ["info", str(named_step), "--features", "--json", str(out)])
    assert res.exit_code == 0, res.output
    rows = json.loads(out.read_text())
    names = sorted(r["name"] for r in rows if r["kind"] != "hole" and r["name"])
    assert names == ["bore", "bottom", "front", "top", "x_walls", "x_walls"]
    assert "x_walls" in res.output


def test_a_named_face_of_a_part_placed_twice_in_an_assembly_is_named_on_both(tmp_path):
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDocStd import TDocStd_Document
    from OCP.TopLoc import TopLoc_Location
    from OCP.XCAFDoc import XCAFDoc_DocumentTool
    from OCP.gp import gp_Trsf, gp_Vec

    from shapeverify.cad.occ_import import read_cad

    box = BRepPrimAPI_MakeBox(10.0, 20.0, 30.0).Shape()
    doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
    tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    part = tool.AddShape(box, False)
    _name_faces(tool, part, box, lambda c: "top" if abs(c[2] - 30.0) < 1e-9 else None)
    assembly = tool.NewShape()
    for dx in (0.0, 50.0):
        move = gp_Trsf()
        move.SetTranslation(gp_Vec(dx, 0.0, 0.0))
        tool.AddComponent(assembly, part, TopLoc_Location(move))
    tool.UpdateAssemblies()
    _write_xcaf_step(doc, tmp_path / "asm.step")
    model = read_cad(tmp_path / "asm.step", isolated=False)
    assert len(model.faces) == 12
    tops = sorted(float(f.center[0]) for f in model_features(model) if f.name == "top")
    np.testing.assert_allclose(tops, [5.0, 55.0], atol=1.0)       # one top face per instance
    for f in model_features(model):
        if f.kind == "plane" and f.name == "top":
            np.testing.assert_allclose(f.axis, [0, 0, 1], atol=1e-9)
            assert abs(f.center[2] - 30.0) < 1e-9
    assert sum(n is not None for n in model.face_names) == 2


def test_has_face_names_reads_the_face_entities_names_from_the_text(tmp_path):
    from shapeverify.cad.step_names import has_face_names

    def step(*records):
        p = tmp_path / f"f{len(list(tmp_path.iterdir()))}.step"
        p.write_text("ISO-10303-21;\nDATA;\n" + "\n".join(records) + "\nENDSEC;\n")
        return p

    assert not has_face_names(step("#1 = ADVANCED_FACE('',(#2),#3,.T.);",
                                   "#4 = ADVANCED_FACE( 'NONE' ,(#5),#6,.F.);",
                                   "#7 = PRODUCT('part','part','',(#8));"))
    assert has_face_names(step("#1 = ADVANCED_FACE('',(#2),#3,.T.);",
                               "#4 = ADVANCED_FACE(\n 'datum ''A''',(#5),#6,.F.);"))
    assert has_face_names(step("#1 = FACE_SURFACE('seal',(#2),#3,.T.);"))
    assert not has_face_names(step("#1 = ORIENTED_FACE('',*,#2,.T.);"))
    assert not has_face_names(tmp_path / "missing.step")


def test_a_failing_name_transfer_reads_the_file_without_names(named_step, monkeypatch, caplog):
    from shapeverify.cad import step_names
    from shapeverify.cad.occ_import import read_cad

    def broken(caf, doc):
        raise RuntimeError("the XCAF transfer of the STEP file failed")

    monkeypatch.setattr(step_names, "transfer", broken)
    with caplog.at_level("WARNING"):
        model = read_cad(named_step, isolated=False)
    assert model.face_names is None and len(model.faces) == 7
    assert "face names could not be read" in caplog.text


def test_hole_in_a_sloped_part_of_the_panel_is_found(tmp_path):
    """Pins: a drilled 24 mm hole at (80, 60) of the panel, where the sheet slopes, was not
    listed: its rim is not a plane circle and the cylinder fit started from the rim's plane
    normal stopped in a tilted local minimum (0.009 mm off); a plan's `near` then silently
    took the other hole, 143 mm away."""
    from shapeverify.cad.examples import PANEL_HOLE, example_part_step
    from shapeverify.cad.load import load_model
    from shapeverify.characteristics.features import find_feature, model_features

    model = load_model(example_part_step(tmp_path / "two.step",
                                         holes=(PANEL_HOLE, (80.0, 60.0, 12.0))))
    holes = [f for f in model_features(model) if f.kind == "hole"]
    assert len(holes) == 2
    got = sorted((round(float(h.center[0]), 6), round(float(h.center[1]), 6),
                  round(float(h.diameter), 6)) for h in holes)
    assert got == [(80.0, 60.0, 24.0), (210.0, 120.0, 36.0)]
    for h in holes:
        np.testing.assert_allclose(np.abs(h.axis), [0, 0, 1], atol=1e-6)
    assert find_feature(holes, near=[80, 60, 10], kind="hole").center[0] == pytest.approx(80)


def test_near_far_from_every_hole_is_an_error_not_the_nearest_hole(tmp_path):
    from shapeverify.cad.examples import example_part_step
    from shapeverify.cad.load import load_model
    from shapeverify.characteristics.features import find_feature, model_features

    feats = model_features(load_model(example_part_step(tmp_path / "one.step")))
    with pytest.raises(ValueError, match=r"no hole near .*143\.\d mm away.*hole:0"):
        find_feature(feats, near=[80, 60, 10], kind="hole")


# ------------------------------------------------------------------ issue 27: any CAD reads
def _flat_sheet_with(inner):
    """A flat 100 x 80 Bezier sheet (x = 100 u, y = 80 v, z = 0) with one inner loop given in
    mm (k, 2), wound clockwise."""
    xs, ys = np.linspace(0, 100, 4), np.linspace(0, 80, 4)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    surf = NurbsSurface(3, 3, [0] * 4 + [1] * 4, [0] * 4 + [1] * 4,
                        np.stack([X, Y, np.zeros_like(X)], -1))
    uv = np.asarray(inner, float) / [100.0, 80.0]
    outer = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    return Model((Face(surf, (outer, uv), (np.ones(4, bool), np.ones(len(uv), bool))),))


def test_parameters_rounded_a_hair_outside_the_domain_are_clamped_not_rejected():
    """Pins issue 27: NIST STEP loops evaluated 1e-15..3e-11 outside [0, pi] raised
    'u must lie in the domain' and `info --features` exited 2 on 23 files."""
    _, surf = _curved_sheet()
    np.testing.assert_array_equal(surf.evaluate(-3e-11, 0.5), surf.evaluate(0.0, 0.5))
    np.testing.assert_array_equal(surf.evaluate(0.3, 1 + 1e-12), surf.evaluate(0.3, 1.0))
    with pytest.raises(ValueError, match=r"u must lie in the domain \[0\.0, 1\.0\]"):
        surf.evaluate(-1e-6, 0.5)


def test_a_slot_shaped_inner_loop_is_a_slot_with_its_outline_not_an_exception():
    """Pins issue 27: FTC 08's non-circular inner loop raised 'points lie on a line/plane'."""
    t = np.linspace(-np.pi / 2, np.pi / 2, 41)           # (t = 0: the tips are vertices)
    right = np.column_stack([60 + 5 * np.cos(t), 40 + 5 * np.sin(t)])
    left = np.column_stack([30 - 5 * np.cos(t), 40 - 5 * np.sin(t)])
    stadium = np.concatenate([right, left])[::-1]                 # clockwise: a hole
    feats = model_features(_flat_sheet_with(stadium))
    slots = [f for f in feats if f.kind == "slot"]
    assert [f.kind for f in feats if f.kind not in ("plane",)] == ["slot"]
    s = slots[0]
    assert s.length == pytest.approx(40.0, abs=1e-6) and s.width == pytest.approx(10.0, abs=1e-3)
    np.testing.assert_allclose(s.center, [45, 40, 0], atol=1e-6)
    np.testing.assert_allclose(np.abs(s.axis), [0, 0, 1], atol=1e-9)
    assert s.outline.shape == (82, 3)
    row = [r for r in features_table(_flat_sheet_with(stadium)) if r["kind"] == "slot"][0]
    assert json.loads(json.dumps(row))["outline"][0] == pytest.approx(list(s.outline[0]))
    # an L-shaped opening is a pocket; a straight-line 'loop' is left out (no exception)
    L = np.array([[20, 20], [20, 50], [30, 50], [30, 30], [50, 30], [50, 20]], float)
    assert [f.kind for f in model_features(_flat_sheet_with(L))] == ["plane", "pocket"]
