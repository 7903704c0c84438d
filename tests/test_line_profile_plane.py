"""Profile of a line of a plane in a datum reference frame (NIST CTC 02 e2 GT19: attached to
one planar face; the semantic PMI gives no section direction).  A plane's located line
element in any section square to it lies in the band |d| <= t/2 about the true plane, so
sections covering the face give 2 max |d| over the face, whatever their direction: checked
here against that brute force, for two directions."""
from __future__ import annotations

import numpy as np
import pytest

from shapeverify.characteristics.profile_line import section_offsets, sections_profile


def _plane_points(rng, n=20000):
    """Points of a 60 x 25 mm plane z = 0 with a smooth deviation d (their z), a bump near
    one corner (the largest |d|)."""
    xy = rng.uniform([0.0, 0.0], [60.0, 25.0], (n, 2))
    d = 0.01 * np.sin(xy[:, 0] / 7.0) + 0.05 * np.exp(-((xy[:, 0] - 57) ** 2
                                                         + (xy[:, 1] - 2) ** 2) / 4.0)
    return np.column_stack([xy, d]), d


@pytest.mark.parametrize("normal", [(1.0, 0.0, 0.0), (0.6, 0.8, 0.0)])
def test_plane_line_profile_sections_covering_the_face_give_the_brute_force_value(normal):
    rng = np.random.default_rng(3)
    X, d = _plane_points(rng)
    n = np.asarray(normal)
    slab = 0.5
    s = X @ n
    count = int(np.ceil(np.ptp(s) / (2 * slab)) + 1)     # as pmi_profile_line plans it
    value, at, per = sections_profile(X, d, n, section_offsets(s, count, slab), slab)
    covered = np.zeros(len(X), bool)
    for p in per:
        covered |= np.abs(s - p["offset"]) <= slab
    assert covered.all()
    assert value == pytest.approx(2.0 * np.abs(d).max(), abs=1e-9)
