"""Held-back matrix for issue 29 item 1: one dent, one region, its area, extreme and centroid,
on scans that shapeverify's simulator did not make (``tests/independent_scans.py``: points drawn
on OpenCASCADE's tessellation of the CAD file, uniformly by area, on a lattice in random order,
in scanner row order, or in rows 3 x farther apart than the points along them; a smooth
``cos^2`` dent along the normal; Gaussian noise along the normal).

Parts and scales (every length follows the part): the wavy cube (1 mm box, dent radius 0.12,
tolerance 0.02, depth 0.05, noise 0.002), the bundled panel (300 mm, radius 15, tolerance 0.2,
depth 0.5, noise 0.02) and the hammer (40.9 m in its file's units: the panel's tolerance, depth and noise x 113, dent radius 1200, as its largest face allows).
Spacings: 1/50, 1/15 and 1/5 of the dent radius (the panel's 0.3, 1 and 3 mm).  The dented scan
covers the surface within 3 dent radii of the dent (a whole part at 1/50 of the radius would be
millions of points); the true out-of-tolerance area is integrated on the tessellation by Monte
Carlo.  Each scan is inspected with :func:`inspect_registered` at the true pose.

Printed per part, sampler and spacing (over the seeds): regions found, area / true area - 1,
extreme / depth - 1 (and its stated uncertainty / depth), the centroid's distance from the dent's
centre and its spread over the seeds (in spacings; a curved part's centroid, a mean of points on
the surface, lies inside it).

Run:  PYTHONPATH=src .venv/bin/python benchmarks/check_region_matrix.py [--seeds 2] [--parts cube panel hammer]
[--dump regions.json] (``--dump``: every scan's regions as JSON, to compare two versions' answers)
"""
from __future__ import annotations

import argparse
import sys
import time
import types
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
CAD = HERE.parents[1] / "shared" / "data" / "cad"

#: part: (file, dent radius, tolerance, depth (< 0: a dent), noise)
K = 40854.05 / 361.06
PARTS = {"cube": ("wavy-cube.stp", 0.12, 0.02, -0.05, 0.002),
         "panel": (None, 15.0, 0.2, -0.5, 0.02),
         "hammer": ("hammer.iges", 1200.0, 0.2 * K, -0.5 * K, 0.02 * K)}
RATIOS = (1 / 50, 1 / 15, 1 / 5)
SAMPLERS = ("random", "grid", "scanner", "aniso")


def identity():
    return types.SimpleNamespace(T_model_scan=np.eye(4), rms=0.0, iterations=1, converged=True,
                                 inlier_fraction=1.0)


def load(name, cache: Path):
    import shapeverify as sv
    import independent_scans as ind

    file = PARTS[name][0]
    if file is None:
        from shapeverify.cad.examples import example_part_step
        path = example_part_step(cache / "panel.step")
    else:
        path = CAD / file
    svm = cache / f"{name}.svm"
    if svm.exists():
        prep = sv.load_prepared(svm)
    else:
        prep = sv.prepare(sv.load_model(path))
        prep.save(svm)
    size = float(prep.model.size)
    V, T, F = ind.tessellate(ind.read_shape(path), (2e-4 if name == "cube" else 2e-5) * size)
    area = 0.5 * np.linalg.norm(np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]]), axis=1)
    ok = np.isfinite(area) & (area > 0)                  # degenerate triangles hold no points
    return prep, V, T[ok], F[ok]


def run(names, seeds, cache, dump=None):
    import independent_scans as ind
    from shapeverify.inspection import inspect_registered

    rows = []
    for name in names:
        _, R, tol, depth, noise = PARTS[name]
        prep, V, T, F = load(name, cache)
        center = ind.dent_site(V, T, F, R)
        cen = V[T].mean(axis=1)
        reach = np.max([np.linalg.norm(V[T[:, j]] - cen, axis=1) for j in range(3)], axis=0)
        Tp = T[np.linalg.norm(cen - center, axis=1) < 3 * R + reach]   # cropped to 3 R below
        truth = ind.true_area(V, T, center, depth, R, tol, np.random.default_rng(0))
        print(f"\n{name}: dent radius {R:.4g}, depth {depth:.4g}, tolerance {tol:.4g}, noise "
              f"{noise:.3g}; true out-of-tolerance area {truth:.5g}", flush=True)
        for sampler in SAMPLERS:
            for ratio in RATIOS:
                s = ratio * R
                h = s / np.sqrt(3) if sampler == "aniso" else s     # same area per point
                res_rows = []
                for seed in range(seeds):
                    rng = np.random.default_rng(100 + seed)
                    P = ind.scan(V, Tp, sampler, h, rng, noise=noise, dents=[(center, depth, R)],
                                 aniso=3.0)
                    P = P[np.linalg.norm(P - center, axis=1) < 3 * R]
                    t0 = time.perf_counter()
                    res = inspect_registered(prep, P, identity(), tolerance=tol)
                    dt = time.perf_counter() - t0
                    regs = [r for r in res.regions if r.kind == "deviation"]
                    if dump is not None:
                        dump.append({"part": name, "sampler": sampler, "ratio": ratio, "seed": seed,
                                     "verdict": res.verdict,
                                     "outliers": res.outliers.to_dict() if res.outliers is not None else None,
                                     "regions": [dict(r.to_dict(), indices=[int(i) for i in r.indices])
                                                 for r in res.regions]})
                    other = len(res.regions) - len(regs)
                    if regs:
                        r = regs[0]
                        u = getattr(r, "extreme_uncertainty", float("nan"))
                        res_rows.append((len(regs), other, r.area / truth - 1, r.extreme / depth - 1,
                                         np.linalg.norm(r.centroid - center) / s, u / abs(depth),
                                         len(P), dt, *r.centroid))
                    else:
                        res_rows.append((0, other, np.nan, np.nan, np.nan, np.nan, len(P), dt,
                                         np.nan, np.nan, np.nan))
                a = np.array(res_rows, float)
                c = a[:, 8:11]
                spread = np.nanmax(np.linalg.norm(c - np.nanmean(c, axis=0), axis=1)) / s
                a = np.column_stack([a, np.full(len(a), spread)])
                rows.append((name, sampler, ratio, a))
                print(f"{name:6s} {sampler:7s} s=R/{1 / ratio:<4.0f} pts {int(a[:, 6].mean()):6d} "
                      f"regions {'/'.join(str(int(x)) for x in a[:, 0])} other "
                      f"{'/'.join(str(int(x)) for x in a[:, 1])} "
                      f"area {' '.join(f'{100 * x:+.1f}' for x in a[:, 2])} % "
                      f"extreme {' '.join(f'{100 * x:+.1f}' for x in a[:, 3])} % "
                      f"(+-{' '.join(f'{100 * x:.1f}' for x in a[:, 5])}) "
                      f"centroid {' '.join(f'{x:.2f}' for x in a[:, 4])} s from the centre, "
                      f"{a[0, 11]:.2f} s from the seeds' mean  "
                      f"{a[:, 7].mean():.2f} s/scan", flush=True)
    return rows


def summary(rows):
    print("\n| part | regions != 1 | worst area error | worst extreme error | worst extreme error "
          "/ stated uncertainty | worst centroid spread over seeds (spacings) |")
    print("|---|---:|---:|---:|---:|---:|")
    for name in dict.fromkeys(r[0] for r in rows):
        a = np.vstack([r[3] for r in rows if r[0] == name])
        print(f"| {name} | {int(np.count_nonzero(a[:, 0] != 1))} of {len(a)} | "
              f"{100 * np.nanmax(np.abs(a[:, 2])):.1f} % | {100 * np.nanmax(np.abs(a[:, 3])):.1f} % | "
              f"{np.nanmax(np.abs(a[:, 3]) / a[:, 5]):.2f} | {np.nanmax(a[:, 11]):.2f} |")
    for ratio in RATIOS:
        a = np.vstack([r[3] for r in rows if r[2] == ratio])
        print(f"| s = R/{1 / ratio:.0f}, all parts | {int(np.count_nonzero(a[:, 0] != 1))} of {len(a)} | "
              f"{100 * np.nanmax(np.abs(a[:, 2])):.1f} % | {100 * np.nanmax(np.abs(a[:, 3])):.1f} % | "
              f"{np.nanmax(np.abs(a[:, 3]) / a[:, 5]):.2f} | {np.nanmax(a[:, 11]):.2f} |")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--parts", nargs="*", default=list(PARTS))
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--cache", type=Path, default=Path("/tmp/region_matrix"))
    ap.add_argument("--dump", type=Path, default=None,
                    help="write every scan's regions (and outlier counts) to this JSON file")
    args = ap.parse_args()
    args.cache.mkdir(parents=True, exist_ok=True)
    dump = [] if args.dump is not None else None
    summary(run(args.parts, args.seeds, args.cache, dump))
    if dump is not None:
        import json
        args.dump.write_text(json.dumps(dump, indent=1))


if __name__ == "__main__":
    main()
