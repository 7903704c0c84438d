"""An object lying on the part (issue 29 item 1): a 6 x 6 x 3 mm box on the example panel, as
tests/test_box_wall_read_as_layer_over_the_part.py builds it (the panel sampled on OpenCASCADE's
tessellation by ``tests/independent_scans.py``: by area, ``random``, or on a lattice, ``grid`` /
``scanner`` / ``aniso``; the box's top and walls by area at the same density, the panel under it
hidden; 0.02 mm noise; tolerance 0.1 mm; ``inspect_registered`` at the true pose).  Truth: the
footprint, 36 mm^2, and the height, 3 mm.  Printed per scan: verdict, regions (those near the box),
area / 36 - 1, extreme / 3 - 1, the largest measured value, points and points beyond the
evaluation distance.

Run:  PYTHONPATH=src .venv/bin/python benchmarks/check_box_on_panel.py --spacings 0.3 0.5 1 3
      --seeds 0 1 2 3 4 5 6 7 [--sampler random] [--cache /tmp/box_on_panel]
(the panel's prepared model is cached; about 2 min the first time, then 1-15 s per scan)
"""
import argparse, sys, time, types
from pathlib import Path
import numpy as np
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import independent_scans as ind
from shapeverify.cad.examples import example_part_step
from shapeverify.cad.load import load_model
from shapeverify.inspection import inspect_registered
from shapeverify.nearest import prepare
import shapeverify as sv

TOL, NOISE, HALF, HEIGHT = 0.1, 0.02, 3.0, 3.0
CACHE = Path("/tmp/box_on_panel")


def ident():
    return types.SimpleNamespace(T_model_scan=np.eye(4), rms=0.0, iterations=1, converged=True,
                                 inlier_fraction=1.0)


def panel():
    path = example_part_step(CACHE / "panel.step")
    svm = CACHE / "panel_box.svm"
    if svm.exists():
        prep = sv.load_prepared(svm)
    else:
        prep = prepare(load_model(path)); prep.save(svm)
    V, T, F = ind.tessellate(ind.read_shape(path), 0.01)
    return prep, V, T, F


def box_scan(prep, V, T, F, spacing, seed, sampler="random", crop=None):
    rng = np.random.default_rng(seed)
    if sampler == "random":
        P, _ = ind.random_points(V, T, spacing, rng)
    else:
        P = ind.lattice_points(V, T, spacing, rng, aniso=3.0 if sampler == "aniso" else 1.0,
                               order="scanner" if sampler == "scanner" else "random")
        P = P[0] if isinstance(P, tuple) else P
    P, c = ind.box_on_part(P, prep, V, T, F, HALF, HEIGHT, spacing, rng)
    P = (P + rng.normal(0.0, NOISE, P.shape))[rng.permutation(len(P))]
    if crop:
        P = P[np.linalg.norm(P - c, axis=1) < crop]
    return P, c


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spacings", type=float, nargs="+", default=[0.5, 1.0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(6)))
    ap.add_argument("--sampler", default="random")
    ap.add_argument("--crop", type=float, default=None)
    ap.add_argument("--cache", type=Path, default=CACHE)
    a = ap.parse_args()
    globals()["CACHE"] = a.cache
    a.cache.mkdir(parents=True, exist_ok=True)
    prep, V, T, F = panel()
    for s in a.spacings:
        for seed in a.seeds:
            t0 = time.time()
            P, c = box_scan(prep, V, T, F, s, seed, a.sampler, a.crop)
            res = inspect_registered(prep, P, ident(), tolerance=TOL)
            near = [r for r in res.regions if np.linalg.norm(r.centroid - c) < 3 * HALF]
            far = len(res.regions) - len(near)
            line = f"{a.sampler:7s} s={s:<4} seed={seed} {res.verdict:4s} regions={len(res.regions)} (far {far})"
            for r in near:
                line += (f" | area {r.area:6.2f} ({r.area / 36 - 1:+6.1%}) ext {r.extreme:+.3f}"
                         f" ({abs(r.extreme) / HEIGHT - 1:+6.1%}) raw {r.extreme_raw:+.3f} n={r.n} nb={r.n_beyond}")
            print(line + f"  [{len(P)} pts, {time.time() - t0:.0f}s]", flush=True)


if __name__ == "__main__":
    main()
