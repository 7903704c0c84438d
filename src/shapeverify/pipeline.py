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
    """SHA-256 of a file's bytes (hex), used to tie history records to the exact model file."""
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


def inspect_scan(prepared, scan_source, *, tolerance: float | None,
                 evaluation_distance: float | None = None, lower: float | None = None,
                 upper: float | None = None, faces=None, min_coverage: float | None = None,
                 init=None, plan=None, scan_format: str | None = None,
                 scan_name: str | None = None, scan_unit: str | None = None, progress=None,
                 stage: Stage | None = None) -> ScanInspection:
    """Read a scan and inspect it against a prepared model: the one inspection of every front end.

    Parameters
    ----------
    prepared : shapeverify.nearest.Prepared
    scan_source : path, bytes, binary file object, or (N, 3) array_like, or a list of them
        The scan file (any format of :func:`shapeverify.io.points.read_points`), its content,
        or points already read (mm). A list is several views of one part, and so is an E57
        file with several scans (:func:`shapeverify.inspection.inspect_views`; ``init`` then a
        list of start poses, one per view).
    tolerance, evaluation_distance, lower, upper, faces, min_coverage, init, plan
        As for :func:`shapeverify.inspect` (None: its defaults; lengths in mm).
    scan_format : str, optional
        The scan's format as a suffix (``".ply"``); needed for bytes (default: the path's suffix).
    scan_name : str, optional
        Stands for the scan in messages (default: the path or the file object's name).
    scan_unit : str, optional
        The unit of a scan file that carries none (:mod:`shapeverify.units`; default mm).
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

    stage = stage or _no_stage
    if isinstance(scan_source, (str, Path)) and (scan_format or Path(scan_source).suffix).lower() \
            .lstrip(".") == "e57":
        scan_source = [scan_source]          # an E57 file with several scans is several views
    if isinstance(scan_source, (list, tuple)) and not isinstance(scan_source[0], (float, int)):
        views, names, shared = _read_views(scan_source, scan_format, scan_unit, stage)
        if len(views) > 1:
            return _inspect_views(prepared, views, names, shared, stage, progress,
                                  tolerance=tolerance, evaluation_distance=evaluation_distance,
                                  lower=lower, upper=upper, faces=faces,
                                  min_coverage=min_coverage, init=init, plan=plan)
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
    opts = {} if min_coverage is None else {"min_coverage": min_coverage}
    with stage(f"Registering and inspecting {len(scan):,} points"):
        result = inspect(prepared, scan, tolerance=tolerance,
                         evaluation_distance=evaluation_distance, lower=lower, upper=upper,
                         faces=faces, init=init, plan=plan, progress=progress, **opts)
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


def _inspect_views(prepared, views, names, shared, stage, progress, *, init, plan, **opts):
    """Several views of one part (:func:`shapeverify.inspection.inspect_views`)."""
    from shapeverify.inspection import inspect_views

    if plan is not None:
        raise ValueError("an inspection plan with several views is not supported yet: inspect "
                         "the views one by one, or merge them into one scan first")
    poses = None
    if init is not None:
        arr = np.asarray(init, dtype=object) if not isinstance(init, str) else None
        if arr is None or arr.shape == (4, 4):
            raise ValueError("with several views give one start pose per view (--poses "
                             "poses.json: a list of 4x4 T_model_scan, null for none), not one "
                             "--init")
        poses = list(init)
    t0 = time.perf_counter()
    clean = {k: v for k, v in opts.items() if v is not None or k == "tolerance"}
    with stage(f"Registering and inspecting {len(views)} views "
               f"({sum(len(v) for v in views):,} points)"):
        result = inspect_views(prepared, views, names=names, poses=poses, shared_frame=shared,
                               **clean)
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


def run_inspection(model_path: str | Path, scan_path: str | Path, tolerance: float,
                   evaluation_distance: float | None = None, lower: float | None = None,
                   upper: float | None = None, json_path=None, report_path=None, png_path=None,
                   colored_path=None, db_path=None, part: str | None = None,
                   stage: Stage | None = None, *, faces=None, min_coverage: float | None = None,
                   init=None, scan_unit: str | None = None, model_unit: str | None = None,
                   plan=None, pdf_path=None, allow_incomplete: bool = False):
    """Inspect one scan file against one model file and write the requested outputs
    (``shapeverify inspect``): :func:`load_reference`, :func:`inspect_scan`, :func:`write_outputs`.

    ``evaluation_distance``, ``faces``, ``min_coverage`` and ``init`` are passed to
    :func:`shapeverify.inspect` (None: its defaults); ``scan_unit`` / ``model_unit`` give the
    units of files that carry none (:mod:`shapeverify.units`). ``plan``: an inspection plan
    (``plan.yaml``, :mod:`shapeverify.characteristics`); ``pdf_path``: the PDF report. The result
    carries ``inputs`` (part id, scan and model file names, the model file's SHA-256).

    Returns
    -------
    result : shapeverify.inspection.InspectionResult
    outputs : InspectionOutputs
    """
    stage = stage or _no_stage
    out = InspectionOutputs()
    t0 = time.perf_counter()
    prep = load_reference(model_path, stage=stage, model_unit=model_unit,
                          allow_incomplete=allow_incomplete)
    out.timings["load_model_s"] = time.perf_counter() - t0

    done = inspect_scan(prep, scan_path, tolerance=tolerance,
                        evaluation_distance=evaluation_distance, lower=lower, upper=upper,
                        faces=faces, min_coverage=min_coverage, init=init, plan=plan,
                        scan_unit=scan_unit, stage=stage)
    out.timings.update(done.timings)
    # the model file's hash ties the written outputs to it; no need to read the file again without
    outputs = (json_path, report_path, png_path, pdf_path, colored_path, db_path)
    model_hash = file_hash(model_path) if any(outputs) else None
    scan_names = ([Path(p).name for p in scan_path] if isinstance(scan_path, (list, tuple))
                  else [Path(scan_path).name])
    result = dataclasses.replace(done.result, inputs={
        "part": part, "scan": ", ".join(scan_names), "model": Path(model_path).name,
        "model_sha256": model_hash})
    write_outputs(result, prep, done.scan, out, json_path=json_path, report_path=report_path,
                  png_path=png_path, pdf_path=pdf_path, colored_path=colored_path,
                  db_path=db_path, part=part, model_hash=model_hash, stage=stage)
    return result, out


def write_outputs(result, prep, scan, out: InspectionOutputs, *, json_path=None, report_path=None,
                  png_path=None, pdf_path=None, colored_path=None, db_path=None,
                  part: str | None = None, model_hash: str | None = None,
                  stage: Stage | None = None) -> InspectionOutputs:
    """Write the requested outputs of one inspection (None: not written) and note them in
    ``out`` (its ``timings`` go into the JSON, plus ``outputs_s``)."""
    from shapeverify.report import write_colored_ply, write_html_report, write_png_summary
    from shapeverify.report.result_json import write_result_json

    stage = stage or _no_stage
    t0 = time.perf_counter()
    if json_path:
        out.json = write_result_json(result, json_path, timings=out.timings)
    if report_path:
        with stage("Writing HTML report"):
            out.report = write_html_report(result, prep, scan, report_path)
    if png_path:
        with stage("Writing PNG summary"):
            out.png = write_png_summary(result, scan, png_path)
    if pdf_path:
        from shapeverify.characteristics.pdf import write_pdf_report
        from shapeverify.inspection.plan_link import plan_result_of
        with stage("Writing PDF report"):
            plan_result = plan_result_of(result)   # no plan: the inspection's own pose
            inputs = result.inputs or {}
            out.pdf = Path(write_pdf_report(
                plan_result, pdf_path, prep, part=part, scan_file=inputs.get("scan"),
                model_file=inputs.get("model"), tolerance=result.tolerance.max_abs,
                regions=result.regions))
    if colored_path:
        out.colored = write_colored_ply(result, scan, colored_path)
    if db_path:
        from shapeverify.report.history import HistoryDB
        with HistoryDB(db_path) as db:
            out.record_id = db.add(result, part=part, model_hash=model_hash)
        if result.plan is not None:
            from shapeverify.characteristics.spc import store_characteristics
            store_characteristics(db_path, result.plan, part=part, inspection_id=out.record_id)
    out.timings["outputs_s"] = time.perf_counter() - t0
    return out
