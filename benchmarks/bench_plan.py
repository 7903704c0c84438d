"""What an inspection plan costs: ``inspect(plan=...)`` against the same inspection without one,
in one process, CPU seconds (``time.process_time``, all threads), and their ratio (issue 27
item 5: at most 2).

* panel: the bundled example (``shapeverify.cad.examples``) scanned as ``shapeverify demo``
  scans it (pixel 1.2 mm, 0.02 mm noise, a shadow, a blob, 5 % outliers, a 0.4 mm dent, 4 deg /
  8 mm off); plan: best fit, the hole (diameter, position), the skin's profile, a check point;
  tolerance 0.2 mm.
* CTC 01 (``../shared/data/cad/nist/nist_ctc_01_asme1_rd.stp``): about 800k points from
  OpenCASCADE's tessellation sampled uniformly by area, 0.02 mm noise along the normal, a random
  pose; plan: datums (face:3, hole:9, hole:10), profile of all faces (0.1), flatness of the top
  (0.1); tolerance 0.05 mm (half the profile's zone, as ``inspect --plan`` sets it).

Each inspection runs once to warm up (numba, the exact-closest tables, the global search's model
side), then ``--repeat`` times each, alternating; the medians are printed.

Run:  .venv/bin/python benchmarks/bench_plan.py [--parts panel ctc01] [--repeat 1]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
CTC01 = HERE.parents[1] / "shared" / "data" / "cad" / "nist" / "nist_ctc_01_asme1_rd.stp"
sys.path.insert(0, str(HERE.parent / "tests"))


def panel(cache: Path):
    import shapeverify as sv
    from shapeverify.cad.examples import PANEL_HOLE, example_part_step
    from shapeverify.simulate import ScanEffects, virtual_scan

    svm = cache / "panel.svm"
    if not svm.exists():
        sv.prepare(sv.load_model(example_part_step(cache / "panel.step"))).save(svm)
    prep = sv.load_prepared(svm)
    sim = virtual_scan(prep.model, pixel=1.2, noise=0.02, motion=(4.0, 8.0), rng=2011,
                       effects=ScanEffects(shadows=1, blobs=1, outlier_fraction=0.05,
                                           dents=[(0.4, 15.0)]))
    x, y, _ = PANEL_HOLE
    plan = {"alignment": {"type": "best_fit"}, "characteristics": [
        {"name": "H1", "type": "hole", "near": [x, y, 0], "diameter": {"tol": 0.5},
         "position": {"tol": 0.6}},
        {"name": "SKIN", "type": "surface_profile", "faces": "all", "tol": 0.4},
        {"name": "BUMP", "type": "check_point", "at": [150, 100, 0], "tol": 0.2}]}
    return prep, sim.scan, plan, 0.2


def ctc01(cache: Path, n: int = 800_000):
    import shapeverify as sv
    from test_plan_nist import _occ_mesh, _scan

    svm = cache / "ctc01.svm"
    if not svm.exists():
        sv.prepare(sv.load_model(CTC01)).save(svm)
    prep = sv.load_prepared(svm)
    V, T = _occ_mesh(CTC01)
    scan, _ = _scan(V, T, n, 0.02, 0)
    plan = {"alignment": {"type": "datums", "primary": "face:3", "secondary": "hole:9",
                          "tertiary": "hole:10"}, "characteristics": [
        {"name": "PROFILE", "type": "surface_profile", "faces": "all", "tol": 0.1},
        {"name": "FLAT_TOP", "type": "flatness", "feature": "face:3", "tol": 0.1}]}
    return prep, scan, plan, 0.05


def run(name, prep, scan, plan, tol, repeat):
    import shapeverify as sv

    def once(p):
        t = time.process_time()
        res = sv.inspect(prep, scan, tolerance=tol, plan=p)
        return time.process_time() - t, res

    once(None), once(plan)                                  # warm-up
    free, with_plan, res = [], [], None
    for _ in range(repeat):
        free.append(once(None)[0])
        dt, res = once(plan)
        with_plan.append(dt)
    f, p = statistics.median(free), statistics.median(with_plan)
    print(f"{name}: {scan.shape[0]:,} points; without plan {f:.2f} s CPU, with plan {p:.2f} s CPU,"
          f" ratio {p / f:.2f}; plan verdict {res.verdict}")
    for c in res.characteristics:
        m = c.measured["diameter"] if isinstance(c.measured, dict) else c.measured
        print(f"    {c.name}: {m} {c.verdict}")
    al = res.plan.alignment
    print(f"    alignment {al.kind}: converged {al.details.get('converged', True)}, "
          f"warnings {al.details.get('warnings', [])}")
    return f, p


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--parts", nargs="+", default=["panel", "ctc01"])
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--cache", default="/tmp/shapeverify-bench-plan")
    a = ap.parse_args()
    cache = Path(a.cache)
    cache.mkdir(parents=True, exist_ok=True)
    print("load:", os.getloadavg())
    for part in a.parts:
        if part == "ctc01" and not CTC01.exists():
            print("ctc01: ../shared/data not present, skipped")
            continue
        run(part, *(panel(cache) if part == "panel" else ctc01(cache)), a.repeat)
    print("load:", os.getloadavg())


if __name__ == "__main__":
    main()
