"""Scan points on NIST FTC 10's supplemental faces (``characteristics/supplemental_points.py``):
how many a perfect scan of the whole file has found, the profile GT10 (1.5 mm, faces 177-180)
on it and with a bump on each of its faces, and the CPU time of ``on_supplemental``.

    PYTHONPATH=src python benchmarks/check_supplemental_points.py [--against OLD.py]
        [--heights 1.0 1.5]

``--against`` runs another version of ``supplemental_points.py`` beside (e.g. ``git show
HEAD~1:src/shapeverify/characteristics/supplemental_points.py > /tmp/old_supp.py``).  The scan
is the one of ``tests/test_scan_points_on_supplemental_geometry.py`` (OpenCASCADE's
tessellation of the whole file at 0.002 mm, 1 point/mm^2 at random, seed 0, noise 0.02 mm);
a bump is ``h cos^2(pi r / 6)`` (6 mm across) along the normal at the middle of the face.
"""
from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
NOISE = 0.02


def scan(tmp: Path):
    sys.path.insert(0, str(ROOT / "tests"))
    from nist_plans import ftc10_gt10_scan

    prep, X, _, truth, plan = ftc10_gt10_scan(tmp, NOISE)
    return prep, X, truth, plan


def bumped(prep, X, cl, face, height):
    on = (np.asarray(cl.face) == face) & (np.abs(np.asarray(cl.distances)) < 0.3)
    mid = X[on].mean(axis=0)
    c0 = X[on][np.argmin(np.linalg.norm(X[on] - mid, axis=1))]
    r = np.linalg.norm(X - c0, axis=1)
    b = on & (r < 3.0)
    Y = X.copy()
    Y[b] += (height * np.cos(np.pi * r[b] / 6.0) ** 2)[:, None] * np.asarray(cl.normals)[b]
    return Y


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--against", help="another supplemental_points.py to run beside")
    ap.add_argument("--heights", type=float, nargs="*", default=[1.0, 1.5])
    a = ap.parse_args()
    from shapeverify.characteristics import evaluate, evaluate_plan, supplemental_points

    rules = {"this": supplemental_points}
    if a.against:
        spec = importlib.util.spec_from_file_location(
            "shapeverify.characteristics._supp_against", a.against)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        rules["against"] = mod
    tmp = Path("/tmp/check_supplemental_points")
    tmp.mkdir(exist_ok=True)
    prep, X, truth, plan = scan(tmp)
    cl = prep.closest(X, exact=True)
    d = np.asarray(cl.distances, np.float64)
    near = np.isfinite(d) & (np.abs(d) <= 3.0)
    want = truth & near & (np.abs(d) >= 0.3)
    for name, mod in rules.items():
        times = []

        def timed(*args, _f=mod.on_supplemental, **kw):
            c0, w0 = time.process_time(), time.perf_counter()
            out = _f(*args, **kw)
            times.append((time.process_time() - c0, time.perf_counter() - w0))
            return out

        mod._LAST.clear()
        evaluate.on_supplemental = timed
        found = timed(prep.model, X, d, near, float(prep.model_spacing), NOISE)
        print(f"{name:8s} direct (|d| <= 3 mm, noise {NOISE}): found {found.sum()}, on the part "
              f"{(found & ~truth).sum()}, supplemental points 0.3-3 mm off found "
              f"{found[want].sum()}/{want.sum()}; cpu {times[0][0]:.3f} s (wall "
              f"{times[0][1]:.3f}) cold", flush=True)
        timed(prep.model, X, d, near, float(prep.model_spacing), NOISE)
        print(f"{name:8s} direct again: cpu {times[-1][0]:.3f} s (wall {times[-1][1]:.3f}) "
              "warm", flush=True)
        c, = evaluate_plan(prep, X, plan, init=np.eye(4)).characteristics
        print(f"{name:8s} perfect: GT10 {c.measured:.3f} {c.verdict}, on_supplemental_geometry "
              f"{c.details['excluded']['on_supplemental_geometry']}; cpu "
              f"{times[-1][0]:.3f} s (wall {times[-1][1]:.3f})", flush=True)
        for h in a.heights:
            for face in (177, 178, 179, 180):
                c, = evaluate_plan(prep, bumped(prep, X, cl, face, h), plan,
                                   init=np.eye(4)).characteristics
                print(f"{name:8s} bump {h:.2f} mm face {face}: GT10 {c.measured:.3f} "
                      f"{c.verdict}, on_supplemental_geometry "
                      f"{c.details['excluded']['on_supplemental_geometry']}, unsupported "
                      f"{c.details['excluded']['unsupported_outliers']}; cpu "
                      f"{times[-1][0]:.3f} s", flush=True)
        evaluate.on_supplemental = supplemental_points.on_supplemental


if __name__ == "__main__":
    main()
