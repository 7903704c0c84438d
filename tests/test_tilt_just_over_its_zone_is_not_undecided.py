"""A face tilted just over its orientation zone was `undecided` on a noisy scan (issue 28).

The zone width of noisy points carries the noise's largest deviates on both sides (about
``2 x 4 sigma``), and U carried that bias: NIST FTC 06's GT16 (perpendicularity 0.3048) on a face
tilted 0.2 deg (true width 0.341) read 0.486 +- 0.196 at 1 mm, undecided; flatness zones of a
few sigma were undecided on perfect parts.  :mod:`shapeverify.characteristics.zone_noise` takes
the expected noise part off the width and keeps its spread in U.
"""
import numpy as np
import pytest

from shapeverify.characteristics.zone_noise import corrected_width, noise_part
from shapeverify.characteristics.zones import decide


def _panel(seed, n=5000):
    rng = np.random.default_rng(seed)
    return rng, np.column_stack([rng.uniform(0, 100, n), rng.uniform(0, 50, n)])


def _heights(T, kind):
    if kind == "flat":
        return np.zeros(len(T))
    if kind == "tilt":
        return T[:, 0] * np.tan(np.radians(0.2))
    r = np.hypot(T[:, 0] - 50, T[:, 1] - 25)                     # a 0.3 mm bump 6 mm across
    return np.where(r < 3, 0.3 * np.cos(np.pi * r / 6) ** 2, 0.0)


@pytest.mark.parametrize("kind", ["flat", "tilt", "bump"])
def test_the_corrected_width_is_within_u_of_the_true_width(kind):
    """20 random scans per surface: the raw width is 0.09-0.15 mm over the truth; the corrected
    value is within its U in at least 19 (U about a third of the old 2 z_n sigma)."""
    covered, raw_over = 0, []
    for seed in range(20):
        rng, T = _panel(seed)
        t = _heights(T, kind)
        v = t + rng.normal(0, 0.02, len(t))
        X = np.column_stack([T, v])
        true = float(np.ptp(t))
        value, u, det = corrected_width(float(np.ptp(v)), X, [0.0, 0.0, 1.0], 0.02)
        raw_over.append(np.ptp(v) - true)
        covered += abs(value - true) <= u
        assert u < 0.6 * 0.177                                   # the old U: 0.177
        assert det["zone_of_points"] == pytest.approx(np.ptp(v))
    assert np.mean(raw_over) > 0.08
    assert covered >= 19


@pytest.mark.parametrize("over, least", [(1.12, 5), (1.2, 19)])
def test_a_tilt_just_over_its_zone_fails(over, least):
    """FTC 06 GT16's case on a 100 x 50 mm face: a tilt ``over`` x the 0.3048 zone fails in at
    least ``least`` of 20 scans and passes in none (the old rule: undecided in all 20 of both;
    12 % over is within U in most scans: 0.036 over against U about 0.058)."""
    fails = old_fails = 0
    for seed in range(20):
        rng, T = _panel(seed)
        v = T[:, 0] * over * 0.3048 / 100.0 + rng.normal(0, 0.02, len(T))
        X = np.column_stack([T, v])
        value, u, _ = corrected_width(float(np.ptp(v)), X, [0.0, 0.0, 1.0], 0.02)
        verdict = decide(value, 0.0, 0.3048, u)
        assert verdict != "pass"
        fails += verdict == "fail"
        old_fails += decide(float(np.ptp(v)), 0.0, 0.3048, 0.177) == "fail"
    assert old_fails == 0
    assert fails >= least


def test_a_wall_with_less_noise_than_the_scan_is_not_overcorrected():
    """A wall seen obliquely carries less line-of-sight noise across its normal than the scan's
    sigma: the correction uses the zone's own noise (test_gdt's bracket wall once read a bias
    larger than its width with the scan's)."""
    rng, T = _panel(3)
    v = rng.normal(0, 0.005, len(T))
    p = noise_part(T, v, 0.02)
    assert p.sigma == pytest.approx(0.005, rel=0.15)
    assert 0 < p.bias < np.ptp(v)


def test_no_noise_estimate_no_correction():
    rng, T = _panel(1, 100)
    v = rng.normal(0, 0.01, len(T))
    p = noise_part(T, v, float("nan"))
    assert p.bias == 0.0
