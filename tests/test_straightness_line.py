"""Straightness of one line element drawn on a face (NIST CTC 05 GT6: a straight line drawn on
the cylinder face 71, a generator; "attached to an edge, not to faces" before).

The zone (two parallel lines, their distance) of a line element's points against brute force:
the minimum-width strip of a planar point set has one side through two of the points (a hull
edge), so the minimum over the directions of all point pairs of the points' spread across that
direction is the minimum zone; to 1e-6 mm.
"""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from shapeverify.characteristics.gdt import line_element_zone

TOL = 1e-6


def _brute_strip(t, d):
    Q = np.column_stack([t, d])
    best = np.inf
    for i, j in itertools.combinations(range(len(Q)), 2):
        e = Q[j] - Q[i]
        if np.linalg.norm(e) < 1e-12:
            continue
        nrm = np.array([-e[1], e[0]]) / np.linalg.norm(e)
        best = min(best, float(np.ptp(Q @ nrm)))
    return best


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_line_element_zone_equals_the_narrowest_strip_over_point_pair_directions(seed):
    """40 points along 38 mm (a bow of 0.05 mm, a 0.3 mrad tilt of the pose, 0.02 mm noise)."""
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(-19.05, 19.05, 40))
    d = 0.05 * (1 - (t / 19.05) ** 2) + 3e-4 * t + 0.02 * rng.standard_normal(40)
    assert line_element_zone(t, d) == pytest.approx(_brute_strip(t, d), abs=TOL)


def test_line_element_zone_of_a_tilted_straight_line_is_zero():
    t = np.linspace(-10, 10, 21)
    assert line_element_zone(t, 0.01 * t + 0.3) == pytest.approx(0.0, abs=1e-9)
