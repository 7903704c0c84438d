"""In-process time of one inspection (register + deviations + verdict) of a 30,000-point scan,
and the time of writing each report, separately.  Goal (issue 5): inspect <= 0.2 s.

Model: a 120 x 90 mm bicubic free-form panel of two trimmed faces (``shapeverify.cad.examples.wavy_panel``,
the test model of tests/test_inspection.py), prepared once.  Scan: the virtual scanner (noise 0.02 mm, 1 % outliers,
a reflection blob, a 0.4 mm dent, a 3 degree / 2 mm fixture misalignment).

Peer, same process, same scan: Open3D 0.18+ (bench extra) -- point-to-plane ICP
(``o3d.pipelines.registration.registration_icp``) to a dense sampling of the CAD surface, plus
signed distances to a fine tessellation (``RaycastingScene.compute_signed_distance``): the usual
"mesh + ICP" way of doing the same job approximately.  The ratio printed is peer time / ours.

CPU per stage (issue 9: the service's throughput is the inspection's CPU cost): for the wavy
panel and for the bundled example panel (300 x 200 mm with a hole, default spacing, the scan of
``bench_service.py``: 30,000 points, 3 % outliers), the CPU seconds of one inspection (all
threads of the process, ``time.process_time``; median of ``--repeat`` runs) and of each stage
(cProfile with a CPU clock: the inclusive CPU of the stage's function; the closest-point
queries' worker threads count towards the stage that waits for them), plus the registration's
iterations and closest-point queries.  ``--profile N`` prints the N functions of most
inclusive CPU of the example panel's inspection; ``--workers`` sets the query threads.

Run:  .venv/bin/python benchmarks/bench_inspect.py [--points 30000] [--repeat 7] [--workers N]
      [--profile 30] [--out benchmarks/results_inspection.md]
"""

from __future__ import annotations

import argparse
import cProfile
import datetime
import os
import platform
import pstats
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


#: (label, module, function): the stages whose inclusive CPU the table gives, in order; a label
#: starting with spaces is a part of the stage above it
STAGES = [
    ("inspect under the profiler", "shapeverify/inspection/inspect.py", "inspect"),
    ("register", "shapeverify/registration/icp.py", "register"),
    ("  coarse stage (subset, re-matched every step)", "shapeverify/registration/_irls.py", "stage_rematch"),
    ("  final stage (all points, fixed planes, verified)", "shapeverify/registration/_irls.py", "stage_final_plane"),
    ("  thin-wall probe", "shapeverify/registration/_basin.py", "probe"),
    ("  pose covariance", "shapeverify/registration/rigid.py", "pose_covariance"),
    ("deviations", "shapeverify/inspection/deviations.py", "_deviations"),
    ("  exact closest points", "shapeverify/nearest/prepared.py", "_closest_exact"),
    ("spacing (grid)", "shapeverify/measures/spacing.py", "median_spacing"),
    ("regions (out-of-tolerance clusters)", "shapeverify/inspection/regions.py", "find_regions"),
    ("material", "shapeverify/inspection/material.py", "find_material"),
    ("floating surfaces", "shapeverify/inspection/material.py", "floating_surfaces"),
    ("coverage", "shapeverify/inspection/coverage.py", "compute_coverage"),
    ("statistics", "shapeverify/inspection/verdict.py", "statistics"),
]


def _cpu_median(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        c0 = time.process_time()
        fn()
        times.append(time.process_time() - c0)
    return float(np.median(times))


def cpu_profile(fn, repeat: int):
    """``(per-stage CPU seconds per call {label: s}, pstats.Stats)`` of ``repeat`` calls."""
    prof = cProfile.Profile(time.process_time)
    prof.enable()
    for _ in range(repeat):
        fn()
    prof.disable()
    st = pstats.Stats(prof)
    out = {}
    for label, path, name in STAGES:
        tot = sum(v[3] for (file, _, func), v in st.stats.items()
                  if func == name and file.replace(os.sep, "/").endswith(path))
        out[label] = tot / repeat
    return out, st


def registration_queries(prep, scan):
    """Closest-point queries of one registration: ``{"calls": .., "points": ..}``."""
    calls = [0, 0]
    orig = type(prep).closest

    def counting(self, q, exact=False):
        calls[0] += 1
        calls[1] += len(np.atleast_2d(q))
        return orig(self, q, exact)

    from shapeverify.registration import register
    type(prep).closest = counting
    try:
        reg = register(scan, prep)
    finally:
        type(prep).closest = orig
    stages = {}
    for h in reg.history:
        stages.setdefault(h.stage, [0, 0, 0])
        stages[h.stage][0] += 1
        stages[h.stage][1] += int(h.matched)
        stages[h.stage][2] = h.n_points
    return {"calls": calls[0], "points": calls[1], "iterations": reg.iterations, "stages": stages}


def panel_case():
    """The example panel at the default spacing and the scan of bench_service.py (seed 7)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from bench_service import make_scan

    from shapeverify.cad.examples import example_part_step
    from shapeverify.cad.load import load_model
    from shapeverify.nearest import prepare

    model = load_model(example_part_step(Path(tempfile.mkdtemp(prefix="bench_inspect_")) / "panel.step"))
    prep = prepare(model)
    return prep, make_scan(model, 7)


def _median_time(fn, repeat: int):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), float(np.min(times)), out


def _open3d_peer(prep, scan, T_true, repeat):
    try:
        import open3d as o3d
    except ImportError:
        return None
    from shapeverify.cad.tessellate import tessellate_model

    tess = tessellate_model(prep.model, max_edge=0.5)
    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(tess.vertices),
                                     o3d.utility.Vector3iVector(tess.triangles.astype(np.int32)))
    mesh.compute_vertex_normals()
    target = mesh.sample_points_uniformly(number_of_points=len(prep.points.points))
    target.estimate_normals()
    tmesh = o3d.t.geometry.TriangleMesh.from_legacy(mesh)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(tmesh)
    source = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(scan))

    def run():
        icp = o3d.pipelines.registration.registration_icp(
            source, target, 1.0, np.eye(4),
            o3d.pipelines.registration.TransformationEstimationPointToPlane(
                o3d.pipelines.registration.TukeyLoss(k=0.1)),
            o3d.pipelines.registration.ICPConvergenceCriteria(max_iteration=50))
        q = scan @ icp.transformation[:3, :3].T + icp.transformation[:3, 3]
        d = scene.compute_signed_distance(o3d.core.Tensor(q.astype(np.float32))).numpy()
        return icp, d

    med, best, (icp, d) = _median_time(run, repeat)
    return {"median": med, "best": best, "fitness": icp.fitness, "T": icp.transformation, "d": d}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=30_000)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--workers", type=int, default=None,
                    help="threads of the closest-point queries (default: every core)")
    ap.add_argument("--profile", type=int, default=0, metavar="N",
                    help="print the N functions of most inclusive CPU (example panel)")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results_inspection.md"))
    args = ap.parse_args()
    load_start = os.getloadavg()[0]

    from shapeverify.cad.examples import wavy_panel

    from shapeverify.inspection import inspect
    from shapeverify.nearest import get_workers, prepare, set_workers
    from shapeverify.report import write_colored_ply, write_html_report, write_png_summary
    from shapeverify.simulate import ScanEffects, virtual_scan

    if args.workers is not None:
        set_workers(args.workers)

    t0 = time.perf_counter()
    prep = prepare(wavy_panel(), spacing=1.0)
    t_prep = time.perf_counter() - t0
    area = 120 * 90 * 1.02
    pixel = float(np.sqrt(area / args.points))
    vs = virtual_scan(prep, pixel=pixel, noise=0.02, motion=(3.0, 2.0), rng=2011,
                      effects=ScanEffects(outlier_fraction=0.01, blobs=1, dents=[(0.4, 10.0)]))
    scan = vs.scan
    inspect(prep, scan, tolerance=0.2)                      # warm-up: numba JIT / cache load
    med, best, res = _median_time(lambda: inspect(prep, scan, tolerance=0.2), args.repeat)
    stages = {k: v for k, v in res.timings.items()}

    out_dir = Path(tempfile.mkdtemp(prefix="bench_inspect_"))
    t_html, _, _ = _median_time(lambda: write_html_report(res, prep, scan, out_dir / "r.html"), 3)
    t_png, _, _ = _median_time(lambda: write_png_summary(res, scan, out_dir / "s.png"), 3)
    t_ply, _, _ = _median_time(lambda: write_colored_ply(res, scan, out_dir / "d.ply"), 3)

    # CPU per stage: the wavy panel and the example panel (the service's model and scan)
    cases = {"wavy panel": (prep, scan)}
    cases["example panel"] = panel_case()
    cpu = {}
    for name, (p, sc) in cases.items():
        r = inspect(p, sc, tolerance=0.2)                   # warm-up (and the exact tables)
        total = _cpu_median(lambda: inspect(p, sc, tolerance=0.2), args.repeat)
        per_stage, st = cpu_profile(lambda: inspect(p, sc, tolerance=0.2), args.repeat)
        cpu[name] = {"total": total, "stages": per_stage, "queries": registration_queries(p, sc),
                     "n_model": p.n_points, "n_scan": len(sc), "verdict": str(r.verdict)}
        if args.profile and name == "example panel":
            st.sort_stats("cumulative").print_stats(args.profile)
    load_end = os.getloadavg()[0]

    peer = _open3d_peer(prep, scan, vs.T_model_scan, args.repeat)
    acc = vs.accuracy(res.T_model_scan)
    blas = (f"OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']} "
            if "OPENBLAS_NUM_THREADS" in os.environ else "")
    opts = "".join(f" {o}" for o in (f"--workers {args.workers}" if args.workers else "",) if o)
    lines = [
        "# Inspection timing (issue 5)",
        "",
        f"Command: `{blas}.venv/bin/python benchmarks/bench_inspect.py --points {args.points} "
        f"--repeat {args.repeat}{opts}`  ",
        f"Date: {datetime.date.today()}, {platform.processor() or platform.machine()}, "
        f"Python {platform.python_version()}; machine shared with other jobs (2 cores, load "
        f"average {load_start:.1f} at the start, {load_end:.1f} at the end); closest-point "
        f"queries on {get_workers()} thread(s); OPENBLAS_NUM_THREADS="
        f"{os.environ.get('OPENBLAS_NUM_THREADS', 'unset (every core)')}.",
        "",
        f"Model: 2-face bicubic panel 120 x 90 mm, prepared in {t_prep:.2f} s "
        f"({len(prep.points.points):,} model points).  Scan: {len(scan):,} points (virtual "
        "scanner: noise 0.02 mm, 1 % outliers, 1 blob, 0.4 mm dent, 3 deg / 2 mm misalignment).",
        "",
        "| step | median [s] | best [s] |",
        "|---|---|---|",
        f"| **inspect** (validate + register + deviations + regions + verdict) | **{med:.3f}** "
        f"| {best:.3f} |",
    ]
    for k, v in stages.items():
        if k != "total":
            lines.append(f"| &nbsp; stage `{k}` (last run) | {v:.3f} | |")
    lines += [
        f"| HTML report (plotly inline) | {t_html:.3f} | |",
        f"| PNG summary | {t_png:.3f} | |",
        f"| coloured PLY | {t_ply:.3f} | |",
        "",
        f"Goal inspect <= 0.2 s: **{'met' if med <= 0.2 else 'NOT met'}** ({med:.3f} s).  "
        f"Verdict {res.verdict}, {len(res.regions)} region(s)"
        + (f", extreme {res.regions[0].extreme:+.3f} mm" if res.regions else "")
        + f"; registration error vs truth: {acc.rotation_deg:.4f} deg, {acc.translation:.4f} mm.",
    ]
    if peer is not None:
        lines += [
            "",
            f"Peer Open3D (point-to-plane ICP with Tukey loss to {len(prep.points.points):,} "
            f"sampled surface points + signed distance to a 0.5 mm tessellation): median "
            f"{peer['median']:.3f} s; ratio peer / ours = **{peer['median'] / med:.2f}**.",
        ]
    else:
        lines += ["", "Peer Open3D: not importable (install the bench extra)."]
    lines += _cpu_table(cpu, args.repeat)
    text = "\n".join(lines) + "\n"
    print(text)
    Path(args.out).write_text(text)


def _cpu_table(cpu: dict, repeat: int) -> list[str]:
    names = list(cpu)
    lines = ["", "### CPU per inspection and per stage (issue 9)", "",
             "CPU seconds of all the process's threads (`time.process_time`), median of "
             f"{repeat} inspections; stages: inclusive CPU of the stage's function under cProfile "
             "with a CPU clock, per inspection (a part of the stage above it is indented; the "
             "profiler's own cost makes them add up to more than the plain total).", "",
             "| | " + " | ".join(f"{n} ({cpu[n]['n_model']:,} model points, {cpu[n]['n_scan']:,} "
                                 "scan points)" for n in names) + " |",
             "|---|" + "---:|" * len(names),
             "| **inspect, CPU [ms]** | " + " | ".join(f"**{1e3 * cpu[n]['total']:.1f}**"
                                                    for n in names) + " |"]
    for label, _, _ in STAGES:
        shown = label.replace("  ", "&nbsp; ", 1) if label.startswith("  ") else label
        lines.append(f"| {shown} | " + " | ".join(f"{1e3 * cpu[n]['stages'][label]:.1f}"
                                                  for n in names) + " |")
    lines.append("| rest (validation, limits, outliers, verdict, notes) | " + " | ".join(
        f"{1e3 * (cpu[n]['stages'][STAGES[0][0]] - _top(cpu[n]['stages'])):.1f}"
        for n in names) + " |")
    lines.append("| verdict | " + " | ".join(cpu[n]["verdict"] for n in names) + " |")
    lines += ["", "Registration, one run: iterations and closest-point queries (fast tangent-patch "
              "answers; stage: steps / re-matchings / points per matching):", ""]
    for n in names:
        q = cpu[n]["queries"]
        st = ", ".join(f"{k} {v[0]} / {v[1]} / {v[2]:,}" for k, v in q["stages"].items())
        lines.append(f"- {n}: {q['iterations']} iterations, {q['calls']} queries of "
                     f"{q['points']:,} points in all ({st})")
    return lines


def _top(stages: dict) -> float:
    """CPU of the stages inside ``inspect`` (labels without indent, but the total's)."""
    return sum(v for k, v in stages.items() if not k.startswith(" ") and k != STAGES[0][0])


if __name__ == "__main__":
    main()
