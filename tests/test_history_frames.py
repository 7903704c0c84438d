"""``shapeverify history --characteristic NAME`` shows the characteristic's feature control
frame (issue 28 item 4): in its header line and in a frame column per series, with the units of
its values on screen (``[mm]`` is Rich markup unless written as plain text: issue 32).

The history is written by the library (``store_characteristics``) from synthetic evaluations of
plans (``fcf_synthetic``), and read back through the command line (typer's CliRunner).
"""
from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from fcf_synthetic import synthetic_plan_result
from shapeverify.characteristics.plan import load_plan
from shapeverify.characteristics.spc import store_characteristics
from shapeverify.cli import app
from shapeverify.report import fcf as F

PLANS = Path(__file__).parent / "data" / "pmi_plans"
runner = CliRunner()
_DATUMS = {k: {"faces": ["face:1"]} for k in "ABC"}


def _plan(*chars):
    return load_plan({"datums": _DATUMS, "characteristics": list(chars)})


def _history(tmp_path, plan, n=5, name="h.sqlite"):
    db = tmp_path / name
    for i in range(n):
        store_characteristics(db, synthetic_plan_result(plan, fraction=0.2 + 0.1 * (i % 4)),
                              part=f"SN-{i}")
    return db


def _show(db, name) -> str:
    r = runner.invoke(app, ["history", "--db", str(db), "--characteristic", name],
                      env={"COLUMNS": "220", "TERMINAL_WIDTH": "220"})
    assert r.exit_code == 0, r.output
    return r.output


def test_history_of_a_characteristic_shows_its_feature_control_frame(tmp_path):
    plan = _plan({"name": "POS1", "type": "position", "features": ["hole:1"], "tol": 0.25,
                  "datums": ["A", "B", "C"], "material": "M",
                  "size": {"lower": -0.1, "upper": 0.1}},
                 {"name": "FLAT", "type": "flatness", "feature": "face:1", "tol": 0.05})
    db = _history(tmp_path, plan)
    want = F.fcf_text(synthetic_plan_result(plan).characteristics[0], plan.characteristics[0])
    assert want == "⌖|Ø0.25Ⓜ|A|B|C"
    text = _show(db, "POS1")
    header = next(line for line in text.splitlines() if line.startswith("POS1"))
    assert header.split() == ["POS1", "frame:", want]
    row = next(line for line in text.splitlines() if "│ POS1 " in line)
    assert want in row and "│ 5 " in row
    # the values' unit on screen: the title's [mm] and the mean's mm
    assert "POS1: 5 values [mm]" in text
    mean = sum(0.2 + 0.1 * (i % 4) for i in range(5)) / 5 * 0.25
    assert f"+{mean:.4f} mm" in row
    assert "⏥|0.05" in _show(db, "FLAT")


def test_history_of_a_hole_shows_the_frame_of_each_series(tmp_path):
    plan = _plan({"name": "H1", "type": "hole", "feature": "hole:1",
                  "diameter": {"lower": -0.05, "upper": 0.05}, "position": {"tol": 0.5},
                  "pmi": {"kind": "geometric_tolerance", "type": "Position", "datums": "A|B"}})
    text = _show(_history(tmp_path, plan), "H1")
    lines = text.splitlines()
    assert any(line.split() == ["H1", "frame:", "Ø10.000", "+0.05/−0.05;", "⌖|Ø0.5|A|B"]
               for line in lines), text
    dia = next(line for line in lines if "│ H1.diameter " in line)
    pos = next(line for line in lines if "│ H1.position " in line)
    assert "Ø10.000 +0.05/−0.05" in dia and "⌖|Ø0.5|A|B" in pos


def test_history_of_an_angle_states_degrees(tmp_path):
    plan = _plan({"name": "ANG", "type": "angle", "faces": ["face:4", "face:5"],
                  "nominal": 60.0, "lower": -0.5, "upper": 0.5})
    text = _show(_history(tmp_path, plan), "ANG")
    assert "ANG  frame: 60.000° +0.5°/−0.5°" in text
    assert "ANG: 5 values [°]" in text
    row = next(line for line in text.splitlines() if "│ ANG " in line)
    assert row.split("│")[4].strip().endswith(" °")


def test_history_says_when_the_frame_changed_and_shows_the_latest(tmp_path):
    old = _plan({"name": "P", "type": "surface_profile", "faces": "all", "tol": 0.2,
                 "datums": ["A", "B"]})
    new = _plan({"name": "P", "type": "surface_profile", "faces": "all", "tol": 0.3,
                 "datums": ["A", "B"]})
    db = _history(tmp_path, old, n=3)
    for i in range(2):
        store_characteristics(db, synthetic_plan_result(new), part=f"N-{i}")
    text = " ".join(_show(db, "P").split())
    assert "P frame: ⌓|0.3|A|B" in text
    assert "frame changed during the history (was ⌓|0.2|A|B)" in text


def test_history_written_before_the_frames_shows_a_dash_not_a_wrong_frame(tmp_path):
    import sqlite3

    plan = _plan({"name": "F", "type": "flatness", "feature": "face:1", "tol": 0.05})
    db = _history(tmp_path, plan, n=3)
    with sqlite3.connect(db) as con:
        con.execute("UPDATE characteristics SET fcf = NULL")
    text = _show(db, "F")
    assert "F  frame: –" in text and "⏥" not in text


def test_history_frame_with_brackets_is_shown_as_written(tmp_path):
    """A modifier the tables do not know is written ``[Name]`` in the frame; Rich would read
    it as markup and drop it."""
    plan = _plan({"name": "Q", "type": "parallelism", "faces": ["face:3"], "tol": 0.1,
                  "datums": ["A"], "pmi": {"kind": "geometric_tolerance", "type": "Parallelism",
                                           "modifiers": ["odd_modifier"]}})
    text = _show(_history(tmp_path, plan, n=2), "Q")
    assert "∥|0.1[odd_modifier]|A" in text
    assert "\\[" not in text


def test_history_listing_shows_each_characteristic_with_its_frame(tmp_path):
    plan = _plan({"name": "POS1", "type": "position", "features": ["hole:1"], "tol": 0.25,
                  "datums": ["A", "B", "C"], "material": "M",
                  "size": {"lower": -0.1, "upper": 0.1}},
                 {"name": "H1", "type": "hole", "feature": "hole:1",
                  "diameter": {"lower": -0.05, "upper": 0.05}, "position": {"tol": 0.5}},
                 {"name": "ANG", "type": "angle", "faces": ["face:4", "face:5"],
                  "nominal": 60.0, "lower": -0.5, "upper": 0.5})
    db = _history(tmp_path, plan, n=4)
    store_characteristics(db, synthetic_plan_result(plan, fraction=1.5), part="SN-9")
    r = runner.invoke(app, ["history", "--db", str(db)],
                      env={"COLUMNS": "220", "TERMINAL_WIDTH": "220"})
    assert r.exit_code == 0, r.output
    rows = {line.split("│")[1].strip(): [c.strip() for c in line.split("│")[2:-1]]
            for line in r.output.splitlines() if line.startswith("│ ") and "│" in line[2:]}
    assert rows["POS1"] == ["position", "⌖|Ø0.25Ⓜ|A|B|C", "5", "≤ 0.25 mm", "fail"]
    assert rows["H1.diameter"] == ["hole diameter", "Ø10.000 +0.05/−0.05", "5",
                                   "-0.05 .. +0.05 mm", "fail"]
    assert rows["H1.position"][:4] == ["hole position", "⌖|Ø0.5", "5", "≤ 0.5 mm"]
    assert rows["ANG"][1:4] == ["60.000° +0.5°/−0.5°", "5", "-0.5 .. +0.5 °"]
    # --part: that part's values only
    r = runner.invoke(app, ["history", "--db", str(db), "--part", "SN-9"],
                      env={"COLUMNS": "220", "TERMINAL_WIDTH": "220"})
    assert any(line.startswith("│ POS1 ") and "│ 1 " in line for line in r.output.splitlines())


def test_history_listing_leaves_a_history_without_characteristics_unchanged(tmp_path):
    import sqlite3

    from shapeverify.report.history import HistoryDB

    db = tmp_path / "plain.sqlite"
    HistoryDB(db).close()
    r = runner.invoke(app, ["history", "--db", str(db)])
    assert r.exit_code == 0, r.output
    assert "Characteristics" not in r.output
    with sqlite3.connect(db) as con:
        tables = {t for (t,) in con.execute("SELECT name FROM sqlite_master WHERE type='table'")}
    assert "characteristics" not in tables


def test_inspect_table_shows_a_bracketed_modifier_as_written(monkeypatch):
    """The inspect table's frame column is plain text (cli_text.Table): escaping it as markup
    as well showed ``\\[odd_modifier]`` (a hand-written plan's lower-case name)."""
    import io
    from types import SimpleNamespace

    from rich.console import Console

    from shapeverify import cli

    plan = _plan({"name": "Q", "type": "parallelism", "faces": ["face:3"], "tol": 0.1,
                  "datums": ["A"], "pmi": {"kind": "geometric_tolerance", "type": "Parallelism",
                                           "modifiers": ["odd_modifier"]}})
    pr = synthetic_plan_result(plan)
    d = {"verdict": "pass", "reasons": [], "characteristics": [pr.characteristics[0].to_dict()]}
    buf = io.StringIO()
    monkeypatch.setattr(cli, "out", Console(file=buf, width=220))
    cli._print_result(SimpleNamespace(verdict="pass", to_dict=lambda: d,
                                      plan=SimpleNamespace(plan=plan)))
    text = buf.getvalue()
    assert "∥|0.1[odd_modifier]|A" in text and "\\[" not in text
