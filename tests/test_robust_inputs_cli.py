"""The command line on broken and hostile input: one clear ``error:`` line and exit code 2, never
an internal error or a traceback.  Each test pins one bug found by trying (docs/robustness.md)."""

from __future__ import annotations

import errno
import os

import numpy as np
import pytest
from typer.testing import CliRunner

from shapeverify.cli import app
from shapeverify.cli_errors import cli_hint, os_error_message

runner = CliRunner()


@pytest.fixture(autouse=True)
def _own_summary_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("SHAPEVERIFY_CACHE_DIR", str(tmp_path / "summary-cache"))


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """A small prepared model (the wavy panel at 3 mm spacing) and a scan of it (mm)."""
    from shapeverify.cad.examples import wavy_panel
    from shapeverify.io.points import write_ply
    from shapeverify.nearest import prepare

    d = tmp_path_factory.mktemp("robust-cli")
    prep = prepare(wavy_panel(), spacing=3.0)
    prep.save(d / "panel.svm")
    scan = prep.points.points[::2] + [0.3, -0.2, 0.1]
    write_ply(d / "scan.ply", scan)
    write_ply(d / "scan_in_m.ply", scan / 1000.0)
    return d


def _error_line(res) -> str:
    assert res.exit_code == 2, res.output
    assert "internal error" not in res.output and "Traceback" not in res.output, res.output
    lines = [ln for ln in res.output.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1, res.output
    return lines[0]


def test_non_utf8_file_name_is_shown_escaped_not_an_internal_error(tmp_path):
    # was: internal error UnicodeEncodeError (surrogates not allowed) from `info` and `inspect`
    p = os.path.join(os.fsencode(tmp_path), b"scan\xff\xfe.xyz")
    with open(p, "wb") as fh:
        fh.write(b"0 0 0\n1 0 0\n0 1 0\n1 1 0\n2 0 1\n0 2 1\n")
    res = runner.invoke(app, ["info", os.fsdecode(p)])
    assert res.exit_code == 0, res.output
    assert "scan\\xff\\xfe.xyz" in res.output
    res = runner.invoke(app, ["info", os.fsdecode(os.path.join(os.fsencode(tmp_path),
                                                               b"gone\xff.xyz"))])
    assert "gone\\xff.xyz: no such file" in _error_line(res)


def test_directory_given_as_the_model_says_directory(small, tmp_path):
    # was: "unsupported model file extension '(none)'"
    d = tmp_path / "folder"
    d.mkdir()
    line = _error_line(runner.invoke(app, ["inspect", str(d), str(small / "scan.ply"),
                                           "--tolerance", "0.2"]))
    assert "folder: is a directory; give a file" in line


def test_output_in_a_missing_folder_names_the_folder(small, tmp_path):
    # was: "nodir/x/r.json: no such file", as if an input were missing
    out = tmp_path / "nodir" / "x" / "r.json"
    line = _error_line(runner.invoke(app, ["inspect", str(small / "panel.svm"),
                                           str(small / "scan.ply"), "--tolerance", "0.2",
                                           "--json", str(out)]))
    assert f"the folder {out.parent} does not exist; create it" in line


def test_output_that_is_a_directory_says_give_a_file_name(small, tmp_path):
    # was: "[Errno 21] Is a directory: '...'"
    line = _error_line(runner.invoke(app, ["inspect", str(small / "panel.svm"),
                                           str(small / "scan.ply"), "--tolerance", "0.2",
                                           "--json", str(tmp_path)]))
    assert f"{tmp_path}: is a directory; give a file name" in line


def test_history_of_a_file_that_is_no_database_is_an_error_not_a_bug(tmp_path):
    # was: internal error ValueError (the history command did not sort input errors)
    p = tmp_path / "h.sqlite"
    p.write_bytes(b"this is not sqlite" * 100)
    line = _error_line(runner.invoke(app, ["history", "--db", str(p)]))
    assert "not an SQLite history database" in line


def test_plan_that_is_not_utf8_is_an_error_not_a_bug(small, tmp_path):
    # was: internal error UnicodeDecodeError
    plan = tmp_path / "plan.yaml"
    plan.write_bytes(b"\xff\xfe units: mm\n")
    line = _error_line(runner.invoke(app, ["inspect", str(small / "panel.svm"),
                                           str(small / "scan.ply"), "--plan", str(plan)]))
    assert "plan.yaml, line 1: not UTF-8 text" in line


@pytest.mark.parametrize("mode", ["identity", "principal-axes"])
def test_init_accepts_the_strategy_names_the_messages_suggest(small, mode):
    # was: "--init principal-axes" -> "principal-axes: no such file", though the registration's
    # message says "give a better init (e.g. init='principal-axes')"
    res = runner.invoke(app, ["inspect", str(small / "panel.svm"), str(small / "scan.ply"),
                              "--tolerance", "0.5", "--init", mode])
    assert res.exit_code in (0, 1, 3), res.output
    assert "verdict:" in res.output


def test_scale_mismatch_names_the_scan_unit_option(small):
    # was: only "multiply its coordinates by 1000", which a command-line user cannot do
    line = _error_line(runner.invoke(app, ["inspect", str(small / "panel.svm"),
                                           str(small / "scan_in_m.ply"), "--tolerance", "0.2"]))
    assert line.endswith("on the command line: --scan-unit m"), line
    res = runner.invoke(app, ["inspect", str(small / "panel.svm"), str(small / "scan_in_m.ply"),
                              "--tolerance", "0.2", "--scan-unit", "m"])
    assert res.exit_code in (0, 1), res.output          # with the option: inspected
    line = _error_line(runner.invoke(app, ["inspect", str(small / "panel.svm"),
                                           str(small / "scan.ply"), "--tolerance", "0.2",
                                           "--scan-unit", "m"]))
    assert "the scan was read in m (--scan-unit m): check that option" in line


@pytest.mark.parametrize("exc, text", [
    (PermissionError(errno.EACCES, "Permission denied", "/out/r.json"),
     "/out/r.json: permission denied; give a path you may read/write"),
    (OSError(errno.EROFS, "Read-only file system", "/mnt/r.json"),
     "/mnt/r.json: the file system is read-only; write the output to another folder"),
    (OSError(errno.ENOSPC, "No space left on device", "/tmp/r.html"),
     "/tmp/r.html: no space left on the device; free some space"),
    (IsADirectoryError(errno.EISDIR, "Is a directory", "out"), "out: is a directory"),
])
def test_file_system_errors_name_the_file_and_what_to_do(exc, text):
    # as root a read-only folder cannot be made in a test: the wording is checked directly
    assert os_error_message(exc).startswith(text)


def test_registration_advice_is_given_as_the_command_line_option():
    msg = ("only 0 scan points have a closest model point off the model's free boundary; give a "
           "better init (e.g. init='principal-axes') or check the model and units")
    assert "--init principal-axes" in cli_hint(msg)
    assert cli_hint("a message without advice") == ""


def test_point_cloud_of_1e30_coordinates_is_refused_by_prepare(tmp_path):
    # was: prepared (exit 0), the scale error came only at inspection
    p = tmp_path / "big.xyz"
    np.savetxt(p, np.random.default_rng(0).uniform(0, 100, (50, 3)) * 1e30)
    line = _error_line(runner.invoke(app, ["prepare", str(p), "-o", str(tmp_path / "b.svm")]))
    assert "all 50 points have coordinates beyond +-1e+12" in line


def test_fit_element_sphere_on_a_laser_scan_in_metres(shared_data, tmp_path):
    # was: no sphere fit on the command line (`fit` fitted a NURBS curve through the ball)
    import json

    src = shared_data / "scans" / "nist_tls_spheres" / "SPH101.xyz"
    out = tmp_path / "s.json"
    res = runner.invoke(app, ["fit", str(src), "-o", str(out), "--element", "sphere",
                              "--loss", "tukey", "--unit", "m"])
    assert res.exit_code == 0, res.output
    fit = json.loads(out.read_text())["fit"]
    assert fit["units"] == "mm" and fit["converged"]
    assert abs(fit["radius"] - 50.0) < 1.5 and fit["rms_inliers"] < 2.0
    from shapeverify import fitting
    from shapeverify.io.points import read_points

    ref = fitting.fit_sphere(read_points(src) * 1000.0, loss="tukey")
    assert fit["radius"] == ref.radius and fit["center"] == ref.center.tolist()


def test_fit_element_refuses_degenerate_points_and_wrong_options(tmp_path):
    p = tmp_path / "same.xyz"
    p.write_text("1 2 3\n" * 20)
    line = _error_line(runner.invoke(app, ["fit", str(p), "-o", str(tmp_path / "s.json"),
                                           "--element", "sphere"]))
    assert "all 20 points are the same point" in line
    line = _error_line(runner.invoke(app, ["fit", str(p), "-o", str(tmp_path / "s.step"),
                                           "--element", "plane"]))
    assert "a fitted plane is written as .json" in line
    line = _error_line(runner.invoke(app, ["fit", str(p), "-o", str(tmp_path / "s.json"),
                                           "--element", "torus"]))
    assert "unknown element 'torus'; use one of sphere, cylinder" in line


def test_info_of_a_cloud_in_metres_says_it_is_read_as_mm_and_names_the_option(tmp_path):
    # was: "size (diagonal) [mm] 0.247" without a word (the bunny views are in metres)
    p = tmp_path / "cloud.xyz"
    np.savetxt(p, np.random.default_rng(1).uniform(0.0, 0.15, (200, 3)))
    res = runner.invoke(app, ["info", str(p)])
    assert res.exit_code == 0, res.output
    text = " ".join(res.output.split())
    assert "carry no unit: read as mm" in text and "give --model-unit m" in text
    q = tmp_path / "part.xyz"
    np.savetxt(q, np.random.default_rng(1).uniform(0.0, 150.0, (200, 3)))
    assert "note:" not in runner.invoke(app, ["info", str(q)]).output


def test_a_named_pipe_is_refused_not_read_for_ever(tmp_path):
    # was: `info pipe.step` waited for ever (the summary cache hashed the FIFO)
    from shapeverify.cad.load import load_model
    from shapeverify.errors import CADImportError, ScanError
    from shapeverify.io.points import read_points

    for name in ("pipe.step", "pipe.ply"):
        os.mkfifo(tmp_path / name)
    line = _error_line(runner.invoke(app, ["info", str(tmp_path / "pipe.step")]))
    assert "pipe.step: is not a regular file (a pipe, socket or device)" in line
    with pytest.raises(CADImportError, match="is not a regular file"):
        load_model(tmp_path / "pipe.step")
    with pytest.raises(ScanError, match="is not a regular file"):
        read_points(tmp_path / "pipe.ply")


def test_model_and_scan_swapped_is_said_before_any_preparing(small):
    # was: the scan prepared as a model (seconds), then "unsupported point-cloud extension '.svm'"
    line = _error_line(runner.invoke(app, ["inspect", str(small / "scan.ply"),
                                           str(small / "panel.svm"), "--tolerance", "0.2"]))
    assert "panel.svm: is a model file, not a scan (the arguments seem swapped)" in line
    assert "Preparing" not in runner.invoke(app, ["inspect", str(small / "scan.ply"),
                                                  str(small / "panel.svm"),
                                                  "--tolerance", "0.2"]).output


def test_an_empty_mesh_given_as_the_scan_is_named(small, tmp_path):
    # a scanner's mesh is a scan (its vertices, issue 30); one with no triangles says so
    p = tmp_path / "scan.stl"
    p.write_text("solid s\nendsolid s\n")
    line = _error_line(runner.invoke(app, ["inspect", str(small / "panel.svm"), str(p),
                                           "--tolerance", "0.2"]))
    assert "scan.stl: ascii STL without any 'vertex' line" in line
