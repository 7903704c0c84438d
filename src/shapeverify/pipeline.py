"""The one place that wires the stages together: file -> model -> prepared -> inspection -> outputs.

:func:`inspect_scan` runs one inspection -- scan source (path, bytes, file object) -> points ->
registration and deviations -> :class:`ScanInspection` -- and all three front ends call it: the
command line (through :func:`run_inspection`, which also loads the model and writes the
outputs), the service (``service/``) and batch (``batch.py``).  The stages themselves never call
a front end.  Functions take an optional ``stage`` callback, a context-manager factory
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

import numpy as np

log = logging.getLogger(__name__)

Stage = Callable[[str], ContextManager]

PREPARED_SUFFIX = ".svm"


def _no_stage(name: str) -> ContextManager:
    return contextlib.nullcontext()


def file_hash(path: str | Path) -> str:
    """SHA-256 of a file's bytes (hex), used to tie history records to the exact model file
    (remembered for an unchanged file where :mod:`shapeverify._file_memo` is enabled)."""
    from shapeverify._file_memo import FILE_HASHES

    return FILE_HASHES.call(_sha256, path)


def _sha256(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def load_reference(path: str | Path, spacing: float | None = None,
                   reach: float | None = None, stage: Stage | None = None, *,
                   model_unit: str | None = None, allow_incomplete: bool = False):
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
    allow_incomplete : bool
        Prepare a CAD model that lacks faces its file declares (see
        :func:`shapeverify.prepare`); default False: an ``IncompleteModelError``.

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
        return prepare(model, spacing=spacing, reach=reach, allow_incomplete=allow_incomplete)


@dataclass(frozen=True, eq=False)
class ScanInspection:
    """One scan inspected (:func:`inspect_scan`).

    Attributes
    ----------
    result : shapeverify.inspection.InspectionResult
    scan : (N, 3) float64
        The scan points that were inspected (mm, after ``scan_unit`` scaling), e.g. for reports.
    timings : dict
        ``read_scan_s`` and ``inspect_s`` (seconds).
    """

    result: object
    scan: np.ndarray
    timings: dict = field(default_factory=dict)

    def __repr__(self) -> str:
        return (f"ScanInspection(verdict={self.result.verdict!r}, n={len(self.scan)}, "
                f"timings={ {k: round(v, 3) for k, v in self.timings.items()} })")


def inspect_scan(prepared, scan_source, options=None, *, scan_format: str | None = None,
                 scan_name: str | None = None, progress=None, stage: Stage | None = None,
                 **kwargs) -> ScanInspection:
    """Read a scan and inspect it against a prepared model: the one inspection of every front end.

    Parameters
    ----------
    prepared : shapeverify.nearest.Prepared
    scan_source : path, bytes, binary file object, or (N, 3) array_like, or a list of them
        The scan file (any format of :func:`shapeverify.io.points.read_points`), its content,
        or points already read (mm). A list is several views of one part, and so is an E57
        file with several scans (:func:`shapeverify.inspection.inspect_views`; ``init`` then a
        list of start poses, one per view).
    options : shapeverify.InspectionOptions, optional
        Every setting of the inspection (tolerance, evaluation distance, faces, init, plan,
        ``scan_unit``: the unit of a scan file that carries none ...).  Instead, the keywords of
        :func:`shapeverify.inspect` and ``scan_unit`` may be given (``**kwargs``).
    scan_format : str, optional
        The scan's format as a suffix (``".ply"``); needed for bytes (default: the path's suffix).
    scan_name : str, optional
        Stands for the scan in messages (default: the path or the file object's name).
    progress : callable(stage: str, fraction: float), optional
        Called after the scan is read (``"read_scan"``) and then by :func:`shapeverify.inspect`;
        it may raise to stop the inspection (the service's time limit does).
    stage : callable(name) -> context manager, optional
        Wraps each stage (the command line's progress lines).

    Returns
    -------
    ScanInspection

    Raises
    ------
    ScanError, UnsupportedFormatError, RegistrationError, ValueError, FileNotFoundError
        As :func:`~shapeverify.io.points.read_points` and :func:`shapeverify.inspect`.

    Examples
    --------
    >>> import numpy as np
    >>> from shapeverify.cad.examples import wavy_panel
    >>> from shapeverify.io.points import ply_bytes
    >>> from shapeverify.nearest import prepare
    >>> prep = prepare(wavy_panel(), spacing=3.0)
    >>> scan = prep.points.points[::3] + [0.3, -0.2, 0.1]
    >>> a = inspect_scan(prep, scan, tolerance=0.2)
    >>> b = inspect_scan(prep, ply_bytes(scan), scan_format=".ply", tolerance=0.2)
    >>> a.result.verdict == b.result.verdict, a.result.registration.rms == b.result.registration.rms
    (True, True)
    """
    from shapeverify.inspection import inspect
    from shapeverify.io.points import read_points
    from shapeverify.options import InspectionOptions

    if options is None:
        options = InspectionOptions.from_kwargs(**kwargs)
    elif kwargs:
        raise TypeError("give the options either as options= or as keywords, not both (also "
                        f"given: {', '.join(sorted(kwargs))})")
    scan_unit = options.scan_unit
    stage = stage or _no_stage
    if isinstance(scan_source, (str, Path)) and (scan_format or Path(scan_source).suffix).lower() \
            .lstrip(".") == "e57":
        scan_source = [scan_source]          # an E57 file with several scans is several views
    if isinstance(scan_source, (list, tuple)) and not isinstance(scan_source[0], (float, int)):
        views, names, shared = _read_views(scan_source, scan_format, scan_unit, stage)
        if len(views) > 1:
            return _inspect_views(prepared, views, names, shared, stage, progress, options)
        scan_source, scan_unit = views[0], None
    timings = {}
    t0 = time.perf_counter()
    if isinstance(scan_source, np.ndarray):
        scan = np.asarray(scan_source, dtype=np.float64)
    else:
        label = scan_name or (Path(scan_source).name if isinstance(scan_source, (str, Path))
                              else getattr(scan_source, "name", "scan"))
        with stage(f"Reading scan {label}"):
            scan = read_points(scan_source, scan_format, name=scan_name)
    if scan_unit is not None:
        from shapeverify.units import scale_points
        scan = scale_points(scan, scan_unit)
    timings["read_scan_s"] = time.perf_counter() - t0
    if progress is not None:
        progress("read_scan", 1.0)

    t0 = time.perf_counter()
    with stage(f"Registering and inspecting {len(scan):,} points"):
        result = inspect(prepared, scan, options=options, progress=progress)
    timings["inspect_s"] = time.perf_counter() - t0
    return ScanInspection(result, scan, timings)


def _read_views(sources, scan_format, scan_unit, stage):
    """The views of several scan sources (an E57 file with several scans gives each of them):
    (views, names, shared_frame)."""
    from shapeverify.io.points import read_points

    views, names = [], []
    e57_multi = False
    for src in sources:
        label = Path(src).name if isinstance(src, (str, Path)) else getattr(src, "name", "scan")
        if isinstance(src, np.ndarray):
            pts = [np.asarray(src, np.float64)]
            labels = [f"view {len(views) + 1}"]
        elif (scan_format or Path(str(label)).suffix).lower().lstrip(".") == "e57":
            from shapeverify.io.e57 import read_e57_views
            with stage(f"Reading scan {label}"):
                ev = read_e57_views(src) if isinstance(src, (str, Path)) else \
                    read_e57_views(src.read() if hasattr(src, "read") else src, label)
            pts = [v.points for v in ev]
            labels = [f"{label}:{v.name}" if len(ev) > 1 else label for v in ev]
            e57_multi |= len(ev) > 1
        else:
            with stage(f"Reading scan {label}"):
                pts = [read_points(src, scan_format)]
            labels = [label]
        if scan_unit is not None and not str(label).lower().endswith(".e57"):
            from shapeverify.units import scale_points
            pts = [scale_points(p, scan_unit) for p in pts]
        views += pts
        names += labels
    return views, names, e57_multi and len(sources) == 1


def _inspect_views(prepared, views, names, shared, stage, progress, options):
    """Several views of one part (:func:`shapeverify.inspection.inspect_views`)."""
    from shapeverify.inspection import inspect_views

    if options.plan is not None:
        raise ValueError("an inspection plan with several views is not supported yet: inspect "
                         "the views one by one, or merge them into one scan first")
    poses = options.init_pose
    if poses is not None and not isinstance(poses, list):
        raise ValueError("with several views give one start pose per view (--poses "
                         "poses.json: a list of 4x4 T_model_scan, null for none), not one "
                         "--init")
    t0 = time.perf_counter()
    with stage(f"Registering and inspecting {len(views)} views "
               f"({sum(len(v) for v in views):,} points)"):
        result = inspect_views(prepared, views, names=names, poses=poses, shared_frame=shared,
                               **options.view_kwargs())
    if progress is not None:
        progress("done", 1.0)
    union = np.concatenate([views[i] @ v.T_model_scan[:3, :3].T + v.T_model_scan[:3, 3]
                            for i, v in enumerate(result.views) if v.used])
    return ScanInspection(result, union, {"inspect_s": time.perf_counter() - t0})


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


def run_inspection(model_path: str | Path, scan_path, options, outputs=None, *,
                   part: str | None = None, stage: Stage | None = None,
                   allow_incomplete: bool = False):
    """Inspect one scan file (or several views) against one model file and write the requested
    outputs (``shapeverify inspect``): :func:`load_reference`, :func:`inspect_scan`,
    :func:`write_outputs`.

    Parameters
    ----------
    model_path : path
        Prepared model (``.svm``) or a model file (its unit: ``options.model_unit``).
    scan_path : path or list of paths
        The scan (several: views of one part).
    options : shapeverify.InspectionOptions
        Every setting of the inspection.
    outputs : shapeverify.OutputRequest, optional
        What to write (None: nothing).
    part : str, optional
        The part id (history, reports).
    stage : callable(name) -> context manager, optional
        Wraps each stage (the command line's progress lines).
    allow_incomplete : bool
        Prepare a CAD model that lacks faces its file declares (:func:`shapeverify.prepare`).

    Returns
    -------
    result : shapeverify.inspection.InspectionResult
        With ``inputs`` (part id, scan and model file names, the model file's SHA-256).
    outputs : InspectionOutputs
    """
    from shapeverify.options import OutputRequest

    request = outputs if outputs is not None else OutputRequest()
    stage = stage or _no_stage
    out = InspectionOutputs()
    t0 = time.perf_counter()
    prep = load_reference(model_path, stage=stage, model_unit=options.model_unit,
                          allow_incomplete=allow_incomplete)
    out.timings["load_model_s"] = time.perf_counter() - t0

    done = inspect_scan(prep, scan_path, options, stage=stage)
    out.timings.update(done.timings)
    # the model file's hash ties the written outputs to it; no need to read the file again without
    model_hash = file_hash(model_path) if request.files else None
    scan_names = ([Path(p).name for p in scan_path] if isinstance(scan_path, (list, tuple))
                  else [Path(scan_path).name])
    result = dataclasses.replace(done.result, inputs={
        "part": part, "scan": ", ".join(scan_names), "model": Path(model_path).name,
        "model_sha256": model_hash})
    write_outputs(result, request.replace(part=part, model_hash=model_hash), prep=prep,
                  scan=done.scan, stage=stage, out=out)
    return result, out


#: keys of a result dict that its history row leaves out (a batch task's own figures)
_NOT_STORED = ("worker_seconds", "record_id", "_report_html")


def write_outputs(result, request, *, prep=None, scan=None, stage: Stage | None = None,
                  out: InspectionOutputs | None = None, commit: Callable[[], bool] | None = None,
                  history=None) -> InspectionOutputs | None:
    """Write what ``request`` (an :class:`~shapeverify.OutputRequest`) asks for of one
    inspection: the one writer of the command line, the service and batch.

    The order: the reports (HTML, PNG, PDF, coloured PLY), then the history row, then the JSON
    (last, so that a JSON on disk means everything before it was written: batch skips such
    scans when it runs again).

    Parameters
    ----------
    result : InspectionResult or dict
        The result, or its JSON-ready dict (what a batch worker sends back, with its HTML
        report, rendered where the points are, under ``"_report_html"``; a dict gets its
        ``record_id`` when it is stored).  PNG, PDF and coloured PLY need the result itself.
    request : shapeverify.OutputRequest
    prep, scan
        The prepared model and the scan points (mm), for the reports of a result.
    stage : callable(name) -> context manager, optional
        Wraps each slow output (the command line's progress lines).
    out : InspectionOutputs, optional
        Filled in and returned (its ``timings`` go into the JSON, plus ``outputs_s``).
    commit : callable() -> bool, optional
        Asked just before the history row is written: False stores nothing more and returns
        None (the service's request that timed out meanwhile).
    history : HistoryDB, optional
        An open history to write the row to (the service keeps one per thread); default: open
        ``request.db``.

    Returns
    -------
    InspectionOutputs, or None when ``commit`` said no.
    """
    stage = stage or _no_stage
    out = out if out is not None else InspectionOutputs()
    is_dict = isinstance(result, dict)
    if is_dict and (request.png or request.pdf or request.colored):
        raise ValueError("a PNG, PDF or coloured PLY is drawn from the InspectionResult, not "
                         "from its dict")
    t0 = time.perf_counter()
    if request.report:
        with stage("Writing HTML report"):
            out.report = _write_report(result, request.report, prep, scan)
    if request.png:
        from shapeverify.report import write_png_summary
        with stage("Writing PNG summary"):
            out.png = write_png_summary(result, scan, request.png)
    if request.pdf:
        with stage("Writing PDF report"):
            out.pdf = _write_pdf(result, request, prep)
    if request.colored:
        from shapeverify.report import write_colored_ply
        out.colored = write_colored_ply(result, scan, request.colored)
    if request.db or history is not None:
        if commit is not None and not commit():
            return None
        out.record_id = _store(result, request, history)
        if is_dict:
            result["record_id"] = out.record_id
    if request.json:
        if is_dict:
            out.json = _write_json_atomically(request.json, result)
        else:
            from shapeverify.report.result_json import write_result_json
            out.json = write_result_json(result, request.json, timings=out.timings)
    out.timings["outputs_s"] = time.perf_counter() - t0
    return out


def _write_report(result, path: Path, prep, scan) -> Path:
    if isinstance(result, dict):
        html = result.pop("_report_html", None)
        if html is None:
            raise ValueError(f"{path}: an HTML report of a result dict needs its rendered "
                             "'_report_html'")
        path.write_text(html, encoding="utf-8")
        return path
    from shapeverify.report import write_html_report
    return write_html_report(result, prep, scan, path)


def _write_pdf(result, request, prep) -> Path:
    from shapeverify.characteristics.pdf import ReportLabels, write_pdf_report
    from shapeverify.inspection.plan_link import plan_result_of

    plan_result = plan_result_of(result)   # no plan: the inspection's own pose
    inputs = result.inputs or {}
    return Path(write_pdf_report(
        plan_result, request.pdf, prep, tolerance=result.tolerance.max_abs,
        labels=ReportLabels(part=request.part, scan_file=inputs.get("scan"),
                            model_file=inputs.get("model")),
        regions=result.regions))


def _store(result, request, history) -> int:
    """The history row (added, or replacing ``request.replace_record``); a plan's
    characteristics beside it."""
    from shapeverify.report.history import HistoryDB

    row = {k: v for k, v in result.items() if k not in _NOT_STORED} \
        if isinstance(result, dict) else result
    db = history if history is not None else HistoryDB(request.db)
    try:
        if request.replace_record is not None:
            record_id = db.replace(request.replace_record, row, part=request.part,
                                   model_hash=request.model_hash)
        else:
            record_id = db.add(row, part=request.part, model_hash=request.model_hash)
    finally:
        if history is None:
            db.close()
    if not isinstance(result, dict) and result.plan is not None:
        from shapeverify.characteristics.spc import store_characteristics
        store_characteristics(db.path, result.plan, part=request.part, inspection_id=record_id)
    return record_id


def _write_json_atomically(path: Path, data: dict) -> Path:
    """``data`` as JSON at ``path``, complete or absent (written to a temporary name, renamed):
    a half-written JSON would be taken for a finished scan."""
    import json
    import os

    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=2))
    os.replace(tmp, path)
    return path
