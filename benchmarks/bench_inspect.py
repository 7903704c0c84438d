"""In-process time of one inspection (register + deviations + verdict) of a 30,000-point scan,
and the time of writing each report, separately.  Goal (issue 5): inspect <= 0.2 s.

Model: a 120 x 90 mm bicubic free-form panel of two trimmed faces (``shapeverify.cad.examples.wavy_panel``,
the test model of tests/test_inspection.py), prepared once.  Scan: the virtual scanner (noise 0.02 mm, 1 % outliers,
a reflection blob, a 0.4 mm dent, a 3 degree / 2 mm fixture misalignment).

Peer, same process, same scan: Open3D 0.18+ (bench extra) -- point-to-plane ICP
(``o3d.pipelines.registration.registration_icp``) to a dense sampling of the CAD surface, plus
signed distances to a fine tessellation (``RaycastingScene.compute_signed_distance``): the usual
"mesh + ICP" way of doing the same job approximately.  The ratio printed is peer time / ours.

Run:  .venv/bin/python benchmarks/bench_inspect.py [--points 30000] [--repeat 7]
      [--out benchmarks/results_inspection.md]
"""

from __future__ import annotations

import argparse
import datetime
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


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
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results_inspection.md"))
    args = ap.parse_args()

    from shapeverify.cad.examples import wavy_panel

    from shapeverify.inspection import inspect
    from shapeverify.nearest import prepare
    from shapeverify.report import write_colored_ply, write_html_report, write_png_summary
    from shapeverify.simulate import virtual_scan

    t0 = time.perf_counter()
    prep = prepare(wavy_panel(), spacing=1.0)
    t_prep = time.perf_counter() - t0
    area = 120 * 90 * 1.02
    pixel = float(np.sqrt(area / args.points))
    vs = virtual_scan(prep, pixel=pixel, noise=0.02, outlier_fraction=0.01, blobs=1,
                      dents=[(0.4, 10.0)], motion=(3.0, 2.0), rng=2011)
    scan = vs.scan
    inspect(prep, scan, tolerance=0.2)                      # warm-up: numba JIT / cache load
    med, best, res = _median_time(lambda: inspect(prep, scan, tolerance=0.2), args.repeat)
    stages = {k: v for k, v in res.timings.items()}

    out_dir = Path(tempfile.mkdtemp(prefix="bench_inspect_"))
    t_html, _, _ = _median_time(lambda: write_html_report(res, prep, scan, out_dir / "r.html"), 3)
    t_png, _, _ = _median_time(lambda: write_png_summary(res, scan, out_dir / "s.png"), 3)
    t_ply, _, _ = _median_time(lambda: write_colored_ply(res, scan, out_dir / "d.ply"), 3)

    peer = _open3d_peer(prep, scan, vs.T_model_scan, args.repeat)
    acc = vs.accuracy(res.T_model_scan)
    lines = [
        "# Inspection timing (issue 5)",
        "",
        f"Command: `.venv/bin/python benchmarks/bench_inspect.py --points {args.points} "
        f"--repeat {args.repeat}`  ",
        f"Date: {datetime.date.today()}, {platform.processor() or platform.machine()}, "
        f"Python {platform.python_version()}; machine shared with other jobs (2 cores).",
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
    text = "\n".join(lines) + "\n"
    print(text)
    Path(args.out).write_text(text)


if __name__ == "__main__":
    main()
