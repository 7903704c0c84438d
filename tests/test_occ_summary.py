"""``shapeverify info``'s summary of a CAD file from OpenCASCADE alone
(:mod:`shapeverify.cad.occ_summary`) equals the summary of the imported model: the same faces,
rational faces, faces with holes and unit, and bounds within 1e-6 of the model's size."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("OCP")

from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut  # noqa: E402
from OCP.BRepPrimAPI import (BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCylinder,  # noqa: E402
                             BRepPrimAPI_MakeSphere, BRepPrimAPI_MakeTorus)
from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt  # noqa: E402
from OCP.IFSelect import IFSelect_RetDone  # noqa: E402
from OCP.IGESControl import IGESControl_Writer  # noqa: E402
from OCP.Interface import Interface_Static  # noqa: E402
from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer  # noqa: E402

from shapeverify.cad.load import load_model  # noqa: E402
from shapeverify.cad.occ_summary import read_summary  # noqa: E402
from shapeverify.cad.summary import summarize  # noqa: E402
from shapeverify.errors import CADImportError, EmptyModelError  # noqa: E402

SHARED_CAD = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "cad"
SHARED_NAMES = ["wavy-cube.stp", "hammer.iges", "impeller.igs"]
BOUNDS_TOL = 1e-6  # of the model's size


def write_step(shape, path, unit="MM"):
    Interface_Static.SetCVal_s("write.step.unit", unit)
    try:
        w = STEPControl_Writer()
        w.Transfer(shape, STEPControl_AsIs)
        assert w.Write(str(path)) == IFSelect_RetDone
    finally:
        Interface_Static.SetCVal_s("write.step.unit", "MM")
    return Path(path)


def write_iges(shape, path, unit="MM"):
    w = IGESControl_Writer(unit, 0)
    w.AddShape(shape)
    w.ComputeModel()
    assert w.Write(str(path))
    return Path(path)


def _drilled_box():
    box = BRepPrimAPI_MakeBox(40.0, 30.0, 10.0).Shape()
    hole = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(20.0, 15.0, -1.0), gp_Dir(0, 0, 1)),
                                    5.0, 12.0).Shape()
    return BRepAlgoAPI_Cut(box, hole).Shape()


def _round_things():
    """A sphere and a torus: faces whose extremes lie inside them, not on an edge."""
    from OCP.BRep import BRep_Builder
    from OCP.TopoDS import TopoDS_Compound

    comp, b = TopoDS_Compound(), BRep_Builder()
    b.MakeCompound(comp)
    b.Add(comp, BRepPrimAPI_MakeSphere(gp_Pnt(3.0, -2.0, 1.0), 7.5).Shape())
    b.Add(comp, BRepPrimAPI_MakeTorus(gp_Ax2(gp_Pnt(30.0, 0.0, 0.0), gp_Dir(1, 1, 1)),
                                      8.0, 2.0).Shape())
    return comp


@pytest.fixture(scope="module")
def made_files(tmp_path_factory, example_step):
    d = tmp_path_factory.mktemp("occ-summary")
    return {
        "panel.step": example_step,
        "drilled-box-inch.step": write_step(_drilled_box(), d / "drilled-box-inch.step", "INCH"),
        "drilled-box.igs": write_iges(_drilled_box(), d / "drilled-box.igs"),
        "round.step": write_step(_round_things(), d / "round.step"),
        "round.iges": write_iges(_round_things(), d / "round.iges"),
    }


def assert_same_summary(fast, full):
    assert (fast.kind, fast.faces, fast.rational_faces, fast.faces_with_holes, fast.vertices,
            fast.unit, fast.scale_to_mm) == \
        (full.kind, full.faces, full.rational_faces, full.faces_with_holes, full.vertices,
         full.unit, full.scale_to_mm)
    gap = np.abs(np.array([fast.lo, fast.hi]) - np.array([full.lo, full.hi]))
    assert gap.max() <= BOUNDS_TOL * full.size, (gap.max() / full.size, fast, full)
    assert abs(fast.size - full.size) <= 2 * BOUNDS_TOL * full.size


@pytest.mark.parametrize("name", ["panel.step", "drilled-box-inch.step", "drilled-box.igs",
                                  "round.step", "round.iges"])
def test_summary_of_a_made_file_is_the_models(made_files, name):
    path = made_files[name]
    full = summarize(load_model(path))
    assert_same_summary(read_summary(path), full)
    if name.startswith("drilled"):  # what the file is: 7 faces, the top and bottom holed
        assert (full.faces, full.faces_with_holes) == (7, 2) and full.rational_faces >= 1
        scale = 25.4 if "inch" in name else 1.0
        assert full.scale_to_mm == scale
        assert np.allclose(full.hi, [40.0, 30.0, 10.0], rtol=1e-9)  # in mm, whatever the unit
    if name.startswith("round"):  # the sphere's and the torus's extremes are inside faces
        ring = 8.0 * np.sqrt(2.0 / 3.0) + 2.0  # the torus (axis (1,1,1)) reaches this far in x
        assert np.allclose(full.lo, [3.0 - 7.5, -2.0 - 7.5, -ring], atol=1e-6)
        assert full.hi[0] == pytest.approx(30.0 + ring, abs=1e-6)


@pytest.mark.slow  # over 4 s of CPU: out of `make test-fast` (issue 32)
@pytest.mark.parametrize("name", SHARED_NAMES)
def test_summary_of_a_shared_file_is_the_models(shared_data, name):
    path = shared_data / "cad" / name
    assert_same_summary(read_summary(path), summarize(load_model(path)))


def test_a_face_the_import_skips_is_left_out_of_the_summary_too(tmp_path, monkeypatch):
    import shapeverify.cad._occ_loops as loops

    step = write_step(_drilled_box(), tmp_path / "box.step")
    real = loops._face_wires

    def wires(work, face, conv, edge_faces, index, path):
        if index == 2:
            raise CADImportError(f"{path}: an edge of face 2 has no pcurve")
        return real(work, face, conv, edge_faces, index, path)

    monkeypatch.setattr(loops, "_face_wires", wires)
    from shapeverify.cad.occ_import import read_cad

    model = read_cad(step, isolated=False)
    assert len(model.faces) == 6 and model.n_faces_in_file == 7 and len(model.skipped_faces) == 1
    assert_same_summary(read_summary(step), summarize(model))


def test_a_file_with_a_dangling_face_has_the_models_summary(tmp_path):
    import re

    step = write_step(_drilled_box(), tmp_path / "box.step")
    text = step.read_text()
    face = re.findall(r"#(\d+) = ADVANCED_FACE", text)[3]
    bad = tmp_path / "dangling.step"
    bad.write_text("".join(ln for ln in text.splitlines(keepends=True)
                           if not ln.startswith(f"#{face} = ADVANCED_FACE")))
    model = load_model(bad)
    assert len(model.faces) == 6 and model.n_missing_faces == 1
    assert_same_summary(read_summary(bad), summarize(model))


def test_errors_are_the_imports(tmp_path):
    empty = tmp_path / "empty.step"
    empty.write_bytes(b"")
    with pytest.raises(CADImportError, match="empty"):
        read_summary(empty)
    with pytest.raises(FileNotFoundError):
        read_summary(tmp_path / "missing.step")
    junk = tmp_path / "junk.igs"
    junk.write_text("not an IGES file\n")
    with pytest.raises(CADImportError, match="IGES"):
        read_summary(junk)
    with pytest.raises((CADImportError, EmptyModelError)):
        load_model(junk)


def test_the_summary_needs_no_numba_in_the_importer(example_step):
    """The summary's process imports neither numba nor scipy (in the importer child, where it
    runs for ``info``, that is ~0.9 s of numba import and kernel loading saved)."""
    code = ("import sys\nfrom shapeverify.cad.occ_summary import read_summary\n"
            "s = read_summary(sys.argv[1])\n"
            "print('FACES', s.faces, 'LOADED', sorted(m for m in ('numba', 'scipy') "
            "if m in sys.modules))\n")
    res = subprocess.run([sys.executable, "-c", code, str(example_step)], capture_output=True,
                         text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert "FACES 1 LOADED []" in res.stdout


def test_the_isolated_summary_is_the_in_process_one(example_step):
    from shapeverify.cad.occ_worker import summary_isolated
    from shapeverify.cad.summary import read_summary as any_summary

    here = read_summary(example_step)
    assert summary_isolated(example_step) == here == any_summary(example_step)
