"""Start-up of the service: load the prepared models once and warm up the JIT before serving.

``serve`` loads and warms up the models in the starting process *before* the port is bound, so
a model that cannot be loaded stops the start with a message and the first request does not pay
for numba compilation. With ``workers > 1`` uvicorn runs that many worker processes on the same
port (the only way past the GIL on a multi-core machine); each loads the models again (numba's
on-disk cache, filled by the warm-up of the starting process, makes that quick), and requests
that arrive while a worker is still loading wait in the listen backlog. All processes write the
same SQLite history (WAL mode; one transaction per record).

Connections whose request headers do not arrive in full within ``header_timeout_s`` (default
10 s) of the connection opening, or of the previous response on a kept-alive connection, are
closed (:class:`HeaderTimeoutProtocol`): a client that sends half a request and stalls (or a
slowloris attack) cannot hold connections open forever.  Idle kept-alive connections are closed
after uvicorn's ``timeout_keep_alive`` (5 s).
"""

from __future__ import annotations

import json
import logging
import os
import socket
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

_ENV = "SHAPEVERIFY_SERVICE_CONFIG"  # settings handed to uvicorn's worker processes
#: seconds a connection may take to send a complete set of request headers
HEADER_TIMEOUT_S = 10.0


def _auto_protocol():
    from uvicorn.protocols.http.auto import AutoHTTPProtocol

    return AutoHTTPProtocol


class HeaderTimeoutProtocol(_auto_protocol()):
    """uvicorn's HTTP protocol (httptools, else h11) with a time limit on request headers.

    A timer starts when the connection opens and again when a response has been sent; it is
    stopped as soon as a request's headers are complete (uvicorn then starts a new request cycle).
    When it fires while no request is in progress, the connection is closed.  The limit is the
    class attribute ``header_timeout`` (seconds; set by :func:`serve`).
    """

    header_timeout = HEADER_TIMEOUT_S

    def connection_made(self, transport) -> None:
        super().connection_made(transport)
        self._header_timer = None
        self._arm_header_timer()

    def _arm_header_timer(self) -> None:
        self._stop_header_timer()
        self._header_cycle = self.cycle
        self._header_timer = self.loop.call_later(self.header_timeout, self._header_time_out)

    def _stop_header_timer(self) -> None:
        if getattr(self, "_header_timer", None) is not None:
            self._header_timer.cancel()
            self._header_timer = None

    def _header_time_out(self) -> None:
        self._header_timer = None
        idle = self.cycle is None or self.cycle.response_complete
        if self.cycle is self._header_cycle and idle and not self.transport.is_closing():
            log.info("closing a connection whose request headers did not arrive within %g s",
                     self.header_timeout)
            self.transport.close()

    def data_received(self, data: bytes) -> None:
        super().data_received(data)
        if self._header_timer is not None and self.cycle is not self._header_cycle:
            self._stop_header_timer()  # a request's headers are complete

    def on_response_complete(self) -> None:
        super().on_response_complete()
        if not self.transport.is_closing():
            self._arm_header_timer()

    def connection_lost(self, exc) -> None:
        self._stop_header_timer()
        super().connection_lost(exc)


def load_models(paths) -> tuple[dict, dict]:
    """Load prepared models (``.svm``); names are the file stems.

    Returns
    -------
    models : dict name -> Prepared
    hashes : dict name -> sha256 of the file

    Raises
    ------
    ValueError
        A file that is not ``.svm``, two models with the same name, or no model at all.
    FileNotFoundError
        A missing file.
    """
    from shapeverify.nearest import load_prepared
    from shapeverify.pipeline import file_hash

    models, hashes = {}, {}
    for p in map(Path, paths):
        if p.suffix.lower() != ".svm":
            raise ValueError(f"{p}: the service serves prepared models (.svm); "
                             f"run `shapeverify prepare {p} -o {p.stem}.svm` first")
        if p.stem in models:
            raise ValueError(f"two models are named {p.stem!r}; rename one file")
        models[p.stem] = load_prepared(p)
        hashes[p.stem] = file_hash(p)
    if not models:
        raise ValueError("no model given: pass at least one .svm file")
    return models, hashes


def warm_up(models: dict) -> None:
    """Run one small inspection per model (the requests' :func:`~shapeverify.pipeline.inspect_scan`)
    so that every numba kernel is compiled before serving."""
    from shapeverify.pipeline import inspect_scan

    for name, prep in models.items():
        pts = prep.points.points
        idx = np.random.default_rng(0).choice(len(pts), size=min(2000, len(pts)), replace=False)
        try:
            inspect_scan(prep, pts[idx], tolerance=1.0)
        except Exception as exc:  # warm-up must not stop the service; the first request will tell
            log.warning("warm-up of %s failed: %s", name, exc)


def serve(model_paths, *, host: str = "127.0.0.1", port: int = 8000, workers: int = 1,
          log_level: str = "warning", on_ready=None, **settings) -> None:
    """Load and warm up the models, then serve HTTP until interrupted (blocks).

    Parameters
    ----------
    model_paths : list of path
        Prepared models (``.svm``); the file stems are the model names.
    host, port
        Where to listen.
    workers : int
        Server processes (uvicorn workers) sharing the port.
    log_level : str
        uvicorn's log level.
    on_ready : callable(models: dict), optional
        Called after loading and warm-up, before the port is bound (the CLI prints a line).
    **settings
        The service's settings, the fields of :class:`~shapeverify.service.app.ServiceConfig`:
        ``db_path`` (default ``history.sqlite``), ``token``, ``max_body_bytes``,
        ``time_limit_s``, ``threads`` (inspection threads per process), ``keep_scans``; and
        ``header_timeout_s``: connections whose request headers are not complete within this
        many seconds are closed (default 10).
    """
    import uvicorn

    from shapeverify.service.app import ServiceConfig, create_app

    s = _settings(settings)
    header_timeout_s = s.pop("header_timeout_s")
    HeaderTimeoutProtocol.header_timeout = header_timeout_s
    models, hashes = load_models(model_paths)
    warm_up(models)
    if on_ready is not None:
        on_ready(models)
    if workers <= 1:
        config = ServiceConfig(models=models, model_hashes=hashes, **s)
        uvicorn.run(create_app(config), host=host, port=port, log_level=log_level,
                    http=HeaderTimeoutProtocol)
        return
    del models
    os.environ[_ENV] = json.dumps(dict(
        s, model_paths=[str(Path(p).resolve()) for p in model_paths],
        db_path=str(s["db_path"].resolve()), header_timeout_s=header_timeout_s))
    from uvicorn.supervisors import Multiprocess

    config = uvicorn.Config("shapeverify.service.server:app_from_env", factory=True, host=host,
                            port=port, workers=int(workers), log_level=log_level,
                            http=HeaderTimeoutProtocol)
    Multiprocess(config, sockets=[listen_socket(host, port)]).run()


def _settings(given: dict) -> dict:
    """``serve``'s settings with their defaults (:class:`ServiceConfig`'s), checked and typed."""
    import dataclasses

    from shapeverify.service.app import ServiceConfig

    defaults = {f.name: f.default for f in dataclasses.fields(ServiceConfig)
                if f.name not in ("models", "model_hashes")}
    defaults["header_timeout_s"] = HEADER_TIMEOUT_S
    unknown = sorted(set(given) - set(defaults))
    if unknown:
        raise TypeError(f"serve() got unknown setting(s) {unknown}; known: {sorted(defaults)}")
    s = {**defaults, **given}
    if not s["header_timeout_s"] > 0:
        raise ValueError(f"header_timeout_s must be > 0 seconds, got {s['header_timeout_s']!r}")
    return dict(db_path=Path(s["db_path"]), token=s["token"],
                max_body_bytes=int(s["max_body_bytes"]), time_limit_s=float(s["time_limit_s"]),
                threads=int(s["threads"]), keep_scans=bool(s["keep_scans"]),
                header_timeout_s=float(s["header_timeout_s"]))


def listen_socket(host: str, port: int) -> socket.socket:
    """The shared listening socket of the worker processes, created with ``IPPROTO_TCP``.

    uvicorn's own ``bind_socket`` creates it with protocol 0; the connections it accepts inherit
    that, and asyncio then skips ``TCP_NODELAY`` on them (it checks ``sock.proto``).  With Nagle's
    algorithm on, a response written in two parts waits for the client's delayed ACK: +40 ms
    per request (measured: sequential p50 120 ms with 2 workers against 76 ms with 1).
    """
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM, socket.IPPROTO_TCP)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except OSError as exc:
        sock.close()
        raise OSError(f"cannot listen on {host}:{port}: {exc.strerror or exc}; is the port already "
                      "in use? choose another with --port") from exc
    sock.set_inheritable(True)
    return sock


def app_from_env():
    """uvicorn factory for worker processes: the settings come from ``$SHAPEVERIFY_SERVICE_CONFIG``."""
    from shapeverify.service.app import ServiceConfig, create_app

    s = json.loads(os.environ[_ENV])
    HeaderTimeoutProtocol.header_timeout = float(s.pop("header_timeout_s", HEADER_TIMEOUT_S))
    models, hashes = load_models(s.pop("model_paths"))
    warm_up(models)
    s["db_path"] = Path(s["db_path"])
    return create_app(ServiceConfig(models=models, model_hashes=hashes, **s))
