"""Verdicts on a near-symmetric prismatic part seen from a sensor's frame: the bundled chamfered
plate (100 x 60 x 5 mm, one corner chamfered 6 mm: only the chamfer tells its ends apart).

Six views from above (random directions, z >= 0.7), each a virtual scan (pixel 0.5 mm, noise
0.02 mm) given in a frame 120 deg / 300 mm away, inspected at +-0.1 mm as scanned ("good":
should pass) and with a 0.5 mm dent of radius 8 mm ("dent": should fail), with no start pose.
Printed per view: the verdict, its rule, the pose error against the truth (a 180 deg error
with the deviations at the noise is the turned copy: as good for a part that shows no
chamfer), the CPU time; once with the alternative poses of the registration tried
(``Registration.alternatives``, :mod:`shapeverify.inspection.ambiguity`) and once without.

Run:  .venv/bin/python benchmarks/check_symmetric_plate.py [--views 6] [--out FILE]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--views", type=int, default=6)
    ap.add_argument("--out", default=str(Path(__file__).with_name("results_symmetric.md")))
    args = ap.parse_args()

    from shapeverify import inspect
    from shapeverify.cad.examples import chamfered_plate_step
    from shapeverify.cad.load import load_model
    from shapeverify.nearest import prepare
    from shapeverify.simulate import ScanEffects, virtual_scan

    module = sys.modules["shapeverify.inspection.inspect"]
    with_alternatives = module._at_alternatives
    model = load_model(chamfered_plate_step(Path(tempfile.mkdtemp()) / "plate.step"))
    prep = prepare(model)
    load0 = os.getloadavg()[0]
    rows, tally = [], {}
    for mode in ("without alternatives", "with alternatives"):
        module._at_alternatives = (with_alternatives if mode == "with alternatives"
                                   else (lambda prep, scan, result, *a: result))
        for s in range(args.views):
            rng = np.random.default_rng(s)
            v = rng.normal(size=3)
            v[2] = abs(v[2]) + 1.0
            v /= np.linalg.norm(v)
            for kind, dents in (("good", ()), ("dent", [(0.5, 8.0)])):
                vs = virtual_scan(model, view=v, pixel=0.5, noise=0.02, motion=(120.0, 300.0),
                                  rng=s, effects=ScanEffects(dents=dents))
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    t = time.process_time()
                    r = inspect(prep, vs.scan, tolerance=0.1)
                    dt = time.process_time() - t
                acc = vs.accuracy(r.registration.T_model_scan)
                want = "pass" if kind == "good" else "fail"
                tally.setdefault((mode, kind), []).append(str(r.verdict) == want)
                rows.append(f"| {mode} | {s} | {kind} | {len(vs.scan)} | {r.verdict} | {r.rule} | "
                            f"{acc.rotation_deg:.1f} / {acc.translation:.2f} | {dt:.2f} |")
                print(rows[-1], flush=True)
    module._at_alternatives = with_alternatives
    summary = [f"| {mode} | {kind} | {sum(ok)}/{len(ok)} |" for (mode, kind), ok in tally.items()]
    text = "\n".join([
        "## Verdicts on a near-symmetric part (the chamfered plate), from a sensor's frame",
        "",
        f"Command: `.venv/bin/python benchmarks/check_symmetric_plate.py --views {args.views}` "
        f"({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load average {load0:.1f} at the "
        "start on 2 cores).  Inputs and columns: see the script's docstring.",
        "",
        "| mode | scan | right verdict |",
        "|---|---|---|",
        *summary,
        "",
        "| mode | view | scan | points | verdict | rule | pose error deg / mm | CPU s |",
        "|---|---:|---|---:|---|---|---|---:|",
        *rows,
        ""])
    Path(args.out).write_text(text)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
