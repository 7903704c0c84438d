"""Command-line pieces of inspection plans (issue 17).

``shapeverify info MODEL --features [--json OUT]`` (:func:`print_features`): the CAD features a
plan can name (holes, planar and cylindrical faces) with their ids.  Plans are run by the one
pipeline, ``shapeverify inspect MODEL SCAN --plan PLAN.yaml [--pdf OUT.pdf]``.
``shapeverify history --db DB --characteristic NAME [--plot PNG] [--csv OUT]``
(:func:`print_characteristic_history`): the characteristic's history with Cp/Cpk and a run chart.
``shapeverify plan PART.stp -o plan.yaml`` (:func:`write_pmi_plan`): a plan from the STEP
AP242 file's semantic PMI; ``shapeverify info PART.stp --pmi`` (:func:`print_pmi`) the same as a
table.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

from shapeverify.cli_text import Table

__all__ = ["print_features", "default_tolerance", "print_characteristic_history",
           "write_pmi_plan", "print_pmi"]


def print_features(m, title: str, json_out: Optional[Path] = None) -> None:
    """``shapeverify info --features``: the CAD features an inspection plan can name."""
    from shapeverify.characteristics.features import feature_notes, features_table
    from shapeverify.cli_common import guard as _guard, out, stage as _stage

    with _stage("Finding features"):
        rows = _guard(features_table, m)
        notes = _guard(feature_notes, m)
    t = Table(title=f"{title} features (mm)")
    for col in ("id", "kind", "name", "centre", "axis / normal", "diameter"):
        t.add_column(col)
    for r in rows:
        c = "(" + ", ".join(f"{x:.3f}" for x in r["center"]) + ")"
        a = "-" if r["axis"] is None else "(" + ", ".join(f"{x:.3f}" for x in r["axis"]) + ")"
        if r["diameter"] is not None:
            d = f"{r['diameter']:.4f}"
        elif r.get("length") is not None:   # a slot/pocket/other opening: its extents
            d = f"{r['length']:.3f}" + ("" if r.get("width") is None else f" x {r['width']:.3f}")
        else:
            d = "-"
        t.add_row(r["id"], r["kind"], r["name"] or "", c, a, d)
    out.print(t)
    for n in notes:
        out.print(f"[yellow]not a feature:[/yellow] {n}")
    if json_out is not None:
        json_out.write_text(json.dumps(rows, indent=1))
        out.print(f"JSON: {json_out}")


def default_tolerance(plan) -> float:
    """±tolerance of the colour map for a plan without one: half the first surface profile's
    zone width (ISO 1101: a profile tolerance t is a zone of total width t), else 0.1 mm
    (:meth:`shapeverify.InspectionOptions.from_plan`)."""
    from shapeverify.options import InspectionOptions

    return InspectionOptions.from_plan(plan).tolerance


def print_characteristic_history(db: Path, characteristic: str, part: Optional[str] = None,
                                 limit: Optional[int] = None, plot: Optional[Path] = None,
                                 csv_out: Optional[Path] = None) -> None:
    """``shapeverify history --characteristic NAME``: Cp/Cpk against the tolerance, run chart,
    CSV export of one characteristic's history."""
    from shapeverify.characteristics.spc import (capability, characteristic_rows, export_csv,
                                                 plot_run_chart)
    from rich.text import Text

    from shapeverify.cli_common import fail as _fail, out

    if not db.exists():
        _fail(f"{db}: no such history file")
    try:
        rows = characteristic_rows(db, characteristic, part=part, limit=limit)
    except KeyError as exc:
        _fail(str(exc.args[0]))
    from shapeverify.report.history_fcf import frame_header, series_frames, series_unit

    frames = series_frames(rows)
    units = {name: series_unit([r for r in rows if r["name"] == name]) for name in frames}
    shown = "mm" if set(units.values()) <= {"mm"} else ", ".join(sorted(set(units.values())))
    out.print(Text(frame_header(characteristic, rows)))
    t = Table(title=f"{characteristic}: {len(rows)} values [{shown}]")
    for col in ("series", "frame", "n", "mean", "Cp", "Cpk", "Pp", "Ppk", "note"):
        t.add_column(col)
    for name in sorted({r["name"] for r in rows}):
        rs = [r for r in rows if r["name"] == name]
        fs = frames.get(name) or []
        frame = fs[-1] if fs else "–"
        changed = (f"frame changed during the history (was {'; '.join(fs[:-1])})"
                   if len(fs) > 1 else "")
        vals = [r["value"] for r in rs if r["value"] is not None]
        if len(vals) < 2:
            t.add_row(name, frame, str(len(vals)), "-", "-", "-", "-", "-",
                      "; ".join(x for x in ("fewer than 2 values", changed) if x))
            continue
        cap = capability(vals, rs[-1]["lower"], rs[-1]["upper"])
        f = (lambda v: "-" if v is None else f"{v:.2f}")
        note = "; ".join(x for x in (cap.message if cap.too_few else "", changed) if x)
        t.add_row(name, frame, str(cap.n), f"{cap.mean:+.4f} {units[name]}", f(cap.cp),
                  f(cap.cpk), f(cap.pp), f(cap.ppk),
                  Text(note, style="yellow") if note else "")
    out.print(t)
    if plot is not None:
        plot_run_chart(rows, plot)
        out.print(f"run chart: {plot}")
    if csv_out is not None:
        export_csv(rows, csv_out)
        out.print(f"CSV: {csv_out}")


def _pmi_plan(model_path: Path, m=None):
    from shapeverify.characteristics.pmi_plan import pmi_plan
    from shapeverify.cli_common import guard as _guard, stage as _stage

    with _stage(f"Reading the PMI of {model_path.name}", watch=False):
        return _guard(pmi_plan, model_path, model=m)


def write_pmi_plan(model_path: Path, output: Optional[Path]) -> None:
    """``shapeverify plan PART.stp -o plan.yaml``: the inspection plan of the file's semantic
    PMI (YAML on stdout without ``-o``)."""
    from shapeverify.characteristics.pmi_plan import plan_yaml
    from shapeverify.cli_common import console, guard as _guard, out

    res = _pmi_plan(model_path)
    text = plan_yaml(res)
    if output is None:
        out.print(text, markup=False, highlight=False, soft_wrap=True)
    else:
        _guard(output.write_text, text, encoding="utf-8")
    n_gt = sum(1 for r in res.rows if r["kind"] == "geometric_tolerance" and not r.get("unread"))
    n_gt_un = sum(1 for u in res.plan.unsupported if u.pmi.kind == "geometric_tolerance")
    unread = res.plan.unread
    console.print(f"{model_path.name}: {len(res.plan.characteristics)} characteristics, "
                  f"alignment {res.plan.alignment.type}; {len(res.plan.unsupported)} PMI items "
                  f"not checked ({n_gt_un} of {n_gt} geometric tolerances), each listed under "
                  "'unsupported' with the reason"
                  + (f"; {len(unread)} more the file declares but OpenCASCADE does not read "
                     f"({', '.join(f'{u.pmi.type} {u.pmi.name!r}' for u in unread)}), listed "
                     "under 'unread': inspect them by hand" if unread else "")
                  + (f"; plan: {output}" if output else ""),
                  markup=False, highlight=False, soft_wrap=True)
    if not any(res.pmi.get(k) for k in ("datums", "tolerances", "dimensions", "unread")):
        console.print(f"note: {model_path.name} holds no semantic PMI (no datum, geometric "
                      "tolerance or dimension that OpenCASCADE's XCAF reads), so the plan is a "
                      "best fit with no characteristics. A drawing, or PMI shown only as "
                      "graphics, cannot become a plan: use the part's STEP AP242 edition with "
                      "semantic PMI, or write the plan by hand (README: Inspection plans).",
                      style="yellow", markup=False, highlight=False, soft_wrap=True)


def print_pmi(model_path: Path, m=None) -> None:
    """``shapeverify info PART.stp --pmi``: the semantic PMI and what the plan makes of it."""
    from shapeverify.cli_common import out

    out.print(pmi_table(model_path.name, _pmi_plan(model_path, m)))


def pmi_table(name: str, res) -> Table:
    """The table ``info --pmi`` prints: one row per PMI item of ``res`` (a PMI plan result:
    ``rows`` and ``plan.alignment``), with the plan entries made of it or why none.

    Cells are plain text (a reason such as "faces [41, 40]" shows as written); an item the file
    attaches to supplemental geometry lists, under its faces, what became of each supplemental
    face (mapped onto the solid faces it lies on, or left out: :mod:`.pmi_supplemental`); an angle
    dimension's values are in degrees, every other value (an angularity's zone too) in mm.
    """
    from rich.text import Text

    al = res.plan.alignment
    t = Table(title=f"{name} PMI (alignment: {al.type}"
                    + (f" {al.primary}|{al.secondary}" + (f"|{al.tertiary}" if al.tertiary else "")
                       if al.type == "datums" else "") + ")")
    for col in ("id", "kind", "type", "value (mm)", "limits (mm)", "datums / targets",
                "modifiers", "faces", "plan"):
        t.add_column(col)
    for r in res.rows:
        faces = ", ".join(r["faces"][:6]) + (f" (+{len(r['faces']) - 6})"
                                            if len(r["faces"]) > 6 else "")
        lim = r.get("limits")
        plan = (", ".join(r["entries"]) if r["entries"]
                else Text.assemble(("not read: " if r.get("unread") else "unsupported: ",
                                    "red" if r.get("unread") else "yellow"), r["reason"]))
        deg = "\u00b0" if r["kind"] == "dimension" and "Angular" in r["type"] else ""
        t.add_row(r["id"], r["kind"].replace("geometric_tolerance", "tolerance"), r["type"],
                  "-" if r.get("value") is None else f"{r['value']:g}{deg}",
                  "-" if not lim else f"{lim[0]:+g}{deg} / {lim[1]:+g}{deg}",
                  r.get("datums") or ", ".join(r.get("targets", [])) or "-",
                  ", ".join(r.get("modifiers", [])) or "-",
                  Text.assemble(faces or "-", ("\n" + r["supplemental_note"], "dim"))
                  if r.get("supplemental_note") else faces or "-", plan)
    return t
