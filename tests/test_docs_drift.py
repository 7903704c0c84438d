"""The docs say what the code is (issue 31 items 4 and 6: docs that drifted).

* Every place the "Where to change a common thing" table of ``docs/architecture.md`` names
  exists: each file, and each name in a row is defined in one of that row's files (or, written
  ``module.name``, importable).
* ``docs/internals.md`` lists every field of :class:`~shapeverify.registration.Registration`
  (five were missing).
* The PDF's deviation bands are :mod:`shapeverify.report.colours`' (the table says every report
  reads it; the PDF had its own copy).
* ``Prepared.points`` is documented as kept, not rebuilt, and is (the same object each time).
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "shapeverify"


def _table_rows() -> list[str]:
    text = (ROOT / "docs" / "architecture.md").read_text()
    part = text[text.index("## Where to change a common thing"):]
    rows = [ln for ln in part.splitlines() if ln.startswith("| ") and not ln.startswith("|---")]
    return rows[1:]                       # the header row is not a place


def _resolve(path: str) -> Path | None:
    for base in (PACKAGE, ROOT):
        p = base / path
        if p.is_file():
            return p
    return None


def _defined(path: Path) -> set[str]:
    """Names a file defines at any level: functions, classes, assignments."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            out.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for t in targets:
                for n in ast.walk(t):
                    if isinstance(n, ast.Name):
                        out.add(n.id)
    return out


ROWS = _table_rows()


def test_the_table_has_rows():
    assert len(ROWS) >= 8


@pytest.mark.parametrize("row", ROWS, ids=lambda r: r.split("|")[1].strip()[:40])
def test_every_place_the_where_to_change_table_names_exists(row):
    tokens = re.findall(r"`([^`]+)`", row)
    paths = [t for t in tokens if t.endswith(".py")]
    files = []
    for p in paths:
        f = _resolve(p)
        assert f is not None, f"{p} (named in the table) does not exist"
        files.append(f)
    names = set().union(*(_defined(f) for f in files)) if files else set()
    for t in tokens:
        if t.endswith(".py") or not re.fullmatch(r"[A-Za-z_][\w.]*", t):
            continue
        if "." in t:                      # module.attribute
            mod, _, attr = t.rpartition(".")
            m = importlib.import_module(f"shapeverify.{mod}")
            assert hasattr(m, attr), f"{t} (named in the table) does not exist"
        else:
            assert t in names, f"{t} (named in the table) is defined in none of {paths}"


def test_internals_lists_every_registration_field():
    from shapeverify.registration import Registration

    text = (ROOT / "docs" / "internals.md").read_text()
    block = text[text.index("Registration(T_model_scan"):]
    block = block[:block.index("```")]
    for f in dataclasses.fields(Registration):
        assert re.search(rf"\b{f.name}\b", block), f"internals.md leaves out Registration.{f.name}"


def test_pdf_bands_are_the_report_colours():
    from shapeverify.characteristics import pdf
    from shapeverify.report import colours

    assert pdf.BAND_COLOURS is colours.BAND_COLOURS
    src = (PACKAGE / "characteristics" / "pdf.py").read_text()
    assert not re.search(r"^BAND_COLOURS\s*=", src, re.M)      # no copy of its own


def test_prepared_points_is_kept_and_documented_so():
    import shapeverify as sv
    from shapeverify.cad.examples import wavy_panel
    from shapeverify.nearest import Prepared

    doc = Prepared.__doc__
    assert "rebuilt on each" not in doc and "kept" in doc
    prep = sv.prepare(wavy_panel(), spacing=6.0)
    assert prep.points is prep.points
