"""Run the OpenCASCADE import in a child process, so that a crash of the native library cannot take
the caller down.

A damaged STEP or IGES file can make OpenCASCADE dereference a null handle and die with a
segmentation fault (measured: 33 of 316 mutated files), which no Python ``try`` can catch.
:func:`read_cad_isolated` therefore sends the path to a long-lived importer process (started on
first use with ``python -m shapeverify.cad.occ_worker``, kept for later imports and started again
after a crash) and gets back the project's own numpy NURBS data
(:func:`shapeverify.cad.persist.model_to_arrays`, pickled over a pipe), never OCP objects.

:func:`summary_isolated` asks the same process for only the figures ``shapeverify info`` shows
(:func:`shapeverify.cad.occ_summary.read_summary`: OpenCASCADE alone, no numba); an importer
started for that (``prestart(summary=True)``, ``python -m shapeverify.cad.occ_worker --summary``)
does not import numba and the kernels ahead, so a new file's ``info`` pays neither.

* A crash of the importer (a signal, or an exit without an answer) raises
  :class:`~shapeverify.errors.CADImportError` ("the CAD importer crashed on FILE (signal 11,
  SIGSEGV) ...").
* A time limit kills an importer that hangs, with the same error: ``timeout`` when the caller
  gives one, else :func:`default_time_limit` (120 s + 30 s per MB of the file, or the seconds
  in ``$SHAPEVERIFY_IMPORT_TIMEOUT``; 0 there: no limit).  Before this limit existed a file with
  a ``NaN`` coordinate kept ``info`` and ``prepare`` busy for ever (issue 33 row 4; such numbers
  are now refused before the import: :mod:`shapeverify.cad.number_check`).
* The importer's log records are re-emitted in the caller under their own logger names, so
  warnings about skipped faces appear as if the import had run in-process.
* Errors raised in the importer come back as the same class with the same message
  (``CADImportError``, ``EmptyModelError``, ``UnsupportedFormatError``, ``FileNotFoundError``);
  anything else raised by OpenCASCADE becomes ``CADImportError``.

Cost (measured on the example panel and the wavy cube): the first import of a process pays for
starting the importer (a Python interpreter that imports numpy and OCP: about +1 s, 2.2 s against
1.1 s in-process); later imports add 7 ms (panel) and 32 ms (wavy cube, 21 ms of which is the
bounding box, computed in the child because ``prepare`` needs it anyway; pickling ~1 ms).  One import runs at a time
(a lock); after 64 imports the importer is replaced, which bounds OpenCASCADE's memory growth.

The protocol is private: 8-byte little-endian length + pickle, requests on the child's stdin,
answers on a copy of its stdout (the child's fd 1 is pointed at stderr, which is discarded, so
that stray console output of the native library cannot corrupt the answers).
"""

from __future__ import annotations

import atexit
import logging
import os
import pickle
import select
import signal
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

from ..errors import CADImportError, EmptyModelError, ShapeVerifyError, UnsupportedFormatError

logger = logging.getLogger(__name__)

__all__ = ["read_cad_isolated", "summary_isolated", "pmi_isolated", "prestart", "shutdown"]

_LEN = struct.Struct("<Q")
_MAX_USES = 64  # imports per importer process before it is replaced
#: time limit (s) of an import when the caller gives none (None: :func:`default_time_limit`,
#: which grows with the file's size); the fuzz tests set it
DEFAULT_TIMEOUT_S: float | None = None
#: the default time limit of an import: this many seconds ...
TIME_LIMIT_BASE_S = 120.0
#: ... plus this many per MB of the file (an undamaged 4 MB IGES file imports in about 10 s)
TIME_LIMIT_PER_MB_S = 30.0
#: environment variable that sets the time limit in seconds (0: none)
TIME_LIMIT_ENV = "SHAPEVERIFY_IMPORT_TIMEOUT"
_ERRORS = {c.__name__: c for c in (CADImportError, EmptyModelError, UnsupportedFormatError)}


# ------------------------------------------------------------------------------- the caller
class _Importer:
    """One importer child process and its pipes (used under ``_LOCK``)."""

    def __init__(self, summary: bool = False):
        root = str(Path(__file__).resolve().parents[2])  # the folder holding ``shapeverify``
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join([root] + [p for p in
                                                      env.get("PYTHONPATH", "").split(os.pathsep) if p])
        if summary:  # no linear algebra in a summary: OpenBLAS's thread pool start (~0.1-0.2 s
            # of numpy's import) is saved where the caller did not choose
            env.setdefault("OPENBLAS_NUM_THREADS", "1")
        self.pid_owner = os.getpid()
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "shapeverify.cad.occ_worker"] + (["--summary"] if summary else []),
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env, close_fds=True)
        self.uses = 0

    def alive(self) -> bool:
        return self.pid_owner == os.getpid() and self.proc.poll() is None

    def request(self, req, deadline: float | None):
        data = pickle.dumps(req, protocol=pickle.HIGHEST_PROTOCOL)
        self.uses += 1
        try:
            self.proc.stdin.write(_LEN.pack(len(data)) + data)
            self.proc.stdin.flush()
        except (BrokenPipeError, OSError):
            return None
        head = self._read(_LEN.size, deadline)
        if head is None:
            return None
        body = self._read(_LEN.unpack(head)[0], deadline)
        return None if body is None else pickle.loads(body)

    def _read(self, n: int, deadline: float | None) -> bytes | None:
        fd = self.proc.stdout.fileno()
        chunks, got = [], 0
        while got < n:
            wait = None if deadline is None else deadline - time.monotonic()
            if wait is not None and wait <= 0:
                raise TimeoutError
            ready, _, _ = select.select([fd], [], [], wait)
            if not ready:
                raise TimeoutError
            chunk = os.read(fd, min(n - got, 1 << 20))
            if not chunk:
                return None  # the child closed its end: it died
            chunks.append(chunk)
            got += len(chunk)
        return b"".join(chunks)

    def close(self, kill: bool = False) -> int | None:
        """Stop the child; return its exit status (negative: killed by that signal)."""
        if self.pid_owner != os.getpid():
            return None  # inherited through fork: the parent's child, not ours to stop
        try:
            if kill:
                self.proc.kill()
            else:
                self.proc.stdin.close()
        except OSError:
            pass
        try:
            return self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            return self.proc.wait()
        finally:
            for fh in (self.proc.stdin, self.proc.stdout):
                try:
                    fh.close()
                except OSError:
                    pass


_LOCK = threading.Lock()
_CURRENT: _Importer | None = None


def prestart(summary: bool = False) -> None:
    """Start the importer process now, if none runs, so that its start (a Python that imports
    numpy and OpenCASCADE) overlaps whatever the caller does before its first import; the
    command line calls it first thing when its model is a CAD file.

    ``summary``: the caller wants only :func:`summary_isolated`, so the importer does not
    import numba and its kernels ahead (a later full import still works: it imports them
    then)."""
    global _CURRENT
    with _LOCK:
        if _CURRENT is None or not _CURRENT.alive():
            _CURRENT = _Importer(summary)


def shutdown(kill: bool = False) -> None:
    """Stop the importer process, if one runs (also done at interpreter exit).

    ``kill``: end it with SIGKILL instead of letting it finish (what interpreter exit does: the
    importer holds nothing to save between requests, and a Python that has imported
    OpenCASCADE takes ~0.2-0.4 s to tear itself down, which the caller would wait for)."""
    global _CURRENT
    with _LOCK:
        if _CURRENT is not None:
            _CURRENT.close(kill=kill)
            _CURRENT = None


def _shutdown_at_exit() -> None:
    shutdown(kill=True)


atexit.register(_shutdown_at_exit)


def _describe(status: int | None) -> str:
    if status is None:
        return "it stopped answering"
    if status < 0:
        try:
            name = signal.Signals(-status).name
        except ValueError:
            name = "unknown signal"
        return f"signal {-status}, {name}"
    return f"exit status {status}"


def read_cad_isolated(path, *, chord_tol: float, gap_tol: float, timeout: float | None = None):
    """:func:`shapeverify.cad.occ_import.read_cad` run in the importer child process.

    Parameters
    ----------
    path : str or Path
        STEP or IGES file (already checked to exist).
    chord_tol, gap_tol : float
        As for ``read_cad`` (mm).
    timeout : float, optional
        Seconds after which a still-running import is killed (default:
        :func:`default_time_limit`: 120 s + 30 s per MB of the file).

    Returns
    -------
    Model

    Raises
    ------
    CADImportError
        The importer crashed (the message gives the signal), timed out, or OpenCASCADE raised.
    EmptyModelError, UnsupportedFormatError, FileNotFoundError
        As raised by ``read_cad`` in the child.
    """
    from .persist import model_from_arrays

    path = Path(path)
    t0 = time.perf_counter()
    payload = _call(path, ("read", os.getcwd(), os.fspath(path), float(chord_tol),
                           float(gap_tol), _level()), timeout)
    model = model_from_arrays(payload, str(path))
    logger.debug("%s: imported in the importer process in %.3f s", path.name,
                 time.perf_counter() - t0)
    return model


def summary_isolated(path, *, timeout: float | None = None):
    """:func:`shapeverify.cad.occ_summary.read_summary` run in the importer child process
    (OpenCASCADE alone: neither the caller nor the importer imports numba for it).

    Parameters
    ----------
    path : str or Path
        STEP or IGES file (already checked to exist).
    timeout : float, optional
        As for :func:`read_cad_isolated`.

    Returns
    -------
    ModelSummary

    Raises
    ------
    CADImportError, EmptyModelError, UnsupportedFormatError, FileNotFoundError
        As :func:`read_cad_isolated`.
    """
    from .number_check import check_numbers
    from .occ_import import CAD_SUFFIXES

    path = Path(path)
    check_numbers(path, CAD_SUFFIXES.get(path.suffix.lower(), "step"))
    return _call(path, ("summary", os.getcwd(), os.fspath(path), _level()), timeout)


def default_time_limit(path) -> tuple[float | None, str]:
    """The time limit (s) of an import of ``path`` when the caller gives none, and how it was
    set (for the message when it is hit).

    :data:`DEFAULT_TIMEOUT_S` if set; else ``$SHAPEVERIFY_IMPORT_TIMEOUT`` (seconds, 0 or
    ``none``: no limit); else :data:`TIME_LIMIT_BASE_S` + :data:`TIME_LIMIT_PER_MB_S` per MB.

    Raises
    ------
    ValueError
        The environment variable is not a number of seconds.
    """
    if DEFAULT_TIMEOUT_S is not None:
        return float(DEFAULT_TIMEOUT_S), "the time limit"
    env = os.environ.get(TIME_LIMIT_ENV, "").strip()
    if env:
        if env.lower() in ("0", "none", "inf"):
            return None, ""
        try:
            val = float(env)
        except ValueError:
            val = float("nan")
        if not (val > 0 and val < float("inf")):
            raise ValueError(f"${TIME_LIMIT_ENV}={env!r} is not a number of seconds (0: no "
                             "time limit on CAD imports)")
        return val, f"${TIME_LIMIT_ENV}"
    try:
        mb = Path(path).stat().st_size / 1e6
    except OSError:
        mb = 0.0
    limit = TIME_LIMIT_BASE_S + TIME_LIMIT_PER_MB_S * mb
    return limit, (f"the default time limit for this {mb:.3g} MB file ({TIME_LIMIT_BASE_S:g} s + "
                   f"{TIME_LIMIT_PER_MB_S:g} s per MB; set ${TIME_LIMIT_ENV}=SECONDS to change "
                   "it, 0 for none)")


def pmi_isolated(path, *, timeout: float | None = None) -> dict:
    """:func:`shapeverify.cad.pmi.read_pmi_here` (the semantic PMI of a STEP file) run in the
    importer child process; raises as :func:`read_cad_isolated`."""
    path = Path(path)
    return _call(path, ("pmi", os.getcwd(), os.fspath(path), _level()), timeout)


def _level() -> int:
    """The most verbose level any shapeverify logger of this process wants (the child logs
    at it)."""
    return min([logging.getLogger("shapeverify").getEffectiveLevel()]
               + [lg.getEffectiveLevel() for name, lg in list(logging.root.manager.loggerDict.items())
                  if name.startswith("shapeverify.") and isinstance(lg, logging.Logger)])


def _call(path: Path, req, timeout: float | None):
    """Send one request to the importer (started if needed); return its answer's payload or
    raise what the importer raised (or :class:`CADImportError` for a crash or time-out)."""
    global _CURRENT
    how = "the time limit given"
    if timeout is None:
        timeout, how = default_time_limit(path)
    deadline = None if timeout is None else time.monotonic() + float(timeout)
    with _LOCK:
        if _CURRENT is not None and (not _CURRENT.alive() or _CURRENT.uses >= _MAX_USES):
            if _CURRENT.pid_owner == os.getpid():
                _CURRENT.close()
            _CURRENT = None
        if _CURRENT is None:
            _CURRENT = _Importer(summary=req[0] == "summary")
        worker = _CURRENT
        try:
            reply = worker.request(req, deadline)
        except TimeoutError:
            _CURRENT = None
            worker.close(kill=True)
            raise CADImportError(f"{path}: the CAD importer did not finish within {timeout:g} s "
                                 f"({how}) and was stopped; the file may be damaged (export it "
                                 "again from the CAD system) or too large for the time limit") \
                from None
        except BaseException:  # interrupted (Ctrl-C): the answer would be stale, start afresh
            _CURRENT = None
            worker.close(kill=True)
            raise
        if reply is None:
            _CURRENT = None
            status = worker.close(kill=True) if worker.proc.poll() is None else worker.close()
            raise CADImportError(f"{path}: the CAD importer crashed on this file "
                                 f"({_describe(status)}); OpenCASCADE could not read it, the file "
                                 "is probably damaged: export it again from the CAD system")
    kind, payload, records = reply
    for name, lvl, msg in records:
        lg = logging.getLogger(name)
        if lg.isEnabledFor(lvl):
            lg.log(lvl, msg)
    if kind == "ok":
        return payload
    if kind == "oserror":
        err, text, fname = payload
        raise (FileNotFoundError if err == 2 else OSError)(err, text, fname)
    cls_name, message = payload
    raise _ERRORS.get(cls_name, CADImportError)(message)


# -------------------------------------------------------------------------------- the child
class _Collect(logging.Handler):
    def __init__(self):
        super().__init__(logging.DEBUG)
        self.records = []

    def emit(self, record):
        try:
            self.records.append((record.name, record.levelno, record.getMessage()))
        except Exception:  # a record that cannot be formatted is dropped, not fatal
            pass


def _answer(req, handler: _Collect):
    from . import occ_import

    kind, cwd, path, *args = req
    level = args[-1]
    logging.getLogger("shapeverify").setLevel(level)
    handler.records = []
    try:
        os.chdir(cwd)  # the path is read as the caller gave it (and named so in messages)
        if kind == "summary":
            from .occ_summary import read_summary

            reply = ("ok", read_summary(path))
        elif kind == "pmi":
            from .pmi import read_pmi_here

            reply = ("ok", read_pmi_here(path))
        else:
            from .persist import model_to_arrays

            chord_tol, gap_tol = args[0], args[1]
            model = occ_import.read_cad(path, chord_tol=chord_tol, gap_tol=gap_tol,
                                        isolated=False)
            reply = ("ok", model_to_arrays(model))
    except OSError as exc:
        reply = ("oserror", (exc.errno, exc.strerror or str(exc), exc.filename))
    except ShapeVerifyError as exc:
        reply = ("error", (type(exc).__name__, str(exc)))
    except Exception as exc:  # noqa: BLE001 - what OpenCASCADE raises: the file's fault
        reply = ("error", ("CADImportError", f"{path}: OpenCASCADE could not read the file "
                                             f"({type(exc).__name__}: {exc})"))
    return reply + (handler.records,)


def _serve() -> None:
    """The importer's loop: one request in, one answer out, until stdin closes."""
    from . import occ_import

    occ_import._NUMBERS_CHECKED_BY_CALLER = True  # read_cad/summary_isolated did, before sending
    out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # console output of the native library goes where stderr goes (discarded)
    inp = sys.stdin.buffer
    handler = _Collect()
    root = logging.getLogger("shapeverify")
    root.addHandler(handler)
    root.propagate = False
    try:  # import now, while the caller is still starting up (see prestart); every import
        # samples edges and bounds faces with the numba kernels, which the modules import
        # lazily; an importer started for summaries only (``--summary``) needs no numba
        if "--summary" in sys.argv[1:]:
            from . import occ_summary  # noqa: F401
            import OCP.STEPControl  # noqa: F401
        else:
            from . import _kernels, _trim_kernels, occ_import  # noqa: F401
            import OCP  # noqa: F401
    except Exception:  # noqa: BLE001 - the request will report it
        pass
    while True:
        head = inp.read(_LEN.size)
        if len(head) < _LEN.size:
            return
        req = pickle.loads(inp.read(_LEN.unpack(head)[0]))
        data = pickle.dumps(_answer(req, handler), protocol=pickle.HIGHEST_PROTOCOL)
        out.write(_LEN.pack(len(data)) + data)
        out.flush()


if __name__ == "__main__":
    _serve()
