"""A fresh install with a shipped numba cache: would the first inspection then meet <= 60 s?

Issue 16 item 7: the first ``prepare`` + ``inspect`` of a fresh install costs ~78 s of CPU, nearly
all of it numba compiling (``bench_coldstart.py``).  A wheel could ship the compiled kernels:
numba's cache files (``__pycache__/*.nbi`` index + ``*.nbc`` data) built at packaging time.
This script measures whether numba accepts such a cache in another install location and what
the first inspection then costs:

1. **build** -- copy ``src/`` (without caches) to ``build/src`` and run ``prepare`` + ``inspect``
   of the example panel there with numba's in-tree cache (no ``NUMBA_CACHE_DIR``), compiled for
   a generic x86-64 CPU (``NUMBA_CPU_NAME=generic``, which also sets ``NUMBA_CPU_FEATURES=""``):
   the cache a wheel would ship.
2. **install** -- copy ``build/src`` with its ``__pycache__`` to ``install-N/src`` with fresh
   modification times (as pip writes a wheel's files) and run the first ``prepare`` +
   ``inspect`` there: with ``NUMBA_CPU_NAME=generic`` (the cache's key), and without it (the
   host CPU's name and features: another key).
3. **speed** -- the warm ``inspect`` with the generic kernels against the same with kernels
   compiled for this CPU (the ``timings`` of its JSON, best of ``--repeats``), and the
   kernels' share: ``prep.closest`` of 200,000 points near the panel, generic against host.

numba 0.68 keys a cache index on the SHA-256 of the source file's bytes (not on its path or
modification time: ``numba/core/caching.py``, ``_SourceFileBackedLocatorMixin``) and each
entry on the signature, the target (LLVM triple, CPU name, CPU features) and the hashes of the
function's bytecode and closure; the in-tree cache is used only where the package directory is
writable (else numba falls back to a per-user cache and ignores the shipped one) and only when
``NUMBA_CACHE_DIR`` is not set.

Run:  .venv/bin/python benchmarks/bench_shipped_cache.py [--repeats 3] [--skip-native]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def make_inputs(work: Path) -> tuple[Path, Path]:
    """The inputs of ``bench_coldstart.py``, made with this tree's own (warm) cache so that they
    compile nothing of the measured caches."""
    from bench_coldstart import make_inputs as coldstart_inputs

    return coldstart_inputs(work, env=dict(os.environ, PYTHONPATH=str(ROOT / "src")))


def env_for(src: Path, generic: bool) -> dict:
    env = dict(os.environ)
    env.pop("NUMBA_CACHE_DIR", None)        # numba's in-tree cache: __pycache__ beside sources
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env.pop("NUMBA_CPU_FEATURES", None)
    if generic:
        env["NUMBA_CPU_NAME"] = "generic"
    else:
        env.pop("NUMBA_CPU_NAME", None)
    env["PYTHONPATH"] = str(src)
    env["SHAPEVERIFY_CACHE_DIR"] = tempfile.mkdtemp(prefix="summaries-")
    return env


def run(args, env, cwd) -> tuple[float, float]:
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, *args], cwd=cwd, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode(errors="replace")
    proc.stderr.close()
    code = os.waitstatus_to_exitcode(status)
    if code not in (0, 1, 3):
        raise RuntimeError(f"{args} exited {code}:\n{err[-2000:]}")
    return wall, ru.ru_utime + ru.ru_stime


def nbc(src: Path) -> set:
    return {str(p.relative_to(src)) for p in src.rglob("*.nbc")}


def copy_tree(src: Path, dst: Path, with_caches: bool) -> None:
    ignore = None if with_caches else shutil.ignore_patterns("__pycache__")
    # copyfile: new modification times, as pip writes the files of a wheel
    shutil.copytree(src, dst, ignore=ignore, copy_function=shutil.copyfile)


def first_inspection(src: Path, work: Path, step: Path, scan: Path, generic: bool, label: str,
                     rows: list) -> None:
    env = env_for(src, generic)
    before = nbc(src)
    w1, c1 = run(["-m", "shapeverify.cli", "prepare", str(step), "-o", str(work / "p.svm")],
                 env, work)
    w2, c2 = run(["-m", "shapeverify.cli", "inspect", str(work / "p.svm"), str(scan),
                  "--tolerance", "0.2", "--json", str(work / "r.json")], env, work)
    new = len(nbc(src) - before)
    rows.append((label, w1, c1, w2, c2, new))
    print(f"{label:<58} prepare {c1:6.2f} s CPU ({w1:6.2f} wall)  inspect {c2:6.2f} s CPU "
          f"({w2:6.2f} wall)  total {c1 + c2:6.2f} s CPU, {new} cache files written", flush=True)


def warm_speed(src: Path, work: Path, scan: Path, generic: bool, repeats: int) -> dict:
    """Best-of timings of a warm inspect (its JSON's stages) and of prep.closest."""
    env = env_for(src, generic)
    best = {}
    for _ in range(repeats):
        run(["-m", "shapeverify.cli", "inspect", str(work / "p.svm"), str(scan), "--tolerance",
             "0.2", "--json", str(work / "r.json")], env, work)
        t = json.loads((work / "r.json").read_text())["timings"]
        for k, v in t.items():
            if isinstance(v, (int, float)):
                best[k] = min(best.get(k, float("inf")), float(v))
    code = ("import sys, time, numpy as np\n"
            "from shapeverify.nearest import load_prepared\n"
            "prep = load_prepared(sys.argv[1])\n"
            "rng = np.random.default_rng(0)\n"
            "pts = prep.points.points[rng.integers(0, prep.n_points, 200000)]"
            " + rng.normal(0, 0.3, (200000, 3))\n"
            "prep.closest(pts[:1000]); prep.closest(pts[:1000], exact=True)\n"
            "b = e = 1e9\n"
            "for _ in range(%d):\n"
            "    t = time.perf_counter(); prep.closest(pts); b = min(b, time.perf_counter() - t)\n"
            "    t = time.perf_counter(); prep.closest(pts[:50000], exact=True)\n"
            "    e = min(e, time.perf_counter() - t)\n"
            "print(b, e)\n") % repeats
    out = subprocess.run([sys.executable, "-c", code, str(work / "p.svm")], env=env, cwd=work,
                         capture_output=True, text=True, check=True).stdout.split()
    best["closest 200k (s)"], best["closest exact 50k (s)"] = float(out[0]), float(out[1])
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--skip-native", action="store_true",
                    help="leave out the install run without NUMBA_CPU_NAME and the host-CPU "
                         "speed comparison (saves ~2 compiles)")
    ap.add_argument("--keep", action="store_true", help="keep the work directory")
    ap.add_argument("--reuse", type=Path, help="a work directory kept by --keep: its build "
                                               "and inputs are used again (no build run)")
    args = ap.parse_args()
    work = args.reuse or Path(tempfile.mkdtemp(prefix="sv-shipped-"))
    rows = []
    try:
        build = work / "build" / "src"
        if args.reuse:
            step, scan = work / "panel.step", work / "scan.ply"
            for d in work.glob("install-*"):
                shutil.rmtree(d)
        else:
            step, scan = make_inputs(work)
            copy_tree(ROOT / "src", build, with_caches=False)
            first_inspection(build, work, step, scan, True,
                             "build: fresh tree, NUMBA_CPU_NAME=generic (the cache shipped)",
                             rows)
        shipped = nbc(build)
        print(f"cache shipped: {len(shipped)} .nbc files, "
              f"{sum(p.stat().st_size for p in build.rglob('*.nb?')) / 1e6:.1f} MB", flush=True)
        inst = work / "install-1" / "src"
        copy_tree(build, inst, with_caches=True)
        first_inspection(inst, work, step, scan, True,
                         "install (copied, new mtimes), NUMBA_CPU_NAME=generic", rows)
        speed = {"generic": warm_speed(inst, work, scan, True, args.repeats)}
        if not args.skip_native:
            inst2 = work / "install-2" / "src"
            copy_tree(build, inst2, with_caches=True)
            first_inspection(inst2, work, step, scan, False,
                             "install (copied), host CPU (no NUMBA_CPU_NAME)", rows)
            speed["host"] = warm_speed(inst2, work, scan, False, args.repeats)
        print(json.dumps(speed, indent=1))
    finally:
        if not (args.keep or args.reuse):
            shutil.rmtree(work, ignore_errors=True)
    load = os.getloadavg()
    print(f"load average at the end {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")


if __name__ == "__main__":
    main()
