"""Held-back check for issue 29 item 1 beyond the round dent: defect shapes and parts that
``benchmarks/check_region_matrix.py`` does not try, on the same independent scans
(``tests/independent_scans.py``: points drawn on OpenCASCADE's tessellation of the CAD file,
uniformly by area / on a lattice in random order / in scanner row order / in rows 3 x farther
apart; Gaussian noise along the normal), inspected with :func:`inspect_registered` at the true
pose.

Defects (every length follows the part's dent radius ``R`` of the matrix; a profile is
``depth * cos^2(pi r / 2W)`` of a distance ``r`` along each triangle's outward normal):

* ``bump``: the matrix's dent with the sign turned (material, +depth);
* ``groove`` / ``arc``: a scratch of half-width ``W = R/2`` whose centre line is 20 W long
  (10:1 to its width): a straight segment, or a quarter circle, in the tangent plane at the
  site, put onto the surface point by point (``r``: distance to the centre line);
* ``edge``: a round dent of radius ``R`` centred on an edge between the largest face and a
  neighbour (sharp or tangent; the angle is printed);  the true deviation is the CAD distance of
  the displaced points (on a convex edge a point pushed into one face can lie nearer the other);
* ``rim``: the round dent at the edge of the scanned area (the scan keeps the half plane beyond
  a line ``RIM_CUT x R`` from its centre: its deepest point is scanned, a third of its
  out-of-tolerance disc is not; where a lattice's last row lies is unknown to within a row, so
  the area's error spreads by about that row times the cut chord);
* ``pairG``: two round dents (each point takes the deeper) whose out-of-tolerance discs are
  ``G`` spacings apart (``pair1``, ``pair2``, ``pair3``, ``pair5``): region count printed
  against the geometric truth (two);
* ``hole``: a round dent on the wall of the NIST part's largest cylinder (radius
  ``min(R, rim distance / 1.5)``).

Spacings: 1/50, 1/15 and 1/5 of ``W`` (``R``, or the groove's half-width).  The scan covers the
surface within 3 W of the defect (1.5 W for grooves).  True out-of-tolerance area: Monte Carlo
on the tessellation, cropped like the scan.  For every case the same scan without the defect
(the good part, seed 0) is inspected as well: it must pass with no region at all.

Printed per case: regions (deviation / material / other), area / true - 1, extreme / true
extreme - 1; the good part's verdict and region count.

Run:  PYTHONPATH=src .venv/bin/python benchmarks/check_defect_shapes.py [--parts panel cube ctc01]
[--defects bump groove arc edge rim pair1 pair2 pair3 hole dent] [--seeds 2] [--ratios 50 15 5]
[--samplers random grid scanner aniso] [--dump out.json]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE))

import check_region_matrix as crm  # noqa: E402

RIM_CUT = 0.3
crm.PARTS["ctc01"] = ("nist/nist_ctc_01_asme1_ap242-e1.stp", 15.0, 0.2, -0.5, 0.02)
crm.PARTS["ftc06"] = ("nist/nist_ftc_06_asme1_ap242-e1.stp", 15.0, 0.2, -0.5, 0.02)


def _rims(V, T, F):
    """Per face: sample points along its boundary edges (the tessellation's unshared edges)."""
    out = {}
    t = np.linspace(0.0, 1.0, 12)[:, None, None]
    for f in np.unique(F):
        tf = T[F == f]
        e = np.sort(np.vstack([tf[:, [0, 1]], tf[:, [1, 2]], tf[:, [2, 0]]]), axis=1)
        ue, cnt = np.unique(e, axis=0, return_counts=True)
        r = ue[cnt == 1]
        out[f] = (V[r[:, 0]][None] * (1 - t) + V[r[:, 1]][None] * t).reshape(-1, 3)
    return out


def site_on(V, T, F, f, rims):
    """The point of face ``f`` farthest from its rim, and that distance."""
    import independent_scans as ind
    sel = np.flatnonzero(F == f)
    area = ind._tri_geometry(V, T[sel])[4].sum()
    cand, _ = ind.random_points(V, T, np.sqrt(area / 5000), np.random.default_rng(0), tris=sel)
    d, _ = cKDTree(rims[f]).query(cand)
    i = np.argmax(d)
    return cand[i], d[i]


def edge_site(V, T, F, f, rims, R, size):
    """A point on an edge of face ``f`` shared with one other face ``g``, as far as can be from
    every other face's rim; (point, g, that distance)."""
    others = [g for g in rims if g != f]
    lab = np.concatenate([np.full(len(rims[g]), g) for g in others])
    tree = cKDTree(np.vstack([rims[g] for g in others]))
    P = rims[f]
    d, i = tree.query(P)
    on = d < 1e-4 * size
    best = (None, None, -1.0)
    for k in np.flatnonzero(on)[:: max(1, on.sum() // 3000)]:
        g = lab[i[k]]
        near = tree.query_ball_point(P[k], 2.0 * R)
        third = [j for j in near if lab[j] != g]
        # distance to the nearest rim point of a third face
        dd = min([np.linalg.norm(tree.data[j] - P[k]) for j in third], default=2.0 * R)
        own = np.linalg.norm(P - P[k], axis=1)
        # a corner of f itself: f's rim points away from the shared edge count too
        far_own = own[~on]
        dd = min(dd, far_own.min() if far_own.size else dd)
        if dd > best[2]:
            best = (P[k], g, dd)
    return best


def face_kinds(path):
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_Cylinder
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS
    import independent_scans as ind
    shape = ind.read_shape(path)
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    cyl = []
    while exp.More():
        s = BRepAdaptor_Surface(TopoDS.Face(exp.Current()))
        cyl.append(s.GetType() == GeomAbs_Cylinder)
        exp.Next()
    return np.array(cyl)


class Defect:
    """``field(P)``: displacement along the normal; ``keep(P)``: the scan's crop."""

    def __init__(self, kind, width, depth, dist, keep, cad_truth=False, pieces=1):
        self.kind, self.width, self.depth = kind, width, depth
        self.dist, self.keep, self.cad_truth, self.pieces = dist, keep, cad_truth, pieces

    def field(self, P):
        r = self.dist(P)
        return np.where(r < self.width, self.depth * np.cos(np.pi * r / (2 * self.width)) ** 2, 0.0)


def centre_line(prep, c, n, length, curved, step):
    e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    s = np.arange(-length / 2, length / 2 + step / 2, step)
    if curved:
        rho = length / (np.pi / 2)
        th = s / rho
        Q = c + rho * np.sin(th)[:, None] * e1 + (rho * (1 - np.cos(th)))[:, None] * e2
    else:
        Q = c + s[:, None] * e1
    for _ in range(2):
        Q = prep.closest(Q).points
    return Q


def make_defect(kind, prep, V, T, F, rims, R, depth, tol, s_of_W, path, size):
    """(Defect, its centre) for ``kind``; ``s_of_W(W)``: the spacing for half-width W."""
    area = crm_area(V, T)
    fmain = int(np.argmax(np.bincount(F, weights=area)))
    if kind == "hole":
        cyl = face_kinds(path)
        best = max(((site_on(V, T, F, f, rims), f) for f in np.flatnonzero(cyl) if f in rims),
                   key=lambda x: x[0][1])
        (c, dr), f = best
        W = min(R, dr / 1.5)
    else:
        c, dr = site_on(V, T, F, fmain, rims)
        W = R
    cp = prep.closest(c[None])
    c, n = cp.points[0], cp.normals[0]
    if kind in ("groove", "arc"):
        W = min(R / 2, dr / 12)
        Q = centre_line(prep, c, n, 20 * W, kind == "arc", W / 100)
        tree = cKDTree(Q)
        dist = lambda P: tree.query(P)[0]  # noqa: E731
        return Defect(kind, W, depth, dist, lambda P: dist(P) < 1.5 * W), c
    if kind == "edge":
        c, g, dd = edge_site(V, T, F, fmain, rims, R, size)
        W = min(R, dd / 1.5)
        dist = lambda P: np.linalg.norm(P - c, axis=1)  # noqa: E731
        d = Defect(kind, W, depth, dist, lambda P: dist(P) < 3 * W, cad_truth=True)
        d.faces = (fmain, g)
        return d, c
    if kind == "rim":
        e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        dist = lambda P: np.linalg.norm(P - c, axis=1)  # noqa: E731
        return Defect(kind, W, depth, dist,
                      lambda P: (dist(P) < 3 * W) & ((P - c) @ e1 > -RIM_CUT * W)), c
    if kind.startswith("pair"):
        gap = float(kind[4:])
        r0 = W * (2 / np.pi) * np.arccos(np.sqrt(tol / abs(depth)))   # out-of-tolerance radius
        half = r0 + gap * s_of_W(W) / 2
        W = min(W, (dr - half) / 1.5)
        r0 = W * (2 / np.pi) * np.arccos(np.sqrt(tol / abs(depth)))
        half = r0 + gap * s_of_W(W) / 2
        e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        C = prep.closest(np.array([c - half * e1, c + half * e1])).points
        dist = lambda P: np.min([np.linalg.norm(P - x, axis=1) for x in C], axis=0)  # noqa: E731
        return Defect(kind, W, depth, dist, lambda P: dist(P) < 3 * W, pieces=2), c
    sign = -1 if kind != "bump" else 1
    dist = lambda P: np.linalg.norm(P - c, axis=1)  # noqa: E731
    return Defect(kind, W, sign * abs(depth), dist, lambda P: dist(P) < 3 * W), c


def crm_area(V, T):
    return 0.5 * np.linalg.norm(np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]]), axis=1)


def truth(defect, prep, V, T, tol, n=300_000):
    """(out-of-tolerance area, extreme signed deviation) by Monte Carlo on the tessellation."""
    import independent_scans as ind
    a, b, c, _, area = ind._tri_geometry(V, T)
    cen = (a + b + c) / 3
    reach = np.sqrt(area.max()) * 3
    near = np.flatnonzero(defect.dist(cen) < defect.width + reach)
    A = area[near].sum()
    P, N = ind.random_points(V, T, np.sqrt(A / n), np.random.default_rng(0), tris=near)
    h = defect.field(P)
    keep = defect.keep(P)
    if defect.cad_truth:
        m = np.abs(h) > 0
        d = np.zeros(len(P))
        d[m] = prep.closest(P[m] + h[m, None] * N[m], exact=True).distances \
            - prep.closest(P[m], exact=True).distances
    else:
        d = h
    out = (np.abs(d) > tol) & keep
    ext = d[keep][np.argmax(np.abs(d[keep]))]
    return A * np.mean(out), ext


def scan(V, Tp, sampler, h, rng, noise, defect, good=False):
    import independent_scans as ind
    if sampler == "random":
        P, N = ind.random_points(V, Tp, h, rng)
    else:
        P, N, _ = ind.lattice_points(V, Tp, h, rng, aniso=3.0 if sampler == "aniso" else 1.0,
                                     order="scanner" if sampler == "scanner" else "random")
    dz = rng.normal(0.0, noise, len(P))
    if not good:
        dz = dz + defect.field(P)
    Q = P + dz[:, None] * N
    return Q[defect.keep(P)]


def inspect(prep, P, tol):
    from shapeverify.inspection import inspect_registered
    t0 = time.perf_counter()
    res = inspect_registered(prep, P, crm.identity(), tolerance=tol)
    return res, time.perf_counter() - t0


def run(args):
    import independent_scans as ind
    rows, dump = [], []
    for name in args.parts:
        file, R, tol, depth, noise = crm.PARTS[name]
        prep, V, T, F = crm.load(name, args.cache)
        size = float(prep.model.size)
        path = crm.CAD / file if file else args.cache / "panel.step"
        rims = _rims(V, T, F)
        for kind in args.defects:
            if kind == "hole" and not name.startswith(("ctc", "ftc")):
                continue
            if kind == "edge" and len(rims) < 2:        # the panel is one face
                continue
            for ratio in args.ratios:
                defect, c = make_defect(kind, prep, V, T, F, rims, R, depth, tol,
                                        lambda W: W / ratio, path, size)
                W = defect.width
                s = W / ratio
                cen = V[T].mean(axis=1)
                reach = np.max([np.linalg.norm(V[T[:, j]] - cen, axis=1) for j in range(3)], axis=0)
                Tp = T[defect.dist(cen) < 3 * W + reach]
                area_t, ext_t = truth(defect, prep, V, Tp, tol)
                extra = ""
                if kind == "edge":
                    # the faces' normals near the site: the angle between them at the edge
                    na = []
                    for f in defect.faces:
                        near = np.min([defect.dist(V[T[:, j]]) for j in range(3)], axis=0) < W
                        tf = T[(F == f) & near] if np.any((F == f) & near) else T[F == f]
                        m = np.mean(ind._tri_geometry(V, tf)[3], axis=0)
                        na.append(m / np.linalg.norm(m))
                    ang = np.degrees(np.arccos(np.clip(na[0] @ na[1], -1.0, 1.0)))
                    extra = f" faces {tuple(int(f) for f in defect.faces)}, normals {ang:.0f} deg apart"
                print(f"\n{name} {kind} W {W:.4g} s {s:.4g}: true area {area_t:.5g}, "
                      f"true extreme {ext_t:+.4g}{extra}", flush=True)
                for sampler in args.samplers:
                    h = s / np.sqrt(3) if sampler == "aniso" else s
                    line = []
                    for seed in range(args.seeds):
                        rng = np.random.default_rng(100 + seed)
                        P = scan(V, Tp, sampler, h, rng, noise, defect)
                        res, dt = inspect(prep, P, tol)
                        dev = [r for r in res.regions if r.kind == "deviation"]
                        mat = [r for r in res.regions if r.kind == "material"]
                        oth = len(res.regions) - len(dev) - len(mat)
                        A = sum(r.area for r in dev)
                        ext = max((r.extreme for r in dev), key=abs, default=np.nan)
                        good = None
                        if seed == 0 and not args.no_good:
                            rng = np.random.default_rng(100 + seed)
                            Pg = scan(V, Tp, sampler, h, rng, noise, defect, good=True)
                            rg, _ = inspect(prep, Pg, tol)
                            good = (getattr(rg.verdict, "value", rg.verdict), len(rg.regions),
                                    sum(r.kind == "material" for r in rg.regions))
                        rec = dict(part=name, defect=kind, sampler=sampler, ratio=ratio, seed=seed,
                                   n=len(P), regions=len(dev), material=len(mat), other=oth,
                                   expected=defect.pieces, area=A / area_t - 1,
                                   extreme=ext / ext_t - 1, time=dt, good=good,
                                   region_areas=[r.area / area_t for r in dev],
                                   verdict=res.verdict)
                        line.append(rec)
                        dump.append(dict(rec, answers=[r.to_dict() for r in res.regions]))
                    rows += line
                    gd = line[0]["good"]
                    sa = " ".join(f"{100 * x['area']:+.1f}" for x in line)
                    se = " ".join(f"{100 * x['extreme']:+.1f}" for x in line)
                    print(f"{name:6s} {kind:6s} {sampler:7s} s=W/{ratio:<3g} pts {line[0]['n']:7d} "
                          f"regions {'/'.join(str(x['regions']) for x in line)} "
                          f"mat {'/'.join(str(x['material']) for x in line)} "
                          f"oth {'/'.join(str(x['other']) for x in line)} "
                          f"area {sa} % "
                          f"extreme {se} % "
                          f"good {gd} {np.mean([x['time'] for x in line]):.1f} s/scan", flush=True)
    if args.dump:
        args.dump.write_text(json.dumps(dump, indent=1, default=float))
    return rows


def summary(rows):
    print("\n| part | defect | scans | regions != expected | worst area error | worst extreme error "
          "| good part fails / regions / material |")
    print("|---|---|---:|---:|---:|---:|---:|")
    keys = dict.fromkeys((r["part"], r["defect"]) for r in rows)
    for p, k in keys:
        a = [r for r in rows if r["part"] == p and r["defect"] == k]
        bad = sum(r["regions"] != r["expected"] for r in a)
        ar = [abs(r["area"]) for r in a if r["regions"]]
        ex = [abs(r["extreme"]) for r in a if r["regions"]]
        g = [r["good"] for r in a if r["good"] is not None]
        print(f"| {p} | {k} | {len(a)} | {bad} | {100 * max(ar, default=np.nan):.1f} % | "
              f"{100 * max(ex, default=np.nan):.1f} % | {sum(x[0] == 'fail' for x in g)} / "
              f"{sum(x[1] for x in g)} / {sum(x[2] for x in g)} of {len(g)} |")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--parts", nargs="*", default=["panel", "cube", "ctc01"])
    ap.add_argument("--defects", nargs="*",
                    default=["bump", "groove", "arc", "edge", "rim", "pair1", "pair2", "pair3", "hole"])
    ap.add_argument("--samplers", nargs="*", default=list(crm.SAMPLERS))
    ap.add_argument("--ratios", nargs="*", type=float, default=[50, 15, 5],
                    help="spacing = W / ratio")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--no-good", action="store_true")
    ap.add_argument("--cache", type=Path, default=Path("/tmp/region_matrix"))
    ap.add_argument("--dump", type=Path, default=None)
    args = ap.parse_args()
    args.cache.mkdir(parents=True, exist_ok=True)
    summary(run(args))


if __name__ == "__main__":
    main()
