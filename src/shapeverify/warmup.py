"""Fill numba's cache once, at set-up, and say so whenever a kernel still compiles on first use.

The numeric kernels are compiled by numba the first time they run on a machine (or after the
package changed) and kept in numba's cache (``__pycache__`` beside the sources, or
``NUMBA_CACHE_DIR``); later processes load them in well under a second.  ``make demo`` and
``make test`` run ``python -m shapeverify.warmup`` once after installing, so the first real
inspection does not pay for compiling.  Run it yourself after ``pip install shapeverify``::

    python -m shapeverify.warmup

It imports, prepares, simulates a scan of and inspects the bundled example panel through the
command line (``info``, ``prepare``, ``inspect`` with every report, and with a plan), then runs
``unwrap``, ``hologram``, ``fit`` and ``measure`` on small inputs
(:mod:`shapeverify._warmup_commands`), each in its own process as a user would run them, so
every kernel those commands call is compiled for the argument types they call it with; then,
in this process, the library with the arrays other programs hand over (read-only, float32,
Fortran-ordered).

:func:`compile_notices` is what the command line uses to tell the user, once, that numba is
compiling (with an estimate) instead of sitting silent for a minute.
"""

from __future__ import annotations

import contextlib
import logging
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

logger = logging.getLogger(__name__)

__all__ = ["COLD_SECONDS", "compile_notices", "install_compile_notices", "input_variants",
           "warm_up", "cache_files", "sources_stamp", "write_snapshot", "main"]

#: measured CPU seconds (fastest, slowest) of compiling everything a command needs with an empty
#: cache, on one core of the 2-core development machines (benchmarks/results_coldstart.md: 14-20 s
#: per command on 2026-12-05, 35-50 s on a slower machine on 2026-12-04); the notice's estimate
COLD_SECONDS = {"inspect": (20.0, 50.0), "prepare": (15.0, 40.0), "warmup": (55.0, 120.0)}


def _when(command: str) -> str:
    """The estimate as text: ``about 20-50 s``."""
    lo, hi = COLD_SECONDS.get(command, (20.0, 60.0))
    return f"about {lo:.0f}-{hi:.0f} s"


def _message(command: str) -> str:
    when = _when(command)
    return (f"compiling the numeric kernels for this machine (first run after installing or "
            f"updating shapeverify: {when} on one core, once; later runs load them from numba's "
            f"cache). To do it ahead: python -m shapeverify.warmup")


@contextlib.contextmanager
def compile_notices(say, command: str = "inspect"):
    """Call ``say(text)`` once if numba compiles a kernel inside the ``with`` block.

    Parameters
    ----------
    say : callable(str)
        Shows the text (the CLI prints it above its spinner).
    command : str
        Which estimate of :data:`COLD_SECONDS` the text gives.

    Yields
    ------
    dict
        ``{"n": kernels compiled, "seconds": wall time spent compiling}`` (filled on exit).

    Examples
    --------
    >>> import numba
    >>> @numba.njit
    ... def twice(x):
    ...     return 2 * x
    >>> said = []
    >>> with compile_notices(said.append) as stats:
    ...     twice(21)
    42
    >>> len(said), stats["n"]
    (1, 1)
    """
    from numba.core import event

    stats, listener = _listener(say, command)
    event.register("numba:compile", listener)
    try:
        yield stats
    finally:
        event.unregister("numba:compile", listener)
        if stats["n"]:
            logger.info("numba compiled %d kernels in %.1f s (cached for later runs)",
                        stats["n"], stats["seconds"])


def install_compile_notices(say, command: str = "inspect") -> dict:
    """:func:`compile_notices` for the rest of the process (the command line's choice).

    Returns
    -------
    dict
        The statistics, updated as kernels compile.
    """
    from numba.core import event

    stats, listener = _listener(say, command)
    event.register("numba:compile", listener)
    return stats


def _listener(say, command: str):
    from numba.core import event

    stats = {"n": 0, "seconds": 0.0}
    lock = threading.Lock()
    state = {"depth": 0, "said": False, "t0": 0.0}

    class _Listener(event.Listener):
        def on_start(self, ev):
            with lock:
                if state["depth"] == 0:
                    state["t0"] = time.perf_counter()
                    stats["n"] += 1
                    if not state["said"]:
                        state["said"] = True
                        try:
                            say(_message(command))
                        except Exception:  # noqa: BLE001 - a notice must never break the work
                            logger.debug("compile notice failed", exc_info=True)
                state["depth"] += 1
            logger.info("numba: compiling %s", getattr(ev.data.get("dispatcher"), "__qualname__", "?"))

        def on_end(self, ev):
            with lock:
                state["depth"] -= 1
                if state["depth"] == 0:
                    stats["seconds"] += time.perf_counter() - state["t0"]

    return stats, _Listener()


def _run(argv, cwd: Path) -> float:
    t0 = time.perf_counter()
    # its own cache of info summaries: info must really import the file (and its kernels)
    env = {**os.environ, "SHAPEVERIFY_CACHE_DIR": str(cwd / "summaries")}
    proc = subprocess.run([sys.executable, "-m", "shapeverify.cli", *map(str, argv)], cwd=cwd,
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
    if proc.returncode not in (0, 1, 3):  # inspect: 1 fail and 3 incomplete are answers too
        raise RuntimeError(f"shapeverify {' '.join(map(str, argv))} exited {proc.returncode}:\n"
                           f"{proc.stderr[-3000:]}")
    return time.perf_counter() - t0


def warm_up(say=logger.info) -> float:
    """Compile (or load from the cache) every kernel of ``info``, ``prepare``, ``inspect`` (with
    and without a plan), ``measure``, ``unwrap``, ``hologram`` and ``fit``.

    Parameters
    ----------
    say : callable(str)
        Receives one line per step.

    Returns
    -------
    float
        Wall-clock seconds.
    """
    from shapeverify.cad.examples import example_part_step
    from shapeverify.cad.load import load_model
    from shapeverify.io.points import write_ply
    from shapeverify.simulate import ScanEffects, virtual_scan

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="shapeverify-warmup-") as d:
        work = Path(d)
        step = example_part_step(work / "panel.step")
        say("importing the example panel")
        _run(["info", step], work)
        say("preparing it (closest-point structure)")
        # the default spacing, as a user's first prepare: a coarser one skips kernels (classify)
        _run(["prepare", step, "-o", work / "panel.svm"], work)
        say("simulating a scan")
        sim = virtual_scan(load_model(step), pixel=3.0, noise=0.02, motion=(4.0, 8.0), rng=2011,
                           effects=ScanEffects(shadows=1, blobs=1, outlier_fraction=0.05,
                                               dents=[(0.4, 15.0)]))
        write_ply(work / "scan.ply", sim.scan)
        say("inspecting it, with every report")
        _run(["inspect", work / "panel.svm", work / "scan.ply", "--tolerance", "0.2",
              "--json", work / "r.json", "--report", work / "r.html", "--png", work / "r.png",
              "--colored", work / "r.ply", "--db", work / "h.sqlite", "--part", "warm-up"], work)
        say("closest points beyond the reach of the structure")
        _far_queries(work / "panel.svm")
        say("scans as other programs hand them over (read-only, float32, Fortran order)")
        input_variants(work / "panel.svm", work / "scan.ply")
        from shapeverify._warmup_commands import global_search, library_variants, run_all

        say("the search with no start (a scan in any pose)")
        global_search(work / "panel.svm", work / "scan.ply")

        run_all(work, _run, say, step=step, svm=work / "panel.svm", scan=work / "scan.ply")
        say("phase maps and points as other programs hand them over")
        library_variants()
    return time.perf_counter() - t0


def input_variants(svm: Path, scan: Path) -> None:
    """Inspect the scan ``scan`` against ``svm`` in this process as a read-only, a float32 and a
    Fortran-ordered array: a read-only buffer (``np.frombuffer``, a memory map, a service's
    request body) reaches the kernels as it is, and numba compiles a read-only array apart from
    a writeable one (2 kernels, measured on the example panel; float32 and Fortran-ordered
    scans are converted at the boundary, and are run here to keep it that way)."""
    import numpy as np

    import shapeverify as sv

    prep = sv.load_prepared(svm)
    points = sv.read_points(scan)
    read_only = points.copy()
    read_only.setflags(write=False)
    for variant in (read_only, points.astype(np.float32), np.asfortranarray(points)):
        sv.inspect(prep, variant, tolerance=0.2)


def _far_queries(svm: Path) -> None:
    """Queries farther than the prepared model's reach take a fallback path (a k-d tree, then the
    patches) that a scan hits only sometimes; a loaded model's arrays are read-only, which numba
    compiles separately from a freshly prepared model's: run both, fast and exact."""
    import numpy as np

    from shapeverify.nearest import load_prepared

    prep = load_prepared(svm)
    size = prep.model.size
    mp = prep.points
    step = max(1, len(mp.points) // 200)
    pts, nrm = mp.points[::step], mp.normals[::step]
    near = pts + 0.1 * nrm
    far = near + 3.0 * max(prep.reach, 0.01 * size) * nrm
    q = np.ascontiguousarray(np.vstack([near, far]))
    for exact in (False, True):
        prep.closest(q, exact=exact)


def _package_root() -> Path:
    return Path(__file__).resolve().parent


def cache_files() -> dict[Path, str]:
    """numba's cache files (``*.nbi`` indexes, ``*.nbc`` kernels) of this package's sources,
    where this process's numba keeps them (``NUMBA_CACHE_DIR`` or ``__pycache__`` beside each
    source folder): path -> the name of that file in a ``NUMBA_CACHE_DIR`` (its folder's
    ``<folder>_<SHA-1 of the source folder>``, numba's own naming, then the file's name)."""
    from numba.core import config
    from numba.core.caching import _CacheLocator

    out = {}
    for folder in sorted({p.parent for p in _package_root().rglob("*.py")}):
        sub = _CacheLocator.get_suitable_cache_subpath(str(folder / "__init__.py"))
        where = Path(config.CACHE_DIR) / sub if config.CACHE_DIR else folder / "__pycache__"
        if where.is_dir():
            for f in sorted(where.iterdir()):
                if f.suffix in (".nbi", ".nbc") and f.is_file():
                    out[f] = f"{sub}/{f.name}"
    return out


def sources_stamp() -> str:
    """SHA-256 of what a numba cache entry of the package depends on: every source file of the
    ``shapeverify`` in use (path, size, mtime and bytes), where it lives (a ``NUMBA_CACHE_DIR``
    holds a folder per source folder), numba's and Python's versions and the interpreter."""
    import hashlib
    import json

    import numba

    root = _package_root()
    h = hashlib.sha256(json.dumps([str(root), numba.__version__, sys.version,
                                   sys.executable]).encode())
    for p in sorted(root.rglob("*.py")):
        st = p.stat()
        h.update(f"{p.relative_to(root)}\0{st.st_size}\0{st.st_mtime_ns}\0".encode())
        h.update(p.read_bytes())
    return h.hexdigest()


def write_snapshot(dest: Path, files: dict[Path, str]) -> None:
    """A copy of the cache files ``files`` (:func:`cache_files`) in ``dest/numba``, laid out as
    a ``NUMBA_CACHE_DIR``, with ``dest/manifest.json``: the :func:`sources_stamp` they were
    compiled from and each copied file's SHA-256.  Written to a temporary folder beside
    ``dest`` and renamed, so ``dest`` is whole or absent."""
    import hashlib
    import json
    import shutil

    dest = Path(dest)
    tmp = dest.with_name(f"{dest.name}.{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    sums = {}
    for src, name in files.items():
        (tmp / "numba" / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, tmp / "numba" / name)
        sums[name] = hashlib.sha256((tmp / "numba" / name).read_bytes()).hexdigest()
    (tmp / "manifest.json").write_text(json.dumps({"stamp": sources_stamp(), "files": sums}))
    shutil.rmtree(dest, ignore_errors=True)
    os.replace(tmp, dest)


def main(argv=None) -> int:
    """``python -m shapeverify.warmup [--quiet] [--snapshot DIR]``: the set-up step; it reports
    through this module's logger, shown on standard output unless ``--quiet``.

    ``--snapshot DIR`` (``make``'s set-up: ``.venv/warmup-snapshot``): when numba's cache held
    no entry of the package before the warm-up, a copy of what the warm-up wrote, and only
    that (:func:`write_snapshot`), taken before anything else can add to the cache; the suite's
    test that the warm-up leaves nothing to compile (tests/test_warmup_coverage.py) runs its
    commands on a copy of it instead of compiling everything again (3-4 minutes of CPU).  With
    entries there already (an earlier run, the tests), no snapshot: DIR is removed."""
    import argparse

    ap = argparse.ArgumentParser(prog="python -m shapeverify.warmup")
    ap.add_argument("--quiet", "-q", action="store_true")
    ap.add_argument("--snapshot", metavar="DIR", type=Path)
    args, _ = ap.parse_known_args(sys.argv[1:] if argv is None else argv)
    snapshot = args.snapshot
    if snapshot is not None:
        before = cache_files()
    if not args.quiet:
        handler = logging.StreamHandler(sys.stdout)
        handler.setFormatter(logging.Formatter("%(message)s"))
        logger.addHandler(handler)
        logger.setLevel(logging.INFO)
        logger.propagate = False
    logger.info("shapeverify: compiling the numeric kernels once for this machine (numba; %s "
                "on one core with an empty cache, a few seconds when they are cached "
                "already). Cache: %s", _when("warmup"),
                os.environ.get("NUMBA_CACHE_DIR") or "__pycache__ beside the sources")
    seconds = warm_up(lambda text: logger.info("  warm-up: %s", text))
    logger.info("shapeverify: kernels ready (%.0f s)", seconds)
    if snapshot is not None:
        import shutil

        made = cache_files()
        if before or not made:
            shutil.rmtree(snapshot, ignore_errors=True)
            logger.info("  no snapshot of the warm-up's cache: %s", "the cache held entries "
                        "before it" if before else "it wrote no cache file")
        else:
            write_snapshot(snapshot, made)
            logger.info("  snapshot of the %d cache files it wrote: %s", len(made), snapshot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
