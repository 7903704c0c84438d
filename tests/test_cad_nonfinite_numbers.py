"""Issue 33 row 4: a STEP/IGES file with a number outside the float range never hangs.

Before: a ``NaN`` or ``*`` among a point's coordinates kept OpenCASCADE busy for ever (measured:
over 60 s, killed; the audit: over 900 s), and the importer child had no default time limit;
``9.99D+99`` loaded silently as 9.99.  Now :mod:`shapeverify.cad.number_check` refuses the file
before OpenCASCADE sees it, naming the file, the line and the token, and the importer has a
default time limit that grows with the file's size.
"""

from __future__ import annotations

import re
import time

import numpy as np
import pytest

import shapeverify as sv
from shapeverify.cad import occ_worker
from shapeverify.cad.number_check import check_numbers
from shapeverify.errors import CADImportError

pytest.importorskip("OCP")

BAD = [b"NaN", b"*", b"1.E+400", b"9.99D+99", b"-INF"]


def _with_token(data: bytes, token: bytes) -> bytes:
    """The first coordinate of the first CARTESIAN_POINT with three coordinates -> token."""
    m = re.search(rb"CARTESIAN_POINT\s*\(\s*'[^']*'\s*,\s*\(\s*([^,()]+),[^,()]+,[^,()]+\)",
                  data)
    return data[:m.start(1)] + token + data[m.end(1):]


@pytest.mark.parametrize("token", BAD, ids=lambda t: t.decode())
def test_row4_step_point_with_nonfinite_number_is_refused_fast(example_step, tmp_path, token):
    path = tmp_path / "panel-bad.step"
    path.write_bytes(_with_token(example_step.read_bytes(), token))
    line = path.read_bytes()[:path.read_bytes().find(token)].count(b"\n") + 1
    t0 = time.perf_counter()
    with pytest.raises(CADImportError) as err:
        sv.load_model(path)
    msg = str(err.value)
    assert "panel-bad.step" in msg and f"line {line}" in msg and token.decode() in msg
    assert "not a finite number" in msg
    # `info` (the OpenCASCADE-only summary) refuses it as well
    from shapeverify.cad.summary import read_summary
    with pytest.raises(CADImportError, match="not a finite number"):
        read_summary(path)
    assert time.perf_counter() - t0 < 10.0


@pytest.mark.parametrize("token", [b"NaN", b"*", b"1.E+400", b"9.99D+99"],
                         ids=lambda t: t.decode())
def test_row4_wavy_cube_with_nonfinite_number_via_cli_info(shared_data, tmp_path, token):
    from typer.testing import CliRunner

    from shapeverify.cli import app

    path = tmp_path / "cube.stp"
    path.write_bytes(_with_token((shared_data / "cad" / "wavy-cube.stp").read_bytes(), token))
    t0 = time.perf_counter()
    res = CliRunner().invoke(app, ["info", str(path)])
    assert res.exit_code == 2, res.output
    assert "cube.stp" in res.output and "not a finite number" in res.output
    assert time.perf_counter() - t0 < 10.0


@pytest.mark.parametrize("token", [b"NaN", b"1.0D+400", b"-1.E999"], ids=lambda t: t.decode())
def test_row4_iges_parameter_with_nonfinite_number_is_refused(shared_data, tmp_path, token):
    lines = (shared_data / "cad" / "hammer.iges").read_bytes().splitlines(keepends=True)
    # the first parameter line of a B-spline surface (type 128): replace its last real
    i = next(k for k, ln in enumerate(lines) if ln[72:73] == b"P" and ln.startswith(b"128,"))
    body = lines[i][:64]
    m = list(re.finditer(rb"(?<=,)[^,;]+(?=,)", body))[-1]
    new = (body[:m.start()] + token + body[m.end():]).ljust(64)[:64]
    assert len(new) == 64, "the token does not fit the line"
    lines[i] = new + lines[i][64:]
    path = tmp_path / "hammer-bad.iges"
    path.write_bytes(b"".join(lines))
    with pytest.raises(CADImportError) as err:
        sv.load_model(path)
    assert "hammer-bad.iges" in str(err.value) and f"line {i + 1}" in str(err.value)
    assert token.decode() in str(err.value)


def test_row4_no_false_alarm_on_real_files_and_strings(shared_data, example_step, tmp_path):
    """Every undamaged file passes; the same words inside STEP strings, tiny exponents that
    underflow to 0, and ORIENTED_EDGE's '*' are not refused."""
    files = sorted((shared_data / "cad").rglob("*.st*p")) + sorted(
        (shared_data / "cad").glob("*.ig*s")) + [example_step]
    for f in files:
        check_numbers(f, "iges" if f.suffix.lower() in (".igs", ".iges") else "step")
    data = example_step.read_bytes()
    odd = data.replace(b"DATA;", b"DATA;\n#999999 = PRODUCT('NaN,*,1.E+400','(INF)',"
                       b"'9.99D+99; #1=(1.,*,2.)',());\n#999998 = CARTESIAN_POINT('',"
                       b"(1.E-400,0.,0.));", 1)
    path = tmp_path / "odd.step"
    path.write_bytes(odd)
    check_numbers(path, "step")


@pytest.mark.slow
def test_row4_number_scan_is_linear_and_fast_on_a_large_file(shared_data, tmp_path):
    """About 20 MB of real STEP text (the NIST parts repeated) in well under a second of CPU
    per 10 MB (measured: 1.3 s CPU for 55 MB on the shared 2-core machine)."""
    parts = b"".join(p.read_bytes() for p in sorted((shared_data / "cad" / "nist").glob("*.stp")))
    data = parts * max(1, int(20e6 // len(parts)))
    t0 = time.process_time()
    check_numbers(tmp_path / "big.stp", "step", data)
    cpu = time.process_time() - t0
    assert cpu < 0.2 * len(data) / 1e6, f"{cpu:.2f} s CPU for {len(data) / 1e6:.0f} MB"
    bad = data + b"#9999999 = CARTESIAN_POINT('',(0.,NaN,0.));\n"
    with pytest.raises(CADImportError, match="NaN"):
        check_numbers(tmp_path / "big.stp", "step", bad)


def test_row4_importer_has_a_default_time_limit_that_grows_with_size(tmp_path, monkeypatch,
                                                                      example_step):
    monkeypatch.delenv(occ_worker.TIME_LIMIT_ENV, raising=False)
    small, how = occ_worker.default_time_limit(example_step)
    size_mb = example_step.stat().st_size / 1e6
    assert small == pytest.approx(occ_worker.TIME_LIMIT_BASE_S
                                  + occ_worker.TIME_LIMIT_PER_MB_S * size_mb)
    assert "MB" in how and occ_worker.TIME_LIMIT_ENV in how
    big = tmp_path / "big.step"
    with open(big, "wb") as fh:
        fh.truncate(50_000_000)
    assert occ_worker.default_time_limit(big)[0] == pytest.approx(
        occ_worker.TIME_LIMIT_BASE_S + 50 * occ_worker.TIME_LIMIT_PER_MB_S)
    monkeypatch.setenv(occ_worker.TIME_LIMIT_ENV, "0")
    assert occ_worker.default_time_limit(example_step)[0] is None
    monkeypatch.setenv(occ_worker.TIME_LIMIT_ENV, "soon")
    with pytest.raises(ValueError, match=occ_worker.TIME_LIMIT_ENV):
        occ_worker.default_time_limit(example_step)


@pytest.mark.slow
def test_row4_time_limit_hit_is_a_clear_error(example_step, monkeypatch):
    """A limit far below the import's time: the importer is stopped, the message says which
    limit and how to change it; the next import works again."""
    occ_worker.shutdown()
    monkeypatch.setenv(occ_worker.TIME_LIMIT_ENV, "0.05")
    with pytest.raises(CADImportError) as err:
        sv.load_model(example_step)  # a fresh importer needs ~1 s just to start
    msg = str(err.value)
    assert "did not finish within 0.05 s" in msg and occ_worker.TIME_LIMIT_ENV in msg
    assert "panel.step" in msg
    monkeypatch.delenv(occ_worker.TIME_LIMIT_ENV)
    model = sv.load_model(example_step)
    assert len(model.faces) == 1 and np.isfinite(model.bounds).all()
