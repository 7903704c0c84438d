"""Fuzzing the CAD import: damaged copies of the bundled STEP/IGES files never crash the process.

Each mutant is one seeded damage of an undamaged file -- an entity line removed, a line
duplicated, a few bytes flipped, the file truncated, a reference pointed at an entity that does
not exist, a shell's face reference left dangling, a number replaced by NaN/INF/1.E+400/'*' -- read with ``shapeverify.load_model``.  What
may happen: the model loads (then it is finite, and a face the file declares but that could not
be read is counted in ``n_faces_in_file`` and named in a warning), or a
:class:`~shapeverify.errors.ShapeVerifyError` is raised (``CADImportError`` when OpenCASCADE
fails or even crashes: the crash is contained in the importer process).  Anything else -- another
exception, or this process dying -- fails the test.

The unmarked test runs one mutant per kind of damage of the example panel (STEP and IGES); the
slow one 6 per kind and file: 108 mutants with ``../shared/data/cad/wavy-cube.stp`` (when present).
The large run (``benchmarks/fuzz_cad.py``: info and prepare in a nice'd worker with a 2 GB limit,
restarted on crash, results in ``benchmarks/results_fuzz.md``) is checked here on 45 mutants
(slow) and runs in full with ``SHAPEVERIFY_FUZZ_LARGE=1``.
"""

from __future__ import annotations

import collections
import logging
import os
import re
from pathlib import Path

import numpy as np
import pytest

import shapeverify as sv
from shapeverify.cad import occ_worker
from shapeverify.cad.summary import read_summary
from shapeverify.errors import CADImportError, IncompleteModelError, ShapeVerifyError

pytest.importorskip("OCP")

WAVY_CUBE = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "cad" / "wavy-cube.stp"
SEED = 20261201


# ------------------------------------------------------------------------------- the damage
def _harness():
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "benchmarks" / "fuzz_cad.py"
    spec = importlib.util.spec_from_file_location("fuzz_cad", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


#: the damage shared with the large run (one implementation: benchmarks/fuzz_cad.py)
_FUZZ = _harness()
remove_entity_line, duplicate_line, flip_bytes, truncate, dangling_reference, dangling_face = (
    _FUZZ.remove_entity_line, _FUZZ.duplicate_line, _FUZZ.flip_bytes, _FUZZ.truncate,
    _FUZZ.dangling_reference, _FUZZ.dangling_face)


def bad_number(data: bytes, fmt: str, rng) -> bytes:
    """A real number of the geometry replaced by one outside the float range (issue 33 row 4:
    NaN and '*' made OpenCASCADE loop for ever; 9.99D+99 was read as 9.99)."""
    tokens = [b"NaN", b"1.E+400", b"-INF"] + ([b"*", b"9.99D+99"] if fmt == "step"
                                              else [b"1.0D+999"])
    tok = tokens[int(rng.integers(len(tokens)))]
    if fmt == "step":
        start = data.find(b"DATA;")
        # '*' only among the coordinates of a list (a point): elsewhere it is STEP's "omitted"
        after = rb"(?=,-?\d)" if tok == b"*" else rb"(?=[,)])"
        ms = [m for m in re.finditer(rb"(?<=[(,])-?\d+\.\d*(?:E[+-]?\d+)?" + after, data)
              if m.start() > start]
        m = ms[int(rng.integers(len(ms)))]
        return data[:m.start()] + tok + data[m.end():]
    lines = data.splitlines(keepends=True)
    cand = [(i, m) for i, ln in enumerate(lines) if ln[72:73] == b"P"
            for m in re.finditer(rb"(?<=[,;])-?\d*\.\d*(?:[ED][+-]?\d+)?(?=[,;])", ln[:64])
            if m.end() - m.start() >= len(tok)]
    i, m = cand[int(rng.integers(len(cand)))]
    ln = lines[i]
    lines[i] = ln[:m.start()] + tok.rjust(m.end() - m.start()) + ln[m.end():]
    return b"".join(lines)


DAMAGE = [remove_entity_line, duplicate_line, flip_bytes, truncate, dangling_reference,
          dangling_face, bad_number]


# ------------------------------------------------------------------------------- the files
@pytest.fixture(scope="module")
def sources(tmp_path_factory):
    """Undamaged files: the example panel as STEP and IGES (+ the shared wavy cube)."""
    from OCP.IGESControl import IGESControl_Writer

    from shapeverify.cad.examples import example_part_step, panel_shape

    d = tmp_path_factory.mktemp("fuzz-src")
    step = example_part_step(d / "panel.step")
    iges = d / "panel.igs"
    w = IGESControl_Writer("MM", 0)
    w.AddShape(panel_shape())
    w.ComputeModel()
    assert w.Write(str(iges))
    files = {"panel.step": step, "panel.igs": iges}
    if WAVY_CUBE.is_file():
        files["wavy-cube.stp"] = WAVY_CUBE
    return files


def _fuzz(sources, names, per_kind: int, tmp_path, monkeypatch, caplog):
    """Import every mutant; return a Counter of outcomes (and check each one)."""
    monkeypatch.setattr(occ_worker, "DEFAULT_TIMEOUT_S", 120.0)  # a hang fails, not blocks
    outcomes = collections.Counter()
    for fi, name in enumerate(names):
        src = Path(sources[name])
        fmt = "step" if src.suffix.lower() in (".step", ".stp") else "iges"
        data = src.read_bytes()
        clean = sv.load_model(src)
        assert clean.n_faces_in_file == len(clean.faces)  # undamaged: nothing missing
        for ki, damage in enumerate(DAMAGE):
            for j in range(per_kind):
                rng = np.random.default_rng([SEED, fi, ki, j])
                path = tmp_path / f"{src.stem}-{damage.__name__}-{j}{src.suffix}"
                path.write_bytes(damage(data, fmt, rng))
                caplog.clear()
                with caplog.at_level(logging.WARNING, logger="shapeverify"):
                    try:
                        model = sv.load_model(path)
                    except CADImportError as exc:
                        assert path.name in str(exc)
                        if damage is bad_number:
                            assert "not a finite number" in str(exc), str(exc)
                        outcomes["CADImportError (importer crashed)" if "crashed" in str(exc)
                                 else "CADImportError"] += 1
                        continue
                    except ShapeVerifyError as exc:
                        assert path.name in str(exc)
                        outcomes[type(exc).__name__] += 1
                        continue
                assert model.kind == "cad" and len(model.faces) >= 1
                assert np.isfinite(model.bounds).all(), path.name
                assert damage is not bad_number, (path.name, "a bad number was read")
                if damage is dangling_face:  # the face is gone: it must not go unnoticed
                    assert model.n_missing_faces >= 1, path.name
                if model.n_missing_faces:
                    assert len(model.skipped_faces) >= 1
                    assert any("were not loaded" in r.getMessage() for r in caplog.records)
                    # issue 33 row 2: `info` says so too, and prepare refuses the model
                    s = read_summary(path)
                    assert s.faces_in_file - s.faces >= 1 and s.missing, path.name
                    with pytest.raises(IncompleteModelError, match=re.escape(path.name)):
                        sv.prepare(model, spacing=model.size / 20)
                    outcomes["loaded, faces missing (warned)"] += 1
                else:
                    outcomes["loaded"] += 1
    return outcomes


def test_damaged_example_files_never_crash_the_process(sources, tmp_path, monkeypatch, caplog):
    out = _fuzz(sources, ["panel.step", "panel.igs"], 1, tmp_path, monkeypatch, caplog)
    assert sum(out.values()) == 2 * len(DAMAGE), out
    print(f"CAD fuzz: {dict(out)}")  # shown with -s


@pytest.mark.slow
def test_fuzz_many_mutants_only_shapeverify_errors(sources, tmp_path, monkeypatch, caplog):
    names = sorted(sources)
    out = _fuzz(sources, names, 6, tmp_path, monkeypatch, caplog)
    assert sum(out.values()) == 6 * len(DAMAGE) * len(names), out
    print(f"CAD fuzz: {sum(out.values())} mutants of {names}: {dict(out)}")  # shown with -s


# ------------------------------------------------------------------------------- the large run
def _assert_clean(r):
    bad = {k: v for k, v in r["per"].items()
           if any(w in k for w in ("PARENT", "BUG", "memory", "importer timeout", "importer hang"))}
    assert not bad, (bad, r["bugs"][:5])
    assert not r["wrong"], r["wrong"][:5]
    cpus = [t[4] for t in r["times"]]
    assert max(cpus) < 60.0, max(cpus)


@pytest.mark.slow
def test_fuzz_cad_harness_every_damage_through_info_and_prepare(tmp_path):
    """``benchmarks/fuzz_cad.py`` (the large run's harness): one mutant per damage and source
    file through ``info`` and ``prepare`` in its nice'd, memory-limited worker: no crash of
    the worker, no hang, no bug, nothing silently wrong."""
    fz = _FUZZ
    n = len(fz.DAMAGE) * 5
    r = fz.run(n, fz.SEED + 1, hang_s=300.0, mem_gb=2.0, nice=10, budget_s=None,
               workdir=tmp_path)
    assert r["n"] == n
    _assert_clean(r)


@pytest.mark.slow
@pytest.mark.skipif(os.environ.get("SHAPEVERIFY_FUZZ_LARGE") != "1",
                    reason="the large CAD fuzz run: set SHAPEVERIFY_FUZZ_LARGE=1 (hours of CPU "
                           "on a busy machine; SHAPEVERIFY_FUZZ_CAD_N mutants, default 10,000)")
def test_fuzz_cad_large_run(tmp_path):
    fz = _FUZZ
    n = int(os.environ.get("SHAPEVERIFY_FUZZ_CAD_N", "10000"))
    r = fz.run(n, fz.SEED, hang_s=60.0, mem_gb=2.0, nice=10, budget_s=None, workdir=tmp_path)
    fz.write_results(r, tmp_path / "results_fuzz.md", f"pytest (N={n})", fz.SEED, 60.0, 2.0)
    print((tmp_path / "results_fuzz.md").read_text())
    assert r["n"] == n
    _assert_clean(r)
