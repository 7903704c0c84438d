"""Does the datum part of U cover the real scatter? (issue 28, "How good")

Independent scans of one NIST part (as ``check_nist_plans.py`` makes them: OpenCASCADE's
tessellation, points uniform by area, 0.02 mm noise along the normal), one seed per scan
(sampling and noise both), inspected with the plan at the true pose.  Cases:

* ``perfect``: the part as modelled;
* ``tilt``: ``check_nist_plans.py``'s tilted face (0.2 deg);
* ``clean``, ``tilt-clean``: the same with no noise on the datum features' faces (the frame
  then rests on exact points: the value's scatter is its own part's alone; a characteristic
  of a datum face loses its own noise too).

Only the characteristics that name datums are evaluated (the others carry no datum part).
Every (seed, case, characteristic) row -- value, U, the datum part, the noise part -- is
appended to ``--out`` (JSON lines); ``--table`` summarises a file of rows: per characteristic
and case the values' mean and standard deviation, the mean U and datum part, and how often
``|value - true| <= U`` (true: 0 on ``perfect``/``clean``; the tilt's ``L tan 0.2 deg`` for
the tilted orientation tolerance).

Command::

    PYTHONPATH=src .venv/bin/python benchmarks/check_datum_u_coverage.py \\
        --file /tmp/nx/nist_ctc_05_asme1_ap242-e1.stp --seeds 0 1 2 --cases perfect tilt \\
        --out /tmp/datumu/rows.jsonl
    PYTHONPATH=src .venv/bin/python benchmarks/check_datum_u_coverage.py --table /tmp/datumu/rows.jsonl
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

import check_nist_plans as cnp  # noqa: E402


def _part(path, only=None):
    from independent_scans import read_shape, tessellate
    from model_cache import cached_prepared

    from shapeverify.characteristics.features import model_features
    from shapeverify.characteristics.plan import load_plan
    from shapeverify.characteristics.pmi_plan import pmi_plan

    prep = cached_prepared(path)
    data = pmi_plan(path, model=prep.model).data
    located = [c for c in data["characteristics"] if c.get("datums")
               and (not only or c["name"].split("_")[0] in only)]
    plan = load_plan({**data, "characteristics": located})
    feats = model_features(prep.model)
    V, T, F = tessellate(read_shape(path), cnp.DEFLECTION)
    return prep, data, plan, feats, (V, T, F)


def _datum_faces(data) -> set[int]:
    """Every datum feature's faces, a target's own face (``face``) too."""
    out = cnp.datum_faces(data)
    for d in (data.get("datums") or {}).values():
        for t in d.get("targets") or ():
            if isinstance(t, dict) and isinstance(t.get("face"), str):
                out |= set(cnp.face_ids([t["face"]]))
    return out


def _scan(tess, data, feats, spacing, seed, case):
    """(points in the model frame, defect) of one scan."""
    from independent_scans import random_points

    V, T, F = tess
    rng = np.random.default_rng(seed)
    P, N, t = random_points(V, T, spacing, rng, with_triangles=True)
    face = F[t]
    e = rng.normal(0.0, cnp.NOISE, len(P))
    if case in ("clean", "tilt-clean"):
        e[np.isin(face, sorted(_datum_faces(data)))] = 0.0
    P = P + e[:, None] * N
    defect = None
    if case in ("tilt", "tilt-clean"):
        name, i, c0, n, axis, ratio, L = cnp.tilt_candidates(data, feats, V, T, F)[0]
        sel = face == i
        P[sel] = cnp.rotate_about(P[sel], c0, axis, cnp.TILT)
        defect = {"characteristic": name, "face": int(i), "length": float(L),
                  "true": float(L * np.tan(np.radians(cnp.TILT)))}
    return P, defect


def _num(x):
    return float(x) if isinstance(x, (int, float, np.floating)) and x is not None else None


def run(path, seeds, cases, spacing, out, only=None):
    from shapeverify.characteristics import evaluate_plan

    prep, data, plan, feats, tess = _part(path, only)
    for seed in seeds:
        for case in cases:
            P, defect = _scan(tess, data, feats, spacing, seed, case)
            t0 = time.process_time()
            res = evaluate_plan(prep, P, plan, init=np.eye(4))
            sec = time.process_time() - t0
            print(f"seed {seed} {case}: {res.timings}", file=sys.stderr, flush=True)
            with open(out, "a") as fh:
                for c in res.characteristics:
                    d = c.details or {}
                    cd = c.to_dict()
                    true = 0.0
                    if defect and c.name == defect["characteristic"]:
                        true = defect["true"]
                    row = {"file": Path(path).name, "seed": seed, "case": case, "name": c.name,
                           "type": c.type, "value": _num(cd["measured"]), "U": _num(cd["uncertainty"]),
                           "upper": _num(cd["upper"]), "verdict": cd["verdict"], "true": true,
                           "u_datum": _num(d.get("u_datums", d.get("u_datum_axis"))),
                           "u_noise": _num(d.get("u_noise")), "cpu_s": sec}
                    fh.write(json.dumps(row) + "\n")
            print(f"seed {seed} {case}: {sec:.0f} s CPU", file=sys.stderr, flush=True)


def table(rows_path) -> str:
    rows = [json.loads(s) for s in Path(rows_path).read_text().splitlines() if s.strip()]
    groups = {}
    for r in rows:
        if r["value"] is None or r["U"] is None:
            continue
        groups.setdefault((r["case"], r["name"]), []).append(r)
    lines = ["| case | char | type | zone | n | true | mean value | sd value | mean U | "
             "mean datum part | 2 sd | |err| <= U | verdicts |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for (case, name), g in sorted(groups.items()):
        v = np.array([r["value"] for r in g])
        U = np.array([r["U"] for r in g])
        ud = np.array([r["u_datum"] or 0.0 for r in g])
        true = g[0]["true"]
        cov = int(np.sum(np.abs(v - true) <= U))
        vs = {}
        for r in g:
            vs[r["verdict"]] = vs.get(r["verdict"], 0) + 1
        lines.append(f"| {case} | {name} | {g[0]['type']} | {g[0]['upper']} | {len(g)} | "
                     f"{true:.3f} | {v.mean():.4f} | {v.std(ddof=1) if len(v) > 1 else 0:.4f} | "
                     f"{U.mean():.4f} | {ud.mean():.4f} | "
                     f"{2 * v.std(ddof=1) if len(v) > 1 else 0:.4f} | {cov}/{len(g)} | "
                     f"{', '.join(f'{k} {n}' for k, n in sorted(vs.items()))} |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--file")
    ap.add_argument("--seeds", type=int, nargs="*", default=[0])
    ap.add_argument("--cases", nargs="*", default=["perfect"],
                    choices=("perfect", "tilt", "clean", "tilt-clean"))
    ap.add_argument("--spacing", type=float, default=1.0)
    ap.add_argument("--only", nargs="*", help="characteristics (e.g. GT4 GT9), default all located")
    ap.add_argument("--out", help="JSON lines file to append to")
    ap.add_argument("--table", help="summarise a JSON lines file")
    a = ap.parse_args(argv)
    if a.table:
        print(table(a.table))
        return
    run(a.file, a.seeds, a.cases, a.spacing, a.out, a.only)


if __name__ == "__main__":
    main()
