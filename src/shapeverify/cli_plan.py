"""Command-line commands of inspection plans (issue 17), registered on the main ``app``.

``shapeverify features MODEL [--json OUT]``: the CAD features a plan can name (holes, planar and
cylindrical faces) with their ids.  ``shapeverify plan-inspect MODEL SCAN --plan PLAN.yaml
[--json] [--pdf] [--db] [--part]``: align and evaluate a plan (exit 0 pass, 1 fail, 3 undecided,
2 error).  ``shapeverify spc --db DB --characteristic NAME [--plot PNG] [--csv OUT]``: the
characteristic's history with Cp/Cpk and a run chart.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer
from rich.table import Table

__all__ = ["register_commands", "run_plan"]

EXIT_UNDECIDED = 3


def run_plan(model: Path, scan: Path, plan: Path, *, json_path: Optional[Path] = None,
             pdf_path: Optional[Path] = None, db_path: Optional[Path] = None,
             part: Optional[str] = None, stage=None):
    """Load, align, evaluate and write the outputs; returns the PlanResult.

    The function the ``inspect --plan`` front end can call: ``model`` a .svm or a CAD file,
    ``scan`` a point file, ``plan`` a YAML plan.
    """
    import contextlib

    from shapeverify.characteristics import evaluate_plan, load_plan
    from shapeverify.io.points import read_points
    from shapeverify.pipeline import load_reference

    stage = stage or (lambda name: contextlib.nullcontext())
    p = load_plan(plan)
    prep = load_reference(model, stage=stage)
    with stage(f"Reading {scan.name}"):
        pts = read_points(scan)
    with stage("Aligning and evaluating the plan"):
        res = evaluate_plan(prep, pts, p)
    if json_path is not None:
        json_path.write_text(json.dumps(res.to_dict(), indent=1))
    if pdf_path is not None:
        from shapeverify.characteristics.pdf import write_pdf_report

        with stage(f"Writing {pdf_path.name}"):
            write_pdf_report(res, pdf_path, prep, part=part, scan_file=str(scan),
                             model_file=str(model))
    if db_path is not None:
        from shapeverify.characteristics.spc import store_characteristics

        store_characteristics(db_path, res, part=part)
    return res


def _num(v):
    if v is None:
        return "-"
    if isinstance(v, dict):
        return ", ".join(f"{k}={x:.4g}" for k, x in v.items() if isinstance(x, (int, float)))
    return f"{v:.4g}"


def register_commands(app: typer.Typer) -> None:
    """Add the ``features``, ``plan-inspect`` and ``spc`` commands to ``app``."""
    from shapeverify.cli import _fail, _guard, _require_files, _stage, out

    @app.command()
    def features(model: Path = typer.Argument(..., help="CAD file or .svm/.svmodel"),
                 json_out: Optional[Path] = typer.Option(None, "--json",
                                                         help="Write the list as JSON")):
        """List the CAD features an inspection plan can name (hole:N, face:N)."""
        from shapeverify.characteristics.features import features_table
        from shapeverify.pipeline import PREPARED_SUFFIX

        _require_files(model)
        if model.suffix.lower() == PREPARED_SUFFIX:
            from shapeverify.nearest import load_prepared
            m = _guard(load_prepared, model).model
        else:
            from shapeverify.cad.load import load_model
            with _stage(f"Importing {model.name}"):
                m = _guard(load_model, model)
        with _stage("Finding features"):
            rows = _guard(features_table, m)
        t = Table(title=f"{model} features (mm)")
        for col in ("id", "kind", "name", "centre", "axis / normal", "diameter"):
            t.add_column(col)
        for r in rows:
            c = "(" + ", ".join(f"{x:.3f}" for x in r["center"]) + ")"
            a = "-" if r["axis"] is None else "(" + ", ".join(f"{x:.3f}" for x in r["axis"]) + ")"
            t.add_row(r["id"], r["kind"], r["name"] or "", c, a,
                      "-" if r["diameter"] is None else f"{r['diameter']:.4f}")
        out.print(t)
        if json_out is not None:
            json_out.write_text(json.dumps(rows, indent=1))
            out.print(f"JSON: {json_out}")

    @app.command("plan-inspect")
    def plan_inspect(model: Path = typer.Argument(..., help="Prepared model (.svm) or CAD file"),
                     scan: Path = typer.Argument(..., help="Scan points file (mm)"),
                     plan: Path = typer.Option(..., "--plan", help="Inspection plan (YAML)"),
                     json_path: Optional[Path] = typer.Option(None, "--json", help="Write JSON"),
                     pdf: Optional[Path] = typer.Option(None, "--pdf", help="Write the PDF report"),
                     db: Optional[Path] = typer.Option(None, "--db",
                                                       help="Append the characteristics to this history"),
                     part: Optional[str] = typer.Option(None, "--part", help="Part id")):
        """Align a scan the plan's way and evaluate its characteristics.

        Exit code: 0 pass, 1 fail, 3 undecided (within the uncertainty of a limit), 2 error.
        """
        _require_files(model, scan, plan)
        res = _guard(run_plan, model, scan, plan, json_path=json_path, pdf_path=pdf, db_path=db,
                     part=part, stage=_stage)
        colour = {"pass": "green", "fail": "red"}.get(res.verdict, "yellow")
        out.print(f"[bold {colour}]verdict: {res.verdict.upper()}[/bold {colour}]  "
                  f"(alignment {res.alignment.kind}, rms {res.alignment.rms:.4f} mm)")
        t = Table(title="Characteristics [mm] (U: expanded uncertainty)")
        for col in ("name", "type", "measured", "deviation", "U", "verdict"):
            t.add_column(col)
        for c in res.characteristics:
            t.add_row(c.name, c.type, _num(c.measured if not isinstance(c.measured, dict)
                                           else {"d": c.measured["diameter"]}),
                      _num(c.deviation if not isinstance(c.deviation, dict) else
                           {k: v for k, v in c.deviation.items() if k != "center"}),
                      _num(c.uncertainty), c.verdict)
        out.print(t)
        for label, p in (("JSON", json_path), ("PDF", pdf)):
            if p is not None:
                out.print(f"{label}: {p}")
        raise typer.Exit({"pass": 0, "fail": 1}.get(res.verdict, EXIT_UNDECIDED))

    @app.command()
    def spc(db: Path = typer.Option(..., "--db", help="SQLite history file"),
            characteristic: str = typer.Option(..., "--characteristic",
                                               help="Name (a hole's name gives both series)"),
            part: Optional[str] = typer.Option(None, "--part", help="Only this part id"),
            limit: Optional[int] = typer.Option(None, help="Most recent N values"),
            plot: Optional[Path] = typer.Option(None, "--plot", help="Run chart (PNG)"),
            csv_out: Optional[Path] = typer.Option(None, "--csv", help="CSV export")):
        """Characteristic history: Cp/Cpk against the tolerance, run chart, CSV export."""
        from shapeverify.characteristics.spc import (capability, characteristic_rows,
                                                     export_csv, plot_run_chart)

        if not db.exists():
            _fail(f"{db}: no such history file")
        try:
            rows = characteristic_rows(db, characteristic, part=part, limit=limit)
        except KeyError as exc:
            _fail(str(exc.args[0]))
        t = Table(title=f"{characteristic}: {len(rows)} values (mm)")
        for col in ("series", "n", "mean", "Cp", "Cpk", "Pp", "Ppk", "note"):
            t.add_column(col)
        for name in sorted({r["name"] for r in rows}):
            rs = [r for r in rows if r["name"] == name]
            vals = [r["value"] for r in rs if r["value"] is not None]
            if len(vals) < 2:
                t.add_row(name, str(len(vals)), "-", "-", "-", "-", "-", "fewer than 2 values")
                continue
            cap = capability(vals, rs[-1]["lower"], rs[-1]["upper"])
            f = (lambda v: "-" if v is None else f"{v:.2f}")
            t.add_row(name, str(cap.n), f"{cap.mean:+.4f}", f(cap.cp), f(cap.cpk), f(cap.pp),
                      f(cap.ppk), "[yellow]" + cap.message + "[/yellow]" if cap.too_few else "")
        out.print(t)
        if plot is not None:
            plot_run_chart(rows, plot)
            out.print(f"run chart: {plot}")
        if csv_out is not None:
            export_csv(rows, csv_out)
            out.print(f"CSV: {csv_out}")
