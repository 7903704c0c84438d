"""Issue 33 row 2: the model you inspect against is the model in the file.

Before: a STEP file with one face entity deleted (its closed shell's reference dangling) gave
``info`` 5 faces with no warning, ``prepare`` a warning and exit 0, and a scan with a dent on
the missing face passed.  Now ``info`` says how many faces the file declares and which are
missing; ``prepare``/``inspect`` refuse such a model unless ``--allow-incomplete-model``
(``prepare(model, allow_incomplete=True)``), and then every inspection's reasons name the
missing faces.  Checked with the shared wavy cube and the bundled chamfered plate.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from typer.testing import CliRunner

import shapeverify as sv
from shapeverify.cad.summary import cached_summary, read_summary
from shapeverify.cli import app
from shapeverify.errors import IncompleteModelError
from shapeverify.nearest import load_prepared

pytest.importorskip("OCP")


def _drop_face(src, dst, which: int = 1) -> tuple:
    """Delete the ``which``-th face entity line of the first closed shell: the shell's
    reference to it dangles.  Returns (path, the deleted entity's '#N', faces in the shell)."""
    data = src.read_bytes()
    shell = re.search(rb"CLOSED_SHELL\s*\(\s*'[^']*'\s*,\s*\(([^)]*)\)", data)
    refs = re.findall(rb"#(\d+)", shell.group(1))
    face = refs[which]
    lines = data.splitlines(keepends=True)
    kept = [ln for ln in lines if not re.match(rb"#" + face + rb"\s*=", ln)]
    assert len(kept) == len(lines) - 1
    dst.write_bytes(b"".join(kept))
    return dst, "#" + face.decode(), len(refs)


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    from shapeverify.cad.examples import chamfered_plate_step

    d = tmp_path_factory.mktemp("incomplete")
    full = chamfered_plate_step(d / "plate.step")
    broken, ref, n = _drop_face(full, d / "plate-missing.step", which=2)
    return full, broken, ref, n


def test_row2_info_reports_faces_expected_and_missing(plate, tmp_path, monkeypatch):
    full, broken, ref, n = plate
    s = read_summary(broken)
    assert (s.faces, s.faces_in_file) == (n - 1, n)
    assert len(s.missing) == 1 and ref in s.missing[0] and "CLOSED_SHELL" in s.missing[0]
    whole = read_summary(full)
    assert (whole.faces, whole.faces_in_file, whole.missing) == (n, n, ())
    # the command line, also when the summary comes from the cache
    monkeypatch.setenv("SHAPEVERIFY_CACHE_DIR", str(tmp_path / "cache"))
    for _ in range(2):
        res = CliRunner().invoke(app, ["info", str(broken)])
        assert res.exit_code == 0, res.output
        flat = " ".join(res.output.split())
        assert f"{n - 1} of {n} in the file" in flat and ref in flat
    assert cached_summary(broken, read_summary)[1]  # the second came from the cache


def test_row2_prepare_refuses_an_incomplete_model_unless_allowed(plate, tmp_path):
    full, broken, ref, n = plate
    model = sv.load_model(broken)
    assert len(model.faces) == n - 1 and model.n_faces_in_file == n
    with pytest.raises(IncompleteModelError) as err:
        sv.prepare(model, spacing=2.0)
    msg = str(err.value)
    assert "plate-missing.step" in msg and ref in msg and "allow_incomplete" in msg
    runner = CliRunner()
    res = runner.invoke(app, ["prepare", str(broken), "-o", str(tmp_path / "m.svm")])
    assert res.exit_code == 2 and ref in res.output and "--allow-incomplete-model" in " ".join(
        res.output.split())
    assert not (tmp_path / "m.svm").exists()
    res = runner.invoke(app, ["prepare", str(broken), "-o", str(tmp_path / "m.svm"),
                              "--spacing", "2", "--allow-incomplete-model"])
    assert res.exit_code == 0, res.output
    assert load_prepared(tmp_path / "m.svm").model.skipped_faces == model.skipped_faces


@pytest.mark.slow
def test_row2_inspection_against_an_allowed_incomplete_model_names_the_missing_faces(plate,
                                                                                     tmp_path):
    """A scan of the complete plate with a 0.5 mm dent on the face that is missing: the
    inspection's reasons say that face is missing (before: a plain pass)."""
    full, broken, ref, n = plate
    whole = sv.prepare(sv.load_model(full), spacing=2.0)
    prep = sv.prepare(sv.load_model(broken), spacing=2.0, allow_incomplete=True)
    pts = whole.points.points
    # the face that is missing: the one whose points the incomplete model does not have
    d = np.abs(prep.closest(pts).distances)
    gone = d > 1.0
    assert gone.sum() > 20
    scan = pts.copy()
    c = pts[gone][np.argmin(np.linalg.norm(pts[gone] - pts[gone].mean(0), axis=1))]
    dent = np.linalg.norm(pts - c, axis=1) < 6.0
    scan[dent] -= 0.5 * whole.points.normals[dent]
    for p in (prep, None):
        if p is None:  # the same through a saved .svm
            prep.save(tmp_path / "inc.svm")
            p = load_prepared(tmp_path / "inc.svm")
        r = sv.inspect(p, scan, tolerance=0.2, init=np.eye(4))
        text = " ".join(r.reasons)
        assert "incomplete model" in text and ref in text and "plate-missing.step" in text, \
            r.reasons
    # the complete model is not flagged, and fails the dent
    r = sv.inspect(whole, scan, tolerance=0.2, init=np.eye(4))
    assert "incomplete model" not in " ".join(r.reasons) and r.verdict == "fail"


def test_row2_inspect_cli_with_a_cad_file_refuses_it_too(plate, tmp_path):
    full, broken, ref, n = plate
    whole = sv.prepare(sv.load_model(full), spacing=2.0)
    np.savetxt(tmp_path / "scan.xyz", whole.points.points[::3])
    res = CliRunner().invoke(app, ["inspect", str(broken), str(tmp_path / "scan.xyz"),
                                   "--tolerance", "0.2"])
    assert res.exit_code == 2 and ref in res.output


def test_row2_wavy_cube_with_a_dangling_face(shared_data, tmp_path):
    src = shared_data / "cad" / "wavy-cube.stp"
    broken, ref, n = _drop_face(src, tmp_path / "cube-missing.stp", which=1)
    s = read_summary(broken)
    assert (s.faces, s.faces_in_file) == (n - 1, n) and ref in s.missing[0]
    model = sv.load_model(broken)           # (imported once: prepare does not change it)
    with pytest.raises(IncompleteModelError, match=ref):
        sv.prepare(model)
    prep = sv.prepare(model, allow_incomplete=True)
    assert len(prep.model.faces) == n - 1
    # the undamaged file prepares as before (prepare(load_model(src)), once per suite run:
    # tests/model_cache.py, shared with test_regions_independent)
    from model_cache import cached_prepared

    assert len(cached_prepared(src).model.faces) == n


def test_row2_open_seams_of_a_solid_are_reported(plate, tmp_path):
    """The faces next to the deleted one now have boundary segments that meet no other face:
    in a file of closed shells (a solid) that is an open seam, named with the missing face; the
    complete solid has none; a surface model (OPEN_SHELL) may have free edges."""
    full, broken, ref, n = plate
    model = sv.load_model(broken)
    assert len(model.open_seams) >= 2, model.open_seams
    assert all("meet no other face" in s for s in model.open_seams)
    with pytest.raises(IncompleteModelError, match="open seams"):
        sv.prepare(model, spacing=2.0)
    assert sv.load_model(full).open_seams == ()
    surf = tmp_path / "surface-model.step"
    surf.write_bytes(broken.read_bytes().replace(b"CLOSED_SHELL", b"OPEN_SHELL"))
    m = sv.load_model(surf)
    assert m.open_seams == () and m.n_missing_faces == 1  # the dangling face is still named
    # the seams travel with the model through .svmodel and .svm files
    model.save(tmp_path / "m.svmodel")
    assert sv.load_model(tmp_path / "m.svmodel").open_seams == model.open_seams
