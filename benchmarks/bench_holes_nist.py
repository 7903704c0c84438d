"""Hole errors on NIST CTC 01 scans made from OpenCASCADE's tessellation (issue 27 item 3).

    PYTHONPATH=src python benchmarks/bench_holes_nist.py [RUNS] [--holes-module PATH]

Area: points uniform by triangle area (the wall is seen: wall cylinder fit); grid: a raster of
rays along the hole's axis (no wall: edge points).  0.02 mm noise along the normal, true pose;
the scan generators are those of tests/test_holes_nist.py.  ``--holes-module`` measures with
another holes.py (e.g. the main branch's, for before/after numbers).  Needs ../shared/data.
"""
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
import test_holes_nist as t  # noqa: E402

import shapeverify as sv  # noqa: E402
from shapeverify.cad.occ_import import read_cad  # noqa: E402
from shapeverify.characteristics import holes as holes_mod  # noqa: E402
from shapeverify.characteristics.features import model_features  # noqa: E402

args = [a for a in sys.argv[1:] if not a.startswith("--")]
runs = int(args[0]) if args else 2
if "--holes-module" in sys.argv:
    src = sys.argv[sys.argv.index("--holes-module") + 1]
    spec = importlib.util.spec_from_file_location("shapeverify.characteristics._holes_other", src)
    holes_mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = holes_mod
    spec.loader.exec_module(holes_mod)

t0 = time.time()
path = ROOT.parent / "shared" / "data" / "cad" / "nist" / t.FILE
model = read_cad(path, isolated=False)
feats = {f.id: f for f in model_features(model)}
prep = sv.prepare(model)
V, T = t.tessellation(path)
for h in t.HOLES:
    f = feats[h]
    R = t._region(V, T, f.center, f.diameter + 25.0)
    for kind in ("area", "grid"):
        for sp in (0.5, 1.0, 1.5):
            e = []
            for run in range(runs):
                rng = np.random.default_rng(run)
                X = (t.area_scan(V, R, sp, rng) if kind == "area" else
                     t.grid_scan(V, R, sp, f.axis, f.center, f.diameter / 2 + 20, rng))
                cl = prep.closest(X, exact=True)
                hm = holes_mod.measure_hole(X, f.center, f.axis, f.diameter,
                                            face=prep.model.faces[f.face],
                                            deviations=cl.distances, normals=cl.normals)
                d = hm.center - f.center
                pos = np.linalg.norm(d - (d @ f.axis) * f.axis)
                e.append((hm.diameter - f.diameter, pos, hm.u_diameter, hm.u_center))
            e = np.array(e)
            print(f"{h} D{f.diameter:g} {kind} {sp} mm: dD {e[:, 0].min():+.4f}..{e[:, 0].max():+.4f}"
                  f" | offset max {e[:, 1].max():.4f} | U_D(k=2) {2 * e[:, 2].mean():.4f}"
                  f" | U_c(k=2) {2 * e[:, 3].mean():.4f} | {time.time() - t0:.0f} s", flush=True)
