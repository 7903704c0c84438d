"""How the characteristics' outlier rule (``characteristics/support.py``) treats steep small
bumps and scattered spikes on a flat panel sampled at random (a Poisson sampler, as an
independent one samples a tessellation).

    PYTHONPATH=src python benchmarks/check_outlier_support.py [--seeds 40] [--against OLD.py]

``--against`` runs another version of ``support.py`` beside (e.g. ``git show
HEAD~1:src/shapeverify/characteristics/support.py > /tmp/old_support.py``).  Prints, per bump
height, in how many scans the bump's sampled extreme is lost (and the worst kept/sampled ratio),
per spike mix how many spikes stay, how many clean points are left out and the largest kept
|d|, and per layer (points over the still-scanned surface: a reflection) how many of its points
stay.
"""
from __future__ import annotations

import argparse
import importlib.util

import numpy as np

NOISE, SPACING, SIZE, WIDTH = 0.02, 1.0, 60.0, 6.0


def panel(rng):
    n = int(SIZE * SIZE / SPACING ** 2)
    feet = np.column_stack([rng.uniform(0, SIZE, n), rng.uniform(0, SIZE, n), np.zeros(n)])
    return feet, rng.normal(0.0, NOISE, n)


def bump(feet, height):
    r = np.linalg.norm(feet[:, :2] - SIZE / 2, axis=1)
    inside = r < WIDTH / 2
    return np.where(inside, height * np.cos(np.pi * r / WIDTH) ** 2, 0.0), inside


def bumps(rule, seeds):
    for h in (0.5, 1.0, 1.5, -1.5):
        lost, worst = 0, 1.0
        for seed in range(seeds):
            rng = np.random.default_rng(seed)
            feet, d = panel(rng)
            b, inside = bump(feet, h)
            d = d + b
            kept = ~rule(feet, d, np.ones(len(d), bool)).unsupported
            top = np.max(np.abs(d[inside]))
            r = np.max(np.abs(d[kept & inside])) / top if (kept & inside).any() else 0.0
            lost += r < 0.999
            worst = min(worst, r)
        yield f"bump {h:+.1f} mm: extreme lost in {lost}/{seeds}, worst kept/sampled {worst:.2f}"


def spikes(rule, seeds):
    for frac, lo in ((0.01, 0.5), (0.03, 0.5), (0.03, 0.15), (0.10, 0.5)):
        kept = total = clean = 0
        worst = 0.0
        for seed in range(seeds):
            rng = np.random.default_rng(200 + seed)
            feet, d = panel(rng)
            spike = rng.random(len(d)) < frac
            d[spike] += rng.choice([-1.0, 1.0], spike.sum()) * rng.uniform(lo, 5.0, spike.sum())
            un = rule(feet, d, np.ones(len(d), bool)).unsupported
            kept += np.count_nonzero(spike & ~un)
            total += spike.sum()
            clean += np.count_nonzero(un & ~spike)
            worst = max(worst, float(np.max(np.abs(d[~un]))))
        yield (f"{frac:.0%} spikes {lo}-5 mm: {kept}/{total} stay, {clean} clean points left "
               f"out, largest kept |d| {worst:.2f}")


def layers(rule, seeds):
    """k points 0.5 mm over a disc of the panel, the surface under them still scanned (a
    reflection): how many of them stay (a layer is not a defect)."""
    for k, rad in ((4, 1.5), (8, 2.0), (15, 3.0), (30, 4.0)):
        kept = 0
        for seed in range(seeds):
            rng = np.random.default_rng(300 + seed)
            feet, d = panel(rng)
            a, r = rng.uniform(0, 2 * np.pi, k), rad * np.sqrt(rng.uniform(0, 1, k))
            lp = np.column_stack([SIZE / 2 + r * np.cos(a), SIZE / 2 + r * np.sin(a), np.zeros(k)])
            n = len(d)
            feet, d = np.vstack([feet, lp]), np.r_[d, 0.5 + rng.normal(0, NOISE, k)]
            kept += np.count_nonzero(~rule(feet, d, np.ones(len(d), bool)).unsupported[n:])
        yield f"layer of {k} points 0.5 mm over a {rad} mm disc: {kept}/{k * seeds} stay"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--against", help="another support.py to run beside")
    a = ap.parse_args()
    from shapeverify.characteristics import support

    rules = {"this": support.neighbourhood_support}
    if a.against:
        spec = importlib.util.spec_from_file_location(
            "shapeverify.characteristics._support_against", a.against)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        rules["against"] = mod.neighbourhood_support
    for name, rule in rules.items():
        for line in [*bumps(rule, a.seeds), *spikes(rule, a.seeds // 2),
                     *layers(rule, a.seeds // 2)]:
            print(f"{name:8s} {line}", flush=True)


if __name__ == "__main__":
    main()
