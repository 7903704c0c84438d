"""The datum reference frame's real scatter on independent scans against the bootstrap's
(:func:`shapeverify.characteristics.datum_noise.frame_motions`) -- issue 28, "How good".

For each seed: a scan of the part as ``check_datum_u_coverage.py`` makes it (perfect, true
pose), the plan's alignment, then the DRF fitted on the scan's datum features; its motion
against the true pose (``drf.T @ T_model_scan`` as a rotation vector, mrad, and translation).
``--runout FACE`` also reads the face's nominal (tessellation) points through that frame and
prints their radial range about the first datum's nominal axis: the total runout the datum's
noise alone puts on a perfect coaxial face (compare ``details['u_datum_axis']``).

    PYTHONPATH=src .venv/bin/python benchmarks/check_datum_frames.py --file /tmp/nx/nist_ctc_05_asme1_ap242-e1.stp \\
        --datums C D --only GT4 GT5 --seeds 0 1 2 3 4 5 6 7 8 9
    PYTHONPATH=src .venv/bin/python benchmarks/check_datum_frames.py --file ... --datums A --only GT9 --runout 37 --seeds 40 41 42
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import check_datum_u_coverage as cdu  # noqa: E402


def main(argv=None):
    from scipy.spatial.transform import Rotation

    from shapeverify.characteristics.alignment import align
    from shapeverify.characteristics.datum_noise import frame_motions
    from shapeverify.characteristics.evaluate import EvalContext, _Scan
    from shapeverify.characteristics.gdt import datum_features, drf_of

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--file", required=True)
    ap.add_argument("--datums", nargs="+", help="DRFs, e.g. C D 'A,B' (letters by commas)")
    ap.add_argument("--only", nargs="*", help="characteristics whose plan to load")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--runout", type=int, help="face index read through the first DRF")
    a = ap.parse_args(argv)
    names = [d.split(",") for d in a.datums]
    prep, data, plan, feats, tess = cdu._part(a.file, a.only)
    V, T, F = tess
    real = {tuple(n): [] for n in names}
    for seed in a.seeds:
        P, _ = cdu._scan(tess, data, feats, 1.0, seed, "perfect")
        al = align(P, prep, plan.alignment, init=np.eye(4))
        S = _Scan(prep, P, al.T_model_scan, 5.0, None, None)
        ctx = EvalContext(S, feats, al, 2.0, prep, P, 5.0, plan)
        line = [str(seed)]
        for n in names:
            Tt = drf_of(n, ctx).T @ np.asarray(al.T_model_scan)
            xi = np.r_[Rotation.from_matrix(Tt[:3, :3]).as_rotvec(), Tt[:3, 3]]
            real[tuple(n)].append(xi)
            line.append(f"{'|'.join(n)} omega mrad {np.round(1e3 * xi[:3], 4).tolist()}")
            if seed == a.seeds[0]:
                b = frame_motions(n, ctx)
                print(f"{'|'.join(n)} bootstrap ({len(b)} replicates, noise {S.noise:.4f}): "
                      f"omega sd mrad {np.round(1e3 * b[:, :3].std(axis=0), 3).tolist()}, "
                      f"t sd {np.round(b[:, 3:].std(axis=0), 4).tolist()}", flush=True)
        if a.runout is not None:
            f0 = datum_features(names[0], ctx)[0]
            Tt = drf_of(names[0], ctx).T @ np.asarray(al.T_model_scan)
            X = V[np.unique(T[F == a.runout])]
            p0 = np.asarray(f0.point, float)
            a0 = np.asarray(f0.direction, float) / np.linalg.norm(f0.direction)

            def rad(Z):
                q = Z - p0
                return np.linalg.norm(q - np.outer(q @ a0, a0), axis=1)
            dev = rad(X @ Tt[:3, :3].T + Tt[:3, 3]) - rad(X)
            line.append(f"face:{a.runout} datum-caused range {np.ptp(dev):.4f} "
                        f"({len(f0.points)} datum points)")
        print("; ".join(line), flush=True)
    for k, v in real.items():
        v = np.array(v)
        print(f"{'|'.join(k)} real ({len(v)} scans): omega rms mrad "
              f"{np.round(1e3 * np.sqrt((v[:, :3] ** 2).mean(axis=0)), 3).tolist()}, "
              f"t rms {np.round(np.sqrt((v[:, 3:] ** 2).mean(axis=0)), 4).tolist()}")


if __name__ == "__main__":
    main()
