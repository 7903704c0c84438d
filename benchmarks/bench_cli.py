"""The command line against an Open3D script doing the same job (issue 32 item 7), in CPU time.

Both are run as a user runs them, each as a fresh process started from this one, and timed by
the CPU (user + system) of that child and the children it waited for
(``resource.getrusage(RUSAGE_CHILDREN)`` before and after; on this shared 2-core machine CPU
time is the fair figure, wall time also counts waiting for a core):

* **ours**: ``shapeverify inspect panel.svm scan.ply --tolerance 0.2 --json r.json`` (a
  prepared model, a 30,000-point scan, the verdict and its JSON report);
* **Open3D**: a script (written next to the inputs, ``open3d_inspect.py``) that reads the scan
  and the prepared model's own points with their normals (``model.ply``: the same surface
  samples our ``.svm`` holds, 115,647 for the example panel), registers the scan by ICP
  point-to-plane with a Tukey loss from the identity pose, takes the signed distance of every
  matched scan point along its model point's normal, and writes a JSON report (statistics and
  the fraction within tolerance);
* **ours with the resident worker** (``shapeverify worker start``, :mod:`shapeverify.cli_worker`):
  the same command, answered by the worker; CPU = the client process (as above) **plus** the
  worker's CPU for that request (its own, its threads' and its children's, which it reports and
  the client appends to ``SHAPEVERIFY_WORKER_CPU_LOG``), so the row counts all the CPU the
  command costs.  The worker's start (imports, numba's first use: once per session) is reported
  apart;
* **ours plain** (``SHAPEVERIFY_NO_WORKER=1``): the command a new user runs, each run a fresh
  Python that imports everything and loads the kernels;
* **ours with the worker the first command starts** (``SHAPEVERIFY_WORKER=auto``): the first
  command's CPU (its own, in-process, plus the worker's start in the background, which the
  worker reports), then each later command's (client + worker);
* for reference: the same inspection as a Python script calling the library (what the command
  line costs on top of it), ``shapeverify info`` of a STEP file whose summary is cached (goal 0.3 s), and
  the floor of any process that runs a numba kernel: ``import numpy, numba`` and one call of a
  cached one-line kernel (numba's first use imports its lowering registries and
  ``scipy.linalg``);
* where the plain command's CPU goes: the steps of ``python -m shapeverify inspect`` done one by
  one in one process (``cli_breakdown.py``, written next to the inputs), with the CPU numba
  spends loading the command's cached kernels (``numba.core.caching.Cache.load_overload``
  timed) and their number.

Goals: ``inspect`` <= 0.6 s CPU, ``info`` (cached) <= 0.3 s, Open3D / ours >= 3.

Inputs: the bundled example panel (300 x 200 mm with a hole, ``example_part_step``), prepared at
the default spacing, and the 30,000-point scan of ``bench_service.py`` (seed 7; noise 0.02 mm,
3 % outliers, 2 mm / 3 degree misalignment).  Each command runs once untimed (numba's cache,
the page cache), then ``--repeat`` times; the table gives the median and the range.

Run:  .venv/bin/python benchmarks/bench_cli.py [--repeat 5] [--work DIR]
      [--out benchmarks/results_cli.md]
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CPU_LOG = "SHAPEVERIFY_WORKER_CPU_LOG"

OPEN3D_SCRIPT = r'''
"""Inspect a scan against sampled model points with Open3D: ICP point-to-plane, signed
distances along the model normals, a JSON report."""
import json
import sys

import numpy as np
import open3d as o3d

scan_path, model_path, out_path, tol = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])
scan = o3d.io.read_point_cloud(scan_path)
model = o3d.io.read_point_cloud(model_path)          # points + normals
reg = o3d.pipelines.registration
icp = reg.registration_icp(
    scan, model, 2.0, np.eye(4),
    reg.TransformationEstimationPointToPlane(reg.TukeyLoss(k=0.1)),
    reg.ICPConvergenceCriteria(relative_fitness=1e-7, relative_rmse=1e-7, max_iteration=60))
T = np.asarray(icp.transformation)
P = np.asarray(scan.points) @ T[:3, :3].T + T[:3, 3]
Q, N = np.asarray(model.points), np.asarray(model.normals)
pair = np.asarray(icp.correspondence_set)
d = np.einsum("ij,ij->i", P[pair[:, 0]] - Q[pair[:, 1]], N[pair[:, 1]])
report = {"n": int(len(d)), "fitness": icp.fitness, "rmse": icp.inlier_rmse,
          "mean": float(d.mean()), "std": float(d.std()), "min": float(d.min()),
          "max": float(d.max()), "p05": float(np.percentile(d, 5)),
          "p95": float(np.percentile(d, 95)),
          "in_tolerance_fraction": float(np.mean(np.abs(d) <= tol)),
          "verdict": "pass" if np.all(np.abs(d) <= tol) else "fail",
          "T_model_scan": T.tolist()}
with open(out_path, "w") as f:
    json.dump(report, f, indent=1)
'''

LIBRARY = r'''
import sys

import shapeverify as sv
from shapeverify.report.result_json import write_result_json

prep = sv.load_prepared(sys.argv[1])
result = sv.inspect(prep, sv.read_points(sys.argv[2]), tolerance=0.2)
write_result_json(result, sys.argv[3])
'''

BREAKDOWN = r'''
import json
import resource
import sys


def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


steps, t = [], cpu()


def step(name):
    global t
    now = cpu()
    steps.append((name, now - t))
    t = now


import numpy as np
step("import numpy")
import numba
step("import numba")


@numba.njit(cache=True)
def total(x):
    return x.sum()


total(np.ones(3))
step("numba's first use (a cached one-line kernel: its lowering registries, scipy.linalg)")
import scipy.spatial
step("import scipy.spatial (the k-d trees of the scan's noise and regions)")
import shapeverify as sv
import shapeverify.inspection, shapeverify.registration, shapeverify.nearest
step("import shapeverify's inspection, registration and closest-point modules")
prep = sv.load_prepared(sys.argv[1])
step("load the prepared model (.svm)")
scan = sv.read_points(sys.argv[2])
step("read the scan (PLY)")
sv.inspect(prep, scan, tolerance=0.2)
step("first inspection (loads its cached kernels)")
sv.inspect(prep, scan, tolerance=0.2)
step("second inspection (the computation alone)")
print(json.dumps(steps))
'''

CLI_BREAKDOWN = r"""
import contextlib, io, json, os, sys, time
os.environ.setdefault("SHAPEVERIFY_NO_WORKER", "1")
cpu = time.process_time
steps, t = [], cpu()


def step(name):
    global t
    now = cpu()
    steps.append((name, now - t))
    t = now


import shapeverify.cli as cli
step("import the command line (shapeverify.cli: typer, rich)")
import numpy
step("import numpy")
import numba
step("import numba")


@numba.njit(cache=True)
def total(x):
    return x.sum()


total(numpy.ones(3))
step("numba's first use (its lowering registries; scipy.linalg through numba's BLAS check)")
import scipy.spatial
step("import scipy.spatial (the k-d trees of the scan's noise, coverage and regions)")
from numba.core import caching

loads = {"n": 0, "cpu": 0.0}
load_overload = caching.Cache.load_overload


def timed(self, sig, target_context):
    t0 = cpu()
    got = load_overload(self, sig, target_context)
    loads["cpu"] += cpu() - t0
    loads["n"] += got is not None
    return got


caching.Cache.load_overload = timed


def run():
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        try:
            cli.app(sys.argv[1:], standalone_mode=False)
        except SystemExit:
            pass


t0 = cpu()
run()
first = cpu() - t0
t0 = cpu()
run()
second = cpu() - t0
steps.append(("the command, less its kernels' loading: shapeverify's modules, typer's conversion, "
              "the model, the scan, the inspection, the JSON report", first - loads["cpu"]))
steps.append((f"loading the {loads['n']} cached numba kernels it calls (unpickle + link)",
              loads["cpu"]))
steps.append(("(the same command again in this process: the work alone)", second))
print(json.dumps(steps))
"""

NUMBA_FLOOR = r'''
import numpy as np
import numba

@numba.njit(cache=True)
def total(x):
    return x.sum()

total(np.ones(3))
'''


def _env() -> dict:
    env = dict(os.environ)
    # as on a user's machine: Python keeps the modules' bytecode (this shared machine sets
    # PYTHONDONTWRITEBYTECODE, which makes every start compile every module again)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src")] + [
        p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    env.setdefault("COLUMNS", "120")
    return env


def cpu_of(argv: list, cwd: Path, env: dict) -> float:
    """CPU seconds (user + system) of one child process and the children it waited for, plus
    the CPU the resident worker reported for it (``SHAPEVERIFY_WORKER_CPU_LOG`` in ``env``)."""
    log = Path(env[CPU_LOG]) if env.get(CPU_LOG) else None
    n_log = len(log.read_text().splitlines()) if log is not None and log.exists() else 0
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run(argv, cwd=cwd, env=env, stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode not in (0, 1, 3):   # inspect: 1 fail, 3 incomplete are answers too
        raise RuntimeError(f"{' '.join(map(str, argv))} exited {proc.returncode}:\n"
                           f"{proc.stderr[-3000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if log is not None:
        lines = log.read_text().splitlines()[n_log:] if log.exists() else []
        if len(lines) != 1 or "worker" in proc.stderr:
            raise RuntimeError(f"{' '.join(map(str, argv))} did not run in the worker:\n"
                               f"{proc.stderr[-3000:]}")
        cpu += json.loads(lines[0])["worker_cpu"]
    return cpu


def make_inputs(work: Path, env: dict) -> dict:
    """The example panel's STEP file, its prepared model, its points with normals as PLY and
    the 30,000-point scan (made once per work directory)."""
    paths = {k: work / v for k, v in (("step", "panel.step"), ("svm", "panel.svm"),
                                      ("scan", "scan.ply"), ("model", "model.ply"),
                                      ("o3d", "open3d_inspect.py"), ("floor", "numba_floor.py"),
                                      ("lib", "library_inspect.py"),
                                      ("breakdown", "breakdown.py"),
                                      ("cli_breakdown", "cli_breakdown.py"),
                                      ("plan", "plan.yaml"))}
    paths["o3d"].write_text(OPEN3D_SCRIPT)
    paths["floor"].write_text(NUMBA_FLOOR)
    paths["lib"].write_text(LIBRARY)
    paths["breakdown"].write_text(BREAKDOWN)
    paths["cli_breakdown"].write_text(CLI_BREAKDOWN)
    # the warm-up's plan of the example panel (its hole and its whole skin)
    paths["plan"].write_text(subprocess.run(
        [sys.executable, "-c", "from shapeverify._warmup_commands import PLAN; "
         "from shapeverify.cad.examples import PANEL_HOLE as h; "
         "print(PLAN.format(x=h[0], y=h[1]), end='')"],
        env=env, capture_output=True, text=True, check=True).stdout)
    if all(paths[k].is_file() for k in ("step", "svm", "scan", "model")):
        return paths
    code = f"""
import sys
sys.path.insert(0, {str(ROOT / 'benchmarks')!r})
import numpy as np
from bench_service import make_scan
from shapeverify.cad.examples import example_part_step
from shapeverify.cad.load import load_model
from shapeverify.io.points import write_ply
from shapeverify.nearest import prepare
step = example_part_step({str(paths['step'])!r})
model = load_model(step)
prep = prepare(model)
prep.save({str(paths['svm'])!r})
write_ply({str(paths['scan'])!r}, make_scan(model, 7))
mp = prep.points
with open({str(paths['model'])!r}, "wb") as f:
    f.write(("ply\\nformat binary_little_endian 1.0\\nelement vertex %d\\n"
             "property double x\\nproperty double y\\nproperty double z\\n"
             "property double nx\\nproperty double ny\\nproperty double nz\\nend_header\\n"
             % len(mp.points)).encode())
    f.write(np.ascontiguousarray(np.hstack([mp.points, mp.normals]), dtype="<f8").tobytes())
"""
    subprocess.run([sys.executable, "-c", code], cwd=work, env=env, check=True)
    return paths


def measure(label: str, argv: list, cwd: Path, env: dict, repeat: int) -> dict:
    cpu_of(argv, cwd, env)                      # untimed: numba's cache, the page cache
    load = os.getloadavg()[0]
    times = [cpu_of(argv, cwd, env) for _ in range(repeat)]
    return {"label": label, "argv": argv, "median": statistics.median(times),
            "min": min(times), "max": max(times), "load": (load + os.getloadavg()[0]) / 2}


def _shown(argv: list, work: Path) -> str:
    text = " ".join(str(a) for a in argv)
    return text.replace(sys.executable, "python").replace(str(work) + os.sep, "")


def _wait_for_worker(env: dict, timeout: float = 300.0) -> dict:
    """The status of the worker a command started in the background (its preload done)."""
    import time

    code = ("import json; from shapeverify.cli_worker import status; "
            "print(json.dumps(status()))")
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        got = json.loads(subprocess.run([sys.executable, "-c", code], env=env,
                                        capture_output=True, text=True, check=True).stdout)
        if got is not None:
            return got
        time.sleep(0.2)
    raise RuntimeError("the worker the first command started does not answer")


def _stop_worker(env: dict, work: Path) -> None:
    subprocess.run([sys.executable, "-m", "shapeverify", "worker", "stop"], cwd=work, env=env,
                   capture_output=True, timeout=120)


def _process_cpu(pid: int) -> float:
    """CPU seconds (user + system, with its waited-for children) of a live process, from /proc."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return sum(int(x) for x in fields[11:15]) / os.sysconf("SC_CLK_TCK")


def measure_auto(argv: list, work: Path, env: dict, rounds: int) -> dict:
    """The worker started by the first command (``SHAPEVERIFY_WORKER=auto``, the default, in a
    socket directory of its own), ``rounds`` times from no worker: the 1st, 2nd and 3rd
    commands' CPU.  Every process is counted: each client (``RUSAGE_CHILDREN``) and the
    worker's whole life (``/proc/PID/stat`` read before it is stopped: its imports, every
    request, its idle threads); the worker's CPU for the 2nd and 3rd requests (which it
    reports, ``SHAPEVERIFY_WORKER_CPU_LOG``) goes to those commands, all the rest of it -- its
    start and, when the first command runs in it, that request -- to the 1st."""
    aenv = {k: v for k, v in env.items() if k not in ("SHAPEVERIFY_NO_WORKER", CPU_LOG)}
    aenv.update(SHAPEVERIFY_WORKER="auto", SHAPEVERIFY_WORKER_DIR=str(work / "sock_auto"))
    log = work / "auto_cpu.jsonl"
    lenv = {**aenv, CPU_LOG: str(log)}
    load = os.getloadavg()[0]
    firsts, seconds, thirds, preloads, in_worker, notes = [], [], [], [], [], set()
    for _ in range(rounds):
        _stop_worker(aenv, work)
        log.unlink(missing_ok=True)
        clients = []
        for i in range(3):
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            proc = subprocess.run(argv, cwd=work, env=lenv, stdout=subprocess.DEVNULL,
                                  stderr=subprocess.PIPE, text=True)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            if proc.returncode not in (0, 1, 3):
                raise RuntimeError(f"auto, command {i + 1} exited {proc.returncode}:\n"
                                   f"{proc.stderr[-3000:]}")
            clients.append((after.ru_utime - before.ru_utime)
                           + (after.ru_stime - before.ru_stime))
            notes.update(ln for ln in proc.stderr.splitlines() if "worker" in ln)
            if i == 0:
                st = _wait_for_worker(aenv)
        worker_total = _process_cpu(st["pid"])
        _stop_worker(aenv, work)
        logged = [json.loads(ln)["worker_cpu"] for ln in log.read_text().splitlines()]
        if len(logged) < 2:
            raise RuntimeError("the 2nd and 3rd commands did not run in the worker")
        w2, w3 = logged[-2:]
        firsts.append(clients[0] + worker_total - w2 - w3)
        seconds.append(clients[1] + w2)
        thirds.append(clients[2] + w3)
        preloads.append(st["preload_cpu"])
        in_worker.append(len(logged) == 3)

    def stats(xs):
        return {"median": statistics.median(xs), "min": min(xs), "max": max(xs)}

    return {"first": stats(firsts), "second": stats(seconds), "third": stats(thirds),
            "preload": statistics.median(preloads), "first_in_worker": all(in_worker),
            "note": sorted(notes), "load": (load + os.getloadavg()[0]) / 2, "rounds": rounds}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--work", type=Path, default=None,
                    help="directory of the inputs (kept; made when missing)")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results_cli.md"))
    ap.add_argument("--peer-python", default=sys.executable,
                    help="the Python that runs the Open3D script (open3d is no dependency of "
                         "shapeverify: e.g. a throwaway venv with open3d-cpu)")
    args = ap.parse_args()
    env = _env()
    work = args.work or Path(tempfile.mkdtemp(prefix="bench_cli_"))
    work.mkdir(parents=True, exist_ok=True)
    paths = make_inputs(work, env)
    env["SHAPEVERIFY_CACHE_DIR"] = str(work / "summaries")     # info: its summary cached
    py = sys.executable

    load_start = os.getloadavg()
    inspect_argv = [py, "-m", "shapeverify", "inspect", paths["svm"], paths["scan"],
                    "--tolerance", "0.2", "--json", work / "r.json"]
    info_argv = [py, "-m", "shapeverify", "info", paths["step"]]
    cold = {**env, "SHAPEVERIFY_NO_WORKER": "1"}
    ours = measure("plain `shapeverify inspect` (no worker; SHAPEVERIFY_NO_WORKER=1): prepared "
                   "model, 30,000 points, JSON report", inspect_argv, work, cold, args.repeat)
    ours_json = json.loads((work / "r.json").read_text())
    planned = measure("plain `shapeverify inspect --plan` (no worker): the same with the "
                      "warm-up's plan of the panel (a hole, the skin's profile)",
                      inspect_argv[:-2] + ["--plan", paths["plan"], "--json", work / "rp.json"],
                      work, cold, args.repeat)
    info = measure("plain `shapeverify info` (no worker): STEP file, summary cached", info_argv,
                   work, cold, args.repeat)
    # the resident worker, in a socket directory of this run's own; always stopped
    wenv = {**env, "SHAPEVERIFY_WORKER": "0", "SHAPEVERIFY_WORKER_DIR": str(work / "sock"),
            CPU_LOG: str(work / "worker_cpu.jsonl")}
    started = cpu_of([py, "-m", "shapeverify", "worker", "start"], work,
                     {k: v for k, v in wenv.items() if k != CPU_LOG})
    try:
        status = _wait_for_worker(wenv)
        warm = measure("`shapeverify inspect` with the worker running (client + worker CPU)",
                       inspect_argv, work, wenv, args.repeat)
        warm_json = json.loads((work / "r.json").read_text())
        info_warm = measure("`shapeverify info` with the worker running (client + worker CPU)",
                            info_argv, work, wenv, args.repeat)
    finally:
        _stop_worker(wenv, work)
    worker_start = started + status["preload_cpu"]
    auto = measure_auto(inspect_argv, work, env, args.repeat)
    peer = measure("Open3D script (ICP point-to-plane + signed distances + JSON report)",
                   [args.peer_python, paths["o3d"], paths["scan"], paths["model"],
                    work / "o3d.json", "0.2"],
                   work, env, args.repeat)
    lib = measure("the same inspection through the library (a Python script, no command line)",
                  [py, paths["lib"], paths["svm"], paths["scan"], work / "lib.json"], work, env,
                  args.repeat)
    floor = measure("floor: import numpy, numba + one cached kernel",
                    [py, paths["floor"]], work, env, args.repeat)
    bare = measure("floor: python -c pass", [py, "-c", "pass"], work, env, args.repeat)

    def median_steps(script, *argv):
        runs = [json.loads(subprocess.run([py, paths[script], *map(str, argv)], cwd=work,
                                          env=cold, capture_output=True, text=True,
                                          check=True).stdout.splitlines()[-1])
                for _ in range(args.repeat)]
        return [(name, statistics.median(r[i][1] for r in runs))
                for i, (name, _) in enumerate(runs[0])]

    cli_steps = median_steps("cli_breakdown", "inspect", paths["svm"], paths["scan"],
                             "--tolerance", "0.2", "--json", work / "r_bd.json")
    breakdown = median_steps("breakdown", paths["svm"], paths["scan"])
    load_end = os.getloadavg()

    same = ({k: v for k, v in ours_json.items() if k != "timings"}
            == {k: v for k, v in warm_json.items() if k != "timings"})
    peer_json = json.loads((work / "o3d.json").read_text())
    verdict = ours_json.get("verdict", "?")
    dev = ours_json.get("deviation", {})
    lines = [
        "## CLI against an Open3D script, CPU time (issue 32 item 7)",
        "",
        f"### {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC",
        "",
        f"Command: `env -u PYTHONDONTWRITEBYTECODE .venv/bin/python benchmarks/bench_cli.py "
        f"--repeat {args.repeat}"
        + (f" --peer-python {args.peer_python}" if args.peer_python != sys.executable else "")
        + "`  ",
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}; load average (1, 5, 15 min) "
        f"{', '.join(f'{x:.1f}' for x in load_start)} at the start, "
        f"{', '.join(f'{x:.1f}' for x in load_end)} at the end (a shared machine: CPU times "
        "run higher under load).",
        "",
        "Each row: a fresh process started by the benchmark, CPU = user + system of it and its "
        "waited-for children (`getrusage(RUSAGE_CHILDREN)`), with a worker plus the CPU the "
        f"worker reports for the request; median and range of {args.repeat} runs after one "
        "untimed run; Open3D / ours = the Open3D script's median over the row's.",
        "",
        "| command | CPU median [s] | range [s] | Open3D / ours | load (1 min) |",
        "|---|---:|---:|---:|---:|",
    ]

    def row(r, ratio=True):
        ratio = f"{peer['median'] / r['median']:.2f}" if ratio and r is not peer else ""
        return (f"| {r['label']}: `{_shown(r['argv'], work)}` | {r['median']:.2f} | "
                f"{r['min']:.2f}-{r['max']:.2f} | {ratio} | {r['load']:.1f} |")

    for r in (ours, warm, peer, lib):
        lines.append(row(r))
    for key, what in (("first", "1st command (it, the worker's start and, when it runs in the "
                                "worker, its request: all the worker's CPU but the 2nd's and "
                                "3rd's)"),
                      ("second", "2nd command (client + worker CPU)"),
                      ("third", "3rd command (client + worker CPU)")):
        a = auto[key]
        lines.append(f"| `shapeverify inspect` with the default worker (`SHAPEVERIFY_WORKER=auto`, "
                     f"{auto['rounds']} rounds from no worker): {what} | {a['median']:.2f} | "
                     f"{a['min']:.2f}-{a['max']:.2f} | {peer['median'] / a['median']:.2f} | "
                     f"{auto['load']:.1f} |")
    for r in (planned, info, info_warm, floor, bare):
        lines.append(row(r, ratio=False))

    def goal(value, limit):
        return f"{'met' if value <= limit else 'NOT met'}, {value:.2f} s"

    lines += [
        "",
        f"Open3D / ours: **{peer['median'] / ours['median']:.2f} plain**, "
        f"{peer['median'] / warm['median']:.2f} with the worker (goal >= 3).  Goals: inspect "
        f"<= 0.6 s ({goal(ours['median'], 0.6)} plain; {goal(warm['median'], 0.6)} with the "
        f"worker running; the default worker: 1st command {goal(auto['first']['median'], 0.6)}, "
        f"2nd {goal(auto['second']['median'], 0.6)}, 3rd {goal(auto['third']['median'], 0.6)}), "
        f"info (cached) <= 0.3 s ({goal(info['median'], 0.3)} plain; "
        f"{goal(info_warm['median'], 0.3)} with the worker).  The worker's JSON report equals "
        f"the plain one (less `timings`): {'yes' if same else 'NO'}.",
        "",
        f"The worker's start: `shapeverify worker start` {started:.2f} s + the worker's imports "
        f"and numba's first use {status['preload_cpu']:.2f} s = {worker_start:.2f} s CPU, once "
        "per session.  Started by the first command (`SHAPEVERIFY_WORKER=auto`, the default): "
        f"the 1st command {auto['first']['median']:.2f} s in all (the worker's imports "
        f"{auto['preload']:.2f} s of it; the command ran "
        + ("in the worker it started" if auto["first_in_worker"] else "in its own process")
        + f"), the 2nd {auto['second']['median']:.2f} s, the 3rd "
        f"{auto['third']['median']:.2f} s.  Its note on stderr: "
        + ("; ".join(f"`{n}`" for n in auto["note"]) or "(none)") + ".",
        "",
        f"Answers: ours {verdict}, {dev.get('n', '?')} evaluated points, std "
        f"{dev.get('std', float('nan')):.4f} mm, min {dev.get('min', float('nan')):+.3f}, max "
        f"{dev.get('max', float('nan')):+.3f} mm; Open3D: fitness {peer_json['fitness']:.3f}, "
        f"{peer_json['n']} matched points, std {peer_json['std']:.4f} mm, min "
        f"{peer_json['min']:+.3f}, max {peer_json['max']:+.3f} mm (no outlier rule: its verdict "
        f"is {peer_json['verdict']}).",
        "",
        "Where the plain command's CPU goes (one Python process doing the steps in order, as "
        "`python -m shapeverify inspect` does them, CPU of each step, median of "
        f"{args.repeat} runs):",
        "",
        "| step | CPU [s] |",
        "|---|---:|",
    ]
    lines += [f"| {name} | {sec:.2f} |" for name, sec in cli_steps]
    lines.append(f"| total (less the repeat) | {sum(sec for _, sec in cli_steps[:-1]):.2f} |")
    lines += ["", "The library's process (the same inspection as a script, twice):", "",
              "| step | CPU [s] |", "|---|---:|"]
    lines += [f"| {name} | {sec:.2f} |" for name, sec in breakdown]
    lines.append(f"| total | {sum(sec for _, sec in breakdown):.2f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    out = Path(args.out)
    old = out.read_text() if out.is_file() else "# CLI start-up and speed\n\n"
    head, sep, rest = old.partition("## ")
    out.write_text(head + text + ("\n" + sep + rest if sep else ""))


if __name__ == "__main__":
    main()
