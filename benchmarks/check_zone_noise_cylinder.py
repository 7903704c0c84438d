"""How well :mod:`shapeverify.characteristics.zone_noise` removes the scan noise from the
circularity and cylindricity of a cylinder (:func:`.gdt.circularity_zone`,
:func:`.gdt.cylindricity_zone`): known radial shapes on a random cylinder scan, noisy radii,
the zone of the points (raw), the corrected value and its U against the true zone (the same
zone of the noiseless points).

    PYTHONPATH=src python benchmarks/check_zone_noise_cylinder.py [--trials 30] [--noise 0.02]
        [--spacing 1] [--radius 10] [--length 30]

One line per shape and characteristic, as check_zone_noise.py: the raw and corrected error
(mean +- sd, largest), the mean U (k = 2) and the old rule's (``2 z_n sigma``, n the points
of a section for circularity), and in how many scans ``|value - true| <= U``.  The bumps sit on
the seam ``theta = 0`` (the arc coordinate wraps there).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from shapeverify.characteristics.gdt import circularity_zone, cylindricity_zone
from shapeverify.characteristics.support import extreme_quantile


SEAM = 0.0


def _bump(hgt, r0, R, L):
    def f(th, h):
        dth = np.angle(np.exp(1j * (th - SEAM)))   # -pi..pi about SEAM
        r = np.hypot(dth * R, h - L / 2)
        return np.where(r < r0, hgt * np.cos(np.pi * r / (2 * r0)) ** 2, 0.0)
    return f


def shapes(R, L):
    return {
        "perfect": lambda th, h: np.zeros_like(th),
        "lobing 0.05 mm (3 lobes)": lambda th, h: 0.025 * np.cos(3 * th),
        "bump 0.1 mm, 3 mm across": _bump(0.1, 1.5, R, L),
        "bump 0.3 mm, 6 mm across": _bump(0.3, 3.0, R, L),
        "taper 0.05 mm": lambda th, h: 0.05 * h / L,
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=30)
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--spacing", type=float, default=1.0)
    ap.add_argument("--radius", type=float, default=10.0)
    ap.add_argument("--length", type=float, default=30.0)
    a = ap.parse_args()
    R, L = a.radius, a.length
    n = int(2 * np.pi * R * L / a.spacing ** 2)
    print(f"cylinder r {R} x {L} mm, {n} random points ({a.spacing} mm), radial noise "
          f"{a.noise} mm, {a.trials} scans each")
    print("| shape | zone | raw error | corrected error | U corrected | U old | covered |")
    print("|---|---|---|---|---|---|---|")
    cpu, calls = 0.0, 0
    axis, centre = np.array([0.0, 0.0, 1.0]), np.zeros(3)
    for name, f in shapes(R, L).items():
        rows = {"circularity": ([], [], [], 0), "cylindricity": ([], [], [], 0)}
        for tr in range(a.trials):
            rng = np.random.default_rng(tr)
            th = rng.uniform(0, 2 * np.pi, n)
            h = rng.uniform(0, L, n)
            r0 = R + f(th, h)
            r = r0 + rng.normal(0, a.noise, n)

            def pts(rr):
                return np.column_stack([rr * np.cos(th), rr * np.sin(th), h])
            for zname, fn in (("circularity", circularity_zone),
                              ("cylindricity", cylindricity_zone)):
                true = fn(pts(r0), centre, axis, float("nan"))[0]
                t0 = time.process_time()
                value, u, det = fn(pts(r), centre, axis, a.noise)
                cpu += time.process_time() - t0
                calls += 1
                raw_e, cor_e, us, cov = rows[zname]
                raw_e.append(det["zone_of_points"] - true)
                cor_e.append(value - true)
                us.append(u)
                rows[zname] = (raw_e, cor_e, us, cov + (abs(value - true) <= u))
        for zname, (raw_e, cor_e, us, cov) in rows.items():
            m = n // 10 if zname == "circularity" else n
            u_old = 2 * extreme_quantile(m) * a.noise
            raw_e, cor_e = np.array(raw_e), np.array(cor_e)
            print(f"| {name} | {zname} | {raw_e.mean():+.3f} +- {raw_e.std():.3f} | "
                  f"{cor_e.mean():+.3f} +- {cor_e.std():.3f} (largest "
                  f"{np.abs(cor_e).max():.3f}) | {np.mean(us):.3f} | {u_old:.3f} | "
                  f"{cov}/{a.trials} |")
    print(f"CPU: {cpu / calls * 1e3:.0f} ms per zone")


if __name__ == "__main__":
    main()
