"""How well :mod:`shapeverify.characteristics.zone_noise` removes the scan noise from a zone
width: known surfaces on a random panel, noisy heights, the width of the points (raw), the
corrected value and its U against the true width.

    PYTHONPATH=src python benchmarks/check_zone_noise.py [--trials 30] [--noise 0.02] [--spacing 1]

One line per surface: the raw and the corrected value's error (mean +- sd, largest), the mean
U (k = 2) of the corrected value and of the old rule (``2 z_n sigma``), and in how many scans
``|value - true| <= U``.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from shapeverify.characteristics.support import extreme_quantile
from shapeverify.characteristics.zone_noise import corrected_width


def _bump(h, r0):
    def f(T):
        r = np.hypot(T[:, 0] - 50, T[:, 1] - 25)
        return np.where(r < r0, h * np.cos(np.pi * r / (2 * r0)) ** 2, 0.0)
    return f


SURFACES = {
    "flat": lambda T: np.zeros(len(T)),
    "tilt 0.2 deg": lambda T: T[:, 0] * np.tan(np.radians(0.2)),
    "tilt 0.05 deg": lambda T: T[:, 0] * np.tan(np.radians(0.05)),
    "bump 0.3 mm, 6 mm across": _bump(0.3, 3.0),
    "bump 0.1 mm, 3 mm across": _bump(0.1, 1.5),
    "dent 0.1 mm, 10 mm across": _bump(-0.1, 5.0),
    "wave 0.1 mm, 40 mm": lambda T: 0.05 * np.sin(2 * np.pi * T[:, 0] / 40),
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=30)
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--spacing", type=float, default=1.0)
    a = ap.parse_args()
    print(f"100 x 50 mm panel, random points at {a.spacing} mm, noise {a.noise} mm, "
          f"{a.trials} scans each")
    print("| surface | raw error | corrected error | U corrected | U old | covered |")
    print("|---|---|---|---|---|---|")
    cpu = 0.0
    for name, f in SURFACES.items():
        raw_e, cor_e, us, cov = [], [], [], 0
        for tr in range(a.trials):
            rng = np.random.default_rng(tr)
            n = int(5000 / a.spacing ** 2)
            T = np.column_stack([rng.uniform(0, 100, n), rng.uniform(0, 50, n)])
            t = f(T)
            true = float(t.max() - t.min())
            v = t + rng.normal(0, a.noise, n)
            t0 = time.process_time()
            value, u, _ = corrected_width(float(np.ptp(v)), np.column_stack([T, v]),
                                          [0.0, 0.0, 1.0], a.noise)
            cpu += time.process_time() - t0
            raw = float(v.max() - v.min())
            raw_e.append(raw - true)
            cor_e.append(value - true)
            us.append(u)
            cov += abs(value - true) <= u
        raw_e, cor_e = np.array(raw_e), np.array(cor_e)
        u_old = 2 * extreme_quantile(n) * a.noise
        print(f"| {name} | {raw_e.mean():+.3f} +- {raw_e.std():.3f} | {cor_e.mean():+.3f} +- "
              f"{cor_e.std():.3f} (largest {np.abs(cor_e).max():.3f}) | {np.mean(us):.3f} | "
              f"{u_old:.3f} | {cov}/{a.trials} |")
    print(f"CPU of corrected_width: {cpu / (len(SURFACES) * a.trials) * 1e3:.0f} ms per width "
          f"({n} points)")


if __name__ == "__main__":
    main()
