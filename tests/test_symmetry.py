"""Symmetry (ASME Y14.5-2009 7.7.2: the median points of a width's opposed elements within two
parallel planes centred on the datum centre plane; NIST FTC 10 GT9 was "Symmetry ... is not
measured").

:func:`symmetry_value` against brute force to 1e-9 mm: tilted planar sides sampled at
different random positions (linear interpolation is exact on a plane, so each median point is
the exact midpoint of the two sides' planes at its position; a point outside the other side's
hull has no opposed element); wavy sides sampled at the same positions (the median points are
the exact midpoints of the pairs).  The zone is fixed (no minimum zone to search): the value
is twice the largest distance of a median point from the true centre plane.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import Delaunay

from shapeverify.characteristics.symmetry import symmetry_value


@pytest.mark.parametrize("seed", [1, 2])
def test_symmetry_of_tilted_planar_sides_is_twice_the_farthest_exact_midpoint(seed):
    """A tab 5 mm wide about x = 47.5 (FTC 10 GT9's), its sides tilted and offset: side 1
    x = 50.1 + 0.004 y - 0.003 z, side 2 x = 45.05 + 0.002 y + 0.001 z, each sampled at its own
    random (y, z) over overlapping boxes."""
    rng = np.random.default_rng(seed)
    s1 = lambda yz: 50.1 + 0.004 * yz[:, 0] - 0.003 * yz[:, 1]
    s2 = lambda yz: 45.05 + 0.002 * yz[:, 0] + 0.001 * yz[:, 1]
    yz1 = rng.uniform([0, 0], [20, 10], (300, 2))
    yz2 = rng.uniform([2, -1], [22, 9], (260, 2))
    X1, X2 = np.column_stack([s1(yz1), yz1]), np.column_stack([s2(yz2), yz2])
    value, M = symmetry_value(X1, X2, [1.0, 0.0, 0.0], 47.5)
    # brute force: every point of one side inside the other side's hull, the exact midpoint
    inside = [yz[Delaunay(other).find_simplex(yz) >= 0] for yz, other in ((yz1, yz2),
                                                                             (yz2, yz1))]
    mids = np.concatenate([0.5 * (s1(yz) + s2(yz)) for yz in inside])
    assert len(M) == len(mids)
    assert value == pytest.approx(2 * np.abs(mids - 47.5).max(), abs=1e-9)
    # the median points' heights are the exact midpoints (order aside)
    np.testing.assert_allclose(np.sort(M[:, 0]), np.sort(mids), atol=1e-9)


def test_symmetry_of_wavy_sides_sampled_alike_is_twice_the_farthest_pair_midpoint():
    """A slot 15 mm wide about x = 47.5 whose sides wave out of phase (the median points move
    by half the sum of the waves) plus 0.02 mm noise, both sides at the same (y, z)."""
    rng = np.random.default_rng(3)
    yz = rng.uniform([0, 0], [30, 12], (400, 2))
    y, z = yz.T
    x1 = 55.0 + 0.05 * np.sin(y / 4) + 0.02 * rng.standard_normal(400)
    x2 = 40.0 + 0.03 * np.cos(z / 2) + 0.02 * rng.standard_normal(400)
    value, M = symmetry_value(np.column_stack([x1, yz]), np.column_stack([x2, yz]),
                              [-1.0, 0.0, 0.0], -47.5)
    assert len(M) == 800
    assert value == pytest.approx(2 * np.abs(0.5 * (x1 + x2) - 47.5).max(), abs=1e-9)


def test_a_centred_width_reads_zero_and_one_moved_reads_twice_its_move():
    g = np.stack(np.meshgrid(np.linspace(0, 10, 11), np.linspace(0, 4, 5)), -1).reshape(-1, 2)
    X1 = np.column_stack([np.full(len(g), 50.0), g])
    X2 = np.column_stack([np.full(len(g), 45.0), g])
    assert symmetry_value(X1, X2, [1.0, 0.0, 0.0], 47.5)[0] == pytest.approx(0.0, abs=1e-12)
    assert symmetry_value(X1 + [0.3, 0, 0], X2 + [0.3, 0, 0], [1.0, 0.0, 0.0],
                          47.5)[0] == pytest.approx(0.6, abs=1e-12)


@pytest.mark.parametrize("order", [(0, 1), (1, 0)])
def test_width_sides_of_a_tab_is_a_tab_of_positive_width(order):
    """A tab's sides (outward normals parting: x = 45 facing -x, x = 50 facing +x) were read
    as a 'slot' of width -5 (the lower side's direction flipped); FTC 10 GT9's tab."""
    from types import SimpleNamespace as NS

    from shapeverify.characteristics.position_zones import width_sides

    feats = [NS(kind="plane", axis=np.array([-1.0, 0, 0]), center=np.array([45.0, 3, 1])),
             NS(kind="plane", axis=np.array([1.0, 0, 0]), center=np.array([50.0, 7, 2]))]
    A, B, u, true, width, slot = width_sides(feats, list(order))
    assert (width, slot) == (5.0, False)
    # u is the first listed face's normal; A the side lower along it, true the centre along u
    assert u[0] == feats[order[0]].axis[0] and true == 47.5 * u[0]
    assert feats[A[0]].center @ u < feats[B[0]].center @ u
    # a slot (normals facing each other) stays a slot of positive width
    feats[0].axis, feats[1].axis = -feats[0].axis, -feats[1].axis
    assert width_sides(feats, list(order))[4:] == (5.0, True)
