"""Units on every screen (issue 32, item 2): Rich read every lower-case ``[mm]`` as markup and
dropped it -- from option help, the ``info`` table, the inspect tables and the ``history``
columns -- and Typer showed flags as ``<bool>``.  Each command's ``--help`` and each table is
rendered here and every bracketed unit its source text holds must be on screen."""

from __future__ import annotations

import io
import re
from types import SimpleNamespace

import numpy as np
import pytest
import typer
from rich.console import Console
from typer.testing import CliRunner

from shapeverify import cli
from shapeverify.cli import app

runner = CliRunner()
_UNIT = re.compile(r"\[[a-zµ²³%/ ]+\]")     # [mm] [mm²] [mm³] [s] ... (what Rich took for tags)


def _commands():
    group = typer.main.get_command(app)
    return group, sorted(group.commands)


def _help(*args) -> str:
    res = runner.invoke(app, [*args, "--help"], env={"COLUMNS": "200", "TERMINAL_WIDTH": "200"})
    assert res.exit_code == 0, res.output
    return " ".join(res.output.replace("│", " ").split())


def test_every_command_is_checked():
    _, names = _commands()
    assert {"info", "prepare", "inspect", "history", "unwrap", "hologram", "fit", "batch",
            "serve", "measure", "calibrate"} <= set(names)


@pytest.mark.parametrize("name", _commands()[1])
def test_help_shows_every_bracketed_unit_and_no_bool_type(name):
    group, _ = _commands()
    cmd = group.commands[name]
    shown = _help(name)
    wanted = [u for p in cmd.params for u in _UNIT.findall(p.help or "")]
    wanted += _UNIT.findall(cmd.help or "")
    for unit in wanted:
        # the help strings are escaped once (cli_text.readable_help): compare with the unescaped
        unit = unit.replace("\\", "")
        assert unit in shown, f"{name} --help lost {unit}: {shown}"
    assert "<bool>" not in shown
    assert "--help" in shown


def test_prepare_help_keeps_the_spacing_unit():
    # the friction as reported: "Model-point spacing  (default..."
    assert "Model-point spacing [mm] (default" in _help("prepare")
    assert "Lower limit [mm]" in _help("inspect")


def _render(renderable) -> str:
    c = Console(file=io.StringIO(), width=220)
    c.print(renderable)
    return c.file.getvalue()


def test_info_table_shows_its_units():
    from shapeverify.cad.summary import ModelSummary
    import dataclasses

    fields = {f.name for f in dataclasses.fields(ModelSummary)}
    values = dict(kind="cad", faces=3, rational_faces=0, faces_with_holes=1, vertices=None,
                  unit="mm", scale_to_mm=1.0, lo=np.zeros(3), hi=np.array([300.0, 200.0, 20.0]),
                  size=float(np.linalg.norm([300, 200, 20])))
    s = ModelSummary(**{k: v for k, v in values.items() if k in fields},
                     **{k: None for k in fields - set(values)})
    text = _render(cli.model_summary_table(s, title="panel [test].step"))
    assert "bounding box [mm]" in text and "size (diagonal) [mm]" in text
    assert "panel [test].step" in text      # a file name with brackets is shown as it is


@pytest.fixture
def captured(monkeypatch):
    buf = io.StringIO()
    monkeypatch.setattr(cli, "out", Console(file=buf, width=220))
    return buf


def test_inspect_tables_show_their_units_and_the_limits(captured):
    d = {"verdict": "fail", "reasons": ["a region of 0.0012 mm² [mm] beyond the limit"],
         "deviation": {"n": 1000, "mean": 0.01, "std": 0.02, "min": -0.4, "max": 0.1,
                       "p05": -0.03, "p95": 0.04, "in_tolerance_fraction": 0.98},
         "characteristics": [
             {"name": "SKIN", "type": "surface_profile", "measured": 0.81, "deviation": 0.61,
              "lower": 0.0, "upper": 0.2, "uncertainty": 0.01, "verdict": "fail"},
             {"name": "H1", "type": "hole", "measured": {"center": [1.0, 2.0, 3.0], "diameter": 36.01},
              "deviation": {"position": 0.05, "diameter": 0.01},
              "lower": {"diameter": 35.8, "position": 0.0}, "upper": {"diameter": 36.2, "position": 0.3},
              "uncertainty": {"diameter": 0.01, "position": 0.02}, "verdict": "pass"}],
         "regions": [{"kind": "deviation", "n": 12, "area": 0.0012345, "extreme": -0.4,
                      "severity": 1e-4, "centroid": [0.5, 0.25, 0.0]}]}
    result = SimpleNamespace(verdict="fail", to_dict=lambda: d)
    cli._print_result(result)
    text = captured.getvalue()
    for unit in ("Deviation from CAD [mm]", "Characteristics [mm]", "area [mm²]", "extreme [mm]",
                 "severity [mm³]", "centroid [mm]", "0.0012 mm² [mm]"):
        assert unit in text, unit
    # the limits column (a zone 0 .. 0.2; a hole's diameter and position limits)
    assert "limits" in text and "+0.0000 .. +0.2000" in text
    assert "diameter 35.8000 .. 36.2000" in text and "position 0.0000 .. 0.3000" in text
    # a small region's area keeps three significant digits (was "0.0")
    assert "0.00123" in text


def test_history_columns_show_their_units(captured, tmp_path, monkeypatch):
    db = tmp_path / "h.sqlite"
    db.write_bytes(b"")
    rows = [{"id": 1, "time": "2026-12-06", "part": "SN-1", "verdict": "fail", "min": -0.5,
             "max": 0.1, "max_abs": 0.5, "lower": -0.2, "upper": 0.2, "n_regions": 1,
             "model_hash": "ab" * 32}]
    monkeypatch.setattr(cli, "_history_rows", lambda *a: (rows, [{"model_hash": "ab" * 32,
                                                                   "name": "panel.step"}]))
    cli.history(db=db, part=None, limit=5, plot=None, characteristic=None, csv_out=None,
                model=None)
    text = captured.getvalue()
    for unit in ("min [mm]", "max [mm]", "max |d| [mm]", "limits [mm]"):
        assert unit in text, unit
    assert "-0.5000" in text and "-0.2 / +0.2" in text
