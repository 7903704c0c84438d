"""A resident worker for the command line (issue 32 item 7): ``shapeverify worker start|stop|status``.

A Python that runs an inspection pays about 1.5 s of CPU before the inspection's own 0.2 s:
numpy, numba and its first use (its lowering registries and ``scipy.linalg``), scipy.spatial,
typer and pydantic, and loading numba's cached kernels.  The worker pays that once: it is a
background process that has imported the command line and the pipeline; each later
``shapeverify ...`` (the client) finds it on a Unix-domain socket, sends its argv, working
directory, environment and umask, and copies back what the command writes to stdout and stderr
and its exit code.  The worker runs one request at a time through the same typer app as the
command line in-process (:data:`shapeverify.cli.app`), so the answers are the same.

Started by the first command, as Gradle's daemon is (``SHAPEVERIFY_WORKER``, default
:data:`DEFAULT_MODE` ``auto``), saying so in one line on stderr (with how to stop it:
``shapeverify worker stop``, and to keep it from starting: ``SHAPEVERIFY_WORKER=0``).  A
command that runs the numeric kernels (:data:`KERNEL_COMMANDS`: ``inspect``, ``prepare`` ...)
and finds no worker starts one, waits for it (its imports) and runs in it: run in its own
process as well, it paid the imports and numba's first use twice, there and in the worker
(first ``inspect`` 3.1-4.4 s of CPU in all, second 0.8-1.1 s; now 1.7-2.5 and 0.3-0.5).  Any
other command (``info``, ``history``, ``--help``) needs none of that: with no worker running it
runs in its own process and starts none (``info`` of a cached file 0.2 s; starting the worker
for it cost 1.2 s more).  With ``SHAPEVERIFY_WORKER=0`` only a worker started by
``shapeverify worker start`` is used.  ``SHAPEVERIFY_NO_WORKER=1`` makes every command run
in-process (the tests set it: ``tests/conftest.py``).  The worker ends by ``shapeverify worker stop``, after
``--idle`` minutes without a request (default 30), or when the installed sources change.

Safety: the socket lives in a directory only the user can enter (``$XDG_RUNTIME_DIR/shapeverify``
or ``~/.cache/shapeverify``; ``SHAPEVERIFY_WORKER_DIR`` overrides it), has mode 0600, and the
worker serves only its own user (``SO_PEERCRED``).  Its name depends on the installation (the
package's directory and the Python), and every request carries the client's version key (the
package version and the size and mtime of every source file) and the environment variables
read at import (``NUMBA_*``, ``OMP_*``, ``OPENBLAS_*``, ``MKL_*``, ``PYTHONPATH`` ...): a
worker of another version or environment answers "stale" and the client runs the command
itself, with one line on stderr.  So does a dead worker (the socket refuses), or one that dies
during the command (the command is run again in-process).  Ctrl-C on the client cancels the
request in the worker (``KeyboardInterrupt`` there, as in-process), which stays up.

CPU: the worker measures each request's CPU (its own, its threads' and its children's) and
sends it with the exit code; with ``SHAPEVERIFY_WORKER_CPU_LOG=FILE`` the client appends it to
FILE (one JSON line per command), so a benchmark counts client + worker CPU.

This module is the client side and the wire protocol (:func:`try_worker`, :func:`version_key`,
:func:`socket_path`, :func:`start`/:func:`stop`/:func:`status`); it imports only the standard
library: it runs before ``shapeverify.cli`` (typer, rich) or numpy is imported.  The worker
process itself is :mod:`shapeverify.cli_worker_server`.
"""

from __future__ import annotations

import hashlib
import os
import struct
import sys
from pathlib import Path

__all__ = ["try_worker", "socket_path", "version_key", "start", "stop", "status",
           "NO_WORKER_ENV", "AUTO_START_ENV", "CPU_LOG_ENV", "DIR_ENV", "LOCAL_COMMANDS",
           "DEFAULT_MODE", "auto_start", "KERNEL_COMMANDS", "runs_kernels"]

NO_WORKER_ENV = "SHAPEVERIFY_NO_WORKER"
AUTO_START_ENV = "SHAPEVERIFY_WORKER"
#: ``SHAPEVERIFY_WORKER`` when unset: ``auto`` (the first command starts the worker in the
#: background) or ``0`` (only ``shapeverify worker start`` starts one) -- the one switch
DEFAULT_MODE = "auto"
_OFF = ("0", "off", "no", "false", "never")
#: a start claimed by another command less than this long ago is left to it (seconds)
START_CLAIM_SECONDS = 120.0
CPU_LOG_ENV = "SHAPEVERIFY_WORKER_CPU_LOG"
DIR_ENV = "SHAPEVERIFY_WORKER_DIR"
#: commands that always run in-process: servers and Dask clusters run long and start their own
#: processes; ``worker`` manages the worker
LOCAL_COMMANDS = frozenset({"serve", "batch", "worker"})
#: environment read when the worker's libraries are imported: a request must match the worker's
_IMPORT_ENV_PREFIXES = ("NUMBA_", "OMP_", "OPENBLAS_", "MKL_")
_IMPORT_ENV_NAMES = ("PYTHONPATH", "PYTHONHOME", "PYTHONWARNINGS", "PYTHONOPTIMIZE",
                     "PYTHONHASHSEED", "PYTHONIOENCODING", "PYTHONUTF8", "PYTHONSAFEPATH")
_PACKAGE = Path(__file__).resolve().parent
_HEAD = struct.Struct(">cI")
CONNECT_TIMEOUT = 2.0       # a live worker accepts at once, even while it runs a request
CANCEL_GRACE = 5.0          # after Ctrl-C: how long the client waits for the worker to stop


# ------------------------------------------------------------------------------------ framing
def _send(sock: socket.socket, kind: bytes, payload: bytes = b"") -> None:
    sock.sendall(_HEAD.pack(kind, len(payload)) + payload)


def _recv_exact(sock: socket.socket, n: int) -> bytes:
    buf = bytearray()
    while len(buf) < n:
        chunk = sock.recv(n - len(buf))
        if not chunk:
            raise ConnectionError("the worker closed the connection")
        buf += chunk
    return bytes(buf)


def _recv(sock: socket.socket) -> tuple[bytes, bytes]:
    kind, n = _HEAD.unpack(_recv_exact(sock, _HEAD.size))
    return kind, _recv_exact(sock, n)


# ---------------------------------------------------------------------- where and which worker
def socket_dir() -> Path:
    """The directory of the worker's socket: ``$SHAPEVERIFY_WORKER_DIR``, else
    ``$XDG_RUNTIME_DIR/shapeverify``, else ``~/.cache/shapeverify`` (made with mode 0700)."""
    if os.environ.get(DIR_ENV):
        return Path(os.path.abspath(os.environ[DIR_ENV]))  # the worker runs in /
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    if runtime and os.path.isdir(runtime):
        return Path(runtime) / "shapeverify"
    return Path(os.path.expanduser("~")) / ".cache" / "shapeverify"


def socket_path() -> Path:
    """The socket of the worker of this installation (package directory and Python) and user."""
    tag = hashlib.sha256(f"{_PACKAGE}\0{sys.executable}".encode()).hexdigest()[:12]
    return socket_dir() / f"worker-{os.getuid()}-{tag}.sock"


def _sources_digest() -> str:
    """Size and mtime of every file of the installed package (not numba's or Python's caches)."""
    h = hashlib.sha256()
    stack = [str(_PACKAGE)]
    while stack:
        top = stack.pop()
        with os.scandir(top) as it:
            entries = sorted(it, key=lambda e: e.name)
        for e in entries:
            if e.is_dir(follow_symlinks=False):
                if e.name != "__pycache__":
                    stack.append(e.path)
            elif not e.name.endswith((".pyc", ".nbi", ".nbc")):
                st = e.stat()
                h.update(f"{e.path}\0{st.st_size}\0{st.st_mtime_ns}\n".encode())
    return h.hexdigest()[:16]


def version_key() -> str:
    """The package version, the sources' digest and the Python: a worker answers only clients
    whose key equals its own (taken when it started)."""
    from shapeverify import __version__

    return f"{__version__}:{_sources_digest()}:{sys.executable}"


def import_env(env) -> dict:
    """The environment variables read when numpy, numba and the package are imported (with the
    default :mod:`shapeverify.cli` gives OpenBLAS's threads before numpy is imported)."""
    got = {k: v for k, v in env.items()
           if k.startswith(_IMPORT_ENV_PREFIXES) or k in _IMPORT_ENV_NAMES}
    got.setdefault("OPENBLAS_NUM_THREADS", "1")
    return got


def _note(text: str) -> None:
    try:
        sys.stderr.write(f"note: {text}\n")
        sys.stderr.flush()
    except OSError:
        pass


def _connect(path: Path, timeout: float = CONNECT_TIMEOUT) -> socket.socket | None:
    """A connection to the worker at ``path``; None (a note said why) when it is not safe or
    not answering; a refused socket file (its worker died) is removed."""
    try:
        st = os.stat(path)
    except OSError:
        return None   # no worker: the usual case, decided without importing socket or json
    if st.st_uid != os.getuid() or st.st_mode & 0o077:
        _note(f"{path} is not this user's private socket; ignoring the worker, running in this "
              "process")
        return None
    import socket

    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.settimeout(timeout)
    try:
        sock.connect(str(path))
    except OSError as exc:
        sock.close()
        _note(f"the shapeverify worker does not answer ({exc.strerror or exc}); running in this "
              "process (start a new one: shapeverify worker start)")
        try:
            os.unlink(path)  # nobody listens on it: the worker died
        except OSError:
            pass
        return None
    return sock


# ---------------------------------------------------------------------------------- the client
def _command(argv: list) -> str | None:
    return next((a for a in argv if not a.startswith("-")), None)


def _terminal_size() -> tuple[int, int] | None:
    for fd in (0, 1, 2):  # rich's order (Console.size)
        try:
            return tuple(os.get_terminal_size(fd))
        except (OSError, ValueError):
            continue
    return None


def _request(argv: list) -> dict:
    env = dict(os.environ)
    size = _terminal_size()
    if size is not None:  # the worker's descriptors are no terminal: tell it this one's size
        env.setdefault("COLUMNS", str(size[0]))
        env.setdefault("LINES", str(size[1]))
    umask = os.umask(0o022)
    os.umask(umask)
    streams = [getattr(sys, s) for s in ("stdout", "stderr")]
    return {"op": "run", "key": version_key(), "argv": list(argv), "cwd": os.getcwd(),
            "env": env, "umask": umask,
            "tty": [bool(getattr(s, "isatty", lambda: False)()) for s in streams],
            "encoding": [getattr(s, "encoding", None) or "utf-8" for s in streams],
            "errors": [getattr(s, "errors", None) or "strict" for s in streams]}


def _write(stream, data: bytes) -> None:
    buf = getattr(stream, "buffer", None)
    stream.flush()
    if buf is not None:
        buf.write(data)
        buf.flush()
    else:  # a replaced stream (tests): text
        stream.write(data.decode(getattr(stream, "encoding", None) or "utf-8", "replace"))
        stream.flush()


def try_worker(argv: list) -> int | None:
    """Run ``shapeverify ARGV`` in the resident worker, if one of this installation, user and
    version listens; returns the exit code, or None when the caller must run it in-process
    (no worker, ``SHAPEVERIFY_NO_WORKER=1``, a command that runs locally, a stale or dead worker:
    the last two with one note on stderr)."""
    if os.environ.get(NO_WORKER_ENV, "") not in ("", "0"):
        return None
    command = _command(argv)
    if command is None or command in LOCAL_COMMANDS:
        return None
    path = socket_path()
    sock = _connect(path)
    if sock is None:
        # a command that needs no kernels (info, history, --help) runs in its own process and
        # starts nothing: the worker's start (1.2 s of CPU) would cost 4-5 times the command
        # (info of a cached file: 0.2 s), and is worth it only to a command that needs it
        if not auto_start() or path.exists() or not runs_kernels(argv):
            return None
        proc = None
        if _claim_start(path):
            try:
                proc = _spawn(path)
            except OSError as exc:
                _note(f"could not start the shapeverify worker ({exc}); commands run in their "
                      "own process")
                return None
        # a command that loads numpy, numba and the kernels: run in the worker that is
        # starting (by this command or another), not in this process as well -- the imports
        # and numba's first use would be paid twice, here and in the worker
        try:
            sock = _wait_for_worker(path, proc)
        except KeyboardInterrupt:
            return 130
        if sock is None:
            _note("the shapeverify worker did not start (see "
                  f"{path.with_suffix('.log')}); running in this process")
            return None
        if proc is not None:
            _note("started the shapeverify worker (1-2 s of CPU, once): this command and the "
                  "next ones run in it; it ends after 30 idle minutes. Stop it: shapeverify "
                  f"worker stop; never start it: {AUTO_START_ENV}=0")
    with sock:
        return _run_remote(sock, argv)


#: commands that import numpy and numba and run compiled kernels: the first of them starts the
#: worker, waits for it and runs in it; any other (info, history, --help) runs in its own
#: process when no worker runs, and starts none
KERNEL_COMMANDS = frozenset({"prepare", "inspect", "measure", "unwrap", "hologram", "fit",
                             "calibrate"})
#: how long the first command waits for the worker's socket before it runs in-process
START_WAIT_SECONDS = START_CLAIM_SECONDS


def runs_kernels(argv: list) -> bool:
    """Whether ``shapeverify ARGV`` runs the numeric kernels (not its ``--help``)."""
    return (_command(argv) in KERNEL_COMMANDS
            and not any(a in ("--help", "-h") for a in argv))


def _wait_for_worker(path: Path, proc, timeout: float = START_WAIT_SECONDS):
    """A connection to the worker starting at ``path`` once it listens (after its imports);
    None when its process ``proc`` (None: started by another command) ended first, its start
    was abandoned, or ``timeout`` seconds passed."""
    import time

    claim = path.with_suffix(".starting")
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if os.path.exists(path):
            sock = _connect(path)
            if sock is not None:
                return sock
        if proc is not None and proc.poll() is not None:
            try:                # it died importing: the next command may start one again
                os.unlink(claim)
            except OSError:
                pass
            return None
        if proc is None:        # started by another command: as long as its claim is fresh
            try:
                if time.time() - os.stat(claim).st_mtime >= START_CLAIM_SECONDS:
                    return None
            except FileNotFoundError:
                if not os.path.exists(path):
                    return None     # the other command's worker gave up
        time.sleep(0.02)
    return None


def auto_start() -> bool:
    """Whether a command that finds no worker starts one (``SHAPEVERIFY_WORKER``, default
    :data:`DEFAULT_MODE`)."""
    mode = os.environ.get(AUTO_START_ENV, "").strip().lower() or DEFAULT_MODE
    return mode not in _OFF


def _claim_start(path: Path) -> bool:
    """Claim the worker's start (a file next to the socket, created exclusively): False when
    another command claimed it less than :data:`START_CLAIM_SECONDS` ago (its worker is still
    importing), so that commands started together start one worker."""
    import time

    claim = path.with_suffix(".starting")
    try:
        path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        os.chmod(path.parent, 0o700)
        if time.time() - os.stat(claim).st_mtime < START_CLAIM_SECONDS:
            return False
        os.unlink(claim)
    except FileNotFoundError:
        pass
    except OSError:
        return False
    try:
        os.close(os.open(claim, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
    except OSError:
        return False
    return True


def _run_remote(sock: socket.socket, argv: list) -> int | None:
    import json

    try:
        _send(sock, b"R", json.dumps(_request(argv)).encode())
        kind, payload = _recv(sock)            # queued, or stale
        if kind != b"Q":
            _note(f"{payload.decode(errors='replace')}; running in this process")
            return None
        sock.settimeout(None)                  # the worker is alive: wait for our turn
        kind, payload = _recv(sock)
        if kind != b"A":
            _note(f"{payload.decode(errors='replace')}; running in this process")
            return None
    except (OSError, ConnectionError, ValueError, struct.error) as exc:
        _note(f"the shapeverify worker failed before the command ran ({exc}); running in this "
              "process")
        return None
    except KeyboardInterrupt:   # before the command started: nothing ran
        return 130
    cancelled = False
    wrote = False
    while True:
        try:
            kind, payload = _recv(sock)
        except KeyboardInterrupt:
            if cancelled:  # a second Ctrl-C: leave at once
                return 130
            cancelled = True
            try:
                _send(sock, b"C")
                sock.settimeout(CANCEL_GRACE)
            except OSError:
                return 130
            continue
        except (OSError, ConnectionError, struct.error) as exc:
            if cancelled:
                return 130
            _note(f"the shapeverify worker stopped during the command ({exc}); running it again "
                  "in this process" + (" (the output above is from the interrupted run)"
                                       if wrote else ""))
            return None
        if kind == b"O":
            _write(sys.stdout, payload)
            wrote = True
        elif kind == b"E":
            _write(sys.stderr, payload)
        elif kind == b"X":
            done = json.loads(payload)
            log = os.environ.get(CPU_LOG_ENV)
            if log:
                with open(log, "a") as f:
                    f.write(json.dumps({"argv": list(argv), "worker_cpu": done["cpu"],
                                        "code": done["code"]}) + "\n")
            return int(done["code"])


# ------------------------------------------------------------------ start, stop, status (client)
def _ask(op: str, timeout: float = CONNECT_TIMEOUT, path: Path | None = None) -> dict | None:
    """Send ``op`` (status, stop) to the worker; its JSON answer, None when none runs."""
    import json
    import socket

    path = socket_path() if path is None else path
    if not path.exists():
        return None
    try:
        st = os.stat(path)
    except OSError:
        return None
    if st.st_uid != os.getuid() or st.st_mode & 0o077:
        return None
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.settimeout(timeout)
    try:
        with sock:
            sock.connect(str(path))
            _send(sock, b"R", json.dumps({"op": op}).encode())
            kind, payload = _recv(sock)
            return json.loads(payload) if kind == b"I" else None
    except (OSError, ConnectionError, ValueError, struct.error):
        return None


def status() -> dict | None:
    """The running worker's state (pid, version key, requests served, CPU), or None."""
    return _ask("status")


def _spawn(path: Path, idle_minutes: float = 30.0):
    import subprocess

    path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
    os.chmod(path.parent, 0o700)
    log = open(path.with_suffix(".log"), "ab")
    try:
        return subprocess.Popen(
            [sys.executable, "-m", "shapeverify.cli_worker_server", str(path),
             str(idle_minutes)],
            stdin=subprocess.DEVNULL, stdout=log, stderr=log, start_new_session=True,
            # what the worker runs never starts another worker
            env={**{k: v for k, v in os.environ.items() if k != AUTO_START_ENV},
                 AUTO_START_ENV: "0"},
            cwd="/")
    finally:
        log.close()


def start(idle_minutes: float = 30.0, wait: float = 300.0) -> dict:
    """Start the worker (a stale one is stopped first) and wait until it answers; its status."""
    import time

    path = socket_path()
    now = status()
    if now is not None:
        if now.get("key") == version_key() and now.get("import_env") == import_env(os.environ):
            return {**now, "already": True}
        stop()
    proc = _spawn(path, idle_minutes)
    t0 = time.monotonic()
    while time.monotonic() - t0 < wait:
        got = status()
        if got is not None and got.get("pid") == proc.pid:
            return got
        if proc.poll() is not None:
            raise RuntimeError(f"the worker exited with code {proc.returncode}; see "
                               f"{path.with_suffix('.log')}")
        time.sleep(0.05)
    proc.kill()
    raise RuntimeError(f"the worker did not answer within {wait:.0f} s; see "
                       f"{path.with_suffix('.log')}")


def stop(wait: float = 30.0) -> dict | None:
    """Stop the worker (after the request it runs, if any) and wait for its process to end;
    its last status, None when none ran."""
    import time

    got = _ask("stop")
    if got is None:
        return None
    pid, t0 = got["pid"], time.monotonic()
    while time.monotonic() - t0 < wait:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return got
        if _zombie(pid):
            return got
        time.sleep(0.02)
    import signal

    os.kill(pid, signal.SIGKILL)
    return got


def _zombie(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] == "Z"
    except (OSError, IndexError):
        return False
