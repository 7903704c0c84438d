"""CPU time of ``find_regions`` (defect regions and measurement outliers) on fixed inputs.

Cases (the deviations are computed once, saved, and only ``find_regions`` is timed, so two
versions of the code can be compared on the same numbers):

* ``panel200k``: the bundled example panel (300 x 200 mm), 200,000 points drawn uniformly by
  area on OpenCASCADE's tessellation (``tests/independent_scans.py``, about 0.55 mm apart), a
  ``cos^2`` dent of radius 15 mm and depth -0.5 mm, noise 0.02 mm, tolerance +-0.2 mm,
  inspected at the true pose;
* ``demo``: the scan of ``make demo`` (``virtual_scan`` of the panel: pixel 1.2 mm, noise
  0.02 mm, a shadow, a reflection blob, 5 % outliers, a 0.4 mm dent), inspected at its true
  pose, tolerance +-0.2 mm.

``--make DIR`` writes the inputs (``DIR/<case>.npz``); ``--time DIR`` times ``find_regions`` on
them (median CPU of ``--repeat`` calls after one warm-up call; ``time.process_time``) with the
``shapeverify`` first on ``PYTHONPATH`` and prints a digest of the answer (to compare versions);
``--profile N`` prints the N functions of most inclusive CPU of one call.

Run:  PYTHONPATH=src .venv/bin/python benchmarks/bench_regions.py --make /tmp/bench_regions
      PYTHONPATH=src .venv/bin/python benchmarks/bench_regions.py --time /tmp/bench_regions
"""
from __future__ import annotations

import argparse
import hashlib
import sys
import time
import types
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))


def _identity():
    return types.SimpleNamespace(T_model_scan=np.eye(4), rms=0.0, iterations=1, converged=True,
                                 inlier_fraction=1.0)


def _capture(prep, P, T, tol, out: Path):
    """Inspect ``P`` at pose ``T`` and save the inputs ``find_regions`` was called with."""
    import importlib

    from shapeverify.inspection import inspect_registered

    mod = importlib.import_module("shapeverify.inspection.inspect")
    orig, cap = mod.find_regions, {}

    def spy(*a, **k):
        cap["a"], cap["k"] = a, k
        return orig(*a, **k)

    mod.find_regions = spy
    try:
        reg = _identity()
        reg.T_model_scan = T
        inspect_registered(prep, P, reg, tolerance=tol)
    finally:
        mod.find_regions = orig
    a, k = cap["a"], cap["k"]
    search = k.get("search")         # RegionSearch since a35b7a6; loose keywords before
    min_points = search.min_points if search is not None else k["min_points"]
    spacing = search.spacing if search is not None else k["spacing"]
    np.savez(out, points=a[0], values=a[1], evaluated=a[2], within=a[3], face=a[4], normals=a[5],
             min_points=min_points, spacing=spacing, lo=k["limits"][0], hi=k["limits"][1])


def make(folder: Path):
    import independent_scans as ind
    import shapeverify as sv
    from shapeverify.cad.examples import example_part_step
    from shapeverify.simulate import virtual_scan

    folder.mkdir(parents=True, exist_ok=True)
    path = example_part_step(folder / "panel.step")
    model = sv.load_model(path)
    prep = sv.prepare(model)
    V, T, F = ind.tessellate(ind.read_shape(path), 2e-5 * prep.model.size)
    area = 0.5 * np.linalg.norm(np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]]), axis=1)
    T, F = T[area > 0], F[area > 0]
    rng = np.random.default_rng(0)
    site = ind.dent_site(V, T, F, 15.0)
    s = np.sqrt(area.sum() / 200_000)
    P = ind.scan(V, T, "random", s, rng, noise=0.02, dents=[(site, -0.5, 15.0)])
    _capture(prep, P, np.eye(4), 0.2, folder / "panel200k.npz")
    sim = virtual_scan(model, pixel=1.2, noise=0.02, shadows=1, blobs=1, outlier_fraction=0.05,
                       dents=[(0.4, 15.0)], motion=(4.0, 8.0), rng=2011)
    _capture(prep, sim.scan, sim.T_model_scan, 0.2, folder / "demo.npz")


def call(f):
    from shapeverify.inspection import regions

    args = (f["points"], f["values"], f["evaluated"], f["within"], f["face"], f["normals"], None)
    if not hasattr(regions, "RegionSearch"):             # versions before a35b7a6
        return regions.find_regions(*args, limits=(f["lo"], f["hi"]),
                                    min_points=int(f["min_points"]), spacing=float(f["spacing"]))
    return regions.find_regions(*args, limits=(f["lo"], f["hi"]),
                                search=regions.RegionSearch(min_points=int(f["min_points"]),
                                                            spacing=float(f["spacing"])))


def digest(regions, outliers) -> str:
    h = hashlib.sha256()
    for r in regions:
        h.update(np.asarray(r.indices, np.int64).tobytes())
        h.update(np.array([r.area, r.extreme, r.extreme_raw, r.severity, *r.centroid,
                           *r.extreme_point]).tobytes())
    h.update(np.asarray(outliers.indices, np.int64).tobytes())
    return h.hexdigest()[:16]


def time_cases(folder: Path, repeat: int, profile: int):
    import shapeverify

    print(f"shapeverify from {Path(shapeverify.__file__).parent}")
    for case in ("panel200k", "demo"):
        f = dict(np.load(folder / f"{case}.npz"))
        regions, outliers, _ = call(f)            # warm-up: numba, lazy imports
        cpu = []
        for _ in range(repeat):
            t0 = time.process_time()
            regions, outliers, _ = call(f)
            cpu.append(time.process_time() - t0)
        n_out = int(np.count_nonzero(f["evaluated"] & ~f["within"]))
        print(f"{case}: {int(f['evaluated'].sum())} evaluated, {n_out} out of tolerance; "
              f"find_regions CPU median {np.median(cpu):.3f} s (min {min(cpu):.3f}, {repeat} calls); "
              f"{len(regions)} regions {[(r.n, round(r.area, 2), round(r.extreme, 4)) for r in regions]}, "
              f"{outliers.n} outliers; digest {digest(regions, outliers)}", flush=True)
        if profile:
            import cProfile
            import pstats
            pr = cProfile.Profile(time.process_time)
            pr.enable()
            call(f)
            pr.disable()
            pstats.Stats(pr).sort_stats("cumulative").print_stats(profile)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--make", type=Path)
    ap.add_argument("--time", type=Path)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--profile", type=int, default=0)
    args = ap.parse_args()
    if args.make:
        make(args.make)
    if args.time:
        time_cases(args.time, args.repeat, args.profile)


if __name__ == "__main__":
    main()
