"""What the missing-material rule (on by default, issue 33 row 3) costs on the demo's inspection,
and that it does not change the demo's verdict.

The demo's panel and scan (``shapeverify.demo``: the example panel, default spacing; the virtual
scan with noise, a shadow, a reflection blob, 5 % outliers, a 0.4 mm dent, a 4 degree / 8 mm
fixture misalignment), inspected at +-0.2 mm with ``missing=True`` (the default) and
``missing=False``; CPU seconds of the whole inspection (``time.process_time``) and the
wall seconds of ``find_missing`` alone, medians of ``--repeat`` runs.

Run:  PYTHONPATH=src .venv/bin/python benchmarks/bench_missing.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args(argv)
    import tempfile
    from pathlib import Path

    import shapeverify as sv
    from shapeverify.cad.examples import example_part_step
    import importlib

    insp = importlib.import_module("shapeverify.inspection.inspect")
    from shapeverify.simulate import ScanEffects, virtual_scan

    d = Path(tempfile.mkdtemp())
    model = sv.load_model(example_part_step(d / "panel.step"))
    prep = sv.prepare(model)
    sim = virtual_scan(model, pixel=1.2, noise=0.02, motion=(4.0, 8.0), rng=2011,
                       effects=ScanEffects(shadows=1, blobs=1, outlier_fraction=0.05,
                                           dents=[(0.4, 15.0)]))
    scan = sim.scan
    spent = []
    real = insp.find_missing

    def timed(*args, **kw):
        t0 = time.perf_counter()
        try:
            return real(*args, **kw)
        finally:
            spent.append(time.perf_counter() - t0)

    insp.find_missing = timed
    out = {}
    for missing in (True, False, True, False):   # warm both first
        cpu = []
        spent.clear()
        for _ in range(a.repeat):
            t0 = time.process_time()
            res = sv.inspect(prep, scan, tolerance=0.2, missing=missing)
            cpu.append(time.process_time() - t0)
        out[missing] = (res, float(np.median(cpu)), float(np.median(spent)) if spent else 0.0)
    insp.find_missing = real
    for missing, (res, cpu, fm) in out.items():
        kinds = [r.kind for r in res.regions]
        print(f"missing={missing!s:5}: verdict {res.verdict}, rule {res.rule}, regions {kinds}; "
              f"inspection {cpu:.3f} s CPU (median of {a.repeat}); find_missing {1e3 * fm:.1f} ms")
    assert out[True][0].verdict == out[False][0].verdict


if __name__ == "__main__":
    main()
