"""Rays per second: exact ray–CAD intersection (fresh and small-motion update) vs Open3D RaycastingScene.

Run: .venv/bin/python benchmarks/bench_rays.py [--size 1024] [--model ../shared/data/cad/impeller.igs]

Open3D (bench extra) intersects a tessellation of the same model; its depth error is measured
against our exact hits on the pixels both hit. Single thread for ours (numba, no parallel).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from shapeverify.cad.load import load_model
from shapeverify.camera import PinholeCamera, depth_map, make_view
from shapeverify.camera.intersect import scene_for

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--model", default=str(ROOT.parent / "shared/data/cad/impeller.igs"))
    args = ap.parse_args()

    t0 = time.perf_counter()
    model = load_model(args.model)
    t_load = time.perf_counter() - t0
    lo, hi = model.bounds
    c = (lo + hi) / 2
    size = np.linalg.norm(hi - lo)
    cam = PinholeCamera.look_at(c + np.array([0.3, -0.6, 0.75]) * size, c, up=(0, 0, 1), fov_deg=45,
                                width=args.size, height=args.size)
    t0 = time.perf_counter()
    scene = scene_for(model)
    t_scene = time.perf_counter() - t0

    small = PinholeCamera.look_at(c + np.array([0.3, -0.6, 0.75]) * size, c, up=(0, 0, 1), fov_deg=45,
                                  width=32, height=32)
    make_view(model, small)  # JIT warm-up
    n = args.size * args.size

    t0, c0 = time.perf_counter(), time.process_time()
    view = make_view(model, cam)
    t_fresh, c_fresh = time.perf_counter() - t0, time.process_time() - c0
    hits = view.hits

    ang = np.radians(0.05)
    T = np.eye(4)
    T[:3, :3] = [[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1]]
    T[:3, 3] = [0.02, -0.01, 0.03]
    depth_map(view, T)  # warm-up of the update kernel
    t0, c0 = time.perf_counter(), time.process_time()
    upd = depth_map(view, T)
    t_upd, c_upd = time.perf_counter() - t0, time.process_time() - c0
    fresh_moved = make_view(model, cam, T).hits
    both = upd.hit & fresh_moved.hit
    upd_err = np.abs(upd.distances[both] - fresh_moved.distances[both]).max() if both.any() else np.nan
    mismatch = int((upd.hit != fresh_moved.hit).sum())

    rows = [("shapeverify exact, fresh", n / t_fresh, n / c_fresh, 0.0),
            ("shapeverify exact, small-motion update", n / t_upd, n / c_upd, upd_err)]
    o3d_note = ""
    try:
        import open3d as o3d

        tess = scene.tess
        mesh = o3d.t.geometry.TriangleMesh()
        mesh.vertex.positions = o3d.core.Tensor(tess.vertices.astype(np.float32))
        mesh.triangle.indices = o3d.core.Tensor(tess.triangles.astype(np.int32))
        rs = o3d.t.geometry.RaycastingScene(nthreads=1) if "nthreads" in o3d.t.geometry.RaycastingScene.__init__.__doc__ else o3d.t.geometry.RaycastingScene()
        rs.add_triangles(mesh)
        o, d = cam.pixel_rays()
        rays = o3d.core.Tensor(np.hstack([o, d]).astype(np.float32))
        rs.cast_rays(rays)
        t0, c0 = time.perf_counter(), time.process_time()
        ans = rs.cast_rays(rays)
        t_o3d, c_o3d = time.perf_counter() - t0, time.process_time() - c0
        t_hit = ans["t_hit"].numpy().astype(np.float64)
        ok = np.isfinite(t_hit) & hits.hit
        err = np.abs(t_hit[ok] - hits.distances[ok])
        rows.append((f"Open3D RaycastingScene ({len(tess.triangles):,} triangles, float32)", n / t_o3d,
                     n / c_o3d, float(np.percentile(err, 99))))
        o3d_note = f"Open3D depth error vs exact: median {np.median(err):.2e} mm, p99 {np.percentile(err, 99):.2e} mm, max {err.max():.2e} mm"
    except Exception as exc:  # open3d is optional (bench extra)
        o3d_note = f"Open3D not run: {exc}"

    embree_note = ""
    try:
        import trimesh
        from trimesh.ray.ray_pyembree import RayMeshIntersector

        tess = scene.tess
        mesh = trimesh.Trimesh(tess.vertices, tess.triangles, process=False)
        rmi = RayMeshIntersector(mesh)
        o, d = cam.pixel_rays()
        rmi.intersects_first(o[:1000], d[:1000])  # warm-up
        t0, c0 = time.perf_counter(), time.process_time()
        tri = rmi.intersects_first(o, d)
        t_em, c_em = time.perf_counter() - t0, time.process_time() - c0
        hit_em = tri >= 0
        # depth of the embree hit: intersect each ray with its triangle's plane
        a = tess.vertices[tess.triangles[np.maximum(tri, 0), 0]]
        nrm = np.cross(tess.vertices[tess.triangles[np.maximum(tri, 0), 1]] - a,
                       tess.vertices[tess.triangles[np.maximum(tri, 0), 2]] - a)
        with np.errstate(divide="ignore", invalid="ignore"):
            t_hit = np.einsum("ij,ij->i", a - o, nrm) / np.einsum("ij,ij->i", d, nrm)
        ok = hit_em & hits.hit
        err = np.abs(t_hit[ok] - hits.distances[ok])
        rows.append(("trimesh + Embree (same tessellation)", n / t_em, n / c_em, float(np.percentile(err, 99))))
        embree_note = (f"Embree depth error vs exact: median {np.median(err):.2e} mm, p99 {np.percentile(err, 99):.2e} mm; "
                       f"hit/miss disagreements with the exact answer: {int((hit_em != hits.hit).sum()):,}")
    except Exception as exc:  # trimesh + embreex are optional (bench extra)
        embree_note = f"trimesh/Embree not run: {exc}"

    lines = [
        f"model {Path(args.model).name}: {len(model.faces)} faces, load {t_load:.2f} s, ray scene build {t_scene:.2f} s "
        f"({len(scene.tess.triangles):,} seed triangles); image {args.size}x{args.size}, {int(hits.hit.sum()):,} hits",
        "",
        "| method | rays/s (wall) | rays/s (CPU time) | depth error p99 [mm] |",
        "|---|---:|---:|---:|",
    ]
    for name, rate, crate, err in rows:
        lines.append(f"| {name} | {rate / 1e6:.3f} M | {crate / 1e6:.3f} M | {err:.1e} |")
    lines += ["", f"update vs fresh at the moved pose: max |dt| {upd_err:.1e} mm, hit/miss mismatches {mismatch}",
              o3d_note, embree_note, f"ratios (CPU time): update/Open3D {rows[1][2] / rows[2][2]:.3f}, fresh/Open3D "
              f"{rows[0][2] / rows[2][2]:.3f}" if len(rows) > 2 else "",
              f"cores: {os.cpu_count()}; load average at start {os.getloadavg()[0]:.1f} (wall rates suffer "
              "from other processes; CPU time is the fairer single-core figure)"]
    text = "\n".join(lines)
    print(text)
    out = ROOT / "benchmarks" / "results_rays.md"
    out.write_text("## Rays (issue 6)\n\nCommand: `.venv/bin/python benchmarks/bench_rays.py --size "
                   f"{args.size}`\n\n{text}\n")


if __name__ == "__main__":
    main()
