"""Command-line pieces of inspection plans (issue 17).

``shapeverify info MODEL --features [--json OUT]`` (:func:`print_features`): the CAD features a
plan can name (holes, planar and cylindrical faces) with their ids.  Plans are run by the one
pipeline, ``shapeverify inspect MODEL SCAN --plan PLAN.yaml [--pdf OUT.pdf]``.
``shapeverify history --db DB --characteristic NAME [--plot PNG] [--csv OUT]``
(:func:`print_characteristic_history`): the characteristic's history with Cp/Cpk and a run chart.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

from shapeverify.cli_text import Table

__all__ = ["print_features", "default_tolerance", "print_characteristic_history"]


def print_features(m, title: str, json_out: Optional[Path] = None) -> None:
    """``shapeverify info --features``: the CAD features an inspection plan can name."""
    from shapeverify.characteristics.features import features_table
    from shapeverify.cli import _guard, _stage, out

    with _stage("Finding features"):
        rows = _guard(features_table, m)
    t = Table(title=f"{title} features (mm)")
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


def default_tolerance(plan) -> float:
    """±tolerance of the colour map for a plan without one: half the first surface profile's
    zone width (ISO 1101: a profile tolerance t is a zone of total width t), else 0.1 mm."""
    from shapeverify.characteristics import load_plan

    for c in load_plan(plan).characteristics:
        if c.type == "surface_profile" and getattr(c, "tol", None):
            return 0.5 * float(c.tol)
    return 0.1


def print_characteristic_history(db: Path, characteristic: str, part: Optional[str] = None,
                                 limit: Optional[int] = None, plot: Optional[Path] = None,
                                 csv_out: Optional[Path] = None) -> None:
    """``shapeverify history --characteristic NAME``: Cp/Cpk against the tolerance, run chart,
    CSV export of one characteristic's history."""
    from shapeverify.characteristics.spc import (capability, characteristic_rows, export_csv,
                                                 plot_run_chart)
    from rich.text import Text

    from shapeverify.cli import _fail, out

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
                  f(cap.ppk), Text(cap.message, style="yellow") if cap.too_few else "")
    out.print(t)
    if plot is not None:
        plot_run_chart(rows, plot)
        out.print(f"run chart: {plot}")
    if csv_out is not None:
        export_csv(rows, csv_out)
        out.print(f"CSV: {csv_out}")
