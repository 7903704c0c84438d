"""Benchmark: robust registration of a 30,000-point simulated scan (issue 4 "How fast").

The example panel (300 x 200 mm B-spline sheet with a hole, ``shapeverify.cad.examples``) is
prepared once; the virtual scanner makes the scan of issue 4 "How good": depth noise 0.02 mm
along the rays, ~11 % scattered outliers plus a reflection blob (~14 % bad points in all), a
0.4 mm dent, a shadowed region, start 6 deg and 12 mm off.  Every method starts from the
identity (the scan's own coordinates) and is judged against the truth by

* sqrt(e^T F e): the pose error in the metric of the Fisher information of the true inliers
  (chi with 6 degrees of freedom for an efficient estimator; 4.74 is its 99.9 % point),
* the RMS of the normal component of the registration error over the scan (what moves the
  deviations), the rotation error and the translation error at the scan's centroid.

Peers: Open3D ``registration_icp`` point-to-plane on the same scan against model points of the
same density (sampled from the CAD model with its normals), plain and with its ``TukeyLoss``
kernel (k = 0.1 mm, and the hand-tuned staged schedule k = 2, 0.5, 0.1 mm).  Open3D's
correspondence distance is 30 mm (it must cover the start).  Everything runs on one thread.
Times are the minimum over ``--repeat`` runs (the machine is shared).

Run:  .venv/bin/python benchmarks/bench_register.py [--repeat 7] [--seeds 3]
                                                   [--out benchmarks/results_register.md]
"""
from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import datetime  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from shapeverify.cad.examples import example_part_step  # noqa: E402
from shapeverify.cad.load import load_model  # noqa: E402
from shapeverify.nearest import prepare  # noqa: E402
from shapeverify.registration import register  # noqa: E402
from shapeverify.simulate import virtual_scan  # noqa: E402

SCAN = dict(pixel=1.37, noise=0.02, shadows=1, blobs=1, blob_radius=20.0, outlier_fraction=0.11,
            dents=[(0.4, 12.0)], motion=(6.0, 12.0))


def timed(fn, repeat):
    best, out = np.inf, None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def open3d_runs(o3d, scan, model_pts, model_nrm, repeat):
    reg = o3d.pipelines.registration
    src = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.array(scan)))
    tgt = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.array(model_pts)))
    tgt.normals = o3d.utility.Vector3dVector(np.array(model_nrm))
    crit = reg.ICPConvergenceCriteria(relative_fitness=1e-9, relative_rmse=1e-9, max_iteration=100)

    def plain():
        return reg.registration_icp(src, tgt, 30.0, np.eye(4),
                                    reg.TransformationEstimationPointToPlane(), crit).transformation

    def tukey():
        est = reg.TransformationEstimationPointToPlane(reg.TukeyLoss(k=0.1))
        return reg.registration_icp(src, tgt, 30.0, np.eye(4), est, crit).transformation

    def staged():
        T = np.eye(4)
        for k in (2.0, 0.5, 0.1):
            est = reg.TransformationEstimationPointToPlane(reg.TukeyLoss(k=k))
            T = reg.registration_icp(src, tgt, 30.0, T, est, crit).transformation
        return T

    return {"Open3D point-to-plane": timed(plain, repeat),
            "Open3D point-to-plane + TukeyLoss(k=0.1)": timed(tukey, repeat),
            "Open3D staged Tukey k=2, 0.5, 0.1 (hand-tuned)": timed(staged, repeat)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--out", default="benchmarks/results_register.md")
    ap.add_argument("--no-open3d", action="store_true")
    args = ap.parse_args(argv)

    with tempfile.TemporaryDirectory() as d:
        model = load_model(example_part_step(Path(d) / "panel.step"))
    t = time.perf_counter()
    prep = prepare(model)
    t_prep = time.perf_counter() - t
    print(f"model: {model}\nprepared in {t_prep:.2f} s: {prep}")
    try:
        if args.no_open3d:
            raise ImportError
        import open3d as o3d
        o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
        o3d_version = o3d.__version__
    except ImportError:
        o3d, o3d_version = None, None

    rows = {}   # method -> list of (time, crb, normal_rms, rot, trans, converged)
    sizes = []
    log = []
    for seed in range(args.seeds):
        vs = virtual_scan(model, rng=seed, **SCAN)
        sizes.append(len(vs))
        c = vs.counts()
        print(f"\nseed {seed}: {vs}  bad fraction "
              f"{(c['outlier'] + c['blob']) / len(vs):.3f}")
        register(vs.scan, prep, rng=0)  # warm-up (numba caches)
        runs = {}
        for label, kw in [("shapeverify point-to-plane, Tukey (default)", {}),
                          ("shapeverify point-to-plane, Welsch", dict(loss="welsch")),
                          ("shapeverify point-to-plane, Huber", dict(loss="huber")),
                          ("shapeverify point-to-point, Tukey", dict(method="point-to-point"))]:
            rep = args.repeat if "point-to-point" not in label else 1
            tt, reg = timed(lambda kw=kw: register(vs.scan, prep, rng=0, **kw), rep)
            runs[label] = (tt, reg.T_model_scan, reg.converged)
        if o3d is not None:
            mp = model.sample(SCAN["pixel"], rng=seed)   # the scan's density
            for label, (tt, T) in open3d_runs(o3d, vs.scan, mp.points, mp.normals,
                                               max(1, args.repeat // 3)).items():
                runs[label] = (tt, np.asarray(T), None)
        for label, (tt, T, conv) in runs.items():
            a = vs.accuracy(T)
            rows.setdefault(label, []).append((tt, a.crb, a.normal_rms, a.rotation_deg,
                                               a.translation, conv))
            line = (f"seed {seed}  {label:48s} {tt * 1e3:8.1f} ms  sqrt(eFe)={a.crb:10.2f}  "
                    f"normal RMS={a.normal_rms * 1e3:10.3f} um  rot={a.rotation_deg:.5f} deg  "
                    f"trans={a.translation * 1e3:10.2f} um  converged={conv}")
            log.append(line)
            print(line)

    lines = ["# Registration benchmark (issue 4)", "",
             f"Command: `.venv/bin/python benchmarks/bench_register.py --repeat {args.repeat} "
             f"--seeds {args.seeds}`  ",
             f"Date: {datetime.date.today()}, Python {platform.python_version()}, "
             f"{platform.machine()}, one thread"
             + (f", Open3D {o3d_version}" if o3d_version else "") + ".  ",
             f"Model: example panel (300 x 200 mm B-spline sheet with a hole), prepared in "
             f"{t_prep:.1f} s ({prep.n_points:,} model points, spacing {prep.spacing:.3g} mm).  ",
             f"Scans: virtual scanner, {min(sizes):,}-{max(sizes):,} points, depth noise 0.02 mm, "
             "~11 % scattered outliers + a reflection blob (~14 % bad), a 0.4 mm dent, a shadow, "
             "start 6 deg / 12 mm off; seeds 0.."
             f"{args.seeds - 1}.  Times: minimum over repeats (shared 2-core machine); errors: "
             "worst over the seeds.", "",
             "| method | time (ms, median over seeds) | sqrt(e^T F e) (worst) | normal error RMS "
             "(um, worst) | rotation error (deg, worst) | translation error (um, worst) | "
             "converged |", "|---|---|---|---|---|---|---|"]
    ours = np.median([r[0] for r in rows["shapeverify point-to-plane, Tukey (default)"]])
    for label, rs in rows.items():
        r = np.array([x[:5] for x in rs], float)
        conv = [x[5] for x in rs]
        cs = "-" if conv[0] is None else f"{sum(conv)}/{len(conv)}"
        lines.append(f"| {label} | {np.median(r[:, 0]) * 1e3:.1f} | {r[:, 1].max():.2f} | "
                     f"{r[:, 2].max() * 1e3:.3f} | {r[:, 3].max():.5f} | "
                     f"{r[:, 4].max() * 1e3:.1f} | {cs} |")
    if "Open3D point-to-plane" in rows:
        o3 = np.median([r[0] for r in rows["Open3D point-to-plane"]])
        lines += ["", f"Speed-up of the default over Open3D point-to-plane: {o3 / ours:.1f}x "
                  f"({ours * 1e3:.1f} ms vs {o3 * 1e3:.1f} ms)."]
    lines += ["", "Targets (issue 4): sqrt(e^T F e) <= 6 and normal error <= 1 um RMS with "
              "default settings; <= 50 ms per registration; >= 20x faster than Open3D "
              "point-to-plane at better accuracy.", "",
              "Notes: sqrt(e^T F e) of an efficient estimator is below 4.74 in 99.9 % of cases "
              "(chi, 6 dof); the Fisher information uses sigma = 0.02 mm, the noise along the "
              "rays.  Point-to-point converges linearly: on this nearly cylindrical panel it "
              "slides towards the optimum by ~1e-4 of the remaining distance per plain "
              "iteration; with Anderson acceleration its pose reaches the bound, but it honestly "
              "reports converged=False at max_iterations=100.  The hand-tuned staged Tukey "
              "schedule in Open3D reaches the bound on some seeds and diverges on others.", "",
              "Per seed:", "", "```", *log, "```", ""]
    text = "\n".join(lines)
    print("\n" + text)
    Path(args.out).write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
