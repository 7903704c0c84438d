"""Benchmark: partial views placed from no start and from 10 deg starts (issue 30 items 3-4),
shapeverify against Open3D, and how often each registration warning fires on right and on
wrong poses.

The held-back sets of issue 30 are NOT on this machine: the inputs are the proxies of
``tests/partial_view_proxies.py`` (read its docstring): a 19-tooth micro gear's rim band (mesh,
noise 1 um, form deviation 6-14 um RMS), the bundled turned part's ring band (OpenCASCADE,
spin free), one side of a box (OpenCASCADE tessellation, depth noise 1.5 mm, 4 symmetric
copies), and the real Stanford bunny views bun000/045/090 against their merged cloud.  Scans
are drawn by area on triangles (not the project's simulator) and put in a seeded sensor frame.

Starts: ``none`` -- shapeverify ``register(scan, prep)`` (init auto: identity check, global
search), Open3D 0.20 FPFH + RANSAC (the settings of ``bench_global.py``) then point-to-plane ICP;
``10deg`` -- the true pose turned 10 deg about a random axis through the scan's centroid and
shifted 1 % of the model's size: shapeverify ``register(scan, prep, init=T0)``, Open3D
point-to-plane ICP (threshold one voxel = size / 40) from T0; ``45deg`` and ``120deg`` -- the
same, 45 deg / 5 % and 120 deg / 10 % of the size off (starts from which a local method often
ends in a wrong minimum: the sets that show whether the warnings catch wrong poses).

Right: rotation < 2 deg and translation (at the scan's centroid) < 1 % of the model's size,
against the nearest symmetric copy of the true pose (gear 38, box 4, turned part every spin):
every copy is an equally right answer.  Wrong: anything else.  Warned: the registration carries
a warning other than the symmetric-copy note (kind ``symmetric-copy``, which reports the copies
of a right pose, not a doubt).

Run:  PYTHONPATH=src .venv/bin/python benchmarks/bench_partial_views.py run --sets gear box \\
          --n 12 ; ... report   (writes benchmarks/results_partial_views.md)
"""
from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
import partial_view_proxies as pv  # noqa: E402

from shapeverify.nearest import prepare  # noqa: E402
from shapeverify.registration import register  # noqa: E402
from shapeverify.registration.rigid import make_transform, rodrigues, rotation_vector  # noqa: E402

DATA = HERE.parents[1] / "shared" / "data"
OUT = Path(os.environ.get("PV_OUT", "/tmp/partial_views"))


def errors(T, T_true, scan, copies):
    """(rotation deg, translation mm at the scan's centroid) against the nearest copy."""
    c = T_true[:3, :3] @ scan.mean(axis=0) + T_true[:3, 3]
    best = None
    for S in copies:
        dT = np.linalg.inv(S) @ T @ np.linalg.inv(T_true)
        e = (float(np.degrees(np.linalg.norm(rotation_vector(dT[:3, :3])))),
             float(np.linalg.norm(dT[:3, :3] @ c + dT[:3, 3] - c)))
        if best is None or e[0] / 2.0 + e[1] < best[0] / 2.0 + best[1]:
            best = e
    return best


def cases(name, n):
    """(prep, [(label, scan, T_true)], copies) of one proxy set."""
    if name == "gear":
        prep = prepare(pv.gear_model(), spacing=0.015)
        items = []
        for s in range(n):
            scan, T, form = pv.gear_band(s, sector=None if s % 2 == 0 else 120.0)
            items.append((f"gear {'ring' if s % 2 == 0 else 'sector'} {s} form {1e3 * form:.0f}um",
                          scan, T))
        return prep, items, pv.gear_copies()
    if name == "turned":
        prep = prepare(pv.turned_model())
        return prep, [(f"turned {'ring' if s % 2 == 0 else 'half'} {s}", *pv.turned_band(s))
                      for s in range(n)], pv.spin_copies()
    if name == "box":
        prep = prepare(pv.box_model())
        return prep, [(f"box {s}", *pv.box_view(s)) for s in range(n)], pv.box_copies()
    if name == "panel":
        prep = prepare(pv.panel_model())
        return prep, [(f"panel {s}", *pv.panel_view(s)) for s in range(n)], [np.eye(4)]
    if name == "bunny":
        views = pv.bunny(DATA)
        preps = {v: prepare(views[v][2], spacing=1.0) for v in pv.BUNNY_VIEWS}
        items = []
        for s in range(n):
            v = pv.BUNNY_VIEWS[s % 3]
            items.append((f"bunny {v[:-4]} {s}", *pv.bunny_view(views, v, s), preps[v]))
        return None, items, [np.eye(4)]
    raise ValueError(f"unknown set {name!r}")


def given_start(T_true, scan, size, seed, deg=10.0, shift=0.01):
    """The true pose turned ``deg`` about a random axis through the scan's centroid and shifted
    ``shift`` x the model's size (seeded)."""
    rng = np.random.default_rng(1000 + seed + int(deg))
    a = rng.normal(size=3)
    R = rodrigues(np.radians(deg) * a / np.linalg.norm(a))
    c = T_true[:3, :3] @ scan.mean(axis=0) + T_true[:3, 3]
    v = rng.normal(size=3)
    D = make_transform(R, c - R @ c + shift * size * v / np.linalg.norm(v))
    return D @ T_true


#: the starts: none (global search), given 10 deg / 1 % off, given 45 deg / 5 % off (where a
#: local method ends in wrong minima: what the warnings must catch)
STARTS = {"none": None, "10deg": (10.0, 0.01), "45deg": (45.0, 0.05), "120deg": (120.0, 0.1)}


class Open3DPeer:
    def __init__(self, prep):
        import open3d as o3d

        from shapeverify.registration.global_search import _model_side

        self.o3d = o3d
        o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
        self.voxel = _model_side(prep).voxel
        mp = prep.points
        tgt = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.array(mp.points)))
        tgt.normals = o3d.utility.Vector3dVector(np.array(mp.normals))
        self.full = tgt
        self.down = tgt.voxel_down_sample(self.voxel)
        self.down.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=2 * self.voxel,
                                                                        max_nn=30))
        self.fpfh = self._fpfh(self.down)

    def _fpfh(self, pc):
        return self.o3d.pipelines.registration.compute_fpfh_feature(
            pc, self.o3d.geometry.KDTreeSearchParamHybrid(radius=5 * self.voxel, max_nn=100))

    def icp(self, src, T0):
        reg = self.o3d.pipelines.registration
        return np.asarray(reg.registration_icp(
            src, self.full, self.voxel, T0, reg.TransformationEstimationPointToPlane(),
            reg.ICPConvergenceCriteria(max_iteration=60)).transformation)

    def run(self, scan, T0=None):
        o3d = self.o3d
        reg = o3d.pipelines.registration
        o3d.utility.random.seed(0)
        src = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.array(scan)))
        if T0 is not None:
            return self.icp(src, T0)
        down = src.voxel_down_sample(self.voxel)
        down.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=2 * self.voxel,
                                                                   max_nn=30))
        thr = 1.5 * self.voxel
        res = reg.registration_ransac_based_on_feature_matching(
            down, self.down, self._fpfh(down), self.fpfh, False, thr,
            reg.TransformationEstimationPointToPoint(False), 3,
            [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9),
             reg.CorrespondenceCheckerBasedOnDistance(thr)],
            reg.RANSACConvergenceCriteria(100000, 0.999))
        return self.icp(src, np.asarray(res.transformation))


def kinds(reg):
    return [getattr(w, "kind", "?") for w in reg.warnings]


def _tilt(scan, prep, reg):
    """(sigma, noise, surface_tilt ...) at the final pose (calibration of the warnings)."""
    from shapeverify.registration import _irls
    from shapeverify.registration._noise import scan_noise
    from shapeverify.registration._pose_warnings import surface_tilt

    T = np.asarray(reg.T_model_scan)
    m = _irls.match(scan, prep, T[:3, :3], T[:3, 3])
    ev = type("E", (), dict(X=m.X, N=m.N, valid=m.valid, w=np.asarray(reg.weights)))
    return [float(reg.scale), float(scan_noise(scan[::max(1, scan.shape[0] // 200_000)])),
            *surface_tilt(ev)]


def run(args):
    OUT.mkdir(parents=True, exist_ok=True)
    for name in args.sets:
        prep0, items, copies = cases(name, args.n)
        peers, rows = {}, []
        for k, (label, scan, T_true, *own) in enumerate(items):
            prep = own[0] if own else prep0
            size = float(prep.model.size)
            if id(prep) not in peers:
                peers[id(prep)] = Open3DPeer(prep) if not args.no_o3d else None
                with warnings.catch_warnings():          # warm-up: numba, model-side caches
                    warnings.simplefilter("ignore")
                    register(scan, prep)
            peer = peers[id(prep)]
            for start in args.starts:
                how = STARTS[start]
                T0 = None if how is None else given_start(T_true, scan, size, k, *how)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    t = time.perf_counter()
                    reg = register(scan, prep, init=T0)
                    t_sv = time.perf_counter() - t
                e = errors(reg.T_model_scan, T_true, scan, copies)
                row = dict(set=name, label=label, start=start, n=int(scan.shape[0]), size=size,
                           sv_err=e, sv_t=t_sv, converged=bool(reg.converged),
                           warnings=[str(w) for w in reg.warnings], kinds=kinds(reg),
                           scale=float(reg.scale), init=reg.init,
                           T=np.asarray(reg.T_model_scan).tolist(), seed=k)
                if peer is not None:
                    t = time.perf_counter()
                    T_o = peer.run(scan, T0)
                    row.update(o3d_err=errors(T_o, T_true, scan, copies),
                               o3d_t=time.perf_counter() - t)
                row.update(tilt=_tilt(scan, prep, reg))
                rows.append(row)
                print(f"{label:30s} {start:5s} sv {e[0]:8.3f} deg {e[1]:8.4f} mm "
                      f"conv={reg.converged} {kinds(reg)} {t_sv:.1f}s"
                      + (f" | o3d {row['o3d_err'][0]:8.3f} deg {row['o3d_err'][1]:8.4f} mm"
                         if peer is not None else ""), flush=True)
        (OUT / f"{name}{args.tag}.json").write_text(json.dumps(
            dict(rows=rows, load=subprocess.run(["uptime"], capture_output=True,
                                                text=True).stdout.strip(),
                 date=str(datetime.datetime.now(datetime.timezone.utc))[:16],
                 command=" ".join(sys.argv))))


def right(e, size):
    return e[0] < 2.0 and e[1] < 0.01 * size


def warned(row):
    return any(k != "symmetric-copy" for k in row["kinds"])


ALL_KINDS = ("inliers", "scale", "noise", "rejected", "mean", "runner-up", "better-elsewhere",
             "symmetric-copy")


def report(args):
    sets = [json.loads(p.read_text()) for p in sorted(OUT.glob("*.json"))]
    from shapeverify.registration._pose_warnings import WRONG_MINIMUM

    lines = ["# Partial views from no start and from given starts 10/45/120 deg off (issue 30 "
             "items 3-4)", "",
             "Inputs are **proxies made here**, not issue 30's held-back sets (not on this "
             "machine): see `tests/partial_view_proxies.py` and the docstring of "
             "`benchmarks/bench_partial_views.py` (sets, criteria, Open3D settings).  One "
             "thread; 2 cores shared by ~9 sessions (times are indicative only).", ""]
    for s in sets:
        lines.append(f"- `{s['command']}` ({s['date']} UTC; load `{s['load']}`)")
    lines += ["", "## Right / wrong / flagged", "",
              "Right: < 2 deg and < 1 % of the model's size from the nearest symmetric copy.  "
              "Flagged: a wrong pose that carries a warning (or is not converged).  "
              "Silent wrong: wrong, converged, no warning.  Wrong -> error: wrong poses with a "
              "warning of a `wrong_minimum` kind (" + ", ".join(sorted(WRONG_MINIMUM)) + "), "
              "which the verdict turns into `error (registration)` (rule 2b).", "",
              "| set | start | cases | shapeverify right | wrong flagged | silent wrong | "
              "wrong -> error | right with a warning | right with symmetric copies reported | "
              "time s (median) | Open3D right | Open3D time s |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in sets:
        for start in STARTS:
            rs = [r for r in s["rows"] if r["start"] == start]
            if not rs:
                continue
            ok = [right(r["sv_err"], r["size"]) for r in rs]
            wrong = [r for r, o in zip(rs, ok) if not o]
            good = [r for r, o in zip(rs, ok) if o]
            flagged = sum(warned(r) or not r["converged"] for r in wrong)
            o3d = [right(r["o3d_err"], r["size"]) for r in rs if "o3d_err" in r]
            lines.append(
                f"| {rs[0]['set']} | {start} | {len(rs)} | {sum(ok)} | {flagged} | "
                f"{len(wrong) - flagged} | "
                f"{sum(any(k in WRONG_MINIMUM for k in r['kinds']) for r in wrong)} | "
                f"{sum(warned(r) for r in good)} | "
                f"{sum('symmetric-copy' in r['kinds'] for r in good)} | "
                f"{np.median([r['sv_t'] for r in rs]):.1f} | "
                + (f"{sum(o3d)}/{len(o3d)} | {np.median([r['o3d_t'] for r in rs]):.1f} |"
                   if o3d else "- | - |"))
    lines += ["", "## How often each warning fires (shapeverify)", "",
              "Counts of poses carrying each warning kind (`PoseWarning.kind`), over all sets "
              "and starts.", "",
              "| warning kind | on right poses | on wrong poses |", "|---|---|---|"]
    rows = [r for s in sets for r in s["rows"]]
    good = [r for r in rows if right(r["sv_err"], r["size"])]
    bad = [r for r in rows if not right(r["sv_err"], r["size"])]
    for k in ALL_KINDS:
        lines.append(f"| {k} | {sum(k in r['kinds'] for r in good)}/{len(good)} | "
                     f"{sum(k in r['kinds'] for r in bad)}/{len(bad)} |")
    lines.append(f"| any but symmetric-copy | {sum(warned(r) for r in good)}/{len(good)} | "
                 f"{sum(warned(r) for r in bad)}/{len(bad)} |")
    lines += ["", "## Per case", "", "```"]
    for r in rows:
        o = r.get("o3d_err")
        lines.append(f"{r['label']:30s} {r['start']:5s} n={r['n']:6d} sv {r['sv_err'][0]:8.3f} "
                     f"deg {r['sv_err'][1]:9.4f} mm conv={r['converged']} {r['kinds']} "
                     f"({r['init']}) {r['sv_t']:.1f}s"
                     + (f" | o3d {o[0]:8.3f} deg {o[1]:9.4f} mm" if o else ""))
    lines += ["```", ""]
    Path(args.out).write_text("\n".join(lines))
    print("\n".join(lines[: 30]))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("what", choices=("run", "report"))
    ap.add_argument("--sets", nargs="+", default=["gear", "turned", "box", "bunny"])
    ap.add_argument("--n", type=int, default=12)
    ap.add_argument("--no-o3d", action="store_true")
    ap.add_argument("--starts", nargs="+", default=["none", "10deg", "45deg"],
                    choices=tuple(STARTS))
    ap.add_argument("--tag", default="", help="suffix of the set's JSON file")
    ap.add_argument("--out", default=str(HERE / "results_partial_views.md"))
    args = ap.parse_args()
    run(args) if args.what == "run" else report(args)


if __name__ == "__main__":
    main()
