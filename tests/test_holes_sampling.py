"""Edge-point hole measurement under any sampling (issue 27 item 3): a flat sheet with a hole
sampled at random, on a square grid and on a 1 x 1.6 grid (random angle and phase), 0.3-2 mm,
no wall seen.  The edge points' offset is measured on virtual holes in the scan's own points."""
from __future__ import annotations

import numpy as np
import pytest

from shapeverify.characteristics.holes import measure_hole

R0 = 10.0


def _sheet(kind, h, rng, centre):
    L = 2 * R0 + 30 * h + 10
    if kind == "random":
        xy = rng.uniform(-L, L, (rng.poisson((2 * L / h) ** 2), 2))
    else:
        hx, hy = (h, h) if kind == "grid" else (h, 1.6 * h)
        g = np.stack(np.meshgrid(np.arange(-L, L, hx), np.arange(-L, L, hy)), -1).reshape(-1, 2)
        th = rng.uniform(0, np.pi)
        R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
        xy = g @ R.T + rng.uniform(0, h, 2)
    xy = xy[np.hypot(*(xy - centre).T) > R0]
    return np.column_stack([xy, rng.normal(0, 0.02, len(xy))])[rng.permutation(len(xy))]


@pytest.mark.parametrize("kind", ["random", "grid", "aniso"])
# spacings 0.3 and 1.0: 5-23 s each (measured at a load of 3, 2026-12-06): slow, out of `make
# test-fast` (issue 32); 2.0 stays quick
@pytest.mark.parametrize("h", [pytest.param(0.3, marks=pytest.mark.slow),
                               pytest.param(1.0, marks=pytest.mark.slow), 2.0])
def test_edge_point_diameter_has_no_sampling_bias(kind, h):
    """Pins: the edge points' offset was a lattice model (0.54 of a grid spacing): random
    sampling read +0.2 (0.3 mm) to +1.9 mm (2 mm) too large in diameter."""
    rng = np.random.default_rng(int(h * 10) + len(kind))
    runs = 8
    e, u = [], []
    for _ in range(runs):
        c = rng.uniform(-0.3, 0.3, 2)
        hm = measure_hole(_sheet(kind, h, rng, c), [0, 0, 0], [0, 0, 1], 2 * R0)
        # a complete sheet: the largest empty circle, calibrated on virtual holes (step 4)
        assert hm.method == "empty circle" and hm.n_virtual >= 6, (hm.method, hm.n_virtual)
        e.append(hm.diameter - 2 * R0)
        u.append(hm.u_diameter)
    e, u = np.array(e), np.array(u)
    # the mean error is within 3 standard errors of the runs' scatter (no bias)...
    assert abs(e.mean()) <= 3 * max(e.std(ddof=1), np.mean(u)) / np.sqrt(runs), (e, u)
    # ...and U (k = 2) covers most runs
    assert np.mean(np.abs(e) <= 2 * u) >= 0.75, (e, u)
