"""Scan-to-scan: a golden point cloud (1 mm) as the reference, an independent rescan (0.7 mm).

Both clouds are area-uniform random points on the analytic sheet z = 6 sin(x/25) cos(y/30)
(120 x 90 mm), the rescan with Gaussian noise along the normal; the truth of each rescan point's
signed distance is its noise (plus the dent, where one is pressed in).  Prints the distance error
of ``prep.closest(q, exact=True)`` (the inspection's deviations), its speed, and the verdicts of
a clean and a dented rescan at a tolerance of twice the noise.

    PYTHONPATH=src python benchmarks/check_cloud_reference.py
"""

from __future__ import annotations

import time

import numpy as np

W, H = 120.0, 90.0


def height(x, y):
    return 6.0 * np.sin(x / 25.0) * np.cos(y / 30.0)


def normal(x, y):
    hx = 6.0 / 25.0 * np.cos(x / 25.0) * np.cos(y / 30.0)
    hy = -6.0 / 30.0 * np.sin(x / 25.0) * np.sin(y / 30.0)
    n = np.column_stack([-hx, -hy, np.ones_like(x)])
    return n / np.linalg.norm(n, axis=1)[:, None]


def sheet_points(spacing, rng, noise=0.0, dent=None, margin=0.0, stratified=False):
    """Area-uniform random points about ``spacing`` apart (one per spacing² of area) on the
    sheet, moved by ``noise`` (std, mm) and a Gaussian ``dent`` (depth, x, y, sigma) along the
    normal; ``stratified``: one uniform random point in each ``spacing`` square of (x, y)
    instead (a jittered grid: no Poisson gaps).  Returns (points, true signed distance)."""
    if stratified:
        gx = np.arange(margin, W - margin, spacing)
        gy = np.arange(margin, H - margin, spacing)
        X, Y = np.meshgrid(gx, gy, indexing="ij")
        x = X.ravel() + rng.uniform(0, spacing, X.size)
        y = Y.ravel() + rng.uniform(0, spacing, X.size)
        keep = (x < W - margin) & (y < H - margin)
        x, y = x[keep], y[keep]
        nrm = normal(x, y)
    else:
        n = int(round(W * H * 1.2 / spacing ** 2))       # area factor ~1.1 for this sheet
        x = rng.uniform(margin, W - margin, 3 * n)
        y = rng.uniform(margin, H - margin, 3 * n)
        nrm = normal(x, y)
        area = 1.0 / nrm[:, 2]                            # sqrt(1 + hx^2 + hy^2)
        keep = rng.uniform(0, area.max(), x.size) < area
        x, y, nrm = x[keep][:n], y[keep][:n], nrm[keep][:n]
    d = rng.normal(0.0, noise, x.size) if noise else np.zeros(x.size)
    if dent is not None:
        depth, cx, cy, s = dent
        d = d - depth * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * s * s))
    p = np.column_stack([x, y, height(x, y)]) + d[:, None] * nrm
    return p, d


def cloud_model(points):
    from shapeverify.cad.model import Model

    return Model(faces=(), source="golden cloud", kind="points", vertices=points)


def main():
    import shapeverify as sv
    from shapeverify.nearest import prepare

    rng = np.random.default_rng(7)
    noise = 0.02
    golden, _ = sheet_points(1.0, rng, noise=0.0)
    scan, truth = sheet_points(0.7, rng, noise=noise, margin=2.0)
    prep = prepare(cloud_model(golden))
    prep.closest(scan[:100], exact=True)      # build the refiner and compile
    t0 = time.perf_counter()
    near = prep.closest(scan, exact=True)
    dt = time.perf_counter() - t0
    # before (the nearest reference point, as ExactCloud measured until issue 29): same load
    from scipy.spatial import cKDTree

    kd = cKDTree(golden)
    t0 = time.perf_counter()
    d_old, j_old = kd.query(scan)
    idx, _ = prep._fast.nearest(scan)
    n_old = prep._fast.normals(idx)
    d_old = np.where(np.einsum("ij,ij->i", scan - golden[j_old], n_old) < 0, -d_old, d_old)
    dt_old = time.perf_counter() - t0
    side = np.sign(np.median(near.distances * truth))     # an unoriented sheet: which side is +
    e_old = np.abs(side * d_old - truth)
    print(f"before (nearest point): error median {np.median(e_old):.4f}  p95 "
          f"{np.percentile(e_old, 95):.4f} mm; speed {len(scan) / dt_old:,.0f} points/s")
    err = np.abs(side * near.distances - truth)
    print(f"golden {len(golden)} points (1 mm), rescan {len(scan)} points (0.7 mm, noise {noise})")
    print(f"after (quadric): exact distance error: median {np.median(err):.4f}  p95 "
          f"{np.percentile(err, 95):.4f}  "
          f"max {err.max():.4f} mm;  |d| p95 {np.percentile(np.abs(near.distances), 95):.4f} mm")
    print(f"after: speed {len(scan) / dt:,.0f} points/s ({dt:.3f} s)")
    tol = 2 * noise
    res = sv.inspect(prep, scan, tolerance=tol)
    print(f"clean rescan at ±{tol}: {res.verdict.value}, regions {len(res.regions)}, "
          f"reasons {res.reasons[:2]}")
    for strat in (False, True):
        dscan, _ = sheet_points(0.7, rng, noise=noise, margin=2.0, dent=(0.3, 60.0, 45.0, 4.0),
                                stratified=strat)
        res = sv.inspect(prep, dscan, tolerance=tol)
        how = "stratified" if strat else "random"
        print(f"{how} dented rescan (0.3 mm) at ±{tol}: {res.verdict.value}, "
              f"regions {len(res.regions)}: "
              f"{res.reasons[0][:100]}; "
              + "; ".join(f"{r.kind} {r.extreme:+.3f} at {np.round(r.centroid, 1).tolist()}"
                          for r in res.regions[:5]))


if __name__ == "__main__":
    main()
