"""Cold start: the time to the first answer, with a fresh numba cache directory and with a warm one.

Each step is one fresh process (``python -m shapeverify ...``, what the ``shapeverify`` command
runs, or ``python -c ...``), timed as wall-clock time and as CPU time (user + system of the
process and of the children it waited for, e.g. the OpenCASCADE importer): on this shared 2-core
machine the CPU time is the fair single-core figure, the wall time also counts waiting for a
core.  Goals (issue 16 item 7):

* ``import shapeverify`` and ``shapeverify info`` of a small STEP file <= 1.5 s;
* the first ``shapeverify inspect`` after set-up (``make demo`` / ``make test`` run
  ``python -m shapeverify.warmup`` once) <= 3 s;
* a fresh install with no cache: <= 60 s on one core for the first inspection.

Steps, in this order (the numba cache directory is ``NUMBA_CACHE_DIR``, fresh for the "cold"
rows; the inputs are made beforehand with a separate cache so that they fill nothing):

1. ``import shapeverify`` (the public names are lazy);
2. ``info`` of a small STEP file (the 10 KB wavy cube of ``../shared/data/cad`` when present, else
   the bundled example panel), with a cold then a warm numba cache (each run with an empty
   cache of ``info`` summaries, best of ``--repeats``), then with its summary cached (no
   OpenCASCADE, no numba), and ``import OCP.STEPControl`` alone (the floor of any run that reads
   a STEP file);
3. fresh cache: ``prepare`` the example panel, then ``inspect`` a simulated scan of it (the first
   inspection of a fresh install), then ``inspect`` again (warm);
4. fresh cache: ``python -m shapeverify.warmup`` (what set-up runs), then ``inspect`` and
   ``prepare`` (both should compile nothing).

Run:  .venv/bin/python benchmarks/bench_coldstart.py [--out benchmarks/results_coldstart.md]
      [--skip-cold]   (only the warm rows; a few seconds)
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SMALL_STEP = ROOT.parent / "shared" / "data" / "cad" / "wavy-cube.stp"


def _env(cache: Path, summaries: Path | None = None) -> dict:
    env = dict(os.environ)
    env["NUMBA_CACHE_DIR"] = str(cache)
    # the cache of ``info`` summaries (shapeverify.cad.summary): a fresh one unless a row says
    env["SHAPEVERIFY_CACHE_DIR"] = str(summaries or tempfile.mkdtemp(prefix="summaries-",
                                                                     dir=cache.parent))
    # as on a user's machine: Python keeps the modules' bytecode (this shared machine sets
    # PYTHONDONTWRITEBYTECODE, which makes every start compile every module again)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src")] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    env.setdefault("COLUMNS", "120")
    env["SHAPEVERIFY_NO_WORKER"] = "1"  # cold starts: never a resident worker (cli_worker)
    return env


def run(args, cache: Path, cwd: Path, summaries: Path | None = None) -> tuple[float, float, int]:
    """(wall s, CPU s of the process and its waited-for children, exit code)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, *args], cwd=cwd, env=_env(cache, summaries),
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode(errors="replace")
    proc.stderr.close()
    if proc.returncode not in (0, 1, 3):
        raise RuntimeError(f"{' '.join(map(str, args))} exited {proc.returncode}:\n{err[-2000:]}")
    return wall, ru.ru_utime + ru.ru_stime, proc.returncode


def cache_files(cache: Path) -> set[str]:
    return {p.name for p in cache.rglob("*.nbc")} if cache.is_dir() else set()


def make_inputs(work: Path, env: dict | None = None) -> tuple[Path, Path]:
    """The example panel (STEP) and a simulated scan of it, made with their own numba cache
    (or in the environment ``env``)."""
    code = (
        "import sys; from pathlib import Path\n"
        "from shapeverify.cad.examples import example_part_step\n"
        "from shapeverify.cad.load import load_model\n"
        "from shapeverify.io.points import write_ply\n"
        "from shapeverify.simulate import virtual_scan\n"
        "w = Path(sys.argv[1]); step = example_part_step(w / 'panel.step')\n"
        "sim = virtual_scan(load_model(step), pixel=1.2, noise=0.02, shadows=1, blobs=1,\n"
        "                   outlier_fraction=0.05, dents=[(0.4, 15.0)], motion=(4.0, 8.0), rng=2011)\n"
        "write_ply(w / 'scan.ply', sim.scan)\n")
    env = _env(work / "inputs-cache") if env is None else env
    subprocess.run([sys.executable, "-c", code, str(work)], check=True, env=env, cwd=work)
    return work / "panel.step", work / "scan.ply"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results_coldstart.md")
    ap.add_argument("--skip-cold", action="store_true", help="only the warm rows")
    ap.add_argument("--small-step", type=Path, default=SMALL_STEP,
                    help="the small STEP file of the info rows (default: ../shared/data/cad/wavy-cube.stp)")
    ap.add_argument("--repeats", type=int, default=5,
                    help="runs of the short warm info rows (the best is shown)")
    args = ap.parse_args()

    work = Path(tempfile.mkdtemp(prefix="sv-coldstart-"))
    rows = []  # (step, cache, wall, cpu, new cache files)
    compiled_late = {}  # step -> the specialisations a warm row still compiled

    def step(name, argv, cache, kind, repeats=1, summaries=None):
        """One row: the best wall and the best CPU time of ``repeats`` runs."""
        before = cache_files(cache)
        runs = [run(argv, cache, work, summaries) for _ in range(repeats)]
        wall, cpu = min(r[0] for r in runs), min(r[1] for r in runs)
        if repeats > 1:
            name += f" (best of {repeats})"
        new = sorted(cache_files(cache) - before)
        rows.append((name, kind, wall, cpu, len(new)))
        if new and kind == "warm":
            compiled_late[name] = new
        print(f"{name:<60} {kind:<6} wall {wall:7.2f} s  CPU {cpu:7.2f} s  "
              f"+{len(new)} cache files {new if kind == 'warm' else ''}", flush=True)

    try:
        step_file, scan = make_inputs(work)
        small = args.small_step if args.small_step.is_file() else step_file
        cli = ["-m", "shapeverify"]  # what the `shapeverify` command runs (cli_start.main)
        insp = cli + ["inspect", "panel.svm", str(scan), "--tolerance", "0.2", "--json", "r.json"]
        warm = work / "cache-warm"
        for i in range(2):
            step("python -c 'import shapeverify'", ["-c", "import shapeverify"], warm, "-")
        if not args.skip_cold:
            cold = work / "cache-info"
            info = cli + ["info", str(small)]
            step(f"shapeverify info {small.name}", info, cold, "cold")
            step(f"shapeverify info {small.name}", info, cold, "warm", repeats=args.repeats)
            summaries = work / "summaries"
            run(info, cold, work, summaries)  # fills the summary cache
            step(f"shapeverify info {small.name} (summary cached)", info, cold, "warm",
                 repeats=args.repeats, summaries=summaries)
            step("python -c 'import OCP.STEPControl' (the importer's floor)",
                 ["-c", "import OCP.STEPControl"], cold, "-", repeats=args.repeats)
            fresh = work / "cache-fresh"
            step("shapeverify prepare panel.step -o panel.svm", cli + ["prepare", str(step_file), "-o", "panel.svm"],
                 fresh, "cold")
            step("shapeverify inspect panel.svm scan.ply (first of a fresh install)", insp, fresh, "cold")
            step("shapeverify inspect panel.svm scan.ply", insp, fresh, "warm")
            set_up = work / "cache-setup"
            step("python -m shapeverify.warmup (set-up: make demo / make test)",
                 ["-m", "shapeverify.warmup"], set_up, "cold")
            step("shapeverify inspect panel.svm scan.ply (first after set-up)", insp, set_up, "warm")
            step("shapeverify prepare panel.step -o again.svm (first after set-up)",
                 cli + ["prepare", str(step_file), "-o", "again.svm"], set_up, "warm")
            step(f"shapeverify info {small.name} (after set-up)", cli + ["info", str(small)], set_up, "warm")
        else:
            step("python -m shapeverify.warmup", ["-m", "shapeverify.warmup"], warm, "warm?")
            step("shapeverify prepare panel.step -o panel.svm", cli + ["prepare", str(step_file), "-o", "panel.svm"],
                 warm, "warm")
            step("shapeverify inspect panel.svm scan.ply", insp, warm, "warm")
            step(f"shapeverify info {small.name}", cli + ["info", str(small)], warm, "warm")
    finally:
        shutil.rmtree(work, ignore_errors=True)

    load = os.getloadavg()
    lines = [
        "## Cold start (issue 16 item 7)",
        "",
        f"Command: `cd {ROOT} && .venv/bin/python benchmarks/bench_coldstart.py`"
        f" ({datetime.date.today().isoformat()}, Python {platform.python_version()}, "
        f"load average at the end {load[0]:.1f} on {os.cpu_count()} cores)",
        "",
        "One fresh process per row. CPU = user + system time of the process and of the children it "
        "waited for (the OpenCASCADE importer): the single-core figure; wall also counts waiting for a "
        "core on this shared machine. \"cold\": a fresh `NUMBA_CACHE_DIR`, \"warm\": the same directory "
        "after the rows above; \"cache files\": numba `.nbc` files the row wrote (one per compiled "
        "specialisation).",
        "",
        "| step | numba cache | wall [s] | CPU [s] | cache files written |",
        "|---|---|---:|---:|---:|",
    ]
    lines += [f"| `{n}` | {k} | {w:.2f} | {c:.2f} | {f} |" for n, k, w, c, f in rows]
    for name, new in compiled_late.items():
        lines += ["", f"Still compiled by `{name}`: " + ", ".join(f"`{n}`" for n in new)]
    text = "\n".join(lines) + "\n"
    args.out.write_text(text)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
