"""pytest set-up for the docstring examples of ``src/shapeverify`` (``--doctest-modules``).

It lives at the repository root because pytest applies a conftest only to the files below it, and
the doctests are collected from ``src/shapeverify`` as well as ``tests/``.

* A module that needs an optional extra which is not installed (``service``: FastAPI, uvicorn;
  ``batch``: Dask distributed) is skipped with the reason, instead of failing to import.
* Every doctest runs in a fresh temporary directory, so examples that write ``history.sqlite``,
  ``plan.yaml`` or ``part.svm`` leave nothing behind.
* ``np`` is in every doctest's namespace; anything else an example uses it builds itself, from
  the small built-in fixtures of :mod:`shapeverify.examples_data` (no files, no +SKIP).
"""

from __future__ import annotations

import importlib
import os
from pathlib import Path

import pytest

_SRC = Path(__file__).resolve().parent / "src"

# The command line's Rich consoles are made at import and fix their width from COLUMNS/LINES
# when these are set (pytest-xdist's workers have COLUMNS=80): the tests that give a CliRunner
# its own COLUMNS would then get 80 columns and numbers cut to "…".  Without them, the width is
# read at each print, as in one pytest process.
for _name in ("COLUMNS", "LINES"):
    os.environ.pop(_name, None)
#: top-level import name -> the extra that provides it
_OPTIONAL = {"fastapi": "service", "starlette": "service", "uvicorn": "service",
             "httptools": "service", "uvloop": "service", "distributed": "batch", "dask": "batch"}


def _module_name(path: Path) -> str | None:
    try:
        rel = path.resolve().relative_to(_SRC)
    except ValueError:
        return None
    parts = list(rel.with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    """Turn the import failure of a module whose optional extra is missing into a skip."""
    name = (_module_name(Path(collector.path)) if isinstance(collector, pytest.Module)
            or type(collector).__name__ == "DoctestModule" else None)
    if name:
        try:
            importlib.import_module(name)
        except Exception as exc:  # noqa: BLE001 - any other failure: pytest reports it as usual
            top = ((exc.name or "") if isinstance(exc, ModuleNotFoundError) else "").split(".")[0]
            if top in _OPTIONAL:
                from _pytest.reports import CollectReport

                reason = (f"{name} needs the '{_OPTIONAL[top]}' extra ({top} is not installed: "
                          f"pip install 'shapeverify[{_OPTIONAL[top]}]')")
                outcome = yield
                outcome.force_result(CollectReport(collector.nodeid, "skipped",
                                                   (str(collector.path), 0, f"Skipped: {reason}"),
                                                   []))
                return
    yield


@pytest.fixture(autouse=True)
def _doctest_in_tmpdir(request, tmp_path, doctest_namespace):
    """Doctests run in their own temporary directory (tests keep the working directory)."""
    if type(request.node).__name__ != "DoctestItem":
        yield
        return
    import numpy as np

    doctest_namespace["np"] = np
    old = os.getcwd()
    os.chdir(tmp_path)
    try:
        yield
    finally:
        os.chdir(old)


#: Test files that take minutes or close to a minute (NIST parts imported and prepared, the
#: README's examples, the warm-up's test), about longest first (the fresh clone's
#: ``--durations=40`` of 2026-12-07: test_nist_extra_plans.py, over 210 s, was handed out in
#: alphabetical order; test_warmup_coverage.py, 248 s then, is about 35 s with make's warm-up
#: snapshot): collected first, so that under ``make
#: test`` (pytest-xdist, ``--dist loadfile --no-loadscope-reorder``: whole files handed out in
#: collection order) they start at once on the workers instead of last, where one of them would
#: leave the other cores idle at the end.  (Without ``--no-loadscope-reorder`` xdist hands out
#: the files with the most tests first, whatever this order, and these files have few tests.)
#: The order of the rest is unchanged; in one process the order makes no difference to the
#: results.
LONG_FILES = ("test_nist_extra_plans.py", "test_datum_targets_nist.py", "test_nearest_exact.py",
              "test_features_nist.py", "test_pmi.py", "test_plan_nist.py",
              "test_nist_plan_end_to_end.py", "test_holes_nist.py", "test_material_impeller.py",
              "test_gdt_nist.py", "test_readme.py", "test_ctc04_dimensions.py",
              "test_uncertainty_coverage.py", "test_warmup_coverage.py", "test_fuzz_cad.py",
              "test_perpendicularity_projected_ftc07.py", "test_position_max_projected.py",
              "test_pmi_edges_nist.py", "test_position_size_nist.py", "test_svm_integrity.py",
              "test_symmetry_ftc10.py", "test_supplemental_faces.py",
              "test_datum_shift_pattern_nist.py", "test_datum_hole_wall.py",
              "test_import_trimmed_periodic.py", "test_stereo_measure.py",
              "test_registration_restart.py", "test_registration_random_pose.py",
              "test_alignment_any_start.py", "test_plan_placements.py", "test_characteristics.py",
              "test_fuzz_readers.py", "test_thin_features_ctc03.py", "test_views_several.py",
              "test_registration_symmetric.py", "test_registration_global.py",
              "test_cli_worker.py", "test_cli_batch_quiet.py", "test_cloud_reference.py",
              "test_io_scanners.py")


def pytest_collection_modifyitems(session, config, items):
    rank = {name: i for i, name in enumerate(LONG_FILES)}
    items.sort(key=lambda item: rank.get(Path(str(item.path)).name, len(rank)))
