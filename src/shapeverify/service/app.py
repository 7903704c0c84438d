"""The inspection service: prepared models stay in memory; every result goes to the history first.

Endpoints (JSON unless noted; lengths in mm):

- ``POST /inspect?model=NAME&tolerance=0.2&evaluation_distance=1.0&part=ID``, body: the scan (PLY, NPY,
  PCD or XYZ/CSV text; the content type or a sniff of the first bytes decides) -> the
  ``shapeverify inspect --json`` result plus ``record_id``, ``model`` and ``part``.  Every option
  of ``shapeverify inspect`` is a query parameter (``lower``, ``upper``, ``faces``,
  ``min_coverage``, ``init``, ``scan_unit``, ``plan``: the plan's YAML text), checked by
  :meth:`shapeverify.InspectionOptions.from_query` (422 naming the parameter); the old name
  ``max_distance`` still works and says so in a ``Warning`` header.
- ``GET /health``, ``GET /models``, ``GET /history?part=&limit=&model=``, ``GET /report/{id}`` (HTML,
  drawn on demand from the stored result: its verdict, reasons and per-point deviations, never
  inspected again; :mod:`.stored`).

Bad input gets a 4xx whose ``detail`` says what was wrong: 401 missing or wrong token, 404 unknown
model or record, 408 the upload took longer than the time limit, 413 body too large, 415
unsupported format, 422 malformed, empty or NaN-only scan (or bad query parameters), 504 the
inspection did not finish within the time limit, 507 the server's disk is full (nothing was stored,
no temporary file is left; free space and send the request again).  ``/report/{id}`` answers 404
for any id that is not a stored record (negative, non-numeric or absurdly large ids included).
Anything else is a bug in shapeverify: 500, with a ``detail`` that says so ("internal error ...,
please report it"), logged with its traceback.

The parts: :mod:`.work` (what the inspection threads do: every inspection is
:func:`shapeverify.pipeline.inspect_scan` on the body's bytes), :mod:`.jobs` (threads, time
limit, errors -> status codes), :mod:`.body` (the upload's format); this module holds the routes.

Records: the result is committed to the SQLite history (WAL) *before* the response is sent, in one
transaction, so a response that reached the client always has its row, and a request that failed
or timed out (504) leaves none: the worker thread checks a cancel flag between stages and commits
only if the request is still wanted (a 504 is only answered while no commit has begun). The scan
(with the registration weights and the report's per-point arrays) is written first, under a
unique name the row refers to, so ``/report/{id}`` can redraw any stored inspection; a crash between the two leaves at worst an
unreferenced scan file, never a row without its scan.
"""

from __future__ import annotations

import asyncio
import logging
import re
import secrets
from contextlib import asynccontextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from fastapi import Depends, FastAPI, HTTPException, Query, Request, Response
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, JSONResponse
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from shapeverify.errors import ShapeVerifyError
from shapeverify.service.body import SCAN_TYPES, SUPPORTED
from shapeverify.service.jobs import Runner
from shapeverify.service.work import Upload, Work

log = logging.getLogger(__name__)

_SCAN_TYPES = SCAN_TYPES     # the scan format registry's (shapeverify.io.formats)
_ERRORS = {
    401: "missing or wrong token (only when the service runs with --token)",
    404: "unknown model or record",
    408: "the upload did not arrive within the time limit",
    413: "body larger than the limit (--max-body-mb)",
    415: f"not a supported scan format; send {SUPPORTED}",
    422: "malformed, empty or NaN-only scan; bad query parameters; a scan that cannot be inspected",
    504: "the inspection did not finish within the time limit (--time-limit); nothing was stored",
    507: "the server's disk is full: nothing was stored and no temporary file is left; free "
         "space on the server and send the request again",
}
_RECORD_ID = re.compile(r"[0-9]{1,18}")  # SQLite integers are 64-bit: longer ids cannot exist


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


def _options(params: dict):
    """The :class:`~shapeverify.InspectionOptions` of a request's query parameters (422 naming
    the parameter when one is bad) and the deprecation notes for old names."""
    import warnings

    from shapeverify.options import InspectionOptions

    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", DeprecationWarning)
            options = InspectionOptions.from_query(params)
    except ValueError as exc:   # OptionError, PlanError (its line and key named)
        name = getattr(exc, "option", "plan" if type(exc).__name__ == "PlanError" else None)
        raise HTTPException(422, f"bad request parameters: {name}: {exc}" if name
                            else f"bad request parameters: {exc}") from None
    notes = [str(w.message) for w in caught if issubclass(w.category, DeprecationWarning)]
    for note in notes:
        log.warning("deprecated query parameter: %s", note)
    return options, notes


def create_app(config: ServiceConfig) -> FastAPI:
    """Build the FastAPI application for ``config`` (models already loaded and warmed up).

    The parts: :class:`~shapeverify.service.work.Work` (what the inspection threads do),
    :class:`~shapeverify.service.jobs.Runner` (the threads and the time limit), and the routes
    (:func:`_model_routes`, :func:`_inspect_route`, :func:`_history_routes`, :func:`_error_handlers`).
    """
    work = Work(config)
    runner = Runner(config.threads, config.time_limit_s)

    @asynccontextmanager
    async def lifespan(_app):
        yield
        runner.shutdown()

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
    auth = [Depends(_check_token)]
    _model_routes(app, config, auth)
    _inspect_route(app, config, runner, work, auth)
    _history_routes(app, runner, work, auth)
    _error_handlers(app)
    return app


_bearer = HTTPBearer(auto_error=False, description="only when the service runs with --token")


def _check_token(cred: HTTPAuthorizationCredentials | None = Depends(_bearer)) -> None:
    # the middleware already refused requests without the token; this dependency puts the
    # security scheme into the OpenAPI schema
    return None


async def _read_body(request: Request, max_bytes: int) -> bytes:
    """The request body, refused (413) as soon as it is known to exceed ``max_bytes``."""
    declared = request.headers.get("content-length", "")
    if declared.isdigit() and int(declared) > max_bytes:
        raise HTTPException(413, f"scan body of {int(declared):,} bytes exceeds the limit of "
                                 f"{max_bytes:,} bytes")
    chunks, size = [], 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > max_bytes:
            raise HTTPException(413, f"scan body exceeds the limit of {max_bytes:,} bytes")
        chunks.append(chunk)
    return b"".join(chunks)


def _model_routes(app: FastAPI, config: ServiceConfig, auth: list) -> None:
    """``GET /health`` and ``GET /models``."""

    @app.get("/health", dependencies=auth, responses=_responses(401))
    def health() -> dict:
        """Liveness: the service is up and its models are loaded."""
        return {"status": "ok", "models": sorted(config.models)}

    @app.get("/models", dependencies=auth, responses=_responses(401))
    def models() -> dict:
        """The prepared models this service holds (lengths in mm)."""
        return {name: {"faces": len(p.model.faces), "model_points": int(p.n_points),
                       "spacing_mm": float(p.model_spacing), "reach_mm": float(p.reach),
                       "max_distance_mm": float(p.reach),   # reach_mm's old name (deprecated; will go)
                       "size_mm": float(p.model.size), "unit": "mm",
                       "sha256": config.model_hashes.get(name)}
                for name, p in config.models.items()}


def _inspect_route(app: FastAPI, config: ServiceConfig, runner: Runner, work: Work, auth: list) -> None:
    """``POST /inspect``."""

    @app.post(
        "/inspect", dependencies=auth, responses=_responses(401, 404, 408, 413, 415, 422, 504, 507),
        openapi_extra={"requestBody": {"required": True, "description": f"The scan points (mm): {SUPPORTED}. "
                       "Without a content type (or "
                       "with application/octet-stream or text/plain) the first bytes decide.",
                       "content": {t: {"schema": {"type": "string", "format": "binary"}} for t in _SCAN_TYPES}}})
    async def inspect_scan(
        request: Request,
        response: Response,
        model: str = Query(..., description="name of a loaded model (see /models)"),
        tolerance: float | None = Query(None, gt=0, allow_inf_nan=False,
                                        description="symmetric tolerance ±mm (or give lower and upper)"),
        lower: float | None = Query(None, allow_inf_nan=False, description="lower limit, mm (<= 0)"),
        upper: float | None = Query(None, allow_inf_nan=False, description="upper limit, mm (>= 0)"),
        evaluation_distance: float | None = Query(
            None, gt=0, allow_inf_nan=False,
            description="scan points farther than this from the CAD surface are not evaluated "
                        "(mm; default max(5 x tolerance, min(1, 5 % of the model size)))"),
        max_distance: float | None = Query(None, gt=0, allow_inf_nan=False, deprecated=True,
                                           description="old name of evaluation_distance (accepted "
                                                       "with a 'Warning' header; it will go)"),
        faces: str | None = Query(None, max_length=10_000,
                                  description="inspect only these CAD faces, e.g. '0,3,7' (default: all)"),
        min_coverage: float | None = Query(None, ge=0, le=1, allow_inf_nan=False,
                                           description="least share of the inspected CAD area that "
                                                       "must be seen (0..1, default 0.2)"),
        init: str | None = Query(None, max_length=2000,
                                 description="start pose: 'auto' (default: the model's fixture pose "
                                             "if it has one, else found automatically), 'identity', "
                                             "'global', 'principal-axes', or 16 comma-separated "
                                             "numbers, T_model_scan row by row (mm)"),
        scan_unit: str | None = Query(None, max_length=20,
                                      description="unit of a scan that carries none (mm, cm, m, in, um; default mm)"),
        plan: str | None = Query(None, max_length=200_000,
                                 description="an inspection plan: its YAML text (plan.yaml's content)"),
        part: str | None = Query(None, max_length=200, description="part id (serial number) for the history"),
    ) -> dict:
        """Register and inspect the scan in the request body; store the result; return it."""
        options, notes = _options(dict(
            tolerance=tolerance, lower=lower, upper=upper, evaluation_distance=evaluation_distance,
            max_distance=max_distance, faces=faces, min_coverage=min_coverage, init=init,
            scan_unit=scan_unit, plan=plan))
        for note in notes:
            response.headers.append("Warning", f'299 shapeverify "{note}"')
        deadline = runner.deadline()
        if model not in config.models:
            raise HTTPException(404, f"unknown model {model!r}; loaded models: {sorted(config.models)}")
        try:
            body = await asyncio.wait_for(_read_body(request, config.max_body_bytes), runner.limit)
        except asyncio.TimeoutError:
            raise HTTPException(408, f"the upload did not complete within the time limit of "
                                     f"{runner.limit:g} s") from None
        upload = Upload(model, body, request.headers.get("content-type"), options, part)
        return await runner.run(deadline, work.inspect_and_store, upload)


def _history_routes(app: FastAPI, runner: Runner, work: Work, auth: list) -> None:
    """``GET /history`` and ``GET /report/{id}``."""

    @app.get("/history", dependencies=auth, responses=_responses(401, 422))
    async def history(part: str | None = Query(None, description="only this part id"),
                      limit_: int = Query(50, alias="limit", ge=1, le=10_000,
                                          description="the most recent N records (returned oldest first)"),
                      model: str | None = Query(None, max_length=200, description="only this model: "
                                                "a loaded model's name, or a SHA-256 (prefix)")) -> list:
        """Stored inspections: id, part, time, model_hash, verdict, statistics (mm; null where
        not available), n_regions, max_abs, region_min, region_max, lower, upper."""
        rows = await runner.run(runner.deadline(), work.query, part, limit_, model)
        return [{k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in r.items()}
                for r in rows]

    @app.get("/report/{record_id}", response_class=HTMLResponse, dependencies=auth,
             responses=_responses(401, 404, 504))
    async def report(record_id: str) -> HTMLResponse:
        """The HTML report of a stored inspection, drawn on demand from the stored result (404 for
        an id that is not a stored record's: negative, non-numeric or too large ones too)."""
        if not _RECORD_ID.fullmatch(record_id):
            raise HTTPException(404, f"no stored inspection with id {record_id[:40]!r}: record ids "
                                     "are the positive integers /history lists")
        html = await runner.run(runner.deadline(), work.render_report, int(record_id))
        return HTMLResponse(html)


def _error_handlers(app: FastAPI) -> None:
    """Bad parameters and the project's errors: 422 with a readable ``detail``; a bug: 500,
    said to be one (and logged with its traceback)."""

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

    @app.exception_handler(Exception)
    async def _internal_error(request: Request, exc: Exception):
        log.error("internal error on %s %s", request.method, request.url.path, exc_info=exc)
        what = " ".join(f"{type(exc).__name__}: {exc}".split())
        return JSONResponse(status_code=500, content={
            "detail": f"internal error (a bug in shapeverify, please report it): {what}"})
