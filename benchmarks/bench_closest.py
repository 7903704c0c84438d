"""Benchmark: closest points with the DVG tree (issue 3) against kd-trees and OpenCASCADE.

Model: a free-form bicubic B-spline sheet, 300 x 200 mm with waves a few mm high (one trimmed
face), sampled with about ``--points`` model points (default 1,000,000).  Queries:
``--queries`` points (default 100,000) within about 2 mm of it (a random model point moved
sideways by up to half a spacing and along its normal by up to 2 mm), once in random order and
once sorted along a Morton curve (the order a scanner's raster gives is close to the latter).

Measured, one thread for everybody (numba kernels are single-threaded; scipy ``workers=1``;
``OMP_NUM_THREADS=1`` for pykdtree):

* fast path ``prep.closest(q)`` (nearest model point + tangent-patch projection, complete
  result object) and the DVG nearest-model-point query alone;
* scipy ``cKDTree.query`` (workers=1), pykdtree ``KDTree.query``, Open3D
  ``KDTreeFlann.search_knn_vector_3d`` (a Python call per point: timed on a subsample);
* exact mode ``prep.closest(q, exact=True)`` against OCP ``GeomAPI_ProjectPointOnSurf`` per
  point (timed on a subsample), and their agreement;
* build time and memory per model point; impeller.igs at 0.5 mm (build, save, load, queries)
  when ../shared/data is present.

CPU time (``time.process_time``) is the figure to compare on a shared machine; wall time is
printed too.  Best of ``--repeat`` runs.

Run:  .venv/bin/python benchmarks/bench_closest.py [--points 1000000] [--queries 100000]
          [--out benchmarks/results_closest.md]
      .venv/bin/python benchmarks/bench_closest.py --issue18 --exact 50000 --queries 1000000
          (exact mode before/after the patch bounds on the panel and the impeller, one vs two
          threads, preparation of mesh and point-cloud references)
"""

from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one core for everybody

import argparse  # noqa: E402
import platform  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402

from shapeverify.cad.model import Face, Model  # noqa: E402
from shapeverify.cad.nurbs import NurbsSurface  # noqa: E402
from shapeverify.cad.occ_write import to_occ  # noqa: E402
from shapeverify.nearest import load_prepared, prepare, set_workers  # noqa: E402
from shapeverify.nearest.dvg import morton_order  # noqa: E402

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def timed(fn, repeat):
    """(result, best CPU seconds, best wall seconds) over ``repeat`` runs."""
    best_c = best_w = np.inf
    out = None
    for _ in range(repeat):
        c0, w0 = time.process_time(), time.perf_counter()
        out = fn()
        best_c = min(best_c, time.process_time() - c0)
        best_w = min(best_w, time.perf_counter() - w0)
    return out, best_c, best_w


def freeform_model():
    """A bicubic B-spline sheet 300 x 200 mm (30 x 20 control points, waves of a few mm)."""
    nu, nv = 30, 20
    x = np.linspace(0, 300, nu)
    y = np.linspace(0, 200, nv)
    X, Y = np.meshgrid(x, y, indexing="ij")
    Z = (12.0 * (1 - ((Y - 100) / 100) ** 2) + 3.0 * np.sin(2 * np.pi * (X / 300 + 0.5 * Y / 200))
         + 4.0 * np.exp(-(((X - 90) / 45) ** 2 + ((Y - 80) / 35) ** 2)))
    ku = np.concatenate([[0, 0, 0], np.linspace(0, 1, nu - 2), [1, 1, 1]])
    kv = np.concatenate([[0, 0, 0], np.linspace(0, 1, nv - 2), [1, 1, 1]])
    srf = NurbsSurface(3, 3, ku, kv, np.stack([X, Y, Z], axis=-1))
    rect = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    return Model(faces=(Face(srf, (rect,), (np.ones(4, bool),)),), source="free-form sheet")


def ocp_projection(model, q, near, repeat_note=""):
    """Time OCP's GeomAPI_ProjectPointOnSurf per point; agreement on interior feet."""
    from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
    from OCP.gp import gp_Pnt

    occ = {}
    t = 0.0
    diffs = []
    for k in range(q.shape[0]):
        f = int(near.face[k])
        if f not in occ:
            occ[f] = to_occ(model.faces[f].surface)
        w0 = time.process_time()
        pr = GeomAPI_ProjectPointOnSurf(gp_Pnt(*map(float, q[k])), occ[f])
        ok = pr.NbPoints() > 0
        d = pr.LowerDistance() if ok else np.nan
        t += time.process_time() - w0
        if ok and not near.on_boundary[k]:
            u, v = pr.LowerDistanceParameters()
            if model.faces[f].contains([[u, v]])[0]:
                p = pr.NearestPoint()
                diffs.append(max(abs(abs(near.distances[k]) - d),
                                 float(np.abs(near.points[k] - [p.X(), p.Y(), p.Z()]).max())))
    return t / q.shape[0], (max(diffs) if diffs else np.nan), len(diffs)


def queries_near(prep, n, reach, rng):
    """Random model points moved sideways by up to half a spacing and along the normal by up
    to ``reach``: the closest surface point is generally not a model point."""
    mp = prep.points
    i = rng.integers(0, prep.n_points, n)
    side = rng.uniform(-0.5, 0.5, (n, 2)) * prep.spacing
    return (mp.points[i] + side[:, :1] * mp.tangent_u[i] + side[:, 1:] * mp.tangent_v[i]
            + mp.normals[i] * rng.uniform(-reach, reach, n)[:, None])


def peers(pts, q, repeat, o3d_sub):
    """Rows (name, cpu s, wall s, n) of the kd-tree peers on queries q."""
    rows = []
    kd = cKDTree(pts)
    (d_kd, i_kd), c, w = timed(lambda: kd.query(q, workers=1), repeat)
    rows.append(("scipy cKDTree.query (workers=1)", c, w, q.shape[0]))
    try:
        from pykdtree.kdtree import KDTree

        pk = KDTree(pts)
        _, c, w = timed(lambda: pk.query(q, k=1), repeat)
        rows.append(("pykdtree KDTree.query (OMP 1 thread)", c, w, q.shape[0]))
    except ImportError:
        rows.append(("pykdtree (not importable)", np.nan, np.nan, 0))
    try:
        import open3d as o3d

        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.array(pts)))  # writable copy
        tree = o3d.geometry.KDTreeFlann(pc)
        sub = q[:o3d_sub]

        def run():
            for p in sub:
                tree.search_knn_vector_3d(p, 1)

        _, c, w = timed(run, 1)
        rows.append(("Open3D KDTreeFlann.search_knn_vector_3d (per-point call)", c, w,
                     sub.shape[0]))
    except Exception as exc:  # noqa: BLE001 - optional peer: report why it is missing
        rows.append((f"Open3D (not usable: {type(exc).__name__})", np.nan, np.nan, 0))
    return rows, d_kd, i_kd


def fmt_rate(n, s):
    return "n/a" if not np.isfinite(s) or n == 0 else f"{n / s / 1e6:.3f} M"


def _best_cpu(fn, repeat):
    best = np.inf
    for _ in range(repeat):
        c0 = time.process_time()
        out = fn()
        best = min(best, time.process_time() - c0)
    return out, best


def _best_wall(fn, repeat):
    best = np.inf
    for _ in range(repeat):
        w0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - w0)
    return out, best


def issue18(args):
    """Exact mode before/after the patch bounds, two threads, preparation of references."""
    from shapeverify.cad.examples import example_part_step
    from shapeverify.cad.load import load_model
    rng = np.random.default_rng(0)
    lines = ["## Closest points: exact mode global, both cores, references prepared "
             "(issue 18 items 2 and 4, issue 14 item 4)", "",
             "Command: `.venv/bin/python benchmarks/bench_closest.py --issue18`; load average "
             f"at start {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores (CPU time is the "
             "fair figure on this shared machine; speed-ups are wall-time ratios and suffer "
             "from the other processes)", ""]
    models = []
    with tempfile.TemporaryDirectory() as d:
        panel = load_model(example_part_step(Path(d) / "panel.step"))
    models.append(("example panel (1 trimmed face, hole), spacing 0.6 mm",
                   prepare(panel, spacing=0.6, max_distance=2.0), 2.0))
    imp = SHARED / "cad" / "impeller.igs"
    if imp.is_file() and not args.no_impeller:
        models.append(("impeller.igs (277 faces), spacing 0.5 mm",
                       prepare(load_model(imp), spacing=0.5, max_distance=3.0), 1.5))
    lines += ["| model | exact, seeds only (before) | exact, complete (now) | cost | "
              "fast, 1 -> 2 threads | exact, 1 -> 2 threads | identical |",
              "|---|---:|---:|---:|---:|---:|---|"]
    for name, p, reach in models:
        q = queries_near(p, args.exact, reach, rng)
        set_workers(1)
        p.closest(q[:100], exact=True)
        p._exact.complete = False
        _, before = _best_cpu(lambda: p.closest(q, exact=True), args.repeat)
        p._exact.complete = True
        r1, now = _best_cpu(lambda: p.closest(q, exact=True), args.repeat)
        qf = queries_near(p, args.queries, reach, rng)
        _, f1 = _best_wall(lambda: p.closest(qf), args.repeat)
        _, e1 = _best_wall(lambda: p.closest(q, exact=True), args.repeat)
        set_workers(2)
        _, f2 = _best_wall(lambda: p.closest(qf), args.repeat)
        r2, e2 = _best_wall(lambda: p.closest(q, exact=True), args.repeat)
        same = all(np.array_equal(getattr(r1, a), getattr(r2, a)) for a in
                   ("points", "normals", "distances", "face", "uv", "index", "on_boundary"))
        n = q.shape[0]
        lines.append(f"| {name} | {n / before / 1e6:.3f} M/s | {n / now / 1e6:.3f} M/s | "
                     f"x{now / before:.2f} | {f1 / f2:.2f}x ({qf.shape[0]:,} queries) | "
                     f"{e1 / e2:.2f}x | {same} |")
        print(lines[-1], flush=True)
    set_workers(1)
    lines += ["", f"({args.exact:,} exact queries, a model point moved sideways by up to half a "
              "spacing and along the normal by up to 2 mm (panel) / 1.5 mm (impeller); fast "
              f"path {args.queries:,} queries; threads: `set_workers(n)`; the library's "
              "default is every core the process may use, the first columns run on one)", ""]
    # references: meshes and a point cloud, default spacing
    lines += ["| reference | model points | prepare CPU | prepare wall |", "|---|---:|---:|---:|"]
    refs = []
    for nu, nv in ((6, 6), (25, 21), (60, 43)):
        V, T = _uv_sphere(50.0, nu, nv)
        refs.append((f"mesh, sphere r = 50 mm, {len(T)} triangles",
                     Model(kind="mesh", vertices=V, triangles=T, source="sphere")))
    bunny = SHARED / "scans" / "bunny" / "bun000.ply"
    if bunny.is_file():
        from shapeverify import read_points

        X = np.asarray(getattr(read_points(bunny), "points", read_points(bunny)))
        refs.append((f"point cloud, bunny bun000 ({len(X):,} points, m -> mm)",
                     Model(kind="points", vertices=X * 1000.0, source="bunny")))
    for name, m in refs:
        c0, w0 = time.process_time(), time.perf_counter()
        p = prepare(m)
        lines.append(f"| {name} | {p.n_points:,} | {time.process_time() - c0:.2f} s | "
                     f"{time.perf_counter() - w0:.2f} s |")
        print(lines[-1], flush=True)
    lines.append("")
    return lines


def _uv_sphere(r, nu, nv):
    th = np.linspace(0, np.pi, nv + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    V = np.array([[0, 0, -r]] + [[r * np.sin(t) * np.cos(p), r * np.sin(t) * np.sin(p),
                                  -r * np.cos(t)] for t in th for p in ph] + [[0, 0, r]])
    T = [[0, 1 + (k + 1) % nu, 1 + k] for k in range(nu)]
    for ring in range(nv - 2):
        a, b = 1 + ring * nu, 1 + (ring + 1) * nu
        for k in range(nu):
            k1 = (k + 1) % nu
            T += [[a + k, a + k1, b + k1], [a + k, b + k1, b + k]]
    top, a = len(V) - 1, 1 + (nv - 2) * nu
    T += [[a + k, a + (k + 1) % nu, top] for k in range(nu)]
    T = np.array(T)
    n = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
    inward = np.einsum("ij,ij->i", n, V[T].mean(axis=1)) < 0
    T[inward] = T[inward][:, ::-1]
    return V, T


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--queries", type=int, default=100_000)
    ap.add_argument("--exact", type=int, default=20_000, help="queries for exact mode")
    ap.add_argument("--ocp", type=int, default=200, help="queries timed with OCP")
    ap.add_argument("--o3d", type=int, default=20_000, help="queries timed with Open3D")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-impeller", action="store_true")
    ap.add_argument("--out", default=None)
    ap.add_argument("--issue18", action="store_true",
                    help="exact mode before/after the patch bounds, 2 threads, references")
    args = ap.parse_args()
    set_workers(1)  # one core for everybody (the --issue18 table measures two as well)
    if args.issue18:
        lines = issue18(args)
        if args.out:
            Path(args.out).write_text("\n".join(lines))
            print(f"wrote {args.out}")
        return
    rng = np.random.default_rng(0)
    lines = ["## Closest points (issue 3)", "",
             "Command: `.venv/bin/python benchmarks/bench_closest.py"
             + (f" --points {args.points}" if args.points != 1_000_000 else "")
             + (f" --queries {args.queries}" if args.queries != 100_000 else "") + "`", ""]
    load0 = os.getloadavg()[0]

    # ----------------------------------------------------------------- free-form model
    model = freeform_model()
    h = float(np.sqrt(300 * 200 * 1.02 / args.points))
    n_probe = len(model.sample(h * 4))  # count scales as 1 / h^2
    h *= np.sqrt(n_probe * 16 / args.points)
    c0, w0 = time.process_time(), time.perf_counter()
    prep = prepare(model, spacing=h, max_distance=2.0)
    build_c, build_w = time.process_time() - c0, time.perf_counter() - w0
    # the tree alone (sampling excluded)
    from shapeverify.nearest.dvg import DVG
    mp = prep.points
    c0 = time.process_time()
    DVG.build(mp.points, h, 2.0)
    tree_c = time.process_time() - c0
    n = prep.n_points
    print(f"model points {n:,}, spacing {h:.4f} mm, prepare {build_c:.1f} s CPU "
          f"({build_w:.1f} s wall), tree alone {tree_c:.1f} s CPU, "
          f"{prep.memory_per_point:.0f} bytes/point")
    q = queries_near(prep, args.queries, 2.0, rng)
    qs = np.ascontiguousarray(q[morton_order(q, h)])
    pts = np.ascontiguousarray(mp.points)
    prep.closest(q[:100])
    prep.closest(q[:100], exact=True)

    lines += ["The fast path is the DVG tree's nearest model point plus the projection onto its "
              "tangent patch, returned as a complete `Closest` (foot, normal, signed distance, "
              "face, uv, on_boundary); the kd-trees return the nearest point's index only.  In "
              "Morton (scan-like) order consecutive queries are close together, so every method "
              "reuses its cache: the kd-trees gain 3-4x, the DVG tree (a few memory reads per "
              "query either way) much less.", ""]
    lines += [f"free-form model: bicubic B-spline sheet 300 x 200 mm, {n:,} model points "
              f"(spacing {h:.4f} mm), max_distance 2 mm; {args.queries:,} queries within 2 mm",
              "",
              f"build: prepare {build_c:.1f} s CPU ({build_w:.1f} s wall) of which the DVG "
              f"tree + graph {tree_c:.1f} s; memory {prep.nbytes / 2**20:.1f} MiB = "
              f"**{prep.memory_per_point:.0f} bytes per model point** (goal <= 200); "
              f"tree depth {prep.tree.depth}, {prep.tree.nodes.size:,} nodes", ""]
    for order, qq in (("random order", q), ("Morton (scan-like) order", qs)):
        near, fc, fw = timed(lambda: prep.closest(qq), args.repeat)
        (idx, dist), nc, nw = timed(lambda: prep._fast.nearest(qq), args.repeat)
        rows, d_kd, i_kd = peers(pts, qq, args.repeat, args.o3d)
        kd_c = rows[0][1]
        exact_share = np.mean(dist <= d_kd * (1 + 1e-12) + 1e-12)
        excess = float(np.max(dist - d_kd))
        lines += [f"### Nearest model point, {order}", "",
                  "| method | queries/s (CPU) | queries/s (wall) | vs cKDTree (CPU) |",
                  "|---|---:|---:|---:|",
                  f"| **shapeverify fast path** `prep.closest(q)` (nearest + patch projection"
                  f", full result) | {fmt_rate(qq.shape[0], fc)} | {fmt_rate(qq.shape[0], fw)}"
                  f" | **{kd_c / fc:.1f}x** |",
                  f"| shapeverify DVG nearest model point only | {fmt_rate(qq.shape[0], nc)} | "
                  f"{fmt_rate(qq.shape[0], nw)} | {kd_c / nc:.1f}x |"]
        for name, c, w, m in rows:
            ratio = (kd_c / qq.shape[0]) / (c / m) if m and np.isfinite(c) else np.nan
            lines.append(f"| {name} | {fmt_rate(m, c)} | {fmt_rate(m, w)} | "
                         f"{'n/a' if not np.isfinite(ratio) else f'{ratio:.2f}x'} |")
        lines += ["", f"DVG answer is the true nearest model point for {100 * exact_share:.3f} % "
                  f"of the queries; largest excess distance {excess:.2e} mm "
                  f"(spacing {h:.3f} mm)", ""]
        print("\n".join(lines[-12:]))

    # ---------------------------------------------------------------- exact vs OCP
    qe = q[:args.exact]
    near_e, ec, ew = timed(lambda: prep.closest(qe, exact=True), args.repeat)
    near_f = prep.closest(qe)
    per_ocp, agree, n_cmp = ocp_projection(model, qe[:args.ocp], near_e)
    per_ex = ec / qe.shape[0]
    err_fast = np.abs(near_f.distances - near_e.distances)
    lines += ["### Exact mode vs OpenCASCADE", "",
              "| method | points/s (CPU) | us per point | vs OCP |", "|---|---:|---:|---:|",
              f"| **shapeverify** `prep.closest(q, exact=True)` | {1 / per_ex / 1e6:.3f} M | "
              f"{per_ex * 1e6:.2f} | **{per_ocp / per_ex:.0f}x** |",
              f"| OCP GeomAPI_ProjectPointOnSurf (per point, {args.ocp} points) | "
              f"{1 / per_ocp / 1e6:.4f} M | {per_ocp * 1e6:.1f} | 1x |", "",
              f"agreement with OCP on {n_cmp} interior feet: max difference {agree:.1e} mm; "
              f"fast path vs exact signed distance: median {np.median(err_fast):.1e} mm, "
              f"p99 {np.percentile(err_fast, 99):.1e} mm, max {err_fast.max():.1e} mm", ""]
    print("\n".join(lines[-8:]))

    # ---------------------------------------------------------------------- impeller
    imp = SHARED / "cad" / "impeller.igs"
    if not args.no_impeller and imp.is_file():
        from shapeverify.cad.load import load_model

        w0 = time.perf_counter()
        m = load_model(imp)
        t_load = time.perf_counter() - w0
        c0, w0 = time.process_time(), time.perf_counter()
        p = prepare(m, spacing=0.5)
        ic, iw = time.process_time() - c0, time.perf_counter() - w0
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "impeller.svm"
            w0 = time.perf_counter()
            p.save(path)
            t_save = time.perf_counter() - w0
            _, _, t_lp = timed(lambda: load_prepared(path), 3)
            size_mb = path.stat().st_size / 2**20
        qi = queries_near(p, args.queries, 2.0, rng)
        p.closest(qi[:100])
        p.closest(qi[:100], exact=True)
        _, fic, _ = timed(lambda: p.closest(qi), args.repeat)
        kdi = cKDTree(np.ascontiguousarray(p.points.points))
        _, kic, _ = timed(lambda: kdi.query(qi, workers=1), args.repeat)
        qie = qi[:args.exact]
        ne, eic, _ = timed(lambda: p.closest(qie, exact=True), args.repeat)
        per_ocp_i, agree_i, n_i = ocp_projection(m, qie[:args.ocp], ne)
        lines += ["### impeller.igs (277 trimmed faces) at 0.5 mm", "",
                  "| step | result | goal |", "|---|---:|---:|",
                  f"| load_model (IGES import) | {t_load:.1f} s wall | |",
                  f"| prepare(spacing=0.5), {p.n_points:,} model points, max_distance "
                  f"{p.max_distance:.2f} mm | **{iw:.1f} s wall** ({ic:.1f} s CPU) | <= 30 s |",
                  f"| memory | **{p.memory_per_point:.0f} bytes/point** | <= 200 |",
                  f"| save .svm ({size_mb:.1f} MiB) | {t_save:.2f} s | |",
                  f"| load_prepared | **{t_lp:.2f} s** wall | <= 0.5 s |",
                  f"| fast path, {qi.shape[0]:,} queries within 2 mm | "
                  f"{fmt_rate(qi.shape[0], fic)}/s CPU, {kic / fic:.1f}x cKDTree | |",
                  f"| exact mode | {qie.shape[0] / eic / 1e6:.3f} M/s CPU "
                  f"({eic / qie.shape[0] * 1e6:.2f} us/point), "
                  f"**{per_ocp_i * qie.shape[0] / eic:.0f}x OCP** ({per_ocp_i * 1e6:.0f} us/point)"
                  " | >= 100x |",
                  f"| agreement with OCP ({n_i} interior feet) | max {agree_i:.1e} mm | 1e-8 |", ""]
        print("\n".join(lines[-12:]))
    lines += [f"cores: {os.cpu_count()}; {platform.processor() or platform.machine()}; "
              f"load average at start {load0:.1f} (other processes share the machine: CPU time "
              "is the fairer single-core figure)", ""]
    if args.out:
        Path(args.out).write_text("\n".join(lines))
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
