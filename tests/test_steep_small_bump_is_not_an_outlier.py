"""A steep small bump is measured, not left out as outliers (issue 28: a part with a defect on
a profile's faces fails it).

The neighbourhood-support rule (:mod:`shapeverify.characteristics.support`) left out every point
that departs from its 9 neighbours' median by ``z sigma``; on a cos^2 bump 6 mm across sampled at
1 mm each point does (the median of a neighbourhood is a constant, the bump is not), and on NIST
FTC 10 a 1.0 mm bump on face 178 read 1.21 mm (half of it), a 1.5 mm one on face 179 1.37 mm,
undecided.  A point the median leaves out now stays when the kept surface of its face is smooth
through it, unless the bulk surface is measured right beside it (a layer); a spike stays out.
"""
from __future__ import annotations

import numpy as np
import pytest

NOISE = 0.02


def _panel(rng, spacing=1.0, size=60.0):
    """Uniform random points on a flat panel (the feet) at ``spacing`` mm, their noise."""
    n = int(size * size / spacing ** 2)
    feet = np.column_stack([rng.uniform(0, size, n), rng.uniform(0, size, n), np.zeros(n)])
    return feet, rng.normal(0.0, NOISE, n)


def _bump(feet, centre, height, width):
    r = np.linalg.norm(feet[:, :2] - centre, axis=1)
    inside = r < width / 2
    return np.where(inside, height * np.cos(np.pi * r / width) ** 2, 0.0), inside


@pytest.mark.parametrize("height", [-1.5, 0.5, 1.0, 1.5])
def test_the_extreme_of_a_steep_bump_is_kept(height):
    """Over 20 random samplings the bump's sampled extreme stays in at least 19 (brute force
    over the points kept; the old rule kept it in 1-10 of 20): in a rare sampling gap over its
    top (nearest neighbour 3 median spacings away) the top may still be left out."""
    from shapeverify.characteristics.support import neighbourhood_support

    kept_top = 0
    for seed in range(20):
        rng = np.random.default_rng(seed)
        feet, d = _panel(rng)
        b, inside = _bump(feet, np.array([30.0, 30.0]), height, 6.0)
        d = d + b
        kept = ~neighbourhood_support(feet, d, np.ones(len(d), bool)).unsupported
        kept_top += np.max(np.abs(d[kept])) == np.max(np.abs(d[inside]))
    assert kept_top >= 19, kept_top


@pytest.mark.parametrize("seed", range(4))
def test_spikes_are_still_left_out_beside_a_bump(seed):
    """1 % scattered outliers 0.5-5 mm either way (the simulator's), a bump in the same scan."""
    from shapeverify.characteristics.support import neighbourhood_support

    rng = np.random.default_rng(100 + seed)
    feet, d = _panel(rng)
    b, inside = _bump(feet, np.array([30.0, 30.0]), 1.0, 6.0)
    d = d + b
    spike = (rng.random(len(d)) < 0.01) & ~inside
    d[spike] += rng.choice([-1.0, 1.0], spike.sum()) * rng.uniform(0.5, 5.0, spike.sum())
    sup = neighbourhood_support(feet, d, np.ones(len(d), bool))
    assert sup.unsupported[spike].mean() >= 0.98, (sup.unsupported[spike].sum(), spike.sum())
    assert not sup.unsupported[inside & (b >= 0.5)].any()
    # no point of the clean surface away from the bump and the spikes is taken
    assert np.count_nonzero(sup.unsupported & ~spike & ~inside) <= 2


@pytest.mark.parametrize("seed", range(10))
def test_a_layer_over_the_measured_surface_is_not_rescued(seed):
    """4 points 0.5 mm over a 1.5 mm disc with the surface still scanned under them (a
    reflection): each has the surface beside it, so none is rescued as a defect (a first version
    of the rescue kept 60 of 80 such points over 20 scans)."""
    from shapeverify.characteristics.support import neighbourhood_support

    rng = np.random.default_rng(300 + seed)
    feet, d = _panel(rng)
    a, r = rng.uniform(0, 2 * np.pi, 4), 1.5 * np.sqrt(rng.uniform(0, 1, 4))
    layer = np.column_stack([30 + r * np.cos(a), 30 + r * np.sin(a), np.zeros(4)])
    n = len(d)
    feet, d = np.vstack([feet, layer]), np.r_[d, 0.5 + rng.normal(0.0, NOISE, 4)]
    sup = neighbourhood_support(feet, d, np.ones(len(d), bool))
    assert sup.unsupported[n:].all(), d[n:][~sup.unsupported[n:]]
