"""Benchmark: a turned part from STEP to pose with no start (issue 14 items 1, 3 and 4).

Input: the turned example part (``shapeverify.cad.examples.turned_part_step``: a stepped shaft
with a bore, a groove and five 1.5 mm fillets, 15 faces, 127 mm) written to STEP.

1. *Preparation*: ``load_model`` (wall, with the importer process) and ``prepare`` (CPU) at the
   default spacing and at ``size / 500`` (the default before the spacing followed the geometry).
2. *Pose from the sensor frame*: ``--views`` virtual scans (pixel 0.3 mm, noise ``--noise``
   0.015 mm, ``--outliers`` 2 %) from random view directions, each moved by a random rotation and a translation of
   up to 800 mm (seeded), registered with no start.  Right: the scan's points lie on the part
   (median exact distance < 0.05 mm) and the part's axis is recovered (tilt < 0.05 deg); the
   spin about the axis is free (the deviations do not depend on it).  Peer: Open3D FPFH +
   RANSAC + point-to-plane ICP with the settings of ``bench_global.py`` (when open3d is
   installed: the ``bench`` extra).  One thread.

Run:  .venv/bin/python benchmarks/bench_turned.py [--views 10] [--noise 0.015] [--outliers 0.02]
      [--out benchmarks/results_turned.md]
"""
from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import datetime  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

from shapeverify.cad.examples import turned_part_step  # noqa: E402
from shapeverify.cad.load import load_model  # noqa: E402
from shapeverify.nearest import prepare  # noqa: E402
from shapeverify.nearest.prepared import default_spacing  # noqa: E402
from shapeverify.registration import register  # noqa: E402
from shapeverify.simulate import ScanEffects, virtual_scan  # noqa: E402


def judge(prep, scan, T, T_true):
    """(right, median |d| mm, axis tilt deg) of the pose T."""
    d = np.abs(prep.closest(scan @ T[:3, :3].T + T[:3, 3], exact=True).distances)
    D = T @ np.linalg.inv(T_true)
    tilt = float(np.degrees(np.arccos(np.clip((D[:3, :3] @ [0, 0, 1.0])[2], -1, 1))))
    med = float(np.median(d))
    return med < 0.05 and tilt < 0.05, med, tilt


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--views", type=int, default=10)
    ap.add_argument("--noise", type=float, default=0.015, help="scan noise (mm, standard deviation)")
    ap.add_argument("--outliers", type=float, default=0.02, help="share of outliers in each scan")
    ap.add_argument("--out", default=str(Path(__file__).with_name("results_turned.md")))
    args = ap.parse_args()
    load = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    lines = []

    def say(txt=""):
        print(txt, flush=True)
        lines.append(txt)

    step = turned_part_step(Path(tempfile.mkdtemp()) / "turned.step")
    w = time.perf_counter()
    model = load_model(step)
    t_load = time.perf_counter() - w
    say(f"turned part: {len(model.faces)} faces, size {model.size:.1f} mm, load {t_load:.2f} s wall "
        "(OpenCASCADE import and NURBS conversion in the importer process)")
    say()
    say("| spacing | model points | prepare CPU (s) |")
    say("|---|---:|---:|")
    preps = {}
    for name, h in (("size / 500 (before)", default_spacing(model.size)), ("default", None)):
        c = time.process_time()
        prep = prepare(model, spacing=h)
        say(f"| {name}: {prep.spacing:.4g} mm | {prep.n_points:,} | {time.process_time() - c:.1f} |")
        preps[name] = prep
    prep = preps["default"]
    try:
        import open3d as o3d

        from bench_global import Open3DGlobal
        peer = Open3DGlobal(o3d, prep)
    except ImportError as exc:
        peer = None
        say(f"\n(Open3D peer not run: {exc}; install the bench extra)")
    say()
    rows = []
    rng = np.random.default_rng(11)
    for k in range(args.views):
        view = rng.normal(size=3)
        M = np.eye(4)
        M[:3, :3] = Rotation.random(random_state=100 + k).as_matrix()
        M[:3, 3] = rng.uniform(-800, 800, 3)
        vs = virtual_scan(model, view=view, pixel=0.3, noise=args.noise, motion=M, rng=k,
                          effects=ScanEffects(outlier_fraction=args.outliers))
        c = time.process_time()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            reg = register(vs.scan, prep)
        t_sv = time.process_time() - c
        ok, med, tilt = judge(prep, vs.scan, reg.T_model_scan, vs.T_model_scan)
        row = dict(n=len(vs.scan), ok=ok, conv=reg.converged, warned=bool(reg.warnings), t=t_sv,
                   txt=f"view {k:2d} n={len(vs.scan):6d}  shapeverify {'right' if ok else 'WRONG'} "
                       f"med|d| {med:.4f} mm tilt {tilt:.4f} deg converged={reg.converged} "
                       f"warnings={len(reg.warnings)} {t_sv:.2f} s CPU ({reg.init})")
        if peer is not None:
            c = time.process_time()
            _, T_icp = peer.run(vs.scan)
            row["t_o3d"] = time.process_time() - c
            row["ok_o3d"], med, tilt = judge(prep, vs.scan, T_icp, vs.T_model_scan)
            row["txt"] += (f"  | Open3D+ICP {'right' if row['ok_o3d'] else 'WRONG'} med|d| "
                           f"{med:.3f} tilt {tilt:.2f} {row['t_o3d']:.2f} s")
        print(row["txt"], flush=True)
        rows.append(row)
    n = len(rows)
    say("| tool | right | wrong and converged without a warning | CPU s per scan (median) |")
    say("|---|---|---|---|")
    say(f"| shapeverify register (no start) | {sum(r['ok'] for r in rows)}/{n} | "
        f"{sum((not r['ok']) and r['conv'] and not r['warned'] for r in rows)} | "
        f"{np.median([r['t'] for r in rows]):.2f} |")
    if peer is not None:
        say(f"| Open3D FPFH + RANSAC + ICP | {sum(r['ok_o3d'] for r in rows)}/{n} | - | "
            f"{np.median([r['t_o3d'] for r in rows]):.2f} |")
    say()
    say("```")
    for r in rows:
        say(r["txt"])
    say("```")
    head = (f"# Turned part: preparation and pose with no start (issue 14)\n\n"
            f"Command: `.venv/bin/python benchmarks/bench_turned.py --views {args.views} "
            f"--noise {args.noise} --outliers {args.outliers}`  \n"
            f"Date: {datetime.date.today()}, Python {platform.python_version()}, "
            f"{platform.machine()}, one thread.  Load: `{load}`.\n"
            f"Inputs and criteria: see the docstring of `benchmarks/bench_turned.py`.\n\n")
    Path(args.out).write_text(head + "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
