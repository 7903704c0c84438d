"""The cost and the coverage of the datums' noise in U (:mod:`.datum_noise`, issue 28).

A NIST part's whole plan (``pmi_plan``, as ``shapeverify plan`` writes it) evaluated on
independent perfect scans (OpenCASCADE's tessellation sampled by area at ``--spacing``,
0.02 mm noise along the normal, random order; tests/independent_scans.py), the alignment
started at the true pose.  Per scan: the plan's evaluation time (CPU and wall, alignment
apart) and each characteristic's value, U, verdict and datum part; at the end the
characteristics' CPU per type and the (characteristic, seed) with value > U among those with
a zone from 0 (a perfect part's value is all error).

Run from the worktree root, once per code version to compare (the same command)::

    PYTHONPATH=$PWD/src python benchmarks/bench_datum_noise.py ftc10 --seeds 0 1 2
    PYTHONPATH=/work/main/src python benchmarks/bench_datum_noise.py ftc10 --seeds 0 1 2

``--profile FILE`` writes cProfile's statistics of the evaluations.
"""
from __future__ import annotations

import argparse
import cProfile
import gzip
import json
import shutil
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

PARTS = {"ftc10": "nist_ftc_10_asme1_ap242-e2.stp.gz",
         "ctc03": "nist_ctc_03_asme1_ap242-e2.stp.gz",
         "ctc03e1": "nist_ctc_03_asme1_ap242-e1.stp.gz"}


def _path(part: str) -> Path:
    gz = ROOT / "tests" / "data" / "nist_extra" / PARTS[part]
    out = Path(tempfile.gettempdir()) / "bench_datum_noise" / gz.name[:-3]
    if not out.exists():
        out.parent.mkdir(parents=True, exist_ok=True)
        with gzip.open(gz, "rb") as src, open(out, "wb") as dst:
            shutil.copyfileobj(src, dst)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("part", choices=sorted(PARTS))
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--spacing", type=float, default=1.0)
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--profile")
    ap.add_argument("--json")
    a = ap.parse_args(argv)

    import yaml

    import shapeverify
    from independent_scans import file_tessellation, random_points
    from model_cache import cached_prepared
    from nist_plans import cached_pmi_plan
    from shapeverify.characteristics import evaluate_plan, registry

    path = _path(a.part)
    data = dict(cached_pmi_plan(path).data)
    data.pop("unsupported", None)
    plan = yaml.safe_dump(data)
    prep = cached_prepared(path, spacing=a.spacing, features=True)
    V, T, _ = file_tessellation(path, 0.002)
    cpu_type = defaultdict(float)
    orig = registry.evaluator

    def timed(name):
        fn = orig(name)

        def run(c, ctx):
            t = time.process_time()
            try:
                return fn(c, ctx)
            finally:
                cpu_type[name] += time.process_time() - t
        return run

    registry.evaluator = timed
    prof = cProfile.Profile() if a.profile else None
    rows, runs = [], []
    print(f"{a.part} ({path.name}), shapeverify from {Path(shapeverify.__file__).parent}")
    for seed in a.seeds:
        rng = np.random.default_rng(seed)
        P, N = random_points(V, T, a.spacing, rng)
        X = (P + rng.normal(0.0, a.noise, len(P))[:, None] * N)[rng.permutation(len(P))]
        c0, w0 = time.process_time(), time.perf_counter()
        if prof:
            prof.enable()
        res = evaluate_plan(prep, X, plan, init=np.eye(4))
        if prof:
            prof.disable()
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        runs.append({"seed": seed, "cpu": cpu, "wall": wall, **res.timings})
        print(f"seed {seed}: {len(X)} points, evaluate_plan {cpu:.1f} s CPU, {wall:.1f} s wall "
              f"(alignment {res.timings['alignment']:.1f} s, characteristics "
              f"{res.timings['characteristics']:.1f} s wall)")
        for c in res.characteristics:
            m, u = c.measured, c.uncertainty
            if isinstance(m, dict) or m is None or u is None:
                continue
            ud = (c.details or {}).get("u_datums")
            rows.append({"seed": seed, "name": c.name, "type": c.type, "value": float(m),
                         "U": float(u), "u_datums": ud, "verdict": c.verdict})
            flag = " <-- value > U" if float(m) > float(u) else ""
            print(f"  {c.name:34s} {c.type:22s} {float(m):9.4f} U {float(u):7.4f} "
                  f"(datums {'-' if ud is None else f'{ud:.4f}'}) {c.verdict}{flag}")
    print("characteristics' CPU per type (all seeds):",
          {k: round(v, 2) for k, v in sorted(cpu_type.items(), key=lambda kv: -kv[1])})
    zone = [r for r in rows if r["type"] in ZONE_FROM_ZERO]
    over = [r for r in zone if r["value"] > r["U"]]
    print(f"mean evaluate_plan CPU {np.mean([r['cpu'] for r in runs]):.1f} s; "
          f"characteristics wall {np.mean([r['characteristics'] for r in runs]):.1f} s")
    print(f"value > U: {len(over)}/{len(zone)} ({100 * len(over) / max(len(zone), 1):.1f} %) "
          f"of (characteristic, seed) with a zone from 0; verdicts: "
          f"{dict(sorted(_count(r['verdict'] for r in rows).items()))}")
    per = defaultdict(int)
    for r in over:
        per[r["name"]] += 1
    if per:
        print("  by characteristic:", dict(sorted(per.items(), key=lambda kv: -kv[1])))
    if prof:
        prof.dump_stats(a.profile)
    if a.json:
        Path(a.json).write_text(json.dumps({"runs": runs, "rows": rows}, indent=1))


def _count(it):
    out = defaultdict(int)
    for x in it:
        out[x] += 1
    return out


#: a perfect part's value of these is all error (noise, datums): value > U is a miss of U
ZONE_FROM_ZERO = {"position", "position_zone", "surface_profile", "line_profile",
                  "orientation", "perpendicularity", "parallelism", "angularity", "symmetry",
                  "concentricity", "flatness", "straightness", "circularity", "cylindricity",
                  "circular_runout", "total_runout"}

if __name__ == "__main__":
    main()
