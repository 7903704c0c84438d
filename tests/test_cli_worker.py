"""The resident worker (issue 32 item 7, ``shapeverify worker``): a command handed to it gives
the same stdout, files and exit code as the command run in-process, and a stale or dead worker
never changes an answer (the client runs the command itself, with one note on stderr).

Every command runs as a user runs it: ``python -m shapeverify ...`` in a fresh process (the
console entry point, where the client lives).  ``SHAPEVERIFY_WORKER_CPU_LOG`` proves that a
command did go to the worker (the client logs the worker's CPU), so no test passes because of a
silent fallback.  The worker's socket is in a temporary directory of its own, and the fixture
always stops the worker and checks that its process is gone.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "shapeverify"


def _env(sock_dir: Path, cache: Path, **extra) -> dict:
    env = {k: v for k, v in os.environ.items()
           if not k.startswith("SHAPEVERIFY_") or k == "SHAPEVERIFY_CACHE_DIR"}
    # no worker starts by itself (SHAPEVERIFY_WORKER=auto by default): a test that wants one
    # starts it, or sets SHAPEVERIFY_WORKER itself
    env.update(SHAPEVERIFY_WORKER="0", SHAPEVERIFY_WORKER_DIR=str(sock_dir),
               SHAPEVERIFY_CACHE_DIR=str(cache),
               COLUMNS="100", PYTHONPATH=os.pathsep.join(
                   [str(ROOT / "src")] + [p for p in os.environ.get("PYTHONPATH", "").split(
                       os.pathsep) if p]))
    env.update(extra)
    return env


def _sv(args, cwd: Path, env: dict, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "shapeverify", *map(str, args)], cwd=cwd,
                          env=env, capture_output=True, timeout=timeout)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return True

def _stop_worker(files, env, pid) -> None:
    """`shapeverify worker stop`; the worker ``pid`` (if any) must end within 30 s (else it is
    killed and the test fails)."""
    _sv(["worker", "stop"], files, env, timeout=60)
    if pid is not None:
        t0 = time.monotonic()
        while _alive(pid) and time.monotonic() - t0 < 30:
            time.sleep(0.05)
        if _alive(pid):
            os.kill(pid, signal.SIGKILL)
            pytest.fail(f"worker {pid} still ran after `shapeverify worker stop`")



@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """The example panel as STEP and .svm, a clean scan (passes) and a dented one (fails), a
    scan file that is not a point cloud."""
    from shapeverify.cad.examples import example_part_step
    from shapeverify.cad.load import load_model
    from shapeverify.io.points import write_ply
    from shapeverify.nearest import prepare
    from shapeverify.simulate import ScanEffects, virtual_scan

    d = tmp_path_factory.mktemp("worker")
    step = example_part_step(d / "panel.step")
    model = load_model(step)
    prepare(model).save(d / "panel.svm")
    for name, dents in (("clean", ()), ("dented", [(0.5, 20.0)])):
        sim = virtual_scan(model, pixel=4.0, noise=0.02,
                           effects=ScanEffects(outlier_fraction=0.02, dents=dents),
                           motion=(1.0, 2.0), rng=5)
        write_ply(d / f"{name}.ply", sim.scan)
    (d / "broken.ply").write_text("ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n")
    return d


@pytest.fixture
def worker(files):
    """A running worker in its own socket directory; always stopped, its process checked gone."""
    sock = Path(tempfile.mkdtemp(prefix="svw-", dir="/tmp"))  # short: a socket path <= 107 bytes
    env = _env(sock, files / "cache")
    pid = None
    try:
        res = _sv(["worker", "start"], files, env)
        assert res.returncode == 0, res.stderr.decode()[-2000:]
        pid = int(re.search(rb"pid (\d+)", res.stdout).group(1))
        yield {"env": env, "pid": pid, "sock": sock}
    finally:
        _stop_worker(files, env, pid)
        assert not list(sock.glob("*.sock")), "the worker left its socket behind"
        shutil.rmtree(sock, ignore_errors=True)


def _timeless(stderr: bytes) -> bytes:
    """stderr without the stage lines' durations, e.g. "(0.27 s)"."""
    return re.sub(rb" \(\d+\.\d\d s\)", b"", stderr)


def _json(path: Path) -> dict:
    data = json.loads(path.read_text())
    data.pop("timings", None)  # seconds measured: differ run to run, in-process too
    return data


CASES = {
    "info of a STEP file": (["info", "panel.step"], None, 0),
    "info of a prepared model": (["info", "panel.svm"], None, 0),
    "inspect, pass": (["inspect", "panel.svm", "clean.ply", "--tolerance", "0.2",
                       "--colored", "c.ply"], "r.json", 0),
    "inspect, fail": (["inspect", "panel.svm", "dented.ply", "--tolerance", "0.2"], "r.json", 1),
    "inspect, unreadable scan": (["inspect", "panel.svm", "broken.ply", "--tolerance", "0.2"],
                                 None, 2),
    "inspect, missing scan": (["inspect", "panel.svm", "nothere.ply"], None, 2),
    "unknown option": (["inspect", "panel.svm", "clean.ply", "--no-such-option"], None, 2),
}


@pytest.mark.slow
def test_worker_answers_byte_identical_to_in_process(files, worker, tmp_path):
    log = tmp_path / "cpu.log"
    env_worker = {**worker["env"], "SHAPEVERIFY_WORKER_CPU_LOG": str(log)}
    env_local = {**env_worker, "SHAPEVERIFY_NO_WORKER": "1"}
    for name, (args, out_file, code) in CASES.items():
        got = {}
        for how, env in (("in-process", env_local), ("worker", env_worker)):
            n_before = len(log.read_text().splitlines()) if log.exists() else 0
            argv = args + (["--json", out_file] if out_file else [])
            res = _sv(argv, files, env)
            n_after = len(log.read_text().splitlines()) if log.exists() else 0
            assert n_after - n_before == (1 if how == "worker" else 0), \
                f"{name}: ran {'in-process' if how == 'worker' else 'in the worker'}"
            data = None
            if out_file:
                data = _json(files / out_file)
                (files / out_file).unlink()
            if "--colored" in argv:                  # a file without timings: byte for byte
                colored = files / argv[argv.index("--colored") + 1]
                data = (data, colored.read_bytes())
                colored.unlink()
            got[how] = (res.returncode, res.stdout, _timeless(res.stderr), data)
        local, remote = got["in-process"], got["worker"]
        assert local[0] == code, f"{name}: {local[2].decode()[-1500:]}"
        assert remote[0] == local[0], name
        assert remote[1] == local[1], name          # stdout, byte for byte
        assert remote[2] == local[2], (name, local[2].decode(), remote[2].decode())
        assert remote[3] == local[3], name          # the JSON report (less timings), the PLY
    cpu = [json.loads(line)["worker_cpu"] for line in log.read_text().splitlines()]
    assert len(cpu) == len(CASES) and all(c > 0 for c in cpu)


def test_stale_worker_falls_back_in_process_and_stops(files, worker, tmp_path):
    # an update of the installed package: the sources' digest changes; the worker answers
    # "stale", the client runs the command itself (same answer), and the stale worker stops
    probe = PACKAGE / "_worker_stale_probe.txt"
    env = worker["env"]
    local = _sv(["info", "panel.svm"], files, {**env, "SHAPEVERIFY_NO_WORKER": "1"})
    try:
        probe.write_text("a changed installation\n")
        res = _sv(["info", "panel.svm"], files, env)
    finally:
        probe.unlink()
    assert res.returncode == local.returncode == 0
    assert res.stdout == local.stdout
    notes = [line for line in res.stderr.decode().splitlines() if "worker" in line]
    assert len(notes) == 1 and "another version" in notes[0] and "in this process" in notes[0]
    t0 = time.monotonic()
    while _alive(worker["pid"]) and time.monotonic() - t0 < 30:
        time.sleep(0.05)
    assert not _alive(worker["pid"]), "a stale worker must stop"


def test_other_import_environment_runs_in_process(files, worker):
    # NUMBA_* are read when numba is imported: a worker started without it cannot honour it
    res = _sv(["info", "panel.svm"], files, {**worker["env"], "NUMBA_OPT": "2"})
    assert res.returncode == 0 and b"model points" in res.stdout
    assert b"other NUMBA_/OMP_/PYTHON* environment" in res.stderr
    assert _alive(worker["pid"])  # the worker itself is fine for its own environment


def test_dead_worker_socket_falls_back_and_is_removed(files, tmp_path):
    import socket as socketlib

    sock_dir = Path(tempfile.mkdtemp(prefix="svw-", dir="/tmp"))
    try:
        env = _env(sock_dir, files / "cache")
        path = Path(subprocess.run(
            [sys.executable, "-c", "from shapeverify.cli_worker import socket_path; "
                                   "print(socket_path())"],
            env=env, capture_output=True, text=True, check=True).stdout.strip())
        s = socketlib.socket(socketlib.AF_UNIX)
        s.bind(str(path))              # a socket file nobody listens on: its worker was killed
        s.close()
        os.chmod(path, 0o600)
        local = _sv(["info", "panel.svm"], files, {**env, "SHAPEVERIFY_NO_WORKER": "1"})
        res = _sv(["info", "panel.svm"], files, env)
        assert res.returncode == local.returncode == 0 and res.stdout == local.stdout
        notes = [ln for ln in res.stderr.decode().splitlines() if "worker" in ln]
        assert len(notes) == 1 and "does not answer" in notes[0]
        assert not path.exists()
    finally:
        shutil.rmtree(sock_dir, ignore_errors=True)


def test_worker_start_status_stop_leave_nothing_behind(files, worker):
    env = worker["env"]
    st = _sv(["worker", "status"], files, env)
    assert st.returncode == 0 and f"pid {worker['pid']}".encode() in st.stdout
    sock = next(worker["sock"].glob("*.sock"))
    assert (sock.stat().st_mode & 0o777) == 0o600
    assert (worker["sock"].stat().st_mode & 0o777) == 0o700
    again = _sv(["worker", "start"], files, env)
    assert again.returncode == 0 and b"already running" in again.stdout
    stop = _sv(["worker", "stop"], files, env)
    assert stop.returncode == 0 and b"worker stopped" in stop.stdout
    assert not _alive(worker["pid"]) and not sock.exists()
    st = _sv(["worker", "status"], files, env)
    assert st.returncode == 1 and b"no worker running" in st.stdout


@pytest.mark.slow
def test_ctrl_c_on_the_client_cancels_and_the_worker_serves_on(files, worker, tmp_path):
    env = worker["env"]
    proc = subprocess.Popen([sys.executable, "-m", "shapeverify", "inspect", "panel.svm",
                             "clean.ply", "--tolerance", "0.2"], cwd=files, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    # wait until the worker runs it, then Ctrl-C the client
    t0 = time.monotonic()
    while time.monotonic() - t0 < 60:
        st = _sv(["worker", "status"], files, env)
        if b"busy" in st.stdout or proc.poll() is not None:
            break
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    # cancelled: exit code 130, as in-process; or, on a slow machine, the command had already
    # finished with its verdict (0)
    assert proc.returncode in (0, 130), err.decode()[-2000:]
    assert _alive(worker["pid"])
    after = _sv(["info", "panel.svm"], files, env)
    assert after.returncode == 0 and b"model points" in after.stdout
    assert b"worker" not in after.stderr


def test_file_memo_keeps_a_prepared_model_and_a_hash_only_while_enabled_and_unchanged(tmp_path):
    """The worker's memory of files (``shapeverify._file_memo``, which replaced its wrapping of
    ``load_prepared`` and the file hashes): off by default; on, an unchanged file gives what
    it gave before, a rewritten one is read again, and bytes are never remembered."""
    import hashlib

    from shapeverify import _file_memo
    from shapeverify.cad.examples import wavy_panel
    from shapeverify.nearest import load_prepared, prepare
    from shapeverify.pipeline import file_hash

    path = tmp_path / "m.svm"
    prepare(wavy_panel(), spacing=4.0).save(path)
    try:
        assert not _file_memo.PREPARED_MODELS.enabled
        assert load_prepared(path) is not load_prepared(path)        # off: read every time
        _file_memo.enable()
        a = load_prepared(path)
        assert load_prepared(path) is a and load_prepared(str(path)) is a
        assert load_prepared(path.read_bytes()) is not a
        h = file_hash(path)
        assert h == hashlib.sha256(path.read_bytes()).hexdigest() == file_hash(str(path))
        prepare(wavy_panel(), spacing=6.0).save(path)                 # rewritten
        b = load_prepared(path)
        assert b is not a and b.n_points != a.n_points
        assert file_hash(path) == hashlib.sha256(path.read_bytes()).hexdigest() != h
        _file_memo.clear()
        assert load_prepared(path) is not b
    finally:
        _file_memo.disable()
    assert load_prepared(path) is not load_prepared(path)


def _status(env: dict, files: Path, wait: float) -> int | None:
    """The pid of the worker answering in ``env``'s socket directory within ``wait`` s."""
    t0 = time.monotonic()
    while True:
        st = _sv(["worker", "status"], files, env)
        m = re.search(rb"pid (\d+)", st.stdout)
        if m:
            return int(m.group(1))
        if time.monotonic() - t0 > wait:
            return None
        time.sleep(0.2)


@pytest.mark.slow
def test_a_first_command_without_kernels_starts_no_worker_and_the_next_ones_use_it(files, tmp_path):
    """SHAPEVERIFY_WORKER unset (``auto``, the default): ``info`` (a cached summary, 0.2 s) and
    ``--help`` started the worker in the background, 1.2 s of CPU more, for commands that may
    never come.  Now they run in their own process and start nothing (no note, nothing in the
    socket directory); the first command that runs the kernels starts it, and an ``info`` after
    that runs in the worker, with the same output and no note."""
    from shapeverify.cli_worker import DEFAULT_MODE

    if DEFAULT_MODE != "auto":
        pytest.skip("the worker does not start by itself in this version (DEFAULT_MODE)")
    sock = Path(tempfile.mkdtemp(prefix="svw-", dir="/tmp"))
    env = _env(sock, files / "cache")
    del env["SHAPEVERIFY_WORKER"]
    log = tmp_path / "cpu.log"
    pid = None
    try:
        first = _sv(["info", "panel.svm"], files, env)
        helped = _sv(["inspect", "--help"], files, env)
        assert first.returncode == 0 and helped.returncode == 0, first.stderr.decode()[-2000:]
        assert b"worker" not in first.stderr and b"worker" not in helped.stderr
        time.sleep(1.0)
        assert list(sock.iterdir()) == [], "a command without kernels started the worker"
        started = _sv(["inspect", "panel.svm", "clean.ply", "--tolerance", "0.2"], files,
                      {**env, "SHAPEVERIFY_WORKER_CPU_LOG": str(log)})
        assert started.returncode == 0, started.stderr.decode()[-2000:]
        notes = [ln for ln in started.stderr.decode().splitlines() if "worker" in ln]
        assert len(notes) == 1 and "started the shapeverify worker" in notes[0], notes
        pid = _status(env, files, wait=5)
        assert pid is not None, "the first inspect started no worker"
        second = _sv(["info", "panel.svm"], files, {**env, "SHAPEVERIFY_WORKER_CPU_LOG": str(log)})
        assert second.returncode == 0
        assert len(log.read_text().splitlines()) == 2, "info ran in its own process"
        assert second.stdout == first.stdout
        assert b"worker" not in second.stderr
        assert not list(sock.glob("*.starting")), "the start's claim was left behind"
    finally:
        _stop_worker(files, env, pid)
        shutil.rmtree(sock, ignore_errors=True)


@pytest.mark.slow
def test_first_inspect_runs_in_the_worker_it_starts_not_in_its_own_process_as_well(files, tmp_path):
    """The first command paid twice (issue 32 item 7): it ran in its own process, importing
    numpy, numba and scipy and loading the kernels (1.8-2.8 s of CPU), while the worker it
    started did the same in the background (0.9-1.4 s), and the second command loaded them
    again in the worker (0.8-1.2 s).  A first command that runs the kernels now waits for the
    worker it starts and runs in it: the client imports none of them (``-X importtime``), the
    worker answers it (the CPU log), with the same output, report and exit code as in-process,
    and one note; the next command runs there without a note."""
    from shapeverify.cli_worker import DEFAULT_MODE

    if DEFAULT_MODE != "auto":
        pytest.skip("the worker does not start by itself in this version (DEFAULT_MODE)")
    sock = Path(tempfile.mkdtemp(prefix="svw-", dir="/tmp"))
    env = _env(sock, files / "cache")
    del env["SHAPEVERIFY_WORKER"]
    log = tmp_path / "cpu.log"
    argv = ["inspect", "panel.svm", "dented.ply", "--tolerance", "0.2", "--json", "r1.json"]
    local = _sv(argv, files, {**env, "SHAPEVERIFY_NO_WORKER": "1"})
    assert local.returncode == 1, local.stderr.decode()[-2000:]
    local_json = _json(files / "r1.json")
    (files / "r1.json").unlink()
    pid = None
    try:
        first = subprocess.run([sys.executable, "-X", "importtime", "-m", "shapeverify", *argv],
                               cwd=files, env={**env, "SHAPEVERIFY_WORKER_CPU_LOG": str(log)},
                               capture_output=True, timeout=600)
        err = first.stderr.decode()
        imported = [ln.rsplit("|", 1)[-1].strip() for ln in err.splitlines()
                    if ln.startswith("import time:")]
        assert "shapeverify.cli_worker" in imported            # the client's imports are seen
        assert not [m for m in imported if m.split(".")[0] in ("numpy", "numba", "scipy")], \
            "the first command imported the numeric libraries in its own process"
        assert first.returncode == local.returncode, err[-2000:]
        assert len(log.read_text().splitlines()) == 1, "the first command did not run in the worker"
        assert first.stdout == local.stdout
        assert _json(files / "r1.json") == local_json
        notes = [ln for ln in err.splitlines() if "worker" in ln and not ln.startswith("import")]
        assert len(notes) == 1 and "this command and the next ones run in it" in notes[0], notes
        assert "shapeverify worker stop" in notes[0] and "SHAPEVERIFY_WORKER=0" in notes[0]
        pid = _status(env, files, wait=5)
        assert pid is not None
        second = _sv(argv, files, {**env, "SHAPEVERIFY_WORKER_CPU_LOG": str(log)})
        assert second.returncode == 1 and second.stdout == local.stdout
        assert len(log.read_text().splitlines()) == 2 and b"worker" not in second.stderr
        assert not list(sock.glob("*.starting")) and not list(sock.glob("*.tmp"))
    finally:
        _stop_worker(files, env, pid)
        shutil.rmtree(sock, ignore_errors=True)


def test_a_command_that_finds_the_worker_starting_waits_for_it_only_when_it_runs_kernels():
    from shapeverify.cli_worker import runs_kernels

    assert runs_kernels(["inspect", "a.svm", "s.ply"]) and runs_kernels(["-v", "prepare", "a"])
    assert not runs_kernels(["inspect", "--help"]) and not runs_kernels(["info", "a.step"])
    assert not runs_kernels(["history"]) and not runs_kernels(["--help"]) and not runs_kernels([])


@pytest.mark.parametrize("setting", [{"SHAPEVERIFY_WORKER": "0"},
                                     {"SHAPEVERIFY_NO_WORKER": "1", "SHAPEVERIFY_WORKER": "auto"}])
def test_worker_off_or_no_worker_starts_none_and_says_nothing(files, setting):
    """``SHAPEVERIFY_WORKER=0`` (and ``SHAPEVERIFY_NO_WORKER=1``, which the tests set in
    conftest) never start a worker: no note, nothing in the socket directory."""
    sock = Path(tempfile.mkdtemp(prefix="svw-", dir="/tmp"))
    try:
        res = _sv(["info", "panel.svm"], files, {**_env(sock, files / "cache"), **setting})
        assert res.returncode == 0 and b"model points" in res.stdout
        assert b"worker" not in res.stderr
        time.sleep(1.0)
        assert list(sock.iterdir()) == []
    finally:
        shutil.rmtree(sock, ignore_errors=True)


def test_the_test_session_starts_no_worker():
    """conftest sets SHAPEVERIFY_NO_WORKER=1: a command a test starts with the test's
    environment never starts a worker, whatever SHAPEVERIFY_WORKER says."""
    from shapeverify.cli_worker import NO_WORKER_ENV

    assert os.environ.get(NO_WORKER_ENV) == "1"


def test_a_worker_that_died_starting_is_not_waited_for(tmp_path):
    """The first kernel command waits for the worker it starts: one that dies importing must
    not keep it (or the next commands) waiting -- its start's claim is removed and the command
    runs in its own process; a claim left by another command long ago is not waited on."""
    from shapeverify.cli_worker import START_CLAIM_SECONDS, _wait_for_worker

    path = tmp_path / "w.sock"
    claim = path.with_suffix(".starting")
    claim.write_text("")
    dead = subprocess.Popen([sys.executable, "-c", "raise SystemExit(3)"])
    dead.wait()
    t0 = time.monotonic()
    assert _wait_for_worker(path, dead, timeout=60) is None
    assert time.monotonic() - t0 < 5 and not claim.exists()
    claim.write_text("")
    old = time.time() - START_CLAIM_SECONDS - 1
    os.utime(claim, (old, old))
    t0 = time.monotonic()
    assert _wait_for_worker(path, None, timeout=60) is None
    assert time.monotonic() - t0 < 5
