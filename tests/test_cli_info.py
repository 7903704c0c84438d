"""``shapeverify info``: its summary equals the model's, comes from the content-keyed cache the
second time (no OpenCASCADE, no numba), and a damaged or stale entry is never shown."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from typer.testing import CliRunner

from shapeverify.cad import summary as S
from shapeverify.cli import app

runner = CliRunner()


def _python(*args):
    """Run this Python with ``args`` in a new process (output captured as text)."""
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, timeout=300)


@pytest.fixture()
def cache(tmp_path, monkeypatch):
    d = tmp_path / "cache"
    monkeypatch.setenv("SHAPEVERIFY_CACHE_DIR", str(d))
    return d


@pytest.fixture(scope="module")
def model(example_step):
    from shapeverify.cad.load import load_model

    return load_model(example_step)


def _counting_load(model, calls):
    def load(path):
        calls.append(path)
        return model
    return load


def test_summary_holds_the_models_figures(model):
    s = S.summarize(model)
    assert s.kind == "cad" and s.faces == len(model.faces)
    assert s.rational_faces == sum(f.surface.rational for f in model.faces)
    assert s.faces_with_holes == sum(len(f.loops) > 1 for f in model.faces)
    assert np.array_equal(np.array([s.lo, s.hi]), model.bounds) and s.size == model.size
    assert s.unit == model.unit and s.vertices is None


def test_second_summary_of_the_same_bytes_comes_from_the_cache(model, example_step, cache,
                                                               tmp_path):
    calls = []
    first, hit1 = S.cached_summary(example_step, _counting_load(model, calls))
    copy = tmp_path / "renamed.step"
    copy.write_bytes(example_step.read_bytes())
    second, hit2 = S.cached_summary(copy, _counting_load(model, calls))  # keyed by content
    assert (hit1, hit2) == (False, True) and len(calls) == 1
    assert second == first  # every float round-trips exactly (JSON repr)
    copy.write_bytes(example_step.read_bytes() + b"\n")  # other bytes: read again
    third, hit3 = S.cached_summary(copy, _counting_load(model, calls))
    assert not hit3 and len(calls) == 2 and third == first


@pytest.mark.parametrize("damage", ["garbage", "truncated", "wrong fields", "old stamp"])
def test_a_damaged_or_stale_entry_is_ignored_and_replaced(model, example_step, cache, damage):
    calls = []
    good, _ = S.cached_summary(example_step, _counting_load(model, calls))
    (entry,) = cache.glob("info-*.json")
    text = entry.read_text()
    entry.write_text({"garbage": "\x00not json",
                      "truncated": text[: len(text) // 2],
                      "wrong fields": json.dumps({"stamp": S._code_stamp(), "faces": "many"}),
                      "old stamp": text.replace(S._code_stamp(), "0" * 16)}[damage])
    again, hit = S.cached_summary(example_step, _counting_load(model, calls))
    assert not hit and again == good and len(calls) == 2
    assert S.cached_summary(example_step, _counting_load(model, calls)) == (good, True)


def test_an_unwritable_cache_costs_only_the_speed_up(model, example_step, tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("a file where the cache directory would be")
    monkeypatch.setenv("SHAPEVERIFY_CACHE_DIR", str(blocker / "cache"))
    calls = []
    for _ in range(2):
        s, hit = S.cached_summary(example_step, _counting_load(model, calls))
        assert not hit and s == S.summarize(model)
    assert len(calls) == 2


def test_info_prints_the_same_table_from_the_cache_without_importing(example_step, cache,
                                                                       monkeypatch):
    first = runner.invoke(app, ["info", str(example_step)])
    assert first.exit_code == 0, first.output
    import shapeverify.cad.load
    import shapeverify.cad.summary

    def no_import(path):
        raise AssertionError("the cached summary must not read the file again")

    monkeypatch.setattr(shapeverify.cad.load, "load_model", no_import)
    monkeypatch.setattr(shapeverify.cad.summary, "read_summary", no_import)
    second = runner.invoke(app, ["info", str(example_step)])
    assert second.exit_code == 0, second.output
    table = lambda out: out[out.index("┌"):]  # noqa: E731  (the stage line's duration differs)
    assert table(second.output) == table(first.output)
    assert "faces" in second.output and "size (diagonal)" in second.output


@pytest.mark.slow
def test_info_of_a_step_file_imports_neither_numba_nor_scipy_in_the_caller(example_step, cache):
    """numba (~1.3 s) and scipy run only in the importer process; the caller only prints."""
    code = ("import sys\nfrom shapeverify.cli import app\n"
            "try:\n    app(['info', sys.argv[1]], standalone_mode=False)\n"
            "finally:\n    print('LOADED', sorted(m for m in ('numba', 'scipy', 'OCP') "
            "if m in sys.modules))\n")
    res = _python("-c", code, str(example_step))
    assert res.returncode == 0, res.stderr
    assert "LOADED []" in res.stdout and "faces" in res.stdout


def test_info_model_unit_scales_a_unitless_cloud_and_refuses_cad(tmp_path):
    # info had no --model-unit: a bunny in metres showed as a 0.247 mm part, with no way to
    # see its size in mm before preparing it
    import numpy as np
    from typer.testing import CliRunner

    from shapeverify.cli import app

    pts = np.random.default_rng(0).random((300, 3)) * [0.2, 0.1, 0.05]
    p = tmp_path / "cloud.xyz"
    np.savetxt(p, pts)
    run = CliRunner()
    plain = run.invoke(app, ["info", str(p)])
    metres = run.invoke(app, ["info", str(p), "--model-unit", "m"])
    again = run.invoke(app, ["info", str(p)])          # the cache holds the file's own figures
    size = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    assert plain.exit_code == metres.exit_code == again.exit_code == 0
    assert f"{size:.3f}" in plain.output and f"{size * 1000:.3f}" in metres.output
    assert "x1000 to mm" in metres.output and f"{size:.3f}" in again.output
    assert "note:" in plain.output and "note:" not in metres.output


def test_info_of_a_new_cad_file_starts_the_importer_before_parsing(example_step, cache, tmp_path):
    """cli_start.early_importer: ``info`` of a CAD file not in the cache starts the importer
    (for a summary: no numba) before typer parses; a cached file, another command, or a
    non-CAD file start nothing."""
    from shapeverify.cad import occ_worker
    from shapeverify.cli_start import early_importer

    occ_worker.shutdown(kill=True)
    early_importer(["prepare", str(example_step), "-o", "x.svm"])
    early_importer(["--verbose", "info", str(tmp_path / "missing.step")])
    early_importer(["info", str(tmp_path)])
    assert occ_worker._CURRENT is None
    early_importer(["--verbose", "info", "--model-unit", "mm", str(example_step)])
    assert occ_worker._CURRENT is not None and "--summary" in occ_worker._CURRENT.proc.args
    occ_worker.shutdown(kill=True)
    S.cached_summary(example_step, lambda p: S.read_summary(p))  # now cached
    occ_worker.shutdown(kill=True)
    early_importer(["info", str(example_step)])
    assert occ_worker._CURRENT is None
    early_importer(["info", "--features", str(example_step)])  # the full import: numba ahead
    assert occ_worker._CURRENT is not None and "--summary" not in occ_worker._CURRENT.proc.args
    occ_worker.shutdown(kill=True)


@pytest.mark.slow
def test_the_command_starts_the_importer_before_it_imports_typer(example_step, cache):
    """``shapeverify`` (``cli_start.main``, also ``python -m shapeverify``) starts the importer of
    a new file's ``info`` before typer and rich are imported (~0.2 s the importer's start used
    to wait for), and answers as ``python -m shapeverify.cli`` does."""
    code = ("import sys, shapeverify.cli_start as s\n"
            "from shapeverify.cad import occ_worker\n"
            "seen = []\n"
            "real = occ_worker.prestart\n"
            "def spy(*a, **kw):\n    seen.append('typer' in sys.modules)\n    real(*a, **kw)\n"
            "occ_worker.prestart = spy\n"
            "sys.argv = ['shapeverify', 'info', sys.argv[1]]\n"
            "try:\n    s.main()\n"
            "except SystemExit as e:\n    print('EXIT', e.code)\n"
            "print('TYPER BEFORE THE IMPORTER', seen)\n")
    res = _python("-c", code, str(example_step))
    assert res.returncode == 0, res.stderr
    assert "TYPER BEFORE THE IMPORTER [False" in res.stdout, res.stdout
    assert "EXIT 0" in res.stdout and "faces" in res.stdout
    plain = _python("-m", "shapeverify", "--help")
    assert plain.returncode == 0 and "inspect" in plain.stdout
