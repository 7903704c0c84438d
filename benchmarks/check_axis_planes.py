"""A hole's axis in two parallel planes (``position`` ``zone: planes``), on independent scans
of NIST CTC 03 (the bundled e2 or e1): a perfect part, the ⌀38.1 hole moved ``--move`` mm
along the zone's direction (y: 'Position.8' must fail when 2 x move > 0.762) and the same
across it (x: it must pass; the ⌀2.032 'Position.6' of the same hole passes both while
2 x move < 2.032).  The scans as in :mod:`check_nist_plans` (OpenCASCADE tessellation, uniform
area sampling, 0.02 mm noise, random pose; ``--init``: the true pose given).

    PYTHONPATH=src .venv/bin/python benchmarks/check_axis_planes.py --file /tmp/nist_ctc_03_asme1_ap242-e2.stp
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from check_nist_plans import DEFLECTION, NOISE, _num, face_ids, inspect_case  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--file", required=True)
    ap.add_argument("--spacing", type=float, default=1.0)
    ap.add_argument("--move", type=float, default=0.5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--init", action="store_true")
    a = ap.parse_args(argv)
    from independent_scans import random_points, read_shape, tessellate

    from shapeverify.characteristics.plan import load_plan
    from shapeverify.characteristics.pmi_plan import pmi_plan

    from shapeverify.cad.load import load_model
    from shapeverify.characteristics.features import model_features
    from shapeverify.nearest import prepare

    prep = prepare(load_model(a.file))
    r = pmi_plan(a.file, model=prep.model)
    data = r.data
    plan = load_plan(data)
    target = [c for c in data["characteristics"]
              if c["type"] == "position" and c.get("zone") == "planes"]
    assert target, "no position with zone: planes in the plan"
    c = target[0]
    g = face_ids(c["features"])
    u = np.asarray(c["direction"], float)
    others = [k["name"] for k in data["characteristics"]
              if set(face_ids(k.get("features") or k.get("faces") or [])) & set(g)]
    V, T, F = tessellate(read_shape(a.file), DEFLECTION)
    rng = np.random.default_rng(a.seed)
    P, N, t = random_points(V, T, a.spacing, rng, with_triangles=True)
    face = F[t]
    P = P + rng.normal(0.0, NOISE, len(P))[:, None] * N
    axis = next(f.axis for f in model_features(prep.model) if f.id == f"face:{g[0]}")
    across = np.cross(u, np.asarray(axis, float))
    cases = [("perfect", P)]
    for label, d in (("along the zone direction", u), ("across it", across)):
        Q = P.copy()
        Q[np.isin(face, g)] += a.move * d / np.linalg.norm(d)
        cases.append((f"hole moved {a.move} mm {label}", Q))
    print(f"{Path(a.file).name}: {len(P):,} points; {c['name']} zone {c['tol']:.4f} normal "
          f"{u.tolist()}; characteristics of the hole: {others}")
    sys.stdout.reconfigure(line_buffering=True)
    for name, Q in cases:
        rows, sec, al = inspect_case(prep, plan, Q, np.random.default_rng(a.seed + 1), a.init)
        fails = [k for k, v in rows.items() if v["verdict"] != "pass"]
        print(f"\n{name} ({sec:.0f} s CPU, pose {al['rot_deg']:.4f} deg / "
              f"{al['trans_mm']:.4f} mm): not passing: {fails or 'none'}")
        for k in dict.fromkeys(others + fails + [r for r in rows if "position" in r]):
            v = rows[k]
            print(f"  {k}: measured {_num(v['measured'])} limit {_num(v['upper'])} "
                  f"U {_num(v['uncertainty'])} -> {v['verdict']}")


if __name__ == "__main__":
    main()
