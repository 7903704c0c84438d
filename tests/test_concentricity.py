"""Concentricity (ASME Y14.5-2009 7.6.4: median points of diametrically opposed elements in a
cylindrical zone about the datum axis; NIST CTC 05 GT7 was "not measured").

:func:`median_offsets` against brute force to 1e-9 mm: a point-by-point re-computation of the
definition (for each point, the two samples around the opposite angle found by their angular
distance, the radius there interpolated linearly, half the difference); an exact circle off
the axis sampled at opposite angles (``r(t) - r(t + pi) = 2 e cos t`` exactly).
"""
from __future__ import annotations

import numpy as np
import pytest

from shapeverify.characteristics.concentricity import median_offsets


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_median_offsets_equal_a_point_by_point_recomputation(seed):
    """A lobed, off-centre section (radius 152.4, 3 lobes of 0.05, 0.2 off along 30 degrees,
    0.02 noise) sampled at 360 random angles."""
    rng = np.random.default_rng(seed)
    t1 = rng.uniform(0, np.pi, 180)
    t = np.concatenate([t1, t1 + np.pi])
    c = 0.2 * np.array([np.cos(np.pi / 6), np.sin(np.pi / 6)])
    R = 152.4 + 0.05 * np.cos(3 * t) + 0.02 * rng.standard_normal(t.size)
    P = c + R[:, None] * np.column_stack([np.cos(t), np.sin(t)])   # points about centre c
    th = np.arctan2(P[:, 1], P[:, 0])                             # seen from the axis (0, 0)
    r = np.hypot(P[:, 0], P[:, 1])
    m, idx = median_offsets(th, r, max_gap=np.radians(5))
    assert idx.size >= 0.9 * th.size
    assert np.abs(m).max() == pytest.approx(_interp_truth(th, r), abs=1e-9)


def _interp_truth(th, r):
    """The largest |r_i - r(theta_i + pi)| / 2 with r(.) interpolated linearly between the
    two samples around theta_i + pi (written out point by point)."""
    ths = np.mod(th, 2 * np.pi)
    best = 0.0
    for i in range(th.size):
        want = np.mod(ths[i] + np.pi, 2 * np.pi)
        d = np.mod(ths - want, 2 * np.pi)            # how far past `want` each sample is
        k_hi = int(np.argmin(d))                      # the first sample at or after it
        k_lo = int(np.argmax(d))                      # the last sample before it
        a, b = 2 * np.pi - d[k_lo], d[k_hi]           # distances before / after
        if a > np.radians(5) or b > np.radians(5):
            continue
        rr = r[k_hi] if a + b == 0 else r[k_lo] + (r[k_hi] - r[k_lo]) * a / (a + b)
        best = max(best, abs(r[i] - rr) / 2)
    return best


def test_concentric_section_has_median_points_on_the_axis_and_an_offset_one_its_offset():
    t = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    m, idx = median_offsets(t, np.full(720, 50.0))
    assert idx.size == 720 and np.abs(m).max() < 1e-12
    # a circle of radius 50 whose centre is 0.3 off the axis: r(t) - r(t + pi) = 2 * 0.3 cos t
    # (exactly, for a circle: r(t) = e cos t + sqrt(R^2 - e^2 sin^2 t))
    e = 0.3
    r = e * np.cos(t) + np.sqrt(50.0 ** 2 - (e * np.sin(t)) ** 2)
    m, _ = median_offsets(t, r)
    assert 2 * np.abs(m).max() == pytest.approx(2 * e, abs=1e-9)


def test_a_point_without_an_opposed_element_in_the_scan_is_left_out():
    t = np.linspace(0, np.pi * 0.9, 100)           # one side only
    m, idx = median_offsets(t, np.full(100, 20.0))
    assert idx.size == 0
