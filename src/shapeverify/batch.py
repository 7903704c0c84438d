"""Batch inspection of a folder of scans on Dask distributed (a LocalCluster or an existing cluster).

The prepared model is sent to every worker once (a broadcast scatter of the ``.svm`` bytes, loaded
once per worker process and cached there); each task gets one scan's bytes, so workers need no
shared file system, and the client keeps only a bounded number of scans in flight. Results are
written by the client, in this order: the history row (if ``db_path``), then the scan's JSON
(atomically), then ``summary.csv`` at the end. A scan whose JSON exists is skipped on the next run
(resumable); a scan whose row was stored but whose JSON was not (the client died in between) gets
its JSON from that row instead of a second row, so every scan has at most one row per model;
``retry_errors`` overwrites the error row of a scan inspected again (:meth:`HistoryDB.replace`).
A scan that cannot be read or inspected (one of shapeverify's errors, see
:func:`shapeverify.errors.is_input_error`) -- or whose worker dies -- is recorded with the verdict
``error`` and its reason (JSON, CSV and history), and the batch goes on.  An unexpected exception
(a bug) is recorded the same way so that one scan cannot stop a long batch, but marked as what it
is: ``"internal_error": true``, the reason starts with "internal error", the JSON carries the
traceback, it is logged as an error and counted in :attr:`BatchSummary.internal_errors`.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import json
import logging
import os
import sqlite3
import tempfile
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from shapeverify.io.formats import SCAN_SUFFIXES
from shapeverify.verdict_table import verdict_counts

log = logging.getLogger(__name__)

#: the file in the output folder that receives Dask's own log lines
DASK_LOG = "dask.log"

_WORKER_MODELS: dict = {}  # sha256 -> Prepared, one per worker process
_CSV_COLUMNS = ["scan", "verdict", "n_points", "mean_mm", "std_mm", "min_mm", "max_mm", "p95_mm",
                "in_tolerance_fraction", "n_regions", "rms_registration_mm", "record_id", "error"]


def _prepared_from_bytes(svm: bytes, digest: str):
    """Load (once per process) the prepared model shipped as bytes."""
    prep = _WORKER_MODELS.get(digest)
    if prep is None:
        from shapeverify.nearest import load_prepared

        prep = load_prepared(svm)
        _WORKER_MODELS[digest] = prep
    return prep


def inspect_bytes(svm: bytes, digest: str, name: str, scan: bytes, options,
                  report: bool) -> dict:
    """One batch task: inspect one scan (its file bytes; the format from ``name``'s suffix) with
    :func:`shapeverify.pipeline.inspect_scan` and the batch's
    :class:`~shapeverify.InspectionOptions` (shipped whole to the worker), and return a
    JSON-ready dict (with ``report``: the HTML report under ``"_report_html"``, rendered here,
    where the points are; :func:`shapeverify.pipeline.write_outputs` writes it).

    Never raises for a bad scan: the result then has ``verdict='error'`` and ``error``.
    """
    t0 = time.perf_counter()
    out = {"scan": name}
    try:
        from shapeverify.pipeline import inspect_scan

        prep = _prepared_from_bytes(svm, digest)
        done = inspect_scan(prep, scan, options, scan_format=Path(name).suffix, scan_name=name)
        out.update(done.result.to_dict())
        if report:
            from shapeverify.report.html import html_report

            out["_report_html"] = html_report(done.result, prep, done.scan, title=name).decode("utf-8")
    except Exception as exc:  # a failing scan is a result, not a crash of the batch
        from shapeverify.errors import is_input_error

        if is_input_error(exc):
            out.update(_error(name, exc))
        else:  # a bug: recorded, but marked as one, with its traceback
            out.update(_error(name, exc, internal=True))
            out["traceback"] = traceback.format_exc()
    out["worker_seconds"] = time.perf_counter() - t0
    return out


def _error(name: str, exc: BaseException, internal: bool = False) -> dict:
    msg = f"{type(exc).__name__}: {str(exc).replace(tempfile.gettempdir(), '')}"
    if internal:
        msg = f"internal error (a bug in shapeverify, please report it): {msg}"
    out = {"scan": name, "verdict": "error", "reasons": [msg], "error": msg, "T_model_scan": None}
    if internal:
        out["internal_error"] = True
    return out


@dataclass(frozen=True)
class BatchSummary:
    """What a batch run did (``total`` scans in the folder, ``skipped`` already done before)."""

    total: int
    skipped: int
    passed: int
    failed: int
    errors: int
    seconds: float
    summary_csv: Path
    internal_errors: int = 0  # of ``errors``: scans that hit a bug (``"internal_error": true``)
    incomplete: int = 0       # not enough of the part seen to decide
    #: scans per verdict, one entry per row of :data:`shapeverify.verdict_table.VERDICT_TABLE`
    counts: dict = field(default_factory=dict)

    def __post_init__(self):
        if not self.counts:     # built from the four named counts
            object.__setattr__(self, "counts", {"pass": self.passed, "fail": self.failed,
                                                "error": self.errors,
                                                "incomplete": self.incomplete})

    @property
    def scans_per_minute(self) -> float:
        done = self.total - self.skipped
        return 60.0 * done / self.seconds if self.seconds > 0 else float("nan")


def _write_json(path: Path, data: dict) -> None:
    from shapeverify.pipeline import _write_json_atomically

    _write_json_atomically(path, data)  # complete or absent: a half-written JSON would be skipped as done


def _stored_row(db_path: Path, part: str, digest: str, name: str | None) -> dict | None:
    """The latest history row a previous batch run stored for this scan (file ``name``, or any
    file of this stem for None), if any."""
    if not db_path.exists():
        return None
    con = sqlite3.connect(str(db_path), timeout=30.0)
    try:
        row = con.execute(
            "SELECT id, result_json FROM inspections WHERE part = ? AND model_hash = ? "
            "ORDER BY id DESC", (part, digest)).fetchall()
    except sqlite3.OperationalError:  # no table yet
        return None
    finally:
        con.close()
    for rid, text in row:
        data = json.loads(text)
        if (name is None or data.get("scan") == name) and data.get("batch"):
            data["record_id"] = rid
            return data
    return None


def _local_cluster(workers: int):
    """A LocalCluster of single-threaded worker processes, *without* dask's default
    ``MALLOC_TRIM_THRESHOLD_=65536`` for the workers: that setting also freezes glibc's mmap
    threshold, so every large temporary array is mmapped and unmapped again, which makes an
    inspection about 1.5x slower (measured in benchmarks/bench_service.py)."""
    import dask
    from distributed import LocalCluster

    with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}):
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                            dashboard_address=None, silence_logs=logging.ERROR)


def _list_scans(scans_dir: Path) -> list[Path]:
    """The scan files of a folder (not recursive), sorted; ValueError without any or with two
    of the same stem."""
    scans = sorted(p for p in scans_dir.iterdir() if p.is_file() and p.suffix.lower() in SCAN_SUFFIXES)
    if not scans:
        raise ValueError(f"{scans_dir}: no scan files ({', '.join(SCAN_SUFFIXES)})")
    stems = [p.stem for p in scans]
    dup = sorted({s for s in stems if stems.count(s) > 1})
    if dup:
        raise ValueError(f"{scans_dir}: several scans share the name(s) {dup} (one JSON per stem); rename them")
    return scans


class _Outputs:
    """Where a batch run's results go: one JSON per scan stem in ``out_dir`` and, with a
    history, one row per scan (an earlier error row replaced with ``retry_errors``); written
    by :func:`shapeverify.pipeline.write_outputs`.  ``part_of(stem)`` is a scan's part id."""

    def __init__(self, out_dir: Path, model_name: str, digest: str, db_path: Path | None,
                 retry_errors: bool, part_of: Callable[[str], str]):
        self.out_dir, self.model_name, self.digest = out_dir, model_name, digest
        self.db_path, self.retry_errors, self.part_of = db_path, retry_errors, part_of
        self.db = None
        self.replace_ids: dict[str, int] = {}  # scan stem -> history row of its earlier error

    def json_path(self, p: Path | str) -> Path:
        return self.out_dir / f"{Path(p).stem}.json"

    def done_before(self, p: Path) -> bool:
        f = self.json_path(p)
        if not f.exists():
            return False
        if not self.retry_errors:
            return True
        try:
            return json.loads(f.read_text()).get("verdict") != "error"
        except ValueError:
            return False

    def open_history(self, todo: list[Path]) -> list[Path]:
        """Open the history; return ``todo`` without the scans an interrupted run stored but
        wrote no JSON for (their JSON is written from the row: no second row)."""
        if self.db_path is None:
            return todo
        from shapeverify.report.history import HistoryDB

        self.db = HistoryDB(self.db_path)
        recovered = []
        for p in todo:
            part = self.part_of(p.stem)
            row = _stored_row(self.db_path, part, self.digest, p.name)
            if row is not None and (row.get("verdict") != "error" or not self.retry_errors):
                _write_json(self.json_path(p), row)
                recovered.append(p)
            elif self.retry_errors:  # an error retried: its new result replaces that row
                old = row or _stored_row(self.db_path, part, self.digest, None)  # (renamed .ply -> .xyz)
                if old is not None and old.get("verdict") == "error":
                    self.replace_ids[p.stem] = old["record_id"]
        return [p for p in todo if p not in recovered]

    def record(self, res: dict) -> None:
        """Write one task's result: its report, its history row, then its JSON."""
        from shapeverify.options import OutputRequest
        from shapeverify.pipeline import write_outputs

        stem = Path(res["scan"]).stem
        res["batch"] = {"model": self.model_name, "model_sha256": self.digest}
        if res.get("internal_error"):
            log.error("%s: internal error (a bug in shapeverify): %s", res["scan"], res["error"])
        request = OutputRequest(
            json=self.json_path(stem), part=self.part_of(stem), model_hash=self.digest,
            report=self.out_dir / f"{stem}.html" if "_report_html" in res else None,
            replace_record=self.replace_ids.pop(stem, None))
        write_outputs(res, request, history=self.db)

    def close(self) -> None:
        if self.db is not None:
            self.db.close()


def part_from_name(pattern: str | None) -> Callable[[str], str]:
    """The part id of a scan file's stem: the stem itself (no ``pattern``), or the first group
    (else the whole match) of the regular expression ``pattern`` searched in the stem
    (``r"SN(\\d+)"``: ``SN0042_top`` is part ``0042``).

    Raises
    ------
    ValueError
        A pattern that is not a regular expression.
    """
    if pattern is None:
        return lambda stem: stem
    import re

    try:
        rx = re.compile(pattern)
    except re.error as exc:
        raise ValueError(f"the part pattern {pattern!r} is not a regular expression: {exc}") from None

    def part(stem: str) -> str:
        m = rx.search(stem)
        if m is None:
            raise ValueError(f"scan {stem!r}: the part pattern {pattern!r} does not match its "
                             "name; fix the pattern or rename the scan")
        return m.group(1) if rx.groups else m.group(0)

    return part


#: Dask's loggers, whose INFO lines (about 35 per run: scheduler, nannies, workers, clients)
#: go to ``OUT/dask.log`` and not to the application's handlers (:func:`_dask_logs_to`)
_DASK_LOGGERS = ("distributed", "dask")


class _LogFile(logging.Handler):
    """Appends formatted records to a file.  Not a :class:`logging.StreamHandler` (nor a
    FileHandler, which is one): ``LocalCluster(silence_logs=...)`` turns every StreamHandler of
    the ``distributed`` logger down to that level while the cluster runs."""

    def __init__(self, path: Path):
        super().__init__()
        self._fh = open(path, "a", encoding="utf-8")

    def emit(self, record: logging.LogRecord) -> None:
        try:
            self._fh.write(self.format(record) + "\n")
            self._fh.flush()
        except Exception:  # noqa: BLE001 - logging's own convention
            self.handleError(record)

    def close(self) -> None:
        self._fh.close()
        super().close()


@contextlib.contextmanager
def _dask_logs_to(path: Path):
    """Send Dask's own log records to the file ``path`` while the batch runs; they also reach
    the root logger's handlers (the terminal of ``shapeverify batch``) only when the root
    logger is enabled for INFO (``shapeverify --verbose batch ...``)."""
    handler = _LogFile(path)
    handler.setFormatter(logging.Formatter("%(asctime)s %(name)s %(levelname)s %(message)s"))
    verbose = logging.getLogger().isEnabledFor(logging.INFO)
    saved = []
    for name in _DASK_LOGGERS:
        lg = logging.getLogger(name)
        saved.append((lg, lg.propagate))
        lg.addHandler(handler)
        lg.propagate = verbose
    try:
        yield
    finally:
        for lg, propagate in saved:
            lg.removeHandler(handler)
            lg.propagate = propagate
        handler.close()


def _run_on_dask(todo: list[Path], svm: bytes, digest: str, task_args: tuple, record,
                 workers: int | str, progress) -> None:
    """Inspect the scans ``todo`` on Dask (a LocalCluster of ``workers``, or the scheduler at
    the address ``workers``),
    a bounded number in flight; ``record(result)`` for each as it completes."""
    from distributed import Client, as_completed

    cluster = None
    if isinstance(workers, str):
        client = Client(workers)
    else:
        cluster = _local_cluster(max(1, int(workers)))
        client = Client(cluster)
    try:
        n_workers = max(1, len(client.scheduler_info().get("workers", {})))
        svm_future = client.scatter(svm, broadcast=True)  # once per worker, not per task
        pending = iter(todo)
        in_flight = as_completed()
        names = {}

        def submit_next() -> bool:
            p = next(pending, None)
            if p is None:
                return False
            fut = client.submit(inspect_bytes, svm_future, digest, p.name, p.read_bytes(),
                                *task_args, pure=False,
                                key=f"inspect-{digest[:8]}-{p.name}-{time.time_ns()}")
            names[fut.key] = p.name
            in_flight.add(fut)
            return True

        for _ in range(2 * n_workers + 2):  # bounded: scan bytes of a few tasks in memory
            if not submit_next():
                break
        n_done = 0
        for fut in in_flight:
            name = names.pop(fut.key)
            try:
                res = fut.result()
            except Exception as exc:  # the worker died (or the task could not run)
                res = _error(name, exc)
            fut.release()
            record(res)
            n_done += 1
            if progress:
                progress(n_done, len(todo), name)
            submit_next()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _write_summary(scans: list[Path], out_dir: Path) -> tuple[list[dict], Path]:
    """``summary.csv`` of every scan that has a JSON (atomically); return those results and it."""
    rows = []
    for p in scans:
        f = out_dir / f"{p.stem}.json"
        if f.exists():
            rows.append(json.loads(f.read_text()))
    summary_csv = out_dir / "summary.csv"
    tmp = summary_csv.with_suffix(".csv.tmp")
    with open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(_CSV_COLUMNS)
        for r in rows:
            d, reg = r.get("deviation") or {}, r.get("registration") or {}
            w.writerow([r.get("scan"), r.get("verdict"), r.get("n_points"), d.get("mean"), d.get("std"),
                        d.get("min"), d.get("max"), d.get("p95"), d.get("in_tolerance_fraction"),
                        len(r.get("regions") or []), reg.get("rms"), r.get("record_id"), r.get("error", "")])
    os.replace(tmp, summary_csv)
    return rows, summary_csv


def run_batch(svm_path: str | Path, scans_dir: str | Path, out_dir: str | Path, options, *,
              workers: int | str = 2, reports: bool = False, db_path: str | Path | None = None,
              retry_errors: bool = False, progress: Callable[[int, int, str], None] | None = None,
              part_pattern: str | None = None) -> BatchSummary:
    """Inspect every scan in ``scans_dir`` against the prepared model ``svm_path`` on Dask.

    Parameters
    ----------
    svm_path : path
        Prepared model (``shapeverify prepare``).
    scans_dir : path
        Folder of scans (``.ply .xyz .txt .csv .npy .pcd .e57 .las .laz``; not recursive).
    out_dir : path
        Output folder: ``<scan stem>.json`` per scan (``.html`` with ``reports``), ``summary.csv``,
        and ``dask.log``: Dask's own log lines (they reach the root logger's handlers too only
        when it is enabled for INFO).
    options : shapeverify.InspectionOptions or dict
        Every setting of the inspections (tolerance or limits, evaluation distance, faces, init,
        plan, scan unit ...), shipped whole to the workers; a dict of its fields is taken too
        (``{"tolerance": 0.3, "faces": "0,3"}``).
    workers : int or str
        The number of single-threaded worker processes of a local Dask cluster (default 2), or
        the address of an existing Dask scheduler (``"tcp://host:8786"``). (Start the workers of
        your own cluster with ``distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_:
        null`` in the dask config, or ``--no-nanny``: dask's default makes inspections ~1.5x
        slower.)
    db_path : path, optional
        Append every result (errors too) to this SQLite history; ``part`` is the scan's part id
        (see ``part_pattern``).
    part_pattern : str, optional
        A regular expression whose first group (else whole match) in a scan file's stem is its
        part id (:func:`part_from_name`); default: the stem.
    retry_errors : bool
        Inspect again the scans whose earlier result is an error (default: skip them too).
    progress : callable, optional
        ``progress(done, total, scan_name)`` after each scan of this run.

    Returns
    -------
    BatchSummary

    Raises
    ------
    FileNotFoundError
        Missing model or folder.
    ValueError
        A folder without scans, two scans with the same stem, a bad option
        (:class:`~shapeverify.options.OptionError`: ``tolerance <= 0`` ...), a part pattern
        that does not match a scan's name.
    ModelFileError
        The prepared model is damaged or not a ``.svm`` file.
    """
    svm_path, scans_dir, out_dir = Path(svm_path), Path(scans_dir), Path(out_dir)
    if not svm_path.is_file():
        raise FileNotFoundError(f"{svm_path}: prepared model not found (make one with `shapeverify prepare`)")
    if not scans_dir.is_dir():
        raise FileNotFoundError(f"{scans_dir}: not a folder of scans")
    from shapeverify.options import InspectionOptions

    if not isinstance(options, InspectionOptions):
        options = InspectionOptions(**dict(options))
    part_of = part_from_name(part_pattern)
    scans = _list_scans(scans_dir)
    for p in scans:
        part_of(p.stem)          # a pattern that misses a scan stops here, not per scan
    from shapeverify.nearest import load_prepared

    load_prepared(svm_path)  # a damaged model stops here (ModelFileError naming the file), not per scan
    out_dir.mkdir(parents=True, exist_ok=True)
    svm = svm_path.read_bytes()
    digest = hashlib.sha256(svm).hexdigest()
    outputs = _Outputs(out_dir, svm_path.name, digest,
                       Path(db_path) if db_path is not None else None, retry_errors, part_of)
    todo = [p for p in scans if not outputs.done_before(p)]
    t0 = time.perf_counter()
    try:
        todo = outputs.open_history(todo)
        if todo:
            with _dask_logs_to(out_dir / DASK_LOG):
                _run_on_dask(todo, svm, digest, (options, reports),
                             outputs.record, workers, progress)
    finally:
        outputs.close()
    rows, summary_csv = _write_summary(scans, out_dir)
    verdicts = [r.get("verdict") for r in rows]
    counts = verdict_counts(verdicts)
    return BatchSummary(total=len(scans), skipped=len(scans) - len(todo), passed=counts["pass"],
                        failed=counts["fail"], errors=counts["error"],
                        incomplete=counts["incomplete"], counts=counts,
                        seconds=time.perf_counter() - t0, summary_csv=summary_csv,
                        internal_errors=sum(bool(r.get("internal_error")) for r in rows))
