"""Batch inspection on Dask distributed (issue 9): a LocalCluster with 2 workers over a small folder."""

from __future__ import annotations

import csv
import json
import sqlite3

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """A prepared example panel and a folder of small simulated scans in several formats, one
    of them dented, one corrupt, plus a file that is not a scan."""
    from shapeverify.cad.examples import example_part_step
    from shapeverify.cad.load import load_model
    from shapeverify.io.points import write_ply
    from shapeverify.nearest import prepare
    from shapeverify.simulate import ScanEffects, virtual_scan

    d = tmp_path_factory.mktemp("batch")
    model = load_model(example_part_step(d / "panel.step"))
    prep = prepare(model, spacing=2.0)
    prep.save(d / "panel.svm")
    scans = d / "scans"
    scans.mkdir()
    truth = {}
    for i, (name, dents) in enumerate([("a_clean", ()), ("b_clean", ()), ("c_dented", [(0.6, 20.0)])]):
        sim = virtual_scan(model, pixel=4.0, noise=0.02,
                           effects=ScanEffects(dents=dents), motion=(1.5, 2.0), rng=10 + i)
        assert 1000 < len(sim.scan) < 8000
        if i == 0:
            np.save(scans / f"{name}.npy", sim.scan)
        elif i == 1:
            write_ply(scans / f"{name}.ply", sim.scan)
        else:
            np.savetxt(scans / f"{name}.xyz", sim.scan, fmt="%.6f")
        truth[name] = "fail" if dents else "pass"
    (scans / "d_corrupt.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 999999999999\n"
                                          b"property float x\nproperty float y\nproperty float z\nend_header\n\0\0")
    truth["d_corrupt"] = "error"
    (scans / "notes.md").write_text("not a scan")
    return d, truth


def _rows(db):
    con = sqlite3.connect(db)
    try:
        return con.execute("select id, part, verdict, result_json from inspections order by id").fetchall()
    finally:
        con.close()


@pytest.fixture(scope="module")
def first_run(folder):
    """One batch run on a fresh LocalCluster with 2 workers (started and closed by run_batch)."""
    from shapeverify.batch import run_batch

    d, _ = folder
    out, db = d / "out", d / "history.sqlite"
    seen = []
    s = run_batch(d / "panel.svm", d / "scans", out, {"tolerance": 0.3}, workers=2, db_path=db,
                  progress=lambda done, total, name: seen.append((done, total, name)))
    return out, db, s, seen


def test_batch_local_cluster_resumable(folder, first_run):
    from shapeverify.batch import run_batch

    d, truth = folder
    out, db, s, seen = first_run
    assert (s.total, s.skipped, s.passed, s.failed, s.errors) == (4, 0, 2, 1, 1)
    assert sorted(n for _, _, n in seen) == sorted(p.name for p in (d / "scans").iterdir() if p.suffix != ".md")
    assert [x[0] for x in seen] == [1, 2, 3, 4] and all(x[1] == 4 for x in seen)

    results = {stem: json.loads((out / f"{stem}.json").read_text()) for stem in truth}
    assert {k: r["verdict"] for k, r in results.items()} == truth
    err = results["d_corrupt"]["error"]
    assert err.startswith("ScanError: d_corrupt.ply: truncated PLY") and "11999999999988 bytes" in err
    for stem in ("a_clean", "b_clean", "c_dented"):
        r = results[stem]
        assert r["registration"]["rms"] < 0.1 and abs(r["deviation"]["mean"]) < 0.05
    assert results["c_dented"]["deviation"]["min"] < -0.3 and len(results["c_dented"]["regions"]) >= 1

    with open(s.summary_csv, newline="") as fh:
        table = list(csv.DictReader(fh))
    assert [r["scan"] for r in table] == ["a_clean.npy", "b_clean.ply", "c_dented.xyz", "d_corrupt.ply"]
    assert {r["scan"].split(".")[0]: r["verdict"] for r in table} == truth
    assert float(table[2]["min_mm"]) == pytest.approx(results["c_dented"]["deviation"]["min"])

    rows = _rows(db)  # one history row per scan, errors included, ids as in the JSONs
    assert sorted((r[1], r[2]) for r in rows) == sorted(truth.items())
    assert {r[1]: r[0] for r in rows} == {k: v["record_id"] for k, v in results.items()}

    # a second run skips everything: no cluster, no new rows, files untouched
    mtimes = {p.name: p.stat().st_mtime_ns for p in out.glob("*.json")}
    s2 = run_batch(d / "panel.svm", d / "scans", out, {"tolerance": 0.3}, workers=2, db_path=db)
    assert (s2.total, s2.skipped, s2.passed, s2.failed, s2.errors) == (4, 4, 2, 1, 1)
    assert len(_rows(db)) == 4
    assert {p.name: p.stat().st_mtime_ns for p in out.glob("*.json")} == mtimes

    # interrupted after the history row but before the JSON: recovered from the row, not re-run
    (out / "b_clean.json").unlink()
    s3 = run_batch(d / "panel.svm", d / "scans", out, {"tolerance": 0.3}, workers=2, db_path=db)
    assert s3.skipped == 4 and len(_rows(db)) == 4
    assert json.loads((out / "b_clean.json").read_text())["record_id"] == results["b_clean"]["record_id"]


def test_batch_on_existing_scheduler_ships_model_once(folder, tmp_path):
    """The same code path against a running cluster: the model is loaded once per worker, and
    --retry-errors re-runs only the failed scan."""
    from distributed import Client, LocalCluster

    import shapeverify.batch as batch

    d, truth = folder
    out = tmp_path / "out"
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        s = batch.run_batch(d / "panel.svm", d / "scans", out, {"tolerance": 0.3}, workers=cluster.scheduler_address)
        assert (s.passed, s.failed, s.errors) == (2, 1, 1)
        loaded = client.run(lambda: {k: id(v) for k, v in __import__("shapeverify.batch").batch._WORKER_MODELS.items()})
        assert all(len(m) <= 1 for m in loaded.values()) and sum(len(m) for m in loaded.values()) >= 1
        before = {stem: (out / f"{stem}.json").stat().st_mtime_ns for stem in truth}
        s2 = batch.run_batch(d / "panel.svm", d / "scans", out, {"tolerance": 0.3},
                             workers=cluster.scheduler_address, retry_errors=True)
        assert s2.skipped == 3 and s2.errors == 1
        after = {stem: (out / f"{stem}.json").stat().st_mtime_ns for stem in truth}
        assert [k for k in truth if after[k] != before[k]] == ["d_corrupt"]
        again = client.run(lambda: {k: id(v) for k, v in __import__("shapeverify.batch").batch._WORKER_MODELS.items()})
        for w, m in loaded.items():  # a worker that had the model loaded kept the same object
            assert all(again[w][k] == v for k, v in m.items())


def test_batch_cli_and_bad_arguments(folder, first_run, tmp_path):
    from typer.testing import CliRunner

    from shapeverify.batch import run_batch
    from shapeverify.cli import app

    d, _ = folder
    with pytest.raises(FileNotFoundError, match="prepared model"):
        run_batch(d / "missing.svm", d / "scans", tmp_path / "o", {"tolerance": 0.2})
    with pytest.raises(ValueError, match="no scan files"):
        empty = tmp_path / "empty"
        empty.mkdir()
        run_batch(d / "panel.svm", empty, tmp_path / "o", {"tolerance": 0.2})
    with pytest.raises(ValueError, match="tolerance"):
        run_batch(d / "panel.svm", d / "scans", tmp_path / "o", {"tolerance": 0})
    # the CLI over a folder whose results exist: nothing to do, exit code 2 (one scan is an error)
    out = first_run[0]
    r = CliRunner().invoke(app, ["batch", str(d / "panel.svm"), str(d / "scans"), "--out", str(out),
                                 "--tolerance", "0.3"])
    assert r.exit_code == 2, r.output
    assert "4 scans (4 already done): 2 pass, 1 fail, 0 incomplete, 1 error" in r.output


def test_retry_errors_replaces_the_scans_history_row(folder, tmp_path):
    """A scan that failed to read, fixed and retried with --retry-errors: its one history row is
    overwritten (same id), not joined by a second one."""
    import shutil

    from distributed import LocalCluster

    from shapeverify.batch import run_batch

    d, _ = folder
    scans = tmp_path / "scans"
    scans.mkdir()
    shutil.copy(d / "scans" / "a_clean.npy", scans / "a_clean.npy")
    shutil.copy(d / "scans" / "d_corrupt.ply", scans / "d_corrupt.ply")
    out, db = tmp_path / "out", tmp_path / "h.sqlite"
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address=None) as cluster:
        s1 = run_batch(d / "panel.svm", scans, out, {"tolerance": 0.3}, db_path=db,
                       workers=cluster.scheduler_address)
        assert (s1.passed, s1.errors, s1.internal_errors) == (1, 1, 0)
        first = {part: (rid, verdict) for rid, part, verdict, _ in _rows(db)}
        assert first["d_corrupt"][1] == "error"
        # the scan is fixed (a good file under the same name) and retried
        np.savetxt(scans / "d_corrupt.xyz", np.load(scans / "a_clean.npy"), fmt="%.6f")
        (scans / "d_corrupt.ply").unlink()
        s2 = run_batch(d / "panel.svm", scans, out, {"tolerance": 0.3}, db_path=db, retry_errors=True,
                       workers=cluster.scheduler_address)
    assert (s2.skipped, s2.passed, s2.errors) == (1, 2, 0)
    rows = _rows(db)
    assert len(rows) == 2 and sorted(r[1] for r in rows) == ["a_clean", "d_corrupt"]
    retried = next(r for r in rows if r[1] == "d_corrupt")
    assert retried[0] == first["d_corrupt"][0] and retried[2] == "pass"
    assert json.loads(retried[3])["scan"] == "d_corrupt.xyz"
    assert json.loads((out / "d_corrupt.json").read_text())["record_id"] == retried[0]


def test_only_shapeverify_errors_are_scan_errors_a_bug_is_marked_internal(folder, monkeypatch):
    import hashlib

    import shapeverify.inspection
    from shapeverify.batch import inspect_bytes
    from shapeverify.options import InspectionOptions

    d, _ = folder
    svm = (d / "panel.svm").read_bytes()
    digest = hashlib.sha256(svm).hexdigest()
    scan = (d / "scans" / "a_clean.npy").read_bytes()
    bad = inspect_bytes(svm, digest, "d_corrupt.ply", (d / "scans" / "d_corrupt.ply").read_bytes(),
                        InspectionOptions(tolerance=0.3), False)
    assert bad["verdict"] == "error" and "internal_error" not in bad
    assert bad["error"].startswith("ScanError")

    def bug(*a, **k):
        raise TypeError("unsupported operand type(s)")

    monkeypatch.setattr(shapeverify.inspection, "inspect", bug)
    res = inspect_bytes(svm, digest, "a_clean.npy", scan, InspectionOptions(tolerance=0.3), False)
    assert res["verdict"] == "error" and res["internal_error"] is True
    assert res["error"].startswith("internal error (a bug in shapeverify")
    assert "TypeError: unsupported operand" in res["error"] and "in bug" in res["traceback"]
