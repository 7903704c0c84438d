"""The resident worker process of the command line (``shapeverify worker start``): it imports
the command line and the pipeline once, then runs the commands that clients
(:mod:`shapeverify.cli_worker`) send over its Unix-domain socket, one at a time, through the
same typer app as in-process; the protocol, the version key and the client are in
:mod:`shapeverify.cli_worker`.

Started as ``python -m shapeverify.cli_worker_server SOCKET [IDLE_MINUTES]`` by
:func:`shapeverify.cli_worker.start`.
"""

from __future__ import annotations

import os
import struct
import sys
from pathlib import Path

from shapeverify.cli_worker import _ask, _recv, _send, import_env, version_key

__all__ = ["Worker", "serve", "KEEP_MODELS"]


def _children_cpu() -> float:
    """CPU seconds of this process's live children (the CAD importer), from /proc (Linux)."""
    total, tick = 0.0, os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
    try:
        tasks = os.listdir("/proc/self/task")
    except OSError:
        return 0.0
    for t in tasks:
        try:
            with open(f"/proc/self/task/{t}/children") as f:
                kids = f.read().split()
        except OSError:
            continue
        for pid in kids:
            try:
                with open(f"/proc/{pid}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
                total += (int(fields[11]) + int(fields[12])) / tick
            except (OSError, IndexError, ValueError):
                continue
    return total


def _cpu() -> float:
    import resource

    s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime + _children_cpu()


class _Raw:
    """The binary stream under a request's ``sys.stdout``/``sys.stderr``: frames to the client."""

    def __init__(self, sock, kind: bytes, tty: bool):
        import io

        class Raw(io.RawIOBase):
            def writable(self):
                return True

            def isatty(self):
                return tty

            def write(self, b):
                if len(b):
                    _send(sock, kind, bytes(b))
                return len(b)

        self.raw = Raw()


def _stream(sock, kind: bytes, tty: bool, encoding: str, errors: str):
    import io

    return io.TextIOWrapper(io.BufferedWriter(_Raw(sock, kind, tty).raw), encoding=encoding,
                            errors=errors, line_buffering=True, write_through=True)


class Worker:
    """The resident process: listens on ``path``, runs one command at a time."""

    def __init__(self, path: Path, idle_minutes: float):
        import threading
        import time

        self.path, self.idle = Path(path), float(idle_minutes) * 60.0
        self.key, self.import_env = version_key(), import_env(os.environ)
        self.started, self.requests, self.cpu, self.preload_cpu = time.time(), 0, 0.0, 0.0
        self.queue = __import__("queue").Queue()
        self.stopping = threading.Event()
        self.lock = threading.Lock()
        self.running = None   # the connection whose request runs now
        self.interruptible = False   # a cancel may interrupt: the command itself runs
        self.cancelled = False       # the running request's client cancelled it
        self.pid = os.getpid()

    # ------------------------------------------------------------------ preparation
    def preload(self) -> None:
        """Import the command line and the pipeline, scipy's k-d tree and numba (cached kernels
        load without numba's registries: :mod:`shapeverify._start_shortcuts`), so that a request
        pays only its own work."""
        import contextlib
        import gc
        import io
        import logging
        import warnings

        # the cyclic collector paused while numpy, scipy and numba import (some million
        # objects; the collections they set off cost ~0.1-0.2 s and free nearly nothing)
        gc.disable()
        sink = io.StringIO()
        with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
            import typer.main

            from shapeverify._lazy import kdtree_class
            from shapeverify._start_shortcuts import (defer_numba_registries,
                                                       import_kernel_env_modules, import_numba)

            import_numba()              # without PyYAML (numba reads a config file with it)
            defer_numba_registries()    # cached kernels load without numba's registries
            # scipy's k-d tree and BLAS/LAPACK modules without the packages scipy.spatial,
            # scipy.sparse and scipy.linalg (0.1-0.2 s): a plain inspect needs none of them, a
            # command that does (a plan, a mesh) imports them at its first use
            kdtree_class()
            import_kernel_env_modules()  # what the kernels' environments name
            from shapeverify import cli, cli_common  # noqa: F401
            import shapeverify.inspection  # noqa: F401
            import shapeverify.nearest  # noqa: F401
            import shapeverify.options  # noqa: F401
            import shapeverify.pipeline  # noqa: F401
            import shapeverify.registration  # noqa: F401
            # the click command typer builds from the app on every call (~0.05 s): built once
            self.command = typer.main.get_command(cli.app)
        _keep_prepared_models()
        # the libraries' objects frozen: later collections need not walk them again.  No
        # gc.collect() first: it walked them all (~0.12 s) to free ~1,100 objects of garbage
        gc.freeze()
        gc.enable()
        self.preload_cpu = _cpu()
        self.filters = list(warnings.filters)
        self.logging_level = logging.getLogger().level

    # ------------------------------------------------------------------ serving
    def serve(self) -> None:
        import socket

        import signal
        import threading

        self.path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        os.chmod(self.path.parent, 0o700)
        if _ask("status", path=self.path) is not None:  # another worker answers there (two started at once)
            return
        listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        # bound and listening under a name of its own, then renamed into place: a client that
        # finds the socket file can connect (one that connected between bind and listen was
        # refused, took the worker for dead and removed its socket file)
        tmp = self.path.with_name(f"{self.path.stem}.{os.getpid()}.tmp")
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        old = os.umask(0o177)
        try:
            listener.bind(str(tmp))
        finally:
            os.umask(old)
        os.chmod(tmp, 0o600)
        listener.listen(16)
        os.replace(tmp, self.path)
        self.inode = os.stat(self.path).st_ino
        try:  # the start a command claimed (cli_worker._claim_start) is done
            os.unlink(self.path.with_suffix(".starting"))
        except OSError:
            pass
        signal.signal(signal.SIGTERM, lambda *_: self._stop_now())
        # a cancel arrives as a frame and is raised by _thread.interrupt_main, which calls
        # this Python SIGINT handler in the main thread (the worker has no terminal: its own
        # session); it raises only while the command itself runs (_command)
        signal.signal(signal.SIGINT, self._on_interrupt)
        threading.Thread(target=self._accept, args=(listener,), daemon=True).start()
        try:
            self._loop()
        finally:
            listener.close()
            try:
                if os.stat(self.path).st_ino == self.inode:
                    os.unlink(self.path)
            except OSError:
                pass

    def _on_interrupt(self, signum, frame) -> None:
        """KeyboardInterrupt in the cancelled command, at a line of the package's own code.

        The handler runs at the main thread's next bytecode after ``interrupt_main``, which
        can be Python code that a compiled kernel or a C extension called back (numba's
        dispatcher, numpy, scipy): raised there, the exception reached the kernel's caller as
        "returned a result with an exception set" (exit 2 instead of 130) and once crashed the
        worker (a segmentation fault in ``scan_noise``'s kernel, seen after its compiled
        version made the inspection mostly numba).  Elsewhere it does nothing and the watcher
        (:meth:`_watch`) asks again 20 ms later; after the command ended, nothing at all."""
        if (self.interruptible and self.cancelled and frame is not None
                and frame.f_code.co_filename.startswith(_PACKAGE_DIR)):
            raise KeyboardInterrupt

    def _command(self, argv: list) -> None:
        """The command line's ``main`` on ``argv``, the one span a cancel interrupts."""
        try:
            self.interruptible = True
            self.command.main(args=argv, prog_name="shapeverify")
        finally:
            self.interruptible = False

    def _stop_now(self) -> None:
        self.stopping.set()
        self.queue.put(None)

    def _loop(self) -> None:
        import socket

        import queue
        import time

        last = time.monotonic()
        while not self.stopping.is_set():
            try:
                item = self.queue.get(timeout=max(0.1, self.idle - (time.monotonic() - last)))
            except queue.Empty:
                if time.monotonic() - last >= self.idle:
                    break
                continue
            except KeyboardInterrupt:   # a late cancel of a request already done
                continue
            if item is None:
                continue
            conn, req = item
            try:
                self._serve_one(conn, req)
            except KeyboardInterrupt:
                pass
            except Exception:  # noqa: BLE001 - the worker must outlive a broken connection
                import traceback
                traceback.print_exc()
            finally:
                try:
                    conn.shutdown(socket.SHUT_RDWR)  # ends the request's watcher thread
                except OSError:
                    pass
                conn.close()
                last = time.monotonic()

    def _accept(self, listener) -> None:
        import threading

        while True:
            try:
                conn, _ = listener.accept()
            except OSError:
                return
            threading.Thread(target=self._handshake, args=(conn,), daemon=True).start()

    def _peer_uid(self, conn) -> int | None:
        import socket

        try:
            creds = conn.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED,
                                    struct.calcsize("3i"))
            return struct.unpack("3i", creds)[1]
        except (OSError, AttributeError):
            return None

    def _state(self) -> dict:
        return {"pid": self.pid, "key": self.key, "import_env": self.import_env,
                "socket": str(self.path), "started": self.started, "requests": self.requests,
                "cpu": round(self.cpu, 4), "preload_cpu": round(self.preload_cpu, 4),
                "idle_minutes": self.idle / 60.0,
                "busy": self.running is not None}

    def _handshake(self, conn) -> None:
        import json

        uid = self._peer_uid(conn)
        if uid is not None and uid != os.getuid():
            conn.close()
            return
        try:
            conn.settimeout(10.0)
            kind, payload = _recv(conn)
            req = json.loads(payload)
            op = req.get("op")
            if op == "status":
                _send(conn, b"I", json.dumps(self._state()).encode())
                conn.close()
                return
            if op == "stop":
                _send(conn, b"I", json.dumps(self._state()).encode())
                conn.close()
                self._stop_now()
                return
            if req.get("key") != self.key:
                stale = req.get("key", "").rsplit(":", 1)[0] != self.key.rsplit(":", 1)[0]
                _send(conn, b"S", b"the shapeverify worker runs another version of shapeverify "
                                  b"(started before an update); it stops now")
                conn.close()
                if stale:
                    self._stop_now()
                return
            if import_env(req.get("env", {})) != self.import_env:
                _send(conn, b"S", b"the shapeverify worker was started with other NUMBA_/OMP_/"
                                  b"PYTHON* environment variables")
                conn.close()
                return
            conn.settimeout(None)
            _send(conn, b"Q", b"")
            self.queue.put((conn, req))
        except (OSError, ConnectionError, ValueError, struct.error):
            conn.close()

    def _watch(self, conn) -> None:
        """Cancel the running request when its client sends C or goes away."""
        import _thread

        try:
            while True:
                kind, _ = _recv(conn)
                if kind == b"C":
                    break
        except (OSError, ConnectionError, struct.error):
            pass
        import time

        with self.lock:
            if self.running is not conn:
                return
            self.running = None
            self.cancelled = True
        # until the command ends: _on_interrupt raises once it is in the package's own code
        while True:
            with self.lock:
                if not self.cancelled:
                    return
                _thread.interrupt_main()
            time.sleep(0.02)

    def _serve_one(self, conn, req: dict) -> None:
        import json

        import threading

        try:
            os.stat(req["cwd"])
        except OSError as exc:
            _send(conn, b"S", f"the worker cannot enter {req['cwd']} ({exc})".encode())
            return
        _send(conn, b"A", b"")
        with self.lock:
            self.running = conn
            self.cancelled = False
        threading.Thread(target=self._watch, args=(conn,), daemon=True).start()
        cpu0 = _cpu()
        try:
            code = self._run(conn, req)
        finally:
            with self.lock:
                self.running = None
                self.cancelled = False
        cpu = _cpu() - cpu0
        self.requests += 1
        self.cpu += cpu
        try:
            _send(conn, b"X", json.dumps({"code": code, "cpu": cpu}).encode())
        except OSError:
            pass

    def _run(self, conn, req: dict) -> int | None:
        """Run one command as ``shapeverify ARGV`` would in-process; its exit code."""
        import logging
        import warnings

        from shapeverify import cli_common

        saved = (os.getcwd(), dict(os.environ), sys.argv, sys.stdin, sys.stdout, sys.stderr)
        umask = os.umask(int(req.get("umask", 0o022)))
        out = _stream(conn, b"O", req["tty"][0], req["encoding"][0], req["errors"][0])
        err = _stream(conn, b"E", req["tty"][1], req["encoding"][1], req["errors"][1])
        try:
            os.chdir(req["cwd"])
            os.environ.clear()
            os.environ.update(req["env"])
            sys.argv = ["shapeverify", *req["argv"]]
            sys.stdin = open(os.devnull)
            sys.stdout, sys.stderr = out, err
            # what a fresh process starts with: no log handlers, the start's warning filters,
            # consoles made for this client's terminal and environment
            root = logging.getLogger()
            for h in list(root.handlers):
                root.removeHandler(h)
            root.setLevel(self.logging_level)
            logging.captureWarnings(False)
            logging.getLogger("py.warnings").setLevel(logging.NOTSET)
            warnings.filters[:] = self.filters
            warnings._filters_mutated()
            warnings.onceregistry.clear()
            cli_common.console.__init__(stderr=True)
            cli_common.out.__init__()
            try:
                self._command(list(req["argv"]))
                code = 0
            except SystemExit as exc:
                code = _exit_code(exc.code)
            except KeyboardInterrupt:
                code = 130
            except BaseException as exc:  # noqa: BLE001 - as the interpreter would report it
                _report_uncaught(exc)
                code = 1
            for s in (out, err):
                try:
                    s.flush()
                except (OSError, ValueError):
                    pass
            return code
        finally:
            sys.stdin.close()
            sys.argv, sys.stdin, sys.stdout, sys.stderr = saved[2:]
            cli_common.console.__init__(stderr=True)
            cli_common.out.__init__()
            os.environ.clear()
            os.environ.update(saved[1])
            os.umask(umask)
            os.chdir(saved[0])


#: the package's source directory: a cancel interrupts the command only in its own code
_PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))

#: prepared models the worker keeps (the most recently used)
KEEP_MODELS = 4


def _keep_prepared_models() -> None:
    """Keep the last :data:`KEEP_MODELS` prepared models (.svm) in memory, as ``shapeverify
    serve`` does: a command that names the same file, unchanged, gets the model already
    loaded, with the structures it built lazily (the exact closest-point refinement, the
    coverage samples), and the file's SHA-256 (the reports' ``model_sha256``; ``info``'s
    summary cache key of a CAD file) without reading the file again
    (:mod:`shapeverify._file_memo`, which ``load_prepared``, ``pipeline.file_hash`` and the
    CAD summary consult; off in any other process)."""
    from shapeverify import _file_memo

    _file_memo.PREPARED_MODELS.keep = KEEP_MODELS
    _file_memo.enable()


def _report_uncaught(exc: BaseException) -> None:
    """Print an exception that escaped the command as ``shapeverify`` in-process would: typer's
    ``Typer.__call__`` marks it and its ``except_hook`` prints it at interpreter exit."""
    try:
        import typer.main as tm

        from shapeverify.cli import app

        setattr(exc, tm._typer_developer_exception_attr_name, tm.DeveloperExceptionConfig(
            pretty_exceptions_enable=app.pretty_exceptions_enable,
            pretty_exceptions_show_locals=app.pretty_exceptions_show_locals,
            pretty_exceptions_short=app.pretty_exceptions_short))
        hook = tm.except_hook
    except (AttributeError, ImportError, TypeError):
        hook = sys.excepthook
    hook(type(exc), exc, exc.__traceback__)


def _exit_code(code) -> int:
    if code is None:
        return 0
    if isinstance(code, int):
        return code
    sys.stderr.write(f"{code}\n")
    return 1


def serve(path: Path, idle_minutes: float = 30.0) -> None:
    """The worker process: preload, then serve until stopped or idle."""
    w = Worker(path, idle_minutes)
    w.preload()
    w.serve()


if __name__ == "__main__":  # python -m shapeverify.cli_worker_server SOCKET [IDLE_MINUTES]
    if len(sys.argv) >= 2:
        serve(Path(sys.argv[1]), float(sys.argv[2]) if len(sys.argv) > 2 else 30.0)
        from shapeverify.cli_start import end

        end(0)      # without the interpreter's teardown of numpy, scipy, numba (~0.3 s CPU)
    else:
        sys.exit("usage: python -m shapeverify.cli_worker_server SOCKET [IDLE_MINUTES]")
