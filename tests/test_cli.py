"""The command line: every command's main path and its error messages and exit codes."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from shapeverify.cli import app

runner = CliRunner()


@pytest.fixture(autouse=True)
def _own_summary_cache(tmp_path, monkeypatch):
    """A fresh cache of ``info`` summaries per test (not the user's; every ``info`` reads)."""
    monkeypatch.setenv("SHAPEVERIFY_CACHE_DIR", str(tmp_path / "summary-cache"))


@pytest.fixture(scope="module")
def panel(tmp_path_factory):
    """The example panel as STEP and prepared .svm, plus a clean and a dented simulated scan."""
    from shapeverify.cad.examples import example_part_step
    from shapeverify.io.points import write_ply
    from shapeverify.simulate import ScanEffects, virtual_scan

    d = tmp_path_factory.mktemp("cli")
    step = example_part_step(d / "panel.step")
    res = runner.invoke(app, ["prepare", str(step), "-o", str(d / "panel.svm")])
    assert res.exit_code == 0, res.output
    from shapeverify.cad.load import load_model

    model = load_model(step)
    for name, dents in (("clean", ()), ("dented", [(0.4, 15.0)])):
        sim = virtual_scan(model, pixel=2.0, noise=0.02,
                           effects=ScanEffects(outlier_fraction=0.03, dents=dents),
                           motion=(2.0, 3.0), rng=11)
        write_ply(d / f"{name}.ply", sim.scan)
    return d


def test_info_prints_faces_and_units(panel):
    res = runner.invoke(app, ["info", str(panel / "panel.step")])
    assert res.exit_code == 0, res.output
    assert "faces" in res.output and "mm" in res.output


@pytest.mark.slow
def test_inspect_pass_fail_and_outputs(panel):
    out = panel / "out"
    out.mkdir()
    res = runner.invoke(app, ["inspect", str(panel / "panel.svm"), str(panel / "clean.ply"), "--tolerance", "0.2",
                              "--json", str(out / "clean.json"), "--db", str(out / "h.sqlite"), "--part", "A1"])
    assert res.exit_code == 0, res.output
    assert "PASS" in res.output
    data = json.loads((out / "clean.json").read_text())
    assert data["verdict"] == "pass"
    assert np.asarray(data["T_model_scan"]).shape == (4, 4)
    for key in ("rms", "iterations", "converged", "inlier_fraction"):
        assert key in data["registration"]
    for key in ("n", "mean", "std", "min", "max", "p05", "p95", "in_tolerance_fraction"):
        assert key in data["deviation"]
    assert "timings" in data and data["tolerance"]

    res = runner.invoke(app, ["inspect", str(panel / "panel.svm"), str(panel / "dented.ply"), "--tolerance", "0.2",
                              "--report", str(out / "r.html"), "--png", str(out / "r.png"),
                              "--colored", str(out / "r.ply"), "--db", str(out / "h.sqlite"), "--part", "A2"])
    assert res.exit_code == 1, res.output
    assert "FAIL" in res.output and "Regions (most severe first)" in res.output
    assert (out / "r.html").stat().st_size > 100_000  # plotly inlined: opens offline
    assert (out / "r.png").read_bytes()[:4] == b"\x89PNG"
    from shapeverify.io.points import read_ply_full

    ply = read_ply_full(out / "r.ply")
    assert "deviation" in ply.properties

    res = runner.invoke(app, ["history", "--db", str(out / "h.sqlite"), "--plot", str(out / "trend.png")])
    assert res.exit_code == 0, res.output
    assert "A1" in res.output and "A2" in res.output
    assert (out / "trend.png").exists()


@pytest.mark.parametrize("args,words", [
    (["inspect", "{svm}", "{missing}", "--tolerance", "0.2"], "no such file"),
    (["inspect", "{svm}", "{empty}", "--tolerance", "0.2"], "empty"),
    (["inspect", "{svm}", "{clean}"], "--tolerance"),
    (["inspect", "{svm}", "{metres}", "--tolerance", "0.2"], "metres"),
    (["info", "{bad_ext}"], "unsupported"),
    (["history", "--db", "{missing}"], "no such history"),
])
def test_errors_exit_2_with_a_message(panel, tmp_path, args, words):
    (tmp_path / "empty.xyz").write_text("")
    (tmp_path / "part.dwg").write_text("not a supported format")
    from shapeverify.io.points import read_points, write_ply

    write_ply(tmp_path / "metres.ply", read_points(panel / "clean.ply") / 1000.0)
    paths = {"svm": panel / "panel.svm", "missing": tmp_path / "nope.ply", "empty": tmp_path / "empty.xyz",
             "clean": panel / "clean.ply", "metres": tmp_path / "metres.ply", "bad_ext": tmp_path / "part.dwg"}
    res = runner.invoke(app, [a.format(**paths) for a in args])
    assert res.exit_code == 2, res.output
    assert words in res.output.lower().replace("\n", " ")


def test_unwrap_and_fit_commands(tmp_path):
    from shapeverify.phase import wrap

    y, x = np.mgrid[0:64, 0:80]
    phi = 0.002 * ((x - 40) ** 2 + (y - 30) ** 2)
    np.save(tmp_path / "psi.npy", wrap(phi))
    res = runner.invoke(app, ["unwrap", str(tmp_path / "psi.npy"), "-o", str(tmp_path / "phi.npy"),
                              "--plot", str(tmp_path / "phi.png")])
    assert res.exit_code == 0, res.output
    out = np.load(tmp_path / "phi.npy")
    k = (out - phi) / (2 * np.pi)
    assert np.allclose(k, np.round(k[0, 0]), atol=1e-9)

    t = np.linspace(0, 1, 300)
    pts = np.column_stack([100 * t, 20 * np.sin(4 * t), 5 * t ** 2])
    np.savetxt(tmp_path / "curve.xyz", pts)
    res = runner.invoke(app, ["fit", str(tmp_path / "curve.xyz"), "--ctrl", "12", "-o", str(tmp_path / "c.json")])
    assert res.exit_code == 0, res.output
    assert json.loads((tmp_path / "c.json").read_text())


# ------------------------------------------------------------------ errors are errors (exit 2)
def _error_lines(output: str) -> list[str]:
    return [ln for ln in output.splitlines() if "error:" in ln]


def _crashing_step(src, dst):
    """The example panel's STEP without the entity line of one pcurve: OpenCASCADE 8.0.1
    dereferences the missing line and dies with SIGSEGV."""
    lines = src.read_text().splitlines(keepends=True)
    drop = next(i for i, ln in enumerate(lines) if ln.startswith("#682 = LINE("))
    dst.write_text("".join(lines[:drop] + lines[drop + 1:]))
    return dst


@pytest.mark.parametrize("damage", ["bit flip", "truncated"])
@pytest.mark.parametrize("command", ["info", "inspect"])
def test_damaged_svm_is_one_error_line_naming_the_file_and_exit_2(panel, tmp_path, damage, command):
    data = bytearray((panel / "panel.svm").read_bytes())
    if damage == "bit flip":
        data[len(data) // 2] ^= 0x10
    else:
        data = data[: len(data) // 3]
    bad = tmp_path / "damaged.svm"
    bad.write_bytes(bytes(data))
    args = ["info", str(bad)] if command == "info" else [
        "inspect", str(bad), str(panel / "clean.ply"), "--tolerance", "0.2"]
    res = runner.invoke(app, args)
    assert res.exit_code == 2, res.output
    lines = _error_lines(res.output)
    assert len(lines) == 1, res.output
    assert "damaged.svm" in lines[0] and "shapeverify prepare" in lines[0]
    assert "internal error" not in res.output and "Traceback" not in res.output


@pytest.mark.slow  # 3.8 s of CPU with numba's cache warm (quick tests: under ~3 s)
def test_a_step_file_that_crashes_opencascade_is_exit_2_not_a_dead_process(panel, tmp_path):
    bad = _crashing_step(panel / "panel.step", tmp_path / "broken.step")
    res = runner.invoke(app, ["info", str(bad)])
    assert res.exit_code == 2, res.output
    lines = _error_lines(res.output)
    assert len(lines) == 1 and "broken.step" in lines[0] and "crashed" in lines[0], res.output
    res = runner.invoke(app, ["info", str(panel / "panel.step")])  # the importer comes back
    assert res.exit_code == 0, res.output


def test_an_unexpected_exception_is_an_internal_error_exit_2_traceback_with_verbose(
        panel, monkeypatch):
    import shapeverify.cad.summary

    def bug(path):
        return {}["no such key"]  # a bug, not a message about the input

    # what info reads a new file with (a CAD file's summary comes from OpenCASCADE alone)
    monkeypatch.setattr(shapeverify.cad.summary, "read_summary", bug)
    res = runner.invoke(app, ["info", str(panel / "panel.step")])
    assert res.exit_code == 2, res.output
    lines = _error_lines(res.output)
    assert len(lines) == 1 and lines[0].startswith("internal error: KeyError: 'no such key'")
    assert "please report it" in lines[0]
    assert "--verbose" in lines[0] and "Traceback" not in res.output
    res = runner.invoke(app, ["--verbose", "info", str(panel / "panel.step")])
    assert res.exit_code == 2
    assert "Traceback" in res.output and "in bug" in res.output


def test_a_valueerror_is_a_message_from_shapeverify_but_a_bug_from_elsewhere(panel, monkeypatch):
    res = runner.invoke(app, ["prepare", str(panel / "panel.step"), "-o", str(panel / "x.svm"),
                              "--spacing", "-1"])
    assert res.exit_code == 2, res.output
    assert _error_lines(res.output)[0].startswith("error: ") and "spacing" in res.output
    import shapeverify.cad.summary

    def numpy_bug(path):
        return np.zeros(3) + np.zeros(4)  # ValueError raised inside numpy: a bug

    monkeypatch.setattr(shapeverify.cad.summary, "read_summary", numpy_bug)
    res = runner.invoke(app, ["info", str(panel / "panel.step")])
    assert res.exit_code == 2
    assert _error_lines(res.output)[0].startswith("internal error: ValueError")
