"""Packaging (issue 16): the library core does not need the front ends' dependencies, and a
front end whose extra is missing says which one to install."""

from __future__ import annotations

import subprocess
import sys

from typer.testing import CliRunner


def test_core_inspection_imports_no_service_or_batch_dependency():
    code = ("import sys, shapeverify, shapeverify.inspection, shapeverify.registration, "
            "shapeverify.nearest, shapeverify.report.html, shapeverify.cli; "
            "bad = [m for m in ('fastapi', 'uvicorn', 'distributed', 'dask') if m in sys.modules]; "
            "print(','.join(bad))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == ""


def test_missing_extra_names_the_install_command(monkeypatch, tmp_path):
    import importlib.util

    from shapeverify.cli import app

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name in ("fastapi", "distributed") else real(name, *a))
    svm = tmp_path / "m.svm"
    svm.write_bytes(b"x")
    r = CliRunner().invoke(app, ["serve", str(svm)])
    assert r.exit_code == 2 and "pip install 'shapeverify[service]'" in r.output
    r = CliRunner().invoke(app, ["batch", str(svm), str(tmp_path), "--out", str(tmp_path / "o"),
                                 "--tolerance", "0.2"])
    assert r.exit_code == 2 and "pip install 'shapeverify[batch]'" in r.output
