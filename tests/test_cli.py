"""The command line: every command's main path and its error messages and exit codes."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from shapeverify.cli import app

runner = CliRunner()


@pytest.fixture(scope="module")
def panel(tmp_path_factory):
    """The example panel as STEP and prepared .svm, plus a clean and a dented simulated scan."""
    from shapeverify.cad.examples import example_part_step
    from shapeverify.io.points import write_ply
    from shapeverify.simulate import virtual_scan

    d = tmp_path_factory.mktemp("cli")
    step = example_part_step(d / "panel.step")
    res = runner.invoke(app, ["prepare", str(step), "-o", str(d / "panel.svm")])
    assert res.exit_code == 0, res.output
    from shapeverify.cad.load import load_model

    model = load_model(step)
    for name, dents in (("clean", ()), ("dented", [(0.4, 15.0)])):
        sim = virtual_scan(model, pixel=2.0, noise=0.02, outlier_fraction=0.03, dents=dents,
                           motion=(2.0, 3.0), rng=11)
        write_ply(d / f"{name}.ply", sim.scan)
    return d


def test_info_prints_faces_and_units(panel):
    res = runner.invoke(app, ["info", str(panel / "panel.step")])
    assert res.exit_code == 0, res.output
    assert "faces" in res.output and "mm" in res.output


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
    assert "FAIL" in res.output and "Defect regions" in res.output
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
