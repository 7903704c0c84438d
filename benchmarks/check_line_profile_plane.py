"""A profile of a line of one plane in a DRF (NIST CTC 02 e2 GT19, planned with sections
covering the face) on independent scans (as :mod:`check_nist_plans`): a perfect part, and the
face's points turned ``--tilt`` degrees about the in-plane axis across its sections' direction
through its centroid (the far ends move ``L/2 tan(tilt)``; CTC 02's face 18 also holds datum
C's target point, near the centroid, so a shift along the normal would move the DRF with it).

    PYTHONPATH=src:tests .venv/bin/python benchmarks/check_line_profile_plane.py --file /tmp/nist_ctc_02_asme1_ap242-e2.stp --spacing 2 --init
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
    ap.add_argument("--tilt", type=float, default=0.2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--init", action="store_true")
    a = ap.parse_args(argv)
    from independent_scans import random_points, read_shape, tessellate

    from shapeverify.cad.load import load_model
    from shapeverify.characteristics.features import model_features
    from shapeverify.characteristics.plan import load_plan
    from shapeverify.characteristics.pmi_plan import pmi_plan
    from shapeverify.nearest import prepare

    sys.stdout.reconfigure(line_buffering=True)
    prep = prepare(load_model(a.file))
    data = pmi_plan(a.file, model=prep.model).data
    plan = load_plan(data)
    c = next(c for c in data["characteristics"] if c["type"] == "line_profile"
             and "sections" in c["pmi"])
    g = face_ids(c["faces"])
    n = np.asarray(next(f.axis for f in model_features(prep.model) if f.id == f"face:{g[0]}"))
    V, T, F = tessellate(read_shape(a.file), DEFLECTION)
    rng = np.random.default_rng(a.seed)
    P, N, t = random_points(V, T, a.spacing, rng, with_triangles=True)
    face = F[t]
    P = P + rng.normal(0.0, NOISE, len(P))[:, None] * N
    from check_nist_plans import rotate_about

    Q = P.copy()
    sel = np.isin(face, g)
    axis = np.cross(n, np.asarray(c["normal"], float))
    Q[sel] = rotate_about(P[sel], P[sel].mean(axis=0), axis / np.linalg.norm(axis), a.tilt)
    L = float(np.ptp(P[sel] @ np.asarray(c["normal"], float)))
    print(f"{Path(a.file).name}: {len(P):,} points; {c['name']} faces {g} tol {c['tol']} "
          f"datums {c['datums']} sections {c['count']}")
    ends = 0.5 * L * np.tan(np.radians(a.tilt))
    for name, X in (("perfect", P), (f"face tilted {a.tilt} deg (ends +-{ends:.3f} mm)", Q)):
        rows, sec, al = inspect_case(prep, plan, X, np.random.default_rng(a.seed + 1), a.init)
        fails = [k for k, v in rows.items() if v["verdict"] != "pass"]
        print(f"\n{name} ({sec:.0f} s CPU): not passing: {fails or 'none'}")
        for k in dict.fromkeys([c["name"]] + fails):
            v = rows[k]
            print(f"  {k}: measured {_num(v['measured'])} limit {_num(v['upper'])} "
                  f"U {_num(v['uncertainty'])} -> {v['verdict']}")


if __name__ == "__main__":
    main()
