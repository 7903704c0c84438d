"""What the service's inspection threads do: inspect and store a scan, redraw a stored report.

Every inspection goes through :func:`shapeverify.pipeline.inspect_scan` (the one the command line
and batch call), reading the upload's bytes in memory.  Storing follows the rule of
:mod:`shapeverify.service.app`: the scan file first (complete or absent), then the history row
in one transaction, and only while the request still wants it (:meth:`Job.begin_commit`).

The scan file also holds the per-point arrays the report draws, and the row the whole result
(verdict, reasons, the registration summary with warnings and robust scale): ``/report/{id}``
redraws that (:class:`~shapeverify.service.stored.StoredResult`), it never inspects again.
Records stored before the arrays were kept are inspected again at their stored pose, and drawn
with their stored verdict, rule and reasons.
"""

from __future__ import annotations

import os
import threading
import uuid
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from fastapi import HTTPException

from shapeverify.service.jobs import Job


def write_scan(path: Path, points: np.ndarray, weights, arrays: dict | None = None) -> None:
    """Store a scan (its registration weights, and the report's ``arrays``:
    :func:`~shapeverify.service.stored.report_arrays`) as ``path``, complete or not at all:
    written to a temporary name and renamed; on any failure (a full disk) the temporary file is
    removed."""
    tmp = path.with_suffix(".tmp")
    try:
        with open(tmp, "wb") as fh:
            np.savez(fh, points=points, weights=np.asarray(weights if weights is not None else []),
                     **(arrays or {}))
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@dataclass(frozen=True)
class StoredRegistration:
    """The registration of a stored inspection, rebuilt from its history record (what
    :func:`shapeverify.inspection.inspect_registered` needs to redraw the report)."""

    T_model_scan: np.ndarray
    rms: float
    iterations: int
    converged: bool
    inlier_fraction: float
    weights: np.ndarray | None = None
    message: str = "stored registration"

    @classmethod
    def from_record(cls, rec: dict, weights) -> "StoredRegistration":
        r = rec["result"].get("registration", {})
        return cls(np.asarray(rec["T_model_scan"], dtype=np.float64), _float(r.get("rms")),
                   int(r.get("iterations") or 0), bool(r.get("converged")),
                   _float(r.get("inlier_fraction")), weights, r.get("message") or "stored registration")


@dataclass(frozen=True)
class Upload:
    """One ``POST /inspect``: the model's name, the body, its content type, the request's
    :class:`~shapeverify.InspectionOptions` and the part id."""

    model: str
    body: bytes
    content_type: str | None
    options: object
    part: str | None = None


def _float(x) -> float:
    return float("nan") if x is None else float(x)


class Work:
    """The work of one service instance's threads (``config``: a :class:`ServiceConfig`).

    Every method takes the request's :class:`Job` first (the :class:`Runner` passes it).
    """

    def __init__(self, config):
        from shapeverify.report.history import HistoryDB

        self.config = config
        self.db_path = Path(config.db_path)
        self.scan_dir = self.db_path.with_name(self.db_path.stem + "-scans")
        self.scan_dir.mkdir(parents=True, exist_ok=True)
        with HistoryDB(self.db_path):
            pass  # create the schema and switch to WAL once, before the first request
        self._local = threading.local()

    def history_db(self):
        """One connection per worker thread, kept open."""
        from shapeverify.report.history import HistoryDB

        db = getattr(self._local, "db", None)
        if db is None:
            db = self._local.db = HistoryDB(self.db_path)
        return db

    def model_hash(self, name: str) -> str:
        return self.config.model_hashes.get(name, name)

    def inspect_and_store(self, job: Job, upload: Upload) -> dict | None:
        """Read and inspect the upload, store the scan, commit the row (if still wanted)."""
        from shapeverify.options import OutputRequest
        from shapeverify.pipeline import inspect_scan, write_outputs
        from shapeverify.service.body import body_format

        if not job.start():
            return None
        name = upload.model
        fmt = body_format(upload.body, upload.content_type)
        done = inspect_scan(self.config.models[name], upload.body, upload.options,
                            scan_format=fmt, scan_name="request body", progress=job.check)
        from shapeverify.service.stored import report_arrays

        payload = done.result.to_dict()
        payload["timings"]["parse_s"] = done.timings["read_scan_s"]
        payload.update(model=name, part=upload.part)
        scan_file = None
        if self.config.keep_scans:
            scan_file = self.scan_dir / f"{uuid.uuid4().hex}.npz"
            write_scan(scan_file, done.scan, getattr(done.result.registration, "weights", None),
                       report_arrays(done.result))
            payload["scan_file"] = scan_file.name
        request = OutputRequest(part=upload.part, model_hash=self.model_hash(name))
        written = None
        try:
            # the row only while the request still wants it: a timed-out client got 504
            written = write_outputs(payload, request, commit=job.begin_commit,
                                    history=self.history_db())
        finally:
            if written is None and scan_file is not None:
                scan_file.unlink(missing_ok=True)
        return payload if written is not None else None

    def query(self, job: Job, part: str | None, limit: int, model: str | None = None) -> list:
        """Stored rows; ``model``: a loaded model's name (no records yet: none) or a SHA-256
        prefix of a stored one (404 when it names none or several)."""
        job.start()
        db = self.history_db()
        if model is not None:
            if model in self.config.models:
                digest = self.model_hash(model)
                if digest not in {m["model_hash"] for m in db.models()}:
                    return []
                model = digest
            try:
                model = db.resolve_model(model)
            except ValueError as exc:
                raise HTTPException(404, str(exc).split(": ", 1)[-1]) from None
        return db.query(part=part, limit=limit, model=model)

    def render_report(self, job: Job, record_id: int) -> bytes:
        """The HTML report of a stored inspection, drawn from what was stored (404s: see the
        messages)."""
        from shapeverify.report.html import html_report
        from shapeverify.service.stored import ARRAY_KEYS, StoredResult

        if not job.start():
            return b""
        try:
            rec = self.history_db().get(record_id)
        except KeyError:
            raise HTTPException(404, f"no stored inspection with id {record_id}") from None
        res = rec["result"]
        name = res.get("model")
        if name not in self.config.models or self.model_hash(name) != rec["model_hash"]:
            raise HTTPException(404, f"inspection {record_id} was made with a model that is not loaded "
                                     f"now ({name!r}, sha256 {str(rec['model_hash'])[:12]}...)")
        if not res.get("scan_file") or not (self.scan_dir / res["scan_file"]).is_file():
            raise HTTPException(404, f"the scan of inspection {record_id} is not stored "
                                     "(the service ran with --no-keep-scans, or it was deleted)")
        with np.load(self.scan_dir / res["scan_file"]) as z:
            stored = {k: z[k] for k in z.files}
        points, weights = stored["points"], stored["weights"]
        prep = self.config.models[name]
        title = f"Inspection {record_id} (part {rec['part'] or '-'}, {rec['time']})"
        if all(k in stored for k in ARRAY_KEYS):
            result = StoredResult.from_stored(res, points, stored)
        else:
            result = self._inspect_again(rec, points, weights)
            title += ": figures recomputed at the stored pose (stored before reports were kept)"
        job.check()
        return html_report(result, prep, points, title=title)

    def _inspect_again(self, rec: dict, points, weights):
        """A record stored without its report arrays: inspected again at its stored pose, with
        the stored verdict, rule and reasons (what was decided then)."""
        import dataclasses

        from shapeverify.inspection import Tolerance, inspect_registered

        res = rec["result"]
        registration = StoredRegistration.from_record(rec, weights if weights.size else None)
        tol = res.get("tolerance", {})
        result = inspect_registered(self.config.models[res["model"]], points, registration,
                                    tolerance=Tolerance(tol["lower"], tol["upper"]),
                                    evaluation_distance=res.get("evaluation_distance",
                                                                res.get("max_distance")))
        return dataclasses.replace(result, verdict=res["verdict"],
                                   reasons=tuple(res.get("reasons") or ()),
                                   rule=str((res.get("decision") or {}).get("rule") or ""))
