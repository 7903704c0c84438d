"""The one place that wires the stages together: file -> model -> prepared -> inspection -> outputs.

Front ends (``cli.py``, the service) call these functions; the stages themselves never call each
other's front ends. Each function takes an optional ``stage`` callback, a context-manager factory
``stage(name)`` that the command line turns into a progress line; the library itself never prints.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, ContextManager

log = logging.getLogger(__name__)

Stage = Callable[[str], ContextManager]

PREPARED_SUFFIX = ".svm"


def _no_stage(name: str) -> ContextManager:
    return contextlib.nullcontext()


def file_hash(path: str | Path) -> str:
    """SHA-256 of a file's bytes (hex), used to tie history records to the exact model file."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def load_reference(path: str | Path, spacing: float | None = None,
                   reach: float | None = None, stage: Stage | None = None, *,
                   model_unit: str | None = None):
    """Load a prepared model (``.svm``) or import and prepare a CAD/mesh/point-cloud model.

    Parameters
    ----------
    path : str or Path
        ``.svm`` (prepared, fastest), or any model file ``shapeverify.load_model`` reads.
    spacing, reach : float, optional
        Model-point spacing and the reach of the closest-point structure (queries within it are
        answered by the grid tree), mm, for preparation (ignored for ``.svm``).
    model_unit : str, optional
        The unit of a mesh or point-cloud reference (STL/PLY/OBJ carry none; default mm), see
        :mod:`shapeverify.units`.

    Returns
    -------
    prepared : shapeverify.nearest.Prepared
    """
    from shapeverify.cad.load import load_model
    from shapeverify.nearest import load_prepared, prepare

    stage = stage or _no_stage
    path = Path(path)
    if path.suffix.lower() == PREPARED_SUFFIX:
        if model_unit not in (None, "mm"):
            raise ValueError(f"{path.name} is a prepared model, already in mm; give the unit when "
                             "preparing it (shapeverify prepare MODEL --model-unit ...)")
        with stage(f"Loading prepared model {path.name}"):
            return load_prepared(path)
    with stage(f"Importing {path.name}"):
        model = load_model(path)
        if model_unit is not None:
            from shapeverify.units import scale_model
            model = scale_model(model, model_unit)
    with stage(f"Preparing closest-point structure ({len(model.faces)} faces)"):
        return prepare(model, spacing=spacing, reach=reach)


@dataclass
class InspectionOutputs:
    """Where the outputs of one inspection were written (None: not requested)."""

    json: Path | None = None
    report: Path | None = None
    pdf: Path | None = None
    png: Path | None = None
    colored: Path | None = None
    record_id: int | None = None
    timings: dict = field(default_factory=dict)


def run_inspection(model_path: str | Path, scan_path: str | Path, tolerance: float,
                   evaluation_distance: float | None = None, lower: float | None = None,
                   upper: float | None = None, json_path=None, report_path=None, png_path=None,
                   colored_path=None, db_path=None, part: str | None = None,
                   stage: Stage | None = None, *, faces=None, min_coverage: float | None = None,
                   init=None, scan_unit: str | None = None, model_unit: str | None = None,
                   plan=None, pdf_path=None):
    """Inspect one scan against one model and write the requested outputs.

    ``evaluation_distance``, ``faces``, ``min_coverage`` and ``init`` are passed to
    :func:`shapeverify.inspect` (None: its defaults); ``scan_unit`` / ``model_unit`` give the
    units of files that carry none (:mod:`shapeverify.units`). ``plan``: an inspection plan
    (``plan.yaml``, :mod:`shapeverify.characteristics`); ``pdf_path``: the PDF report. The result carries ``inputs`` (part id,
    scan and model file names, the model file's SHA-256).

    Returns
    -------
    result : shapeverify.inspection.InspectionResult
    outputs : InspectionOutputs
    """
    import json

    from shapeverify.inspection import inspect
    from shapeverify.io.points import read_points

    stage = stage or _no_stage
    out = InspectionOutputs()
    t0 = time.perf_counter()
    prep = load_reference(model_path, stage=stage, model_unit=model_unit)
    out.timings["load_model_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    with stage(f"Reading scan {Path(scan_path).name}"):
        scan = read_points(scan_path)
        if scan_unit is not None:
            from shapeverify.units import scale_points
            scan = scale_points(scan, scan_unit)
    out.timings["read_scan_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    opts = {} if min_coverage is None else {"min_coverage": min_coverage}
    with stage(f"Registering and inspecting {len(scan):,} points"):
        result = inspect(prep, scan, tolerance=tolerance, evaluation_distance=evaluation_distance,
                         lower=lower, upper=upper, faces=faces, init=init, plan=plan, **opts)
    out.timings["inspect_s"] = time.perf_counter() - t0
    # the model file's hash ties the written outputs to it; no need to read the file again without
    outputs = (json_path, report_path, png_path, pdf_path, colored_path, db_path)
    model_hash = file_hash(model_path) if any(outputs) else None
    result = dataclasses.replace(result, inputs={
        "part": part, "scan": Path(scan_path).name, "model": Path(model_path).name,
        "model_sha256": model_hash})

    t0 = time.perf_counter()
    if json_path:
        out.json = Path(json_path)
        payload = result.to_dict()
        payload["timings"] = {**payload.get("timings", {}), **out.timings}
        out.json.write_text(json.dumps(payload, indent=2))
    if report_path:
        from shapeverify.report.html import write_html_report
        with stage("Writing HTML report"):
            out.report = Path(write_html_report(result, prep, scan, report_path))
    if png_path:
        from shapeverify.report.png import write_png_summary
        with stage("Writing PNG summary"):
            out.png = Path(write_png_summary(result, scan, png_path))
    if pdf_path:
        from shapeverify.characteristics import evaluate_plan
        from shapeverify.characteristics.pdf import write_pdf_report
        with stage("Writing PDF report"):
            plan_result = result.plan if result.plan is not None else evaluate_plan(
                prep, scan, None, registration=result.registration)
            out.pdf = Path(write_pdf_report(
                plan_result, pdf_path, prep, part=part, scan_file=Path(scan_path).name,
                model_file=Path(model_path).name, tolerance=result.tolerance.max_abs))
    if colored_path:
        from shapeverify.report.ply import write_colored_ply
        out.colored = Path(write_colored_ply(result, scan, colored_path))
    if db_path:
        from shapeverify.report.history import HistoryDB
        with HistoryDB(db_path) as db:
            out.record_id = db.add(result, part=part, model_hash=model_hash)
        if result.plan is not None:
            from shapeverify.characteristics.spc import store_characteristics
            store_characteristics(db_path, result.plan, part=part, inspection_id=out.record_id)
    out.timings["outputs_s"] = time.perf_counter() - t0
    return result, out
