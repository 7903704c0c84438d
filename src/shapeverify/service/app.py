"""The inspection service: prepared models stay in memory; every result goes to the history first.

Endpoints (JSON unless noted; lengths in mm):

- ``POST /inspect?model=NAME&tolerance=0.2&evaluation_distance=1.0&part=ID``, body: the scan (PLY, NPY,
  PCD or XYZ/CSV text; the content type or a sniff of the first bytes decides) -> the
  ``shapeverify inspect --json`` result plus ``record_id``, ``model`` and ``part``.
- ``GET /health``, ``GET /models``, ``GET /history?part=&limit=``, ``GET /report/{id}`` (HTML,
  drawn on demand from the stored scan and registration).

Bad input gets a 4xx whose ``detail`` says what was wrong: 401 missing or wrong token, 404 unknown
model or record, 408 the upload took longer than the time limit, 413 body too large, 415
unsupported format, 422 malformed, empty or NaN-only scan (or bad query parameters), 504 the
inspection did not finish within the time limit, 507 the server's disk is full (nothing was stored,
no temporary file is left; free space and send the request again).  ``/report/{id}`` answers 404
for any id that is not a stored record (negative, non-numeric or absurdly large ids included).

Records: the result is committed to the SQLite history (WAL) *before* the response is sent, in one
transaction, so a response that reached the client always has its row, and a request that failed
or timed out (504) leaves none: the worker thread checks a cancel flag between stages and commits
only if the request is still wanted (a 504 is only answered while no commit has begun). The scan
(and the registration weights) is written first, under a unique name the row refers to, so
``/report/{id}`` can redraw any stored inspection; a crash between the two leaves at worst an
unreferenced scan file, never a row without its scan.
"""

from __future__ import annotations

import asyncio
import errno
import logging
import os
import re
import sqlite3
import secrets
import threading
import time
import uuid
from concurrent.futures import ThreadPoolExecutor
from contextlib import asynccontextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from fastapi import Depends, FastAPI, HTTPException, Query, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, JSONResponse
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from shapeverify.errors import ShapeVerifyError, UnsupportedFormatError

log = logging.getLogger(__name__)

_SCAN_TYPES = ["application/octet-stream", "application/x-npy", "application/ply", "model/ply",
               "application/x-pcd", "text/plain", "text/csv", "text/x-xyz"]
_ERRORS = {
    401: "missing or wrong token (only when the service runs with --token)",
    404: "unknown model or record",
    408: "the upload did not arrive within the time limit",
    413: "body larger than the limit (--max-body-mb)",
    415: "not a supported scan format (PLY, NPY, PCD, XYZ/CSV text)",
    422: "malformed, empty or NaN-only scan; bad query parameters; a scan that cannot be inspected",
    504: "the inspection did not finish within the time limit (--time-limit); nothing was stored",
    507: "the server's disk is full: nothing was stored and no temporary file is left; free "
         "space on the server and send the request again",
}
_RECORD_ID = re.compile(r"[0-9]{1,18}")  # SQLite integers are 64-bit: longer ids cannot exist


def _disk_full(exc: BaseException) -> bool:
    """Whether storing failed because the disk (or the user's quota) is full."""
    if isinstance(exc, OSError):
        return exc.errno in (errno.ENOSPC, errno.EDQUOT)
    return isinstance(exc, sqlite3.OperationalError) and "full" in str(exc).lower()


def _write_scan(path: Path, points: np.ndarray, weights) -> None:
    """Store a scan (and its registration weights) as ``path``, complete or not at all: written
    to a temporary name and renamed; on any failure (a full disk) the temporary file is removed."""
    tmp = path.with_suffix(".tmp")
    try:
        with open(tmp, "wb") as fh:
            np.savez(fh, points=points, weights=np.asarray(weights if weights is not None else []))
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _responses(*codes: int) -> dict:
    return {c: {"description": _ERRORS[c], "content": {"application/json": {"example": {"detail": "..."}}}}
            for c in codes}


@dataclass
class ServiceConfig:
    """Settings of one service instance (models already loaded, see ``load_models``)."""

    models: dict  # name -> Prepared
    model_hashes: dict = field(default_factory=dict)  # name -> sha256 of the .svm file
    db_path: Path = Path("history.sqlite")
    token: str | None = None
    max_body_bytes: int = 64 * 1024 * 1024
    time_limit_s: float = 60.0
    threads: int = 2  # inspection threads of this process
    keep_scans: bool = True  # store each scan beside the history (needed by /report/{id})


@dataclass(frozen=True)
class _StoredRegistration:
    """The registration of a stored inspection (what ``inspect_registered`` needs)."""

    T_model_scan: np.ndarray
    rms: float
    iterations: int
    converged: bool
    inlier_fraction: float
    weights: np.ndarray | None = None
    message: str = "stored registration"

    @classmethod
    def from_record(cls, rec: dict, weights) -> "_StoredRegistration":
        r = rec["result"].get("registration", {})
        return cls(np.asarray(rec["T_model_scan"], dtype=np.float64), _float(r.get("rms")),
                   int(r.get("iterations") or 0), bool(r.get("converged")),
                   _float(r.get("inlier_fraction")), weights, r.get("message") or "stored registration")


def _float(x) -> float:
    return float("nan") if x is None else float(x)


class _Payload:
    """A result dict in the form :meth:`HistoryDB.add` takes (anything with ``to_dict``)."""

    def __init__(self, d: dict):
        self._d = d

    def to_dict(self) -> dict:
        return self._d


class _Cancelled(Exception):
    """The request was answered with a time-out; the worker stops without storing anything."""


class _Job:
    """Hand-over between a request (which may time out) and its worker thread."""

    def __init__(self):
        self._lock = threading.Lock()
        self.state = "queued"

    def _move(self, allowed: tuple, new: str) -> bool:
        with self._lock:
            if self.state not in allowed:
                return False
            self.state = new
            return True

    def start(self) -> bool:
        return self._move(("queued",), "running")

    def begin_commit(self) -> bool:
        return self._move(("running",), "committing")

    def cancel(self) -> bool:
        """True if the job will store nothing; False if its commit has already begun."""
        return self._move(("queued", "running"), "cancelled")

    def check(self, *_args) -> None:  # also the ``progress`` callback of inspect()
        if self.state == "cancelled":
            raise _Cancelled


class _TokenMiddleware:
    """Pure ASGI middleware: with a token, *every* HTTP request (docs included) must carry it."""

    def __init__(self, app, token: str):
        self.app = app
        self.token = token.encode()

    async def __call__(self, scope, receive, send):
        if scope["type"] == "http":
            auth = dict(scope.get("headers") or ()).get(b"authorization", b"")
            scheme, _, cred = auth.partition(b" ")
            if scheme.lower() != b"bearer" or not secrets.compare_digest(cred.strip(), self.token):
                resp = JSONResponse({"detail": "missing or wrong token: send 'Authorization: Bearer TOKEN'"},
                                    status_code=401, headers={"WWW-Authenticate": "Bearer"})
                await resp(scope, receive, send)
                return
        await self.app(scope, receive, send)


def _parse_init(text: str | None):
    """The ``init`` query parameter: None, a strategy name, or a 4x4 pose from 16 numbers."""
    if text is None or text.strip().lower() in ("", "auto"):
        return None
    key = text.strip().lower()
    if key in ("identity", "global", "principal-axes", "pca"):
        return key
    try:
        T = np.array([float(v) for v in text.replace(";", ",").split(",")], dtype=np.float64)
    except ValueError:
        T = np.zeros(0)
    if T.shape != (16,) or not np.all(np.isfinite(T)):
        raise HTTPException(422, "init must be 'auto', 'identity', 'global', 'principal-axes' or 16 "
                                 "comma-separated numbers (T_model_scan row by row)")
    return T.reshape(4, 4)


def create_app(config: ServiceConfig) -> FastAPI:
    """Build the FastAPI application for ``config`` (models already loaded and warmed up)."""
    from shapeverify.report.history import HistoryDB

    db_path = Path(config.db_path)
    scan_dir = db_path.with_name(db_path.stem + "-scans")
    scan_dir.mkdir(parents=True, exist_ok=True)
    with HistoryDB(db_path):
        pass  # create the schema and switch to WAL once, before the first request
    executor = ThreadPoolExecutor(max(1, int(config.threads)), thread_name_prefix="inspect")
    local = threading.local()
    limit = float(config.time_limit_s)

    def history_db() -> HistoryDB:
        """One connection per worker thread, kept open."""
        db = getattr(local, "db", None)
        if db is None:
            db = local.db = HistoryDB(db_path)
        return db

    @asynccontextmanager
    async def lifespan(_app):
        yield
        executor.shutdown(wait=True, cancel_futures=True)

    app = FastAPI(
        title="shapeverify inspection service",
        version="0.1.0",
        lifespan=lifespan,
        description=(
            "Register a scan to a prepared CAD model, compute signed deviations (mm) along the "
            "model's outward normals and decide pass/fail. Every result is committed to the SQLite "
            "history before the response is sent; a failed or timed-out request stores nothing. "
            + ("Every request needs `Authorization: Bearer TOKEN`." if config.token else "")),
    )
    if config.token:
        app.add_middleware(_TokenMiddleware, token=config.token)
    bearer = HTTPBearer(auto_error=False, description="only when the service runs with --token")

    def check_token(cred: HTTPAuthorizationCredentials | None = Depends(bearer)) -> None:
        # the middleware already refused requests without the token; this dependency puts the
        # security scheme into the OpenAPI schema
        return None

    def get_model(name: str):
        if name not in config.models:
            raise HTTPException(404, f"unknown model {name!r}; loaded models: {sorted(config.models)}")
        return config.models[name]

    async def read_body(request: Request) -> bytes:
        declared = request.headers.get("content-length", "")
        if declared.isdigit() and int(declared) > config.max_body_bytes:
            raise HTTPException(413, f"scan body of {int(declared):,} bytes exceeds the limit of "
                                     f"{config.max_body_bytes:,} bytes")
        chunks, size = [], 0
        async for chunk in request.stream():
            size += len(chunk)
            if size > config.max_body_bytes:
                raise HTTPException(413, f"scan body exceeds the limit of {config.max_body_bytes:,} bytes")
            chunks.append(chunk)
        return b"".join(chunks)

    async def run_limited(job: _Job, deadline: float, fn, *args):
        """Run ``fn(job, *args)`` on the inspection threads; 504 at the deadline unless the
        job's commit has already begun (then its result is awaited and answered)."""
        fut = asyncio.get_running_loop().run_in_executor(executor, fn, job, *args)
        try:
            try:
                return await asyncio.wait_for(asyncio.shield(fut), max(0.0, deadline - time.monotonic()))
            except asyncio.TimeoutError:
                if job.cancel():
                    # the worker stops at its next check; its outcome is of no interest any more
                    fut.add_done_callback(lambda f: f.cancelled() or f.exception())
                    raise HTTPException(504, f"the request exceeded the time limit of {limit:g} s; "
                                             "nothing was stored") from None
                return await fut
        except UnsupportedFormatError as exc:
            raise HTTPException(415, str(exc)) from None
        except (ShapeVerifyError, ValueError) as exc:
            raise HTTPException(422, str(exc)) from None
        except (OSError, sqlite3.OperationalError) as exc:
            if not _disk_full(exc):
                raise
            log.error("disk full, request not stored: %s", exc)
            raise HTTPException(507, "the server's disk is full: the result was not stored; free "
                                     "space on the server and send the request again") from None

    def inspect_and_store(job: _Job, *args):
        try:
            return _inspect_and_store(job, *args)
        except _Cancelled:
            return None

    def _inspect_and_store(job: _Job, name, prep, body, content_type, tolerance, evaluation_distance,
                           part, init=None):
        """Worker thread: parse, inspect, store the scan, commit the row (if still wanted)."""
        from shapeverify.inspection import inspect
        from shapeverify.service.body import parse_scan

        if not job.start():
            return None
        t0 = time.perf_counter()
        points = parse_scan(body, content_type)
        t_parse = time.perf_counter() - t0
        job.check()
        result = inspect(prep, points, tolerance=tolerance, evaluation_distance=evaluation_distance,
                         init=init, progress=job.check)
        payload = result.to_dict()
        payload["timings"]["parse_s"] = t_parse
        payload.update(model=name, part=part)
        scan_file = None
        if config.keep_scans:
            scan_file = scan_dir / f"{uuid.uuid4().hex}.npz"
            _write_scan(scan_file, points, getattr(result.registration, "weights", None))
            payload["scan_file"] = scan_file.name
        if not job.begin_commit():  # timed out meanwhile: the client got 504, store nothing
            if scan_file is not None:
                scan_file.unlink(missing_ok=True)
            return None
        try:
            record_id = history_db().add(_Payload(payload), part=part,
                                         model_hash=config.model_hashes.get(name, name))
        except BaseException:
            if scan_file is not None:
                scan_file.unlink(missing_ok=True)
            raise
        payload["record_id"] = record_id
        return payload

    def render_report(job: _Job, record_id: int) -> str:
        import tempfile

        from shapeverify.inspection import Tolerance, inspect_registered
        from shapeverify.report.html import write_html_report

        if not job.start():
            return ""
        try:
            rec = history_db().get(record_id)
        except KeyError:
            raise HTTPException(404, f"no stored inspection with id {record_id}") from None
        res = rec["result"]
        name = res.get("model")
        if name not in config.models or config.model_hashes.get(name, name) != rec["model_hash"]:
            raise HTTPException(404, f"inspection {record_id} was made with a model that is not loaded "
                                     f"now ({name!r}, sha256 {str(rec['model_hash'])[:12]}...)")
        if not res.get("scan_file") or not (scan_dir / res["scan_file"]).is_file():
            raise HTTPException(404, f"the scan of inspection {record_id} is not stored "
                                     "(the service ran with --no-keep-scans, or it was deleted)")
        with np.load(scan_dir / res["scan_file"]) as z:
            points, weights = z["points"], z["weights"]
        registration = _StoredRegistration.from_record(rec, weights if weights.size else None)
        tol = res.get("tolerance", {})
        result = inspect_registered(config.models[name], points, registration,
                                    tolerance=Tolerance(tol["lower"], tol["upper"]),
                                    evaluation_distance=res.get("evaluation_distance",
                                                                res.get("max_distance")))
        job.check()
        with tempfile.TemporaryDirectory() as tmp:
            path = write_html_report(result, config.models[name], points, Path(tmp) / "report.html",
                                     title=f"Inspection {record_id} (part {rec['part'] or '-'}, {rec['time']})")
            return Path(path).read_text(encoding="utf-8")

    # ------------------------------------------------------------------------------ routes
    auth = [Depends(check_token)]

    @app.get("/health", dependencies=auth, responses=_responses(401))
    def health() -> dict:
        """Liveness: the service is up and its models are loaded."""
        return {"status": "ok", "models": sorted(config.models)}

    @app.get("/models", dependencies=auth, responses=_responses(401))
    def models() -> dict:
        """The prepared models this service holds (lengths in mm)."""
        return {name: {"faces": len(p.model.faces), "model_points": int(p.n_points),
                       "spacing_mm": float(p.spacing), "max_distance_mm": float(p.max_distance),
                       "size_mm": float(p.model.size), "unit": "mm",
                       "sha256": config.model_hashes.get(name)}
                for name, p in config.models.items()}

    @app.post(
        "/inspect", dependencies=auth, responses=_responses(401, 404, 408, 413, 415, 422, 504, 507),
        openapi_extra={"requestBody": {"required": True, "description": "The scan points (mm): PLY "
                       "(ascii or binary), .npy, PCD or XYZ/CSV text. Without a content type (or "
                       "with application/octet-stream or text/plain) the first bytes decide.",
                       "content": {t: {"schema": {"type": "string", "format": "binary"}} for t in _SCAN_TYPES}}})
    async def inspect_scan(
        request: Request,
        model: str = Query(..., description="name of a loaded model (see /models)"),
        tolerance: float = Query(..., gt=0, allow_inf_nan=False, description="symmetric tolerance ±mm"),
        evaluation_distance: float | None = Query(
            None, gt=0, allow_inf_nan=False,
            description="scan points farther than this from the CAD surface are not evaluated "
                        "(mm; default max(1, 5 x tolerance))"),
        max_distance: float | None = Query(None, gt=0, allow_inf_nan=False, deprecated=True,
                                           description="old name of evaluation_distance"),
        part: str | None = Query(None, max_length=200, description="part id (serial number) for the history"),
        init: str | None = Query(None, max_length=2000,
                                 description="start pose: 'auto' (default: the model's fixture pose "
                                             "if it has one, else found automatically), 'identity', "
                                             "'global', 'principal-axes', or 16 comma-separated "
                                             "numbers, T_model_scan row by row (mm)"),
    ) -> dict:
        """Register and inspect the scan in the request body; store the result; return it."""
        start = _parse_init(init)
        deadline = time.monotonic() + limit
        prep = get_model(model)
        try:
            body = await asyncio.wait_for(read_body(request), limit)
        except asyncio.TimeoutError:
            raise HTTPException(408, f"the upload did not complete within the time limit of {limit:g} s") from None
        return await run_limited(_Job(), deadline, inspect_and_store, model, prep, body,
                                 request.headers.get("content-type"), tolerance,
                                 evaluation_distance if evaluation_distance is not None else max_distance,
                                 part, start)

    @app.get("/history", dependencies=auth, responses=_responses(401, 422))
    async def history(part: str | None = Query(None, description="only this part id"),
                      limit_: int = Query(50, alias="limit", ge=1, le=10_000,
                                          description="the most recent N records (returned oldest first)")) -> list:
        """Stored inspections: id, part, time, model_hash, verdict, statistics (mm; null where
        not available), n_regions."""
        def query(job, part, n):
            job.start()
            return history_db().query(part=part, limit=n)

        rows = await run_limited(_Job(), time.monotonic() + limit, query, part, limit_)
        return [{k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in r.items()}
                for r in rows]

    @app.get("/report/{record_id}", response_class=HTMLResponse, dependencies=auth,
             responses=_responses(401, 404, 504))
    async def report(record_id: str) -> HTMLResponse:
        """The HTML report of a stored inspection, drawn on demand from the stored scan (404 for
        an id that is not a stored record's: negative, non-numeric or too large ones too)."""
        if not _RECORD_ID.fullmatch(record_id):
            raise HTTPException(404, f"no stored inspection with id {record_id[:40]!r}: record ids "
                                     "are the positive integers /history lists")
        html = await run_limited(_Job(), time.monotonic() + limit, render_report, int(record_id))
        return HTMLResponse(html)

    @app.exception_handler(RequestValidationError)
    async def _bad_parameters(request: Request, exc: RequestValidationError):
        msgs = []
        for e in exc.errors():
            loc = ".".join(str(p) for p in e.get("loc", ()) if p not in ("query", "path", "body"))
            msgs.append(f"{loc}: {e.get('msg')}" if loc else str(e.get("msg")))
        return JSONResponse(status_code=422, content={"detail": "bad request parameters: " + "; ".join(msgs)})

    @app.exception_handler(ShapeVerifyError)
    async def _library_error(request: Request, exc: ShapeVerifyError):
        return JSONResponse(status_code=422, content={"detail": str(exc)})

    return app
