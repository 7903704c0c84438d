"""The extreme of an object lying on the part is its height, not a paraboloid dipping over its
edge (issue 29 item 2: a region's extreme within 10 % of the defect's depth on any scan).

The 6 x 6 x 3 mm box on the example panel read +1.87 mm at 0.5 mm spacing, seed 5.  A region's
extreme is the peak of a quadratic fitted around its worst core point (the largest
neighbourhood median); on a flat top every point is "worst" by its noise alone, and there it
lay 0.6 mm from two walls: within the fit's radius the walls' points (their feet on the rim,
values 0..3 mm) and the panel's beside them pulled the quadratic down to 1.87 mm, 1.1 mm below
the median of the measured values around its own centre (3.0 mm).  The fit was only ever
checked against going *beyond* the measured values.  Now a fitted extreme short of its centre's
neighbourhood median by more than 3 of that median's standard errors is no peak of the data:
the median is the extreme, when the fit's residuals exceed twice the local noise
(``regions.MEDIAN_SHORT``; a fit that fits stays: the largest of a smooth dent's many medians is
biased by their noise).  Truth: the box's height.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from shapeverify.inspection import inspect_registered
from shapeverify.inspection import regions as R
from test_box_wall_read_as_layer_over_the_part import HEIGHT, TOL, _box_scan, _identity, panel  # noqa: F401
from test_region_area_of_an_object_on_the_part import _box_on_plane


@pytest.mark.parametrize("seed", range(6))
def test_box_extreme_fit_dips_below_its_top_near_a_corner(seed):
    """A box on a plane at 0.5 mm, described around a top point near a corner whose
    neighbourhood median is the top's height (``find_regions`` picks the largest median, on a
    flat top any point): the extreme within 5 % of the height (the quadratic alone read
    2.70 mm on seed 1; on seed 2 it reads 2.86 mm, -4.8 %, still: the local noise among the
    walls' crowded feet reads 0.45 mm, so its residuals, 0.88 mm, count as fitting)."""
    s, tol = 0.5, 0.15
    P = _box_on_plane(seed, s)
    n = len(P)
    feet = np.column_stack([P[:, :2], np.zeros(n)])
    v = P[:, 2]
    tree, ev = cKDTree(feet), np.arange(n)
    within = np.abs(v) <= tol
    # a top point 0.2-1.5 mm from two walls whose 9 nearest are the top's (its median the top's
    # height: as good a worst core point as any on a flat top), the nearest to the corner
    top = np.flatnonzero((v > 2.9) & (np.maximum(P[:, 0], P[:, 1]) < -1.5) &
                         (np.minimum(P[:, 0], P[:, 1]) > -2.8))
    med = R.neighbourhood_median(tree, ev, v, feet[top], R.MEDIAN_RADIUS * s)
    ok = np.flatnonzero(med > HEIGHT - 0.1)
    k = ok[np.argmin(np.hypot(P[top[ok], 0] + 3.0, P[top[ok], 1] + 3.0))]
    near = top
    lim = np.full(n, tol)
    r = R._describe(np.flatnonzero(~within), near[[k]], med[[k]], feet, v, np.zeros(n, int),
                    np.tile([0.0, 0.0, 1.0], (n, 1)), tree, ev, s, -lim, lim, within)
    assert abs(r.extreme / HEIGHT - 1.0) < 0.05, (r.extreme, med[k])


@pytest.mark.slow
def test_box_extreme_fit_dips_below_its_top_on_the_panel(panel):  # noqa: F811
    """The box on the panel scanned by area at 0.5 mm, seed 5: one region, its extreme within
    10 % of the height (was +1.87 mm)."""
    prep, V, T, F = panel
    P, _ = _box_scan(prep, V, T, F, 0.5, 5)
    res = inspect_registered(prep, P, _identity(), tolerance=TOL)
    assert len(res.regions) == 1, res.reasons
    assert abs(res.regions[0].extreme / HEIGHT - 1.0) <= 0.10, res.regions[0].extreme
