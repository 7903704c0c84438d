"""The ``shapeverify`` command line (the only module that talks to the terminal).

Exit codes of ``shapeverify inspect``: 0 the part passes, 1 it fails the tolerance, 2 error
(bad input, failed registration, unreadable file), 3 incomplete (not enough of the part was
seen to decide). Other commands: 0 success, 2 error.
"""

from __future__ import annotations

import logging
import os
import sys

# numpy's OpenBLAS wakes a second thread for long dot products and leaves it spinning: on the
# registration's and inspection's short products that is CPU taken from the numba kernels (and
# from the service's and batch's other workers) for no gain (bench_inspect: 154 -> 100 ms CPU
# per inspection).  Set before numpy is first imported; a value the user set is kept.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
from pathlib import Path
from typing import List, Optional

import typer
from rich.logging import RichHandler
from rich.markup import escape
from typer.core import TyperGroup

from shapeverify.cli_errors import clean, size_note
from shapeverify.cli_params import install as _install_plain_params
from shapeverify.cli_common import (EVALUATION_DISTANCE as _EVALUATION_DISTANCE,  # noqa: F401
                                    EXIT_ERROR, EXIT_FAIL, EXIT_INCOMPLETE, EXIT_PASS,
                                    FACES as _FACES, INIT as _INIT, LOWER as _LOWER,
                                    MAX_DISTANCE as _MAX_DISTANCE,
                                    MIN_COVERAGE as _MIN_COVERAGE, PLAN as _PLAN,
                                    SCAN_UNIT as _SCAN_UNIT, UPPER as _UPPER,
                                    VERBOSE_KEY as _VERBOSE_KEY, console, out)
from shapeverify.cli_common import fail as _fail  # noqa: F401 (the old private names)
from shapeverify.cli_common import guard as _guard
from shapeverify.cli_common import internal_error as _internal_error
from shapeverify.cli_common import is_init_mode as _is_init_mode
from shapeverify.cli_common import require_files as _require_files
from shapeverify.cli_common import renamed as _renamed
from shapeverify.cli_common import stage as _stage
from shapeverify.cli_start import CAD_SUFFIXES as _CAD_SUFFIXES
from shapeverify.cli_start import early_importer as _early_importer
from shapeverify.cli_start import is_prepared as _is_prepared
from shapeverify.cli_text import Table, coordinates, format_limits, readable_help, sig3
from shapeverify.io.formats import scan_help  # the scan format registry (no numpy)
from shapeverify.verdict_table import VERDICT_TABLE, verdict_style  # a leaf: no numpy

# usage errors (a missing argument, an unknown option) and exits are not bugs.  typer >= 0.2x
# vendors its own click (typer._click, and click is no longer installed with it), older typer
# uses click: the base class is taken from typer's own BadParameter, so both work
_NOT_A_BUG = (typer.Exit, typer.Abort) + tuple(
    c for c in typer.BadParameter.__mro__ if c.__name__ == "ClickException")


class _GuardedGroup(TyperGroup):
    """Runs every command so that an unexpected exception (a bug) also ends with exit code 2 and
    one line -- never exit code 1, which ``inspect`` reserves for "the part fails".
    Help texts are shown as written (``[mm]`` is a unit, not Rich markup: cli_text)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        readable_help(self)

    def add_command(self, cmd, *args, **kwargs):
        readable_help(cmd)
        return super().add_command(cmd, *args, **kwargs)

    def main(self, args=None, *rest, **kwargs):
        _early_importer(sys.argv[1:] if args is None else list(args))
        return super().main(args, *rest, **kwargs)

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except _NOT_A_BUG:
            raise
        except Exception as exc:  # noqa: BLE001 - the last line of defence
            _internal_error(exc, bool(ctx.meta.get(_VERBOSE_KEY)))


_install_plain_params()  # option values converted without pydantic when plain (cli_params)

app = typer.Typer(
    cls=_GuardedGroup,
    add_completion=False,
    no_args_is_help=True,
    help="Shape verification of free-form parts against their CAD model. Lengths in mm.",
)

# the verdict table's exit codes (shapeverify.verdict_table; cli_common reads the same table)
VERDICT_EXIT = {str(v): row.exit_code for v, row in VERDICT_TABLE.items()}


def _setup_logging(verbose: bool) -> None:
    logging.basicConfig(
        level=logging.INFO if verbose else logging.WARNING,
        format="%(message)s",
        handlers=[RichHandler(console=console, show_path=False)],
    )
    # the library's warnings (e.g. undetermined pose directions) are in the result's reasons in
    # plain words; on the terminal they appear once, and only with --verbose
    logging.captureWarnings(True)
    logging.getLogger("py.warnings").setLevel(logging.WARNING if verbose else logging.ERROR)


def _prestart_importer(model: Path, summary: bool = False) -> None:
    """Start the CAD importer process now when ``model`` is a CAD file: its start (a Python that
    imports OpenCASCADE, about a second) then overlaps the rest of this process's start-up
    (``summary``: for a summary only, so without numba)."""
    if model.suffix.lower() in _CAD_SUFFIXES and model.is_file():
        from shapeverify.cad.occ_worker import prestart

        prestart(summary)


@app.callback()
def _main(ctx: typer.Context,
          verbose: bool = typer.Option(False, "--verbose", "-v",
                                       help="Log progress details; show the traceback of an internal error.")):
    ctx.meta[_VERBOSE_KEY] = verbose
    _setup_logging(verbose)


@app.command()
def info(model: Path = typer.Argument(..., help="CAD file (.step/.stp/.igs/.iges), mesh, point cloud or .svm/.svmodel"),
         features: bool = typer.Option(False, "--features", help="Also list the CAD features an inspection plan can name (hole:N, face:N)"),
         json_out: Optional[Path] = typer.Option(None, "--json", help="With --features: write them as JSON"),
         pmi: bool = typer.Option(False, "--pmi", help="Also list the semantic PMI of a STEP AP242 file and what `shapeverify plan` makes of it"),
         model_unit: Optional[str] = typer.Option(None, "--model-unit", help="Unit of the model file (default mm for STL/PLY/OBJ/point clouds; overrides the unit a CAD file declares, with a warning naming both and the size)")):
    """Print a summary of a model: faces, units, size (and with --features its holes and faces)."""
    from shapeverify.cad.summary import in_unit

    _require_files(model)
    prep = m = None
    if _is_prepared(model):
        if model_unit not in (None, "mm"):
            _fail(f"{clean(model)} is a prepared model, already in mm; give the unit when "
                  "preparing it (shapeverify prepare MODEL --model-unit ...)")
        from shapeverify.nearest import load_prepared
        with _stage(f"Loading {model.name}"):
            prep = _guard(load_prepared, model)
        m = prep.model
        summary = m
    elif features or pmi:
        _prestart_importer(model)
        from shapeverify.cad.load import load_model
        with _stage(f"Importing {model.name}", watch=False):  # numba runs only in the importer
            m = _guard(load_model, model)
        summary = m
    else:
        # the summary of a file read before comes from the cache (no OpenCASCADE, no numba);
        # of a new CAD file from OpenCASCADE alone, in the importer (no numba either)
        from shapeverify.cad.summary import cached_summary, read_summary

        def load(path):
            _prestart_importer(path, summary=True)
            return read_summary(path)

        with _stage(f"Importing {model.name}", watch=False):  # numba runs only in the importer
            summary, _ = _guard(cached_summary, model, load)
    if model_unit is not None and prep is None:
        if features or pmi:
            from shapeverify.units import scale_model
            summary = m = _guard(scale_model, m, model_unit)
        else:
            summary = _guard(in_unit, summary, model_unit, str(model))
    out.print(model_summary_table(summary, title=clean(model)))
    note = size_note(summary.kind, summary.unit, summary.size)
    if note:
        console.print(f"[yellow]note:[/yellow] {escape(note)}", soft_wrap=True)
    if prep is not None:
        out.print(f"prepared: {prep.n_points:,} model points at {prep.model_spacing:.3g} mm spacing, "
                  f"reach {prep.reach:.3g} mm")
    if features:
        from shapeverify.cli_plan import print_features
        print_features(m, str(model), json_out)
    if pmi:
        from shapeverify.cli_plan import print_pmi
        print_pmi(model, m)


@app.command()
def plan(model: Path = typer.Argument(..., help="STEP AP242 file with semantic PMI"),
         output: Optional[Path] = typer.Option(None, "-o", "--output", help="Plan file to write (default: print it)")):
    """Write an inspection plan (plan.yaml) from the STEP file's semantic PMI (datums, GD&T, dimensions)."""
    _require_files(model)
    _prestart_importer(model)
    from shapeverify.cli_plan import write_pmi_plan
    write_pmi_plan(model, output)


def model_summary_table(m, title: str) -> Table:
    """The summary table of a :class:`~shapeverify.cad.model.Model` or of its
    :class:`~shapeverify.cad.summary.ModelSummary`."""
    from shapeverify.cad.summary import ModelSummary, summarize

    s = m if isinstance(m, ModelSummary) else summarize(m)
    t = Table(title=title, show_header=False)
    t.add_row("kind", s.kind)
    t.add_row("faces", str(s.faces) if not s.missing else  # issue 33 row 2
              f"{s.faces} of {s.faces_in_file} in the file; missing: {'; '.join(s.missing)}")
    if getattr(s, "supplemental", ()):
        from shapeverify.cad.summary import face_ranges
        t.add_row("supplemental faces",
                  f"{len(s.supplemental)} (faces {face_ranges(s.supplemental)}: outside the solid, "
                  "kept for the PMI; excluded from model points, registration and deviations)")
    if s.kind == "cad":
        t.add_row("rational faces", str(s.rational_faces))
        t.add_row("faces with holes", str(s.faces_with_holes))
    if s.vertices is not None:
        t.add_row("vertices", f"{s.vertices:,}")
    t.add_row("file unit", f"{s.unit} (x{s.scale_to_mm:g} to mm)")
    # rounded to 0.01 mm, written as numpy writes arrays, without numpy (cli_text.coordinates)
    t.add_row("bounding box [mm]", f"{coordinates(s.lo)} .. {coordinates(s.hi)}")
    t.add_row("size (diagonal) [mm]", f"{s.size:.3f}")
    return t


_ALLOW_INCOMPLETE = typer.Option(
    False, "--allow-incomplete-model",
    help="Accept a CAD model that lacks faces its file declares (dangling or unconvertible "
         "faces, open seams of a solid; refused otherwise); every inspection then names them")


@app.command()
def prepare(
    model: Path = typer.Argument(..., help="CAD file, mesh or point cloud"),
    output: Path = typer.Option(..., "-o", "--output", help="Output .svm file"),
    spacing: Optional[float] = typer.Option(None, help="Model-point spacing [mm] (default: model size / 500, up to 2x coarser for a solid part; see prepare)"),
    reach: Optional[float] = typer.Option(None, "--reach",
                                          help="Reach of the closest-point structure [mm]: queries "
                                               "within it are answered by the grid tree, farther ones "
                                               "more slowly (default: 3 % of the model size)"),
    model_unit: Optional[str] = typer.Option(None, "--model-unit", help="Unit of the model file (default mm for STL/PLY/OBJ/point clouds; overrides the unit a CAD file declares, with a warning naming both and the size)"),
    fixture: Optional[Path] = typer.Option(None, "--fixture", help="Fixture pose T_model_scan (T.json or T.npy) saved with the model: inspections start there when no --init is given"),
    allow_incomplete_model: bool = _ALLOW_INCOMPLETE,
    max_distance: Optional[float] = _MAX_DISTANCE,
):
    """Import a model and pre-compute its closest-point structure (once per model)."""
    reach = _renamed(max_distance, reach, "--max-distance", "--reach")
    _prestart_importer(model)
    from shapeverify.pipeline import load_reference

    _require_files(model, *([fixture] if fixture is not None else []))
    T_fixture = _guard(_read_init, fixture) if fixture is not None else None
    prep = _guard(load_reference, model, spacing=spacing, reach=reach, stage=_stage,
                  model_unit=model_unit, allow_incomplete=allow_incomplete_model)
    if T_fixture is not None:
        prep.fixture = T_fixture
    with _stage(f"Writing {output.name}"):
        _guard(prep.save, output)
    out.print(f"{output}: {prep.n_points:,} model points, spacing {prep.model_spacing:.3g} mm, "
              f"reach {prep.reach:.3g} mm" + (", with a fixture pose" if prep.fixture is not None else ""))


@app.command()
def inspect(
    model: Path = typer.Argument(..., help="Prepared model (.svm, fastest) or CAD/mesh file"),
    scans: List[Path] = typer.Argument(..., metavar="SCAN...", help=f"Scan: {scan_help()}. Several scans (or an E57 file with several) are views of one part: each is placed, the union inspected"),
    tolerance: Optional[float] = typer.Option(None, help="Symmetric tolerance ±MM"),
    lower: Optional[float] = _LOWER,
    upper: Optional[float] = _UPPER,
    evaluation_distance: Optional[float] = _EVALUATION_DISTANCE,
    faces: Optional[str] = _FACES,
    min_coverage: Optional[float] = _MIN_COVERAGE,
    init: Optional[str] = _INIT,
    poses: Optional[Path] = typer.Option(None, "--poses", help="With several views: their start poses, a JSON list of 4x4 T_model_scan (null: found by the global search), one per view"),
    scan_unit: Optional[str] = _SCAN_UNIT,
    model_unit: Optional[str] = typer.Option(None, "--model-unit", help="Unit of the model file (default mm for STL/PLY/OBJ/point clouds; overrides the unit a CAD file declares, with a warning naming both and the size)"),
    plan: Optional[Path] = _PLAN,
    json_path: Optional[Path] = typer.Option(None, "--json", help="Write the result as JSON"),
    report: Optional[Path] = typer.Option(None, "--report", help="Write the HTML report"),
    pdf: Optional[Path] = typer.Option(None, "--pdf", help="Write the PDF report (colour map, histogram, characteristics)"),
    png: Optional[Path] = typer.Option(None, "--png", help="Write a PNG summary"),
    colored: Optional[Path] = typer.Option(None, "--colored", help="Write a PLY coloured by deviation"),
    db: Optional[Path] = typer.Option(None, "--db", help="Append the result to this SQLite history"),
    part: Optional[str] = typer.Option(None, "--part", help="Part id stored in the history"),
    allow_incomplete_model: bool = _ALLOW_INCOMPLETE,
    max_distance: Optional[float] = _MAX_DISTANCE,
):
    """Register a scan to the model, compute deviations and decide the verdict.

    Exit code: 0 pass, 1 fail, 2 error, 3 incomplete (not enough of the part seen).
    """
    evaluation_distance = _renamed(max_distance, evaluation_distance, "--max-distance",
                                   "--evaluation-distance")
    _prestart_importer(model)
    from shapeverify.options import InspectionOptions, OutputRequest
    from shapeverify.pipeline import run_inspection

    init_file = Path(init) if init is not None and not _is_init_mode(init) else None
    _require_files(model, *scans, *([init_file] if init_file is not None else []),
                   *([plan] if plan is not None else []), *([poses] if poses else []))
    for scan in scans:
        _check_scan_suffix(model, scan)
    options = _guard(InspectionOptions.from_cli, dict(
        tolerance=tolerance, lower=lower, upper=upper, evaluation_distance=evaluation_distance,
        faces=faces, min_coverage=min_coverage, init=init, poses=poses, scan_unit=scan_unit,
        model_unit=model_unit, plan=plan), n_scans=len(scans))
    request = OutputRequest(json=json_path, report=report, pdf=pdf, png=png, colored=colored,
                            db=db)
    result, outputs = _guard(
        run_inspection, model, scans[0] if len(scans) == 1 else list(scans), options, request,
        part=part, stage=_stage, _scan_unit=scan_unit, allow_incomplete=allow_incomplete_model)
    _print_result(result)
    for label, path in (("JSON", outputs.json), ("report", outputs.report), ("PDF", outputs.pdf),
                        ("PNG", outputs.png), ("coloured PLY", outputs.colored)):
        if path is not None:
            out.print(f"{label}: {path}")
    if outputs.record_id is not None:
        out.print(f"history record {outputs.record_id} in {db}")
    raise typer.Exit(verdict_style(result.verdict).exit_code)


def _check_scan_suffix(model: Path, scan: Path) -> None:
    """Fail at once (before a model is prepared) when the scan's suffix is not a scan format --
    a model file given second: the arguments swapped."""
    from shapeverify.cad.load import MODEL_EXTENSIONS
    from shapeverify.io.formats import SCAN_SUFFIXES
    from shapeverify.pipeline import PREPARED_SUFFIX

    suffix = scan.suffix.lower()
    if suffix in SCAN_SUFFIXES:
        return
    if suffix == PREPARED_SUFFIX or suffix in MODEL_EXTENSIONS:
        swapped = (" (the arguments seem swapped)" if model.suffix.lower() in SCAN_SUFFIXES
                   else "")
        _fail(f"{scan}: is a model file, not a scan{swapped}; the order is "
              "`shapeverify inspect MODEL SCAN`")
    _fail(f"{scan}: unsupported scan extension {scan.suffix or '(none)'!r}; supported: "
          f"{', '.join(SCAN_SUFFIXES)}")


def _read_init(path: Path):
    """A 4x4 start pose from ``T.json`` or ``T.npy`` (:func:`shapeverify.registration.read_init`)."""
    from shapeverify.registration import read_init

    return read_init(path)


def _print_result(result) -> None:
    d = result.to_dict()
    style = verdict_style(result.verdict)
    colour = style.terminal
    out.print(f"[bold {colour}]verdict: {style.word}[/bold {colour}]")
    for reason in d.get("reasons", []) or []:
        out.print(f"  {escape(reason)}")
    reg = d.get("registration", {})
    dev = d.get("deviation", {})
    t = Table(title="Deviation from CAD [mm]")
    t.add_column("statistic")
    t.add_column("value", justify="right")
    for key in ("n", "mean", "std", "min", "max", "p05", "p95", "in_tolerance_fraction"):
        if key in dev:
            v = dev[key]
            t.add_row(key, f"{v:,}" if isinstance(v, int) else f"{v:.4f}")
    out.print(t)
    if reg:
        fit = d.get("fit") or {}
        if fit.get("inlier_fraction") is not None and fit.get("rms") is not None:
            out.print(f"fit: rms {fit['rms']:.4f} mm, inliers {100 * fit['inlier_fraction']:.1f} % "
                      "(the evaluated points less the isolated outliers)")
        out.print(f"registration: {reg.get('iterations')} iterations, converged "
                  f"{reg.get('converged')} (robust rms {reg.get('rms', float('nan')):.4f} mm, "
                  f"weights' inliers {100 * reg.get('inlier_fraction', 0):.1f} %)")
    cov = d.get("coverage")
    if cov:
        out.print(f"coverage: {100 * cov['fraction']:.1f} % of the inspected area "
                  f"({sig3(cov['covered_area_mm2'])} of {sig3(cov['area_mm2'])} mm²; at least "
                  f"{100 * cov['min_coverage']:.0f} % needed)")
    ex = d.get("excluded") or {}
    if any(ex.values()):
        out.print("not in the statistics: " + ", ".join(f"{v:,} {k.replace('_', ' ')}"
                                                         for k, v in ex.items() if v))
    views = d.get("views") or []
    if views:
        vt = Table(title="Views (mm)")
        for col in ("view", "points", "used", "rms (mm)", "inliers", "coverage alone",
                    "verdict alone", "rotation (deg)", "translation (mm)"):
            vt.add_column(col)
        for v in views:
            T = v.get("T_model_scan")
            rot = tr = "-"
            if T is not None:
                import numpy as np

                from shapeverify.registration.rigid import rotation_vector
                rot = f"{np.degrees(np.linalg.norm(rotation_vector(np.asarray(T)[:3, :3]))):.2f}"
                tr = f"{float(np.linalg.norm(np.asarray(T)[:3, 3])):.2f}"
            vt.add_row(v["name"], f"{v['n_points']:,}", "yes" if v["used"] else "NO",
                       f"{v['rms']:.4f}" if v.get("rms") is not None else "-",
                       f"{100 * v['inlier_fraction']:.1f} %" if v.get("inlier_fraction") is not None else "-",
                       f"{100 * (v.get('coverage') or 0):.1f} %", v.get("verdict") or "-", rot, tr)
        out.print(vt)
    chars = d.get("characteristics") or []
    if chars:
        from shapeverify.characteristics.evaluate import format_value as _fmt_value
        from shapeverify.characteristics.zone_noise import noise_note
        from shapeverify.report.fcf import fcf_text
        plan = getattr(getattr(result, "plan", None), "plan", None)    # the Plan, if any
        entries = {e.name: e for e in getattr(plan, "characteristics", ())}
        ct = Table(title="Characteristics [mm]")
        for col in ("name", "type", "frame", "measured", "deviation", "limits", "uncertainty U",
                    "verdict"):
            ct.add_column(col)
        for c in chars:
            ct.add_row(str(c.get("name")), str(c.get("type")),
                       fcf_text(c, entries.get(c.get("name"))),
                       _fmt_value(c.get("measured")) + (f"\n({_note})" if (
                           _note := noise_note(c.get("details"))) else ""),
                       _fmt_value(c.get("deviation"), signed=True),
                       format_limits(c.get("lower"), c.get("upper")),
                       _fmt_value(c.get("uncertainty")), str(c.get("verdict")))
        out.print(ct)
    regions = d.get("regions") or []
    if regions:
        rt = Table(title="Regions (most severe first)")
        for col in ("#", "kind", "points", "area [mm²]", "extreme [mm]", "severity [mm³]", "centroid [mm]"):
            rt.add_column(col)
        for i, r in enumerate(regions[:20]):
            c = r.get("centroid", [0, 0, 0])
            rt.add_row(str(i + 1), r.get("kind", "deviation"), str(r.get("n")), sig3(r.get("area", 0)),
                       f"{r['extreme']:+.3f}" if r.get("extreme") is not None else "–", f"{r.get('severity', 0):.3g}",
                       f"({c[0]:.1f}, {c[1]:.1f}, {c[2]:.1f})")
        out.print(rt)
        if len(regions) > 20:
            out.print(f"... and {len(regions) - 20} more regions (see the JSON)")


@app.command()
def history(
    db: Path = typer.Option(..., "--db", help="SQLite history file"),
    part: Optional[str] = typer.Option(None, "--part", help="Only this part id"),
    limit: int = typer.Option(50, help="Most recent N records"),
    plot: Optional[Path] = typer.Option(None, "--plot", help="Write trend charts (PNG)"),
    characteristic: Optional[str] = typer.Option(None, "--characteristic", help="A plan characteristic: its run chart with control limits and Cp/Cpk (a hole's name gives both series)"),
    csv_out: Optional[Path] = typer.Option(None, "--csv", help="With --characteristic: export its history as CSV"),
    model: Optional[str] = typer.Option(None, "--model", help="Only this model: its SHA-256 (a unique prefix is enough) or the model file itself"),
):
    """List past inspections and draw trend charts for process control (SPC)."""
    from shapeverify.report.history import plot_trend

    if characteristic is not None:
        from shapeverify.cli_plan import print_characteristic_history
        print_characteristic_history(db, characteristic, part=part, limit=limit, plot=plot,
                                     csv_out=csv_out)
        return

    if not db.exists():
        _fail(f"{db}: no such history file (create one with `shapeverify inspect ... --db {db}`)")
    rows, models = _guard(_history_rows, db, part, limit, model)
    t = Table(title=f"{db} ({len(rows)} records)")
    for col in ("id", "time", "part", "model", "verdict", "min [mm]", "max [mm]", "max |d| [mm]",
                "limits [mm]", "regions"):
        t.add_column(col)
    def f(v, beyond=False):
        from rich.text import Text
        text = "-" if v is None or v != v else f"{v:+.4f}"
        return Text(text, style="red" if beyond else "")

    for r in rows:
        lo, hi = r.get("lower"), r.get("upper")
        known = lo is not None and hi is not None and lo == lo and hi == hi
        lim = f"{lo:+.3g} / {hi:+.3g}" if known else "-"
        t.add_row(str(r["id"]), str(r["time"]), str(r.get("part") or ""),
                  str(r.get("model_hash") or "-")[:12], r["verdict"],
                  f(r.get("min"), known and r["min"] < lo), f(r.get("max"), known and r["max"] > hi),
                  f(r.get("max_abs")).plain.lstrip("+"), lim, str(r.get("n_regions") or 0))
    out.print(t)
    _print_characteristic_listing(db, part, rows if model is not None else None)
    shown = sorted({str(r.get("model_hash")) for r in rows})
    if len(shown) > 1:
        out.print(f"{len(shown)} models in these records; one chart per model: add --model "
                  "(" + ", ".join(f"{m['model_hash'][:12]} {m['name'] or ''}".strip()
                                  for m in models if m["model_hash"]) + ")")
    if plot:
        chart = rows
        if len(shown) > 1:   # one chart shows one model: the latest record's, unless --model
            latest = max(rows, key=lambda r: r["id"])["model_hash"]
            chart = [r for r in rows if r.get("model_hash") == latest]
            out.print(f"the trend chart shows model {str(latest)[:12]} (the latest record's, "
                      f"{len(chart)} of {len(rows)} records); choose another with --model")
        _guard(plot_trend, chart, plot)
        out.print(f"trend chart: {plot}")


def _print_characteristic_listing(db: Path, part, rows=None) -> None:
    """The characteristic series of the history (plan inspections): each with its feature
    control frame, its number of values, its latest limits and verdict; ``rows``: only the
    values of these inspections (``--model``)."""
    from shapeverify.report.history_fcf import characteristic_listing

    ids = None if rows is None else {r["id"] for r in rows}
    series = _guard(characteristic_listing, db, part, ids)
    if not series:
        return
    t = Table(title=f"Characteristics ({len(series)} series; history --characteristic NAME "
                    "for one's Cp/Cpk)")
    for col in ("characteristic", "type", "frame", "values", "limits", "latest verdict"):
        t.add_column(col)
    for c in series:
        lo, hi, unit = c["lower"], c["upper"], c["unit"]
        lim = ("-" if hi is None else f"≤ {hi:.4g} {unit}" if lo is None else
               f"{lo:+.4g} .. {hi:+.4g} {unit}")
        t.add_row(c["name"], str(c["type"]), c["frame"], str(c["n"]), lim, str(c["verdict"]))
    out.print(t)


def _history_rows(db: Path, part, limit: int, model=None) -> tuple:
    from shapeverify.report.history import HistoryDB

    if model is not None and Path(model).is_file():
        from shapeverify.pipeline import file_hash
        model = file_hash(model)
    with HistoryDB(db) as h:
        return h.query(part=part, limit=limit, model=model), h.models()


@app.command()
def unwrap(
    input: Path = typer.Argument(..., help="Wrapped phase: .npy, .png or .tif"),
    output: Path = typer.Option(..., "-o", "--output", help="Unwrapped phase (.npy)"),
    method: str = typer.Option("auto", help="auto | quality | ls | wls | lp"),
    mask: Optional[Path] = typer.Option(None, help="Mask image/array (nonzero = valid)"),
    plot: Optional[Path] = typer.Option(None, help="Write a PNG of wrapped and unwrapped phase"),
):
    """Unwrap a wrapped phase map (radians)."""
    from shapeverify.phase.files import unwrap_file

    with _stage(f"Unwrapping {input.name}"):
        summary = _guard(unwrap_file, input, output, method=method, mask_path=mask, plot_path=plot)
    for k, v in summary.items():
        out.print(f"{k}: {v}")


@app.command()
def hologram(
    h1: Path = typer.Argument(..., help="Off-axis hologram at --lambda1 (intensity: .npy, .png, .tif)"),
    h2: Path = typer.Argument(..., help="Off-axis hologram at --lambda2"),
    output: Path = typer.Option(..., "-o", "--output", help="Depth map (.npy, mm, NaN = not measured)"),
    lambda1: float = typer.Option(..., help="Wavelength of H1 in mm (e.g. 632.8e-6)"),
    lambda2: float = typer.Option(..., help="Wavelength of H2 in mm"),
    reference: Optional[Path] = typer.Option(None, help="CAD-predicted depth map (.npy, mm) that regularises the unwrapping"),
    pitch: Optional[float] = typer.Option(None, help="Pixel pitch in mm (needed with --distance)"),
    distance: float = typer.Option(0.0, help="Propagation from the image plane to the camera (mm)"),
    window: int = typer.Option(5, help="Speckle filter window (odd)"),
):
    """Depth map from two off-axis holograms at two wavelengths (carrier filtering, synthetic wavelength)."""
    from shapeverify.phase.hologram import hologram_file

    with _stage(f"Reconstructing {h1.name} and {h2.name}"):
        summary = _guard(hologram_file, h1, h2, output, lambda1, lambda2, reference_path=reference,
                         pixel_pitch=pitch, distance=distance, window=window)
    for k, v in summary.items():
        out.print(f"{k}: {v}")


@app.command()
def fit(
    points: Path = typer.Argument(..., help="Points: .ply .xyz .txt .csv .npy .pcd"),
    output: Path = typer.Option(..., "-o", "--output", help=".step, .igs/.iges or .json (an --element: .json)"),
    surface: bool = typer.Option(False, "--surface", help="Fit a surface (default: a curve)"),
    element: Optional[str] = typer.Option(None, "--element", help="Fit a geometric element instead of a NURBS: sphere, cylinder, cone, plane, line or circle"),
    loss: str = typer.Option("l2", "--loss", help="With --element: l2 (least squares) or a robust loss (tukey, huber, cauchy, welsch) that ignores stray points"),
    unit: Optional[str] = typer.Option(None, "--unit", help="With --element: the unit of the points file (mm, cm, m, in, um); the result is then in mm"),
    ctrl: List[int] = typer.Option([10], "--ctrl", help="Control points: N (curve); a surface: --ctrl NU --ctrl NV (one value: NU = NV)"),
    degree: int = typer.Option(3, help="Degree"),
    method: str = typer.Option("odr", help="odr (Gauss-Newton, orthogonal distance) | varpro | fixed"),
    smoothing: float = typer.Option(0.0, help="Smoothness weight (needed when the points leave parts "
                                              "of the parameter domain empty)"),
    slide_stiffness: float = typer.Option(100.0, help="Resistance of the control points to sliding along "
                                                      "the shape (0: plain orthogonal distance, which "
                                                      "folds to follow noisy data)"),
):
    """Fit a NURBS curve or surface (or, with --element, a sphere, cylinder, ...) to points by
    orthogonal distance and write it out."""
    from shapeverify.fitting.export import fit_points_file

    if element is not None:
        from shapeverify.fitting.element_file import fit_element_file

        if surface:
            _fail("--surface fits a NURBS surface; leave it out with --element")
        with _stage(f"Fitting a {element} to {points.name}"):
            summary = _guard(fit_element_file, points, output, element, loss=loss, unit=unit)
        for k, v in summary.items():
            out.print(f"{k}: {v}")
        return

    n = tuple(ctrl) if surface else ctrl[0]
    if surface and len(n) == 1:
        n = (n[0], n[0])
    with _stage(f"Fitting {'surface' if surface else 'curve'} to {points.name}"):
        summary = _guard(fit_points_file, points, output, surface=surface, ctrl=n, degree=degree,
                         method=method, smoothing=smoothing, slide_stiffness=slide_stiffness)
    for k, v in summary.items():
        out.print(f"{k}: {v}")


@app.command()
def worker(
    action: str = typer.Argument(..., help="start | stop | status"),
    idle: float = typer.Option(30.0, "--idle", help="start: stop the worker after this many minutes without a command"),
):
    """A resident worker that keeps the libraries and kernels loaded, so later commands answer
    in a fraction of the time (the first command that runs the kernels -- inspect, prepare,
    measure, unwrap, hologram, fit, calibrate -- starts it and runs in it, unless
    SHAPEVERIFY_WORKER=0; SHAPEVERIFY_NO_WORKER=1 ignores it).

    Exit code of status: 0 a worker runs, 1 none does.
    """
    from shapeverify import cli_worker

    if action == "start":
        with _stage("Starting the worker", watch=False):
            st = _guard(cli_worker.start, idle)
        what = "already running" if st.get("already") else "started"
        out.print(f"worker {what}: pid {st['pid']}, socket {st['socket']}; stop it with "
                  "`shapeverify worker stop`")
    elif action == "stop":
        st = cli_worker.stop()
        out.print("no worker running" if st is None else
                  f"worker stopped (pid {st['pid']}, {st['requests']} commands served, "
                  f"{st['cpu']:.2f} s CPU)")
    elif action == "status":
        st = cli_worker.status()
        if st is None:
            out.print(f"no worker running (socket {cli_worker.socket_path()})")
            raise typer.Exit(1)
        current = st["key"] == cli_worker.version_key()
        out.print(f"worker running: pid {st['pid']}, socket {st['socket']}, "
                  f"{st['requests']} commands served, {st['cpu']:.2f} s CPU, "
                  f"{'busy' if st['busy'] else 'idle'}"
                  + ("" if current else "; STALE (another version: commands run in-process)"))
    else:
        _fail(f"worker {action}: unknown action; one of start, stop, status")


# the commands of the optical chain and of the front ends live in their own modules
from .cli_frontends import register_commands as _register_frontends  # noqa: E402 (serve, batch)
from .cli_optics import register_commands as _register_optics  # noqa: E402  (measure, calibrate)

_register_optics(app)
_register_frontends(app)


def main() -> None:  # pragma: no cover - entry point
    """Entry point: run the command line (exit codes in the module docstring)."""
    app(prog_name="shapeverify")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
