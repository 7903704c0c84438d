"""Benchmark: registration with no start (issue 14 item 1) against Open3D's FPFH + RANSAC.

Inputs (the same for both tools):

* the example panel (300 x 200 mm sheet with a hole) scanned by the virtual scanner (~30,000
  points, noise 0.03 mm, 5 % outliers) and given in a sensor frame 800 mm away under a random
  rotation (seeded);
* the Stanford bunny views bun045 and bun090 (real, partial overlap) against the bun000 cloud as
  the reference, given 30 deg / 20 mm off their bun.conf pose (skipped when
  ../shared/data is absent);
* the impeller (../shared/data/cad/impeller.igs, default preparation) seen by the virtual
  scanner from 4 directions (5,000-8,000 points, noise 0.02 mm, a third to half of the part),
  given in a sensor frame 120 deg / 300 mm away; a pose that is one of its 11 blade copies of
  the truth counts as right (errors are to the nearest copy).

shapeverify: ``register(scan, prep)`` (init='auto': identity check, then principal axes +
FPFH/RANSAC hypotheses, refined, best fit wins; then the robust ICP).  Open3D 0.20:
``registration_ransac_based_on_feature_matching`` on FPFH of voxel-downsampled clouds (voxel =
model size / 40, normal radius 2 voxels, feature radius 5 voxels, mutual filter off,
distance threshold 1.5 voxels, edge-length checker 0.9, 100,000 iterations, confidence 0.999 --
the Open3D tutorial's settings), then ``registration_icp`` point-to-plane (threshold 1 voxel) from
its result.  The model side of both (model points, features, trees) is built once, outside the
timing.  One thread everywhere.

Success: rotation error < 1 deg and translation error (at the scan's centroid) < 1 mm after the
refinement; "basin": the global stage alone within 5 deg / 10 mm.

Run:  .venv/bin/python benchmarks/bench_global.py [--seeds 6] [--out benchmarks/results_global.md]
"""
from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import datetime  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

from shapeverify.cad.examples import example_part_step  # noqa: E402
from shapeverify.cad.load import load_model  # noqa: E402
from shapeverify.nearest import prepare  # noqa: E402
from shapeverify.registration import register  # noqa: E402
from shapeverify.registration.global_search import _model_side, global_alignment  # noqa: E402
from shapeverify.registration.rigid import apply_transform, make_transform, rotation_vector  # noqa: E402,E501
from shapeverify.simulate import ScanEffects, random_motion, virtual_scan  # noqa: E402

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def errors(T, T_true, scan, copies=(np.eye(4),)):
    """(rotation deg, translation mm at the scan's centroid) of T against T_true, or against
    the nearest of its symmetric copies (``copies``: model-frame symmetries S, T = S T_true)."""
    out = []
    for S in copies:
        dT = np.linalg.inv(S) @ T @ np.linalg.inv(T_true)
        c = apply_transform(T_true, scan.mean(axis=0))
        ang = float(np.degrees(np.linalg.norm(rotation_vector(dT[:3, :3]))))
        out.append((ang, float(np.linalg.norm(dT[:3, :3] @ c + dT[:3, 3] - c))))
    return min(out, key=lambda e: e[0] + e[1])


#: the impeller's views (directions from the part to the camera) and its blade count
IMPELLER_VIEWS = ((0.189, -0.198, 0.962), (0.598, 0.260, -0.758), (0.658, 0.067, 0.750),
                  (0.3, -0.8, 0.52))
IMPELLER_BLADES = 11


def cases(seeds):
    model = load_model(example_part_step(Path(tempfile.mkdtemp()) / "panel.step"))
    prep = prepare(model, spacing=1.0)
    for s in range(seeds):
        M = np.eye(4)
        M[:3, :3] = Rotation.random(random_state=s).as_matrix()
        v = np.random.default_rng(s).normal(size=3)
        M[:3, 3] = 800.0 * v / np.linalg.norm(v)
        vs = virtual_scan(model, pixel=1.37, noise=0.03, motion=M, rng=s,
                          effects=ScanEffects(outlier_fraction=0.05))
        yield f"panel seed {s}", prep, vs.scan, vs.T_model_scan
    d = DATA / "scans" / "bunny"
    if not d.is_dir():
        return
    from shapeverify.io.points import read_points

    def pose(name):
        for line in (d / "bun.conf").read_text().splitlines():
            f = line.split()
            if len(f) == 9 and f[0] == "bmesh" and f[1] == name:
                R = Rotation.from_quat(np.array(f[5:9], float)).as_matrix()
                return make_transform(R.T, np.array(f[2:5], float) * 1000.0)

    ref = load_model(d / "bun000.ply")
    bprep = prepare(dataclasses.replace(ref, vertices=ref.vertices * 1000.0), spacing=1.0)
    for name in ("bun045.ply", "bun090.ply"):
        scan0 = read_points(d / name) * 1000.0
        T0 = np.linalg.inv(pose("bun000.ply")) @ pose(name)
        for s in range(3):
            Pm = random_motion(30.0, 20.0, center=apply_transform(T0, scan0.mean(0)), rng=s)
            yield f"{name[:-4]} seed {s}", bprep, apply_transform(Pm @ T0, scan0), np.linalg.inv(Pm)
    yield from impeller_cases(seeds)


def impeller_cases(seeds):
    """The impeller seen by the virtual scanner from 4 directions (a third to a half of it),
    given in a sensor frame 120 deg / 300 mm away: labels, the model's 11 blade copies."""
    from shapeverify.registration import _restart

    f = DATA / "cad" / "impeller.igs"
    if not f.is_file():
        return
    iprep = prepare(load_model(f))
    axis, centre = _restart._model_axis(iprep)
    copies = [_restart._spin(axis, centre, 2 * np.pi * k / IMPELLER_BLADES)
              for k in range(IMPELLER_BLADES)]
    for k, v in enumerate(IMPELLER_VIEWS):
        for s in range(max(1, seeds // 3)):
            vs = virtual_scan(iprep, view=np.array(v), pixel=0.3, noise=0.02,
                              motion=(120.0, 300.0), rng=s + 1)
            yield f"impeller view {k} seed {s + 1}", iprep, vs.scan, vs.T_model_scan, copies


class Open3DGlobal:
    def __init__(self, o3d, prep):
        self.o3d = o3d
        side = _model_side(prep)      # the same model points the shapeverify search uses
        self.voxel = side.voxel
        mp = prep.points
        tgt = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.array(mp.points)))
        tgt.normals = o3d.utility.Vector3dVector(np.array(mp.normals))
        self.full = tgt
        self.down = tgt.voxel_down_sample(self.voxel)
        self.down.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=2 * self.voxel,
                                                                        max_nn=30))
        self.fpfh = self._fpfh(self.down)

    def _fpfh(self, pc):
        reg = self.o3d.pipelines.registration
        return reg.compute_fpfh_feature(pc, self.o3d.geometry.KDTreeSearchParamHybrid(
            radius=5 * self.voxel, max_nn=100))

    def run(self, scan):
        o3d = self.o3d
        reg = o3d.pipelines.registration
        src = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.array(scan)))
        down = src.voxel_down_sample(self.voxel)
        down.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=2 * self.voxel,
                                                                   max_nn=30))
        f = self._fpfh(down)
        thr = 1.5 * self.voxel
        res = reg.registration_ransac_based_on_feature_matching(
            down, self.down, f, self.fpfh, False, thr,
            reg.TransformationEstimationPointToPoint(False), 3,
            [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9),
             reg.CorrespondenceCheckerBasedOnDistance(thr)],
            reg.RANSACConvergenceCriteria(100000, 0.999))
        T_glob = np.asarray(res.transformation)
        icp = reg.registration_icp(src, self.full, self.voxel, T_glob,
                                   reg.TransformationEstimationPointToPlane(),
                                   reg.ICPConvergenceCriteria(max_iteration=60))
        return T_glob, np.asarray(icp.transformation)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--out", default=str(Path(__file__).with_name("results_global.md")))
    args = ap.parse_args()
    import open3d as o3d

    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    load = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    rows, peers = [], {}
    for label, prep, scan, T_true, *copies in cases(args.seeds):
        copies = copies[0] if copies else (np.eye(4),)
        if id(prep) not in peers:
            peers[id(prep)] = Open3DGlobal(o3d, prep)
            with warnings.catch_warnings():   # warm-up: numba compilation, model-side caches
                warnings.simplefilter("ignore")
                register(scan, prep)
        peer = peers[id(prep)]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t = time.perf_counter()
            ga = global_alignment(scan, prep)
            t_ga = time.perf_counter() - t
            t = time.perf_counter()
            reg = register(scan, prep)
            t_reg = time.perf_counter() - t
        o3d.utility.random.seed(0)
        t = time.perf_counter()
        T_og, T_oi = peer.run(scan)
        t_o3d = time.perf_counter() - t
        e_ga, e_reg = (errors(ga.T_model_scan, T_true, scan, copies),
                       errors(reg.T_model_scan, T_true, scan, copies))
        e_og, e_oi = errors(T_og, T_true, scan, copies), errors(T_oi, T_true, scan, copies)
        rows.append(dict(label=label, n=scan.shape[0], t_ga=t_ga, t_reg=t_reg, t_o3d=t_o3d,
                         e_ga=e_ga, e_reg=e_reg, e_og=e_og, e_oi=e_oi, conv=reg.converged,
                         warned=bool(reg.warnings), init=reg.init))
        print(f"{label:18s} n={scan.shape[0]:6d} sv global {t_ga:.3f}s {e_ga[0]:8.3f} deg "
              f"{e_ga[1]:8.3f} mm | sv register {t_reg:.3f}s {e_reg[0]:.4f} deg {e_reg[1]:.4f} mm "
              f"conv={reg.converged} warn={bool(reg.warnings)} ({reg.init}) | open3d {t_o3d:.3f}s "
              f"global {e_og[0]:8.3f} deg {e_og[1]:8.3f} mm, +icp {e_oi[0]:.4f} deg "
              f"{e_oi[1]:.4f} mm", flush=True)
    write(args, rows, load)


def _ok(e, a=1.0, t=1.0):
    return e[0] < a and e[1] < t


def write(args, rows, load):
    groups = {}
    for r in rows:
        groups.setdefault(r["label"].split()[0], []).append(r)
    lines = ["# Global registration benchmark (issue 14 item 1)", "",
             f"Command: `.venv/bin/python benchmarks/bench_global.py --seeds {args.seeds}`  ",
             f"Date: {datetime.date.today()}, Python {platform.python_version()}, "
             f"{platform.machine()}, one thread, Open3D 0.20.  ",
             f"Machine load at the start (`uptime`): `{load}` (2 cores shared by ~6 agents).",
             "", "Inputs, settings and success criteria: see the docstring of "
             "`benchmarks/bench_global.py`.  Times: one run each (wall clock).", "",
             "| input | scans | points | shapeverify global: in basin (5 deg/10 mm) | "
             "global time (s, median) | shapeverify register (init auto): right (1 deg/1 mm) | "
             "wrong and converged without warning | register time (s, median) | Open3D "
             "FPFH+RANSAC: in basin | Open3D + ICP: right | Open3D time (s, median) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for g, rs in groups.items():
        wrong_silent = sum((not _ok(r["e_reg"])) and r["conv"] and not r["warned"] for r in rs)
        lines.append(
            f"| {g} | {len(rs)} | {int(np.median([r['n'] for r in rs]))} | "
            f"{sum(_ok(r['e_ga'], 5, 10) for r in rs)}/{len(rs)} | "
            f"{np.median([r['t_ga'] for r in rs]):.3f} | "
            f"{sum(_ok(r['e_reg']) for r in rs)}/{len(rs)} | {wrong_silent} | "
            f"{np.median([r['t_reg'] for r in rs]):.3f} | "
            f"{sum(_ok(r['e_og'], 5, 10) for r in rs)}/{len(rs)} | "
            f"{sum(_ok(r['e_oi']) for r in rs)}/{len(rs)} | "
            f"{np.median([r['t_o3d'] for r in rs]):.3f} |")
    lines += ["", "Per scan (errors: rotation deg / translation mm at the scan's centroid):", "",
              "```"]
    for r in rows:
        lines.append(
            f"{r['label']:18s} n={r['n']:6d}  sv global {r['t_ga']:.3f} s {r['e_ga'][0]:8.3f} / "
            f"{r['e_ga'][1]:8.3f}   sv register {r['t_reg']:.3f} s {r['e_reg'][0]:.4f} / "
            f"{r['e_reg'][1]:.4f} conv={r['conv']} warn={r['warned']} ({r['init']})   "
            f"open3d {r['t_o3d']:.3f} s global {r['e_og'][0]:8.3f} / {r['e_og'][1]:8.3f} "
            f"+icp {r['e_oi'][0]:.4f} / {r['e_oi'][1]:.4f}")
    lines += ["```", ""]
    Path(args.out).write_text("\n".join(lines))
    print("\n".join(lines[:16]))


if __name__ == "__main__":
    main()
