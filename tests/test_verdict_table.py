"""One verdict policy (issue 31 item 3): every reader of a verdict -- the CLI's exit codes and
terminal colour, the HTML, PNG and PDF reports, the history's SQL CHECK, batch's counts and exit
code -- reads :data:`shapeverify.verdict_table.VERDICT_TABLE`, so a new verdict value is one row
there.  The tests add a row ("review") and check that each reader shows it as the row says;
and that the rules of the plan and of the symmetric copy are :mod:`shapeverify.inspection.verdict`'s.
"""

from __future__ import annotations

import dataclasses
import enum
import io
import sqlite3

import numpy as np
import pytest

from shapeverify import verdict_table as vt
from shapeverify.inspection import verdict as V

#: a verdict value as a new member of the Verdict enum would be (a str enum)
_EXTRA = enum.StrEnum("Verdict", {"REVIEW": "review", "MAYBE": "maybe"})
NEW = vt.VerdictStyle(exit_code=7, colour="#123456", word="REVIEW", terminal="cyan", severity=9)


@pytest.fixture
def review(monkeypatch):
    """The table with one more verdict value, "review"."""
    monkeypatch.setitem(vt.VERDICT_TABLE, "review", NEW)
    return _EXTRA.REVIEW


def _with_verdict(result, verdict):
    """``result`` with a verdict value the Verdict enum does not have yet (as a new member of it
    would be: one member and one row of the table, both in verdict_table.py)."""
    out = dataclasses.replace(result)
    object.__setattr__(out, "verdict", verdict)
    return out


@pytest.fixture(scope="module")
def inspected():
    from test_report import PlanePrep

    from shapeverify.inspection import inspect_registered
    from types import SimpleNamespace

    rng = np.random.default_rng(7)
    x, y = np.meshgrid(np.arange(1, 99, 1.0), np.arange(1, 59, 1.0))
    scan = np.column_stack([x.ravel(), y.ravel(), rng.normal(0, 0.02, x.size)])
    reg = SimpleNamespace(T_model_scan=np.eye(4), rms=0.02, iterations=5, converged=True,
                          inlier_fraction=1.0, weights=np.ones(len(scan)), message="converged")
    prep = PlanePrep()
    res = inspect_registered(prep, scan, reg, tolerance=0.2)
    assert res.verdict == "pass"
    return prep, scan, res


def test_table_has_one_row_per_verdict_with_distinct_exit_codes_and_colours():
    assert set(vt.VERDICT_TABLE) == set(vt.Verdict)
    rows = list(vt.VERDICT_TABLE.values())
    assert len({r.exit_code for r in rows}) == len(rows)
    assert len({r.colour for r in rows}) == len(rows)
    assert len({r.severity for r in rows}) == len(rows)
    # the documented exit codes of `shapeverify inspect`
    assert {str(v): r.exit_code for v, r in vt.VERDICT_TABLE.items()} == \
        {"pass": 0, "fail": 1, "error": 2, "incomplete": 3}


def test_cli_exit_code_and_terminal_colour_of_a_new_verdict_come_from_the_table(review):
    from shapeverify import cli

    assert (cli.EXIT_PASS, cli.EXIT_ERROR) == (0, 2)
    assert cli.verdict_style(review) == NEW       # inspect exits with verdict_style(...).exit_code
    from types import SimpleNamespace

    printed = []
    res = SimpleNamespace(verdict=review, to_dict=lambda: {"reasons": []})
    real = cli.out.print
    cli.out.print = lambda *a, **k: printed.append(a[0] if a else "")
    try:
        cli._print_result(res)
    finally:
        cli.out.print = real
    assert any("[bold cyan]verdict: REVIEW" in str(p) for p in printed), printed


def test_html_banner_of_a_new_verdict_has_its_colour_and_word(review, inspected):
    from shapeverify.report.html import html_report

    prep, scan, res = inspected
    page = html_report(_with_verdict(res, review), prep, scan).decode()
    assert 'style="background:#123456"' in page and "<h1>REVIEW</h1>" in page


def test_png_banner_of_a_new_verdict_is_painted_in_its_colour(review, inspected):
    from matplotlib.image import imread

    from shapeverify.report.png import png_summary

    prep, scan, res = inspected
    img = imread(io.BytesIO(png_summary(_with_verdict(res, review), scan)))
    rgb = np.round(img[..., :3] * 255).astype(int).reshape(-1, 3)
    want = np.array([0x12, 0x34, 0x56])
    assert np.count_nonzero(np.all(rgb == want, axis=1)) > 10_000     # the banner


def test_pdf_colours_of_a_new_verdict_and_of_undecided_characteristics(review):
    from shapeverify.characteristics import pdf

    assert pdf._colour(review) == "#123456"
    for v, row in vt.VERDICT_TABLE.items():
        assert pdf._colour(v) == row.colour
    assert pdf._colour("undecided") == pdf._UNDECIDED   # a characteristic's own verdict


def test_history_check_accepts_exactly_the_verdicts_of_the_table(review, inspected, tmp_path):
    from shapeverify.report.history import HistoryDB

    _, _, res = inspected
    with HistoryDB(tmp_path / "h.db") as db:
        for v in vt.VERDICT_TABLE:
            member = vt.Verdict(v) if v in vt.VERDICTS else _EXTRA(v)
            db.add(_with_verdict(res, member), part=str(v))
        with pytest.raises(sqlite3.IntegrityError):
            db.add(_with_verdict(res, _EXTRA.MAYBE), part="x")
        assert sorted(r["verdict"] for r in db.query()) == sorted(map(str, vt.VERDICT_TABLE))


def test_history_made_before_a_new_verdict_accepts_it_and_keeps_its_rows(inspected, tmp_path,
                                                                        monkeypatch):
    """An existing history file's CHECK lists the verdicts of when it was made: opened after a
    row was added to the table, it takes the new value and keeps every row and index."""
    from shapeverify.report.history import HistoryDB

    _, _, res = inspected
    path = tmp_path / "old.db"
    with HistoryDB(path) as db:
        first = db.add(res, part="A-1")
        with pytest.raises(sqlite3.IntegrityError):
            db.add(_with_verdict(res, _EXTRA.REVIEW), part="A-2")
    monkeypatch.setitem(vt.VERDICT_TABLE, "review", NEW)
    with HistoryDB(path) as db:
        db.add(_with_verdict(res, _EXTRA.REVIEW), part="A-2")
        rows = db.query()
        assert [(r["id"], r["part"], r["verdict"]) for r in rows] == [
            (first, "A-1", "pass"), (first + 1, "A-2", "review")]
        idx = {r[0] for r in db._con.execute(
            "SELECT name FROM sqlite_master WHERE type = 'index'").fetchall()}
        assert {"inspections_part", "inspections_model"} <= idx


def test_batch_counts_and_exit_code_follow_the_table(review):
    counts = vt.verdict_counts(["pass", "review", "fail", "review", None])
    assert counts == {"pass": 1, "fail": 1, "error": 0, "incomplete": 0, "review": 2}
    assert vt.most_severe(v for v, n in counts.items() if n) == "review"
    assert vt.most_severe(["pass", "incomplete", "fail", "error"]) == "error"
    assert vt.most_severe(["pass", "incomplete"]) == "incomplete"


def test_plan_rule_is_the_policy_s(inspected):
    """Rule 8 (the characteristics') lives in verdict.py: a failing characteristic fails a
    passing part, an undecided one makes it incomplete, an error stands."""
    v, rule, reasons = V.with_characteristics_rule("pass", "within_tolerance", ("pass: ok",),
                                                    ["bore"], [])
    assert (v, rule) == ("fail", "characteristics") and reasons[0].startswith("fail: ")
    v, rule, _ = V.with_characteristics_rule("pass", "within_tolerance", ("pass",), [], ["f"])
    assert (v, rule) == ("incomplete", "undecided")
    v, rule, reasons = V.with_characteristics_rule("error", "no_data", ("e",), ["bore"], [])
    assert (v, rule) == ("error", "no_data") and len(reasons) == 2


def test_symmetric_copy_rule_is_the_policy_s():
    assert V.symmetric_copy_applies("fail", "pass")
    assert not V.symmetric_copy_applies("pass", "pass")
    assert not V.symmetric_copy_applies("fail", "incomplete")
    assert V.symmetric_copy_fits_alike(1.0, V.SYMMETRIC_COPY_SHARE)
    assert not V.symmetric_copy_fits_alike(1.0, 0.96)


def test_rules_are_listed_in_the_documented_order():
    names = [r.__name__ for r in V.RULES]
    assert names == ["_rule_no_data", "_rule_does_not_fit", "_rule_wrong_minimum", "_rule_coverage",
                     "_rule_registration", "_rule_regions", "_rule_undecided",
                     "_rule_within_tolerance"]
