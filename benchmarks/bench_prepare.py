"""Benchmark: where ``prepare`` spends its time and memory, stage by stage (issue 18 item 3,
issue 14 item 4).

The stages are those of :func:`shapeverify.nearest.prepared.prepare`, run one after the other
here so that each gets its own clock:

* ``sample``      ``Model.sample`` (candidates on every face, trims, thinning, tangents);
* ``order``       the Morton order of the model points;
* ``kd``          the scipy kd-tree over the model points (neighbour graph, exact fallback);
* ``graph``       the 8 nearest neighbours of each model point;
* ``frames``      normals, tangents and the patches' half extents (from the graph);
* ``records``     the 128-byte model point records;
* ``tree``        the DVG cell tree (:func:`shapeverify.nearest.dvg.build_tree`);
* ``other``       the other-face links of the exact mode.

CPU seconds (``time.process_time``, all threads of the process) is the figure to compare on
this shared, loaded machine; wall seconds are printed beside it.  ``--peak`` measures the
Python-level peak allocation with ``tracemalloc`` (numpy arrays included); the process'
peak RSS is best taken with ``/usr/bin/time -v``.

``--save-answers FILE`` writes the nearest-model-point indices of fixed queries (random and
scan-like, see :func:`queries`) and the tree's ``nodes`` and ``lists``; ``--compare FILE``
checks a later build against them (tree arrays included, when the file has them) and against
scipy's cKDTree.

Run:  .venv/bin/python benchmarks/bench_prepare.py impeller --spacing 0.175
      .venv/bin/python benchmarks/bench_prepare.py panel --spacing 0.6 --reach 2
      /usr/bin/time -v .venv/bin/python benchmarks/bench_prepare.py impeller --spacing 0.175
      .venv/bin/python benchmarks/bench_prepare.py impeller --spacing 0.35 --levels
"""

from __future__ import annotations

import argparse
import os
import time
import tracemalloc
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from shapeverify.nearest import dvg
from shapeverify.nearest import prepared as _prepared

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def load(name: str):
    """The benchmark models: ``impeller`` (shared data), ``panel`` (bundled example), a path."""
    from shapeverify import load_model

    if name == "impeller":
        cache = Path(os.environ.get("TMPDIR", "/tmp")) / "bench_prepare_impeller.svmodel"
        if cache.is_file():
            return load_model(cache)
        m = load_model(SHARED / "cad" / "impeller.igs")
        m.save(cache)
        return m
    if name == "panel":
        import tempfile

        from shapeverify.cad.examples import example_part_step
        with tempfile.TemporaryDirectory() as d:
            return load_model(example_part_step(Path(d) / "panel.step"))
    return load_model(name)


class Clock:
    """CPU and wall seconds of named stages."""

    def __init__(self, stage_peaks=False):
        self.rows: list[tuple[str, float, float, float]] = []
        self.stage_peaks = stage_peaks  # each stage's own peak RSS (VmHWM reset before it)
        self.peak = 0.0  # the largest of them, MiB

    def run(self, name, fn, *a, **kw):
        tracing = tracemalloc.is_tracing()
        if tracing:
            tracemalloc.reset_peak()
        if self.stage_peaks:
            self.peak = max(self.peak, _rss_kb("VmHWM") / 1024)
            _reset_peak_rss()
        c, w = time.process_time(), time.perf_counter()
        out = fn(*a, **kw)
        peak = tracemalloc.get_traced_memory()[1] / 2**20 if tracing else float("nan")
        self.rows.append((name, time.process_time() - c, time.perf_counter() - w, peak,
                          _rss_kb("VmRSS") / 1024, _rss_kb("VmHWM") / 1024))
        self.peak = max(self.peak, self.rows[-1][5])
        return out

    def table(self) -> str:
        tc = sum(r[1] for r in self.rows)
        tw = sum(r[2] for r in self.rows)
        lines = ["| stage | CPU s | share | wall s | peak MiB (tracemalloc) | RSS after, MiB "
                 f"| peak RSS {'in the stage' if self.stage_peaks else 'so far'} |",
                 "|---|---:|---:|---:|---:|---:|---:|"]
        for name, c, w, p, rss, hwm in self.rows:
            lines.append(f"| {name} | {c:.2f} | {100 * c / max(tc, 1e-9):.0f} % | {w:.2f} | "
                         f"{p:.0f} | {rss:.0f} | {hwm:.0f} |")
        lines.append(f"| **total** | **{tc:.2f}** | | {tw:.2f} | | | |")
        return "\n".join(lines)


def staged_prepare(model, spacing, reach, clock: Clock, finest=None,
                   mmap_threshold=_prepared.PREPARE_MMAP_THRESHOLD):
    """The steps of ``prepare`` one by one (same calls, same order, same result, the same
    arrays held, glibc's malloc held lean after the sampling)."""
    size = model.size
    h = float(spacing)
    maxd = _prepared.default_max_distance(size, h) if reach is None else float(reach)
    held = [clock.run("sample", model.sample, h, half_extents=False)]
    with _prepared.lean_malloc(mmap_threshold):
        return _staged_structure(model, held, h, maxd, clock, finest)


def _staged_structure(model, held, h, maxd, clock, finest):
    mp = held.pop()  # freed before the tree, as prepare does
    order = clock.run("order", dvg.morton_order, mp.points, h)
    pts = clock.run("points", lambda: np.ascontiguousarray(mp.points[order]))
    kd = clock.run("kd", cKDTree, pts)
    graph = clock.run("graph", dvg.neighbor_graph, pts, tree=kd, spacing=h)
    frames = clock.run("frames", _prepared._frames_from_graph, mp, order, pts, graph, h)
    rec = clock.run("records", dvg.make_records, pts, graph, frames)
    face = np.ascontiguousarray(mp.face[order])
    rows = np.empty((face.shape[0], 4), dtype=np.int32)  # prepare's rows and boundary
    rows[:, 0] = face
    rows.view(np.float32)[:, 1:3] = mp.uv[order]
    boundary = np.ascontiguousarray(mp.boundary[order])
    del mp, frames, graph, pts  # as prepare does: only the records are held during the tree
    _prepared.release_memory()
    _STEP_CLOCK[0] = time.process_time()
    tree = clock.run("tree", dvg.build_tree, rec, h, maxd, kd=kd,
                     finest=None if finest is None else finest * h)
    fast = dvg.DVG(rec, tree)
    fast._kd = kd
    if model.kind == "cad":
        rows[:, 3] = clock.run("other", _prepared._other_face_points, fast.points, face, h, kd)
    del rows, boundary
    return fast, maxd


def queries(pts, normals, h, reach, n, rng=0):
    """Fixed test queries: (random in the tree's box, scan-like: a model point moved sideways
    by up to half a spacing and along its normal by up to the reach)."""
    rng = np.random.default_rng(rng)
    lo, hi = pts.min(axis=0) - reach, pts.max(axis=0) + reach
    rand = rng.uniform(lo, hi, (n, 3))
    i = rng.integers(0, pts.shape[0], n)
    side = rng.uniform(-0.5 * h, 0.5 * h, (n, 3))
    side -= np.einsum("ij,ij->i", side, normals[i])[:, None] * normals[i]
    scan = pts[i] + side + normals[i] * rng.uniform(-reach, reach, n)[:, None]
    scan = scan[dvg.morton_order(scan, h)]  # scanner-like order
    return rand, scan


_STEP_CLOCK = [0.0]  # CPU seconds at the previous tree step (reset when the tree starts)


def _log_tree_steps():
    """Print each debug line of the tree build with the CPU seconds since the previous one
    (``time.process_time``: all threads) and the process' RSS (now and peak so far)."""
    import logging

    last = _STEP_CLOCK

    class Steps(logging.Handler):
        def emit(self, record):
            t = time.process_time()
            print(f"  tree +{t - last[0]:6.2f} s CPU, RSS {_rss_kb('VmRSS') / 1024:4.0f} MiB "
                  f"(peak {_rss_kb('VmHWM') / 1024:4.0f})  {record.getMessage()}", flush=True)
            last[0] = t

    lg = logging.getLogger("shapeverify.nearest.dvg_build")
    lg.setLevel(logging.DEBUG)
    lg.addHandler(Steps())
    lg.propagate = False


def _reset_peak_rss():
    """Reset the process' peak RSS (VmHWM) to its RSS now (Linux: /proc/self/clear_refs).
    ``/usr/bin/time -v``'s maximum then misses what came before the last reset."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        pass


def _rss_kb(field):
    """A field of /proc/self/status in kB (VmRSS: now, VmHWM: peak); nan elsewhere."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith(field + ":"):
                    return float(line.split()[1])
    except OSError:
        pass
    return float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("model", help="impeller | panel | a model file")
    ap.add_argument("--spacing", type=float, default=None)
    ap.add_argument("--reach", type=float, default=None)
    ap.add_argument("--finest", type=float, default=None,
                    help="finest tree cell in spacings (build_tree's default: 0.5)")
    ap.add_argument("--mmap-threshold", type=int, default=_prepared.PREPARE_MMAP_THRESHOLD,
                    help="glibc mmap threshold while preparing (prepared.lean_malloc)")
    ap.add_argument("--warm", action="store_true",
                    help="prepare at 8x the spacing first, so that the RSS before the measured "
                         "preparation holds the loaded numba kernels")
    ap.add_argument("--peak", action="store_true", help="tracemalloc peak (slower)")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--queries", type=int, default=200_000)
    ap.add_argument("--save-answers", type=Path, default=None)
    ap.add_argument("--compare", type=Path, default=None)
    ap.add_argument("--stage-peaks", action="store_true",
                    help="each stage's own peak RSS (VmHWM reset before each stage; the peak "
                         "printed is the largest; /usr/bin/time -v's maximum is then wrong)")
    ap.add_argument("--levels", action="store_true",
                    help="print the tree's steps (per level: classification, multi-seed pass, "
                         "seed-list packing, candidate lists) with their CPU seconds and RSS")
    args = ap.parse_args()
    if args.levels:
        _log_tree_steps()
    from shapeverify.nearest import set_workers
    set_workers(args.workers)
    model = load(args.model)
    h = _prepared.default_spacing(model.size) if args.spacing is None else args.spacing
    if args.warm:  # every kernel loaded (as in a service that prepared a model before)
        staged_prepare(model, 8 * h, args.reach, Clock())
    if args.peak:
        tracemalloc.start()
    clock = Clock(args.stage_peaks)
    load_avg = os.getloadavg()[0]
    rss0 = _rss_kb("VmRSS")
    fast, maxd = staged_prepare(model, h, args.reach, clock, args.finest, args.mmap_threshold)
    peak = tracemalloc.get_traced_memory()[1] if args.peak else None
    if args.peak:
        tracemalloc.stop()
    result = fast.nbytes + fast.n_points * 17  # + rows (16 B) and boundary flag (1 B)
    print(f"{args.model}: {fast.n_points:,} model points, spacing {h:g} mm, reach {maxd:g} mm, "
          f"load average {load_avg:.1f} on {os.cpu_count()} cores, workers {args.workers}")
    print(repr(fast.tree))
    print(clock.table())
    hwm = max(_rss_kb("VmHWM"), 1024 * clock.peak)
    print(f"RSS before preparing (Python, imports, model{', kernels' if args.warm else ''}) "
          f"{rss0 / 1024:.0f} MiB, peak RSS "
          f"{hwm / 1024:.0f} MiB: {(hwm - rss0) / 1024:.0f} MiB above = "
          f"{(hwm - rss0) * 1024 / result:.2f}x the result")
    print(f"result {result / 2**20:.1f} MiB" + (
        f", tracemalloc peak {peak / 2**20:.1f} MiB ({peak / result:.2f}x the result)"
        if peak else ""))
    if args.save_answers or args.compare:
        pts = np.ascontiguousarray(fast.points)
        nrm = fast.frames()[:, 0:3]
        rand, scan = queries(pts, nrm, h, maxd, args.queries)
        kd = cKDTree(pts)
        out = {}
        for name, q in (("random", rand), ("scan", scan)):
            idx, dist = fast.nearest(q)
            d_true, _ = kd.query(q, workers=-1)
            inside = d_true <= maxd
            right = dist <= d_true * (1 + 1e-12) + 1e-12
            print(f"{name}: {q.shape[0]:,} queries, {int(inside.sum()):,} within the reach; "
                  f"exact nearest distance for {right[inside].mean():.6f} of them "
                  f"({int((~right[inside]).sum())} not), largest excess "
                  f"{np.max(dist - d_true):.3g} mm")
            out[name] = idx
        tree = {"nodes": fast.tree.nodes, "lists": fast.tree.lists}
        if args.save_answers:
            np.savez(args.save_answers, **out, **tree)
        if args.compare:
            ref = np.load(args.compare)
            for name, idx in out.items():
                same = ref[name] == idx
                print(f"{name}: identical to {args.compare}: {same.mean():.6f} "
                      f"({int((~same).sum())} differ)")
            for name, arr in tree.items():  # the tree arrays themselves
                if name in ref.files:
                    print(f"tree {name}: identical to {args.compare}: "
                          f"{bool(np.array_equal(ref[name], arr))} ({arr.size:,} entries)")


if __name__ == "__main__":
    main()
