"""The scan's own noise on thin walls (``registration._noise.scan_noise``).

An impeller scanned at 1 mm (blades 1-2 mm thick, noise 0.02 mm) read 0.34 mm: the 24 neighbours
of a point held both sides of a blade and one quadric through both measured the wall, not the
noise; the verdict rule on the noise's share of the tolerance then called a good part
'incomplete'.  The scans here are made without the project's simulator: OpenCASCADE solids
tessellated and sampled uniformly by area (:mod:`independent_scans`), or sheets drawn with numpy,
with Gaussian noise along the normal; the estimate is compared with the noise drawn.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import independent_scans as ind
from shapeverify.registration._noise import scan_noise

NOISE = 0.02
_R = Rotation.from_rotvec([0.4, -0.3, 0.2]).as_matrix()


def _sampled(shape, spacing, seed):
    rng = np.random.default_rng(seed)
    V, T, _ = ind.tessellate(shape, 0.002)
    P, N = ind.random_points(V, T, spacing, rng)
    P = P + rng.normal(0.0, NOISE, len(P))[:, None] * N
    return P[rng.permutation(len(P))] @ _R.T + 5.0


def _plate(thickness):
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox

    return BRepPrimAPI_MakeBox(60.0, 40.0, thickness).Shape()


def _tube(radius, wall):
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder

    outer = BRepPrimAPI_MakeCylinder(radius + wall, 40.0).Shape()
    return BRepAlgoAPI_Cut(outer, BRepPrimAPI_MakeCylinder(radius, 40.0).Shape()).Shape()


@pytest.mark.parametrize("make,seed", [(lambda: _plate(1.5), 1), (lambda: _plate(1.0), 2),
                                       (lambda: _tube(5.0, 1.2), 3)])
def test_scan_noise_of_a_thin_walled_part_is_the_sensor_noise(make, seed):
    """A plate 1-1.5 mm thick and a tube with a 1.2 mm wall, sampled at 1 mm with 0.02 mm
    noise: the estimate within 30 % of the noise (it read 0.4-0.7 mm: quadrics across the
    wall)."""
    P = _sampled(make(), 1.0, seed)
    assert scan_noise(P) == pytest.approx(NOISE, rel=0.3)


def _sheets(gap, seed, outliers=0.0, spacing=1.0, noise=NOISE, size=60.0):
    rng = np.random.default_rng(seed)
    n = int(size * size / spacing ** 2)
    P = np.vstack([np.c_[rng.uniform(0, size, (n, 2)), z + rng.normal(0, noise, n)]
                   for z in (0.0, gap)])
    k = int(outliers * len(P))
    if k:
        P = np.vstack([P, P[rng.choice(len(P), k)] + rng.normal(0.0, 1.0, (k, 3))])
    return P[rng.permutation(len(P))] @ _R.T


@pytest.mark.parametrize("gap,outliers", [(0.6, 0.0), (1.5, 0.0), (1.5, 0.03), (3.0, 0.0)])
def test_scan_noise_of_two_sheets_close_together_is_the_sensor_noise(gap, outliers):
    """Two parallel sheets 0.6-3 mm apart at 1 mm spacing (0.6 mm: under the spacing), with
    and without 3 % outliers: within 30 % of the noise (it read 0.4-0.7 mm at 0.6-1.5 mm)."""
    assert scan_noise(_sheets(gap, 4, outliers)) == pytest.approx(NOISE, rel=0.3)


def test_scan_noise_stays_right_on_one_sheet_rasters_and_coarse_noise():
    """What the old quadrics measured right still is: a doubled exposure (two passes 0.02 mm
    apart) reads one sheet's scatter, a raster's rows 10 x farther apart than its points are
    no sheets, noise as large as the spacing reads at least as high as before (0.78 x)."""
    doubled = scan_noise(_sheets(0.02, 5))
    assert doubled == pytest.approx(np.hypot(NOISE, 0.01), rel=0.15)
    rng = np.random.default_rng(6)
    gx, gy = np.meshgrid(np.arange(0, 60, 0.3), np.arange(0, 60, 3.0))
    raster = np.c_[gx.ravel(), gy.ravel(), rng.normal(0, NOISE, gx.size)] @ _R.T
    assert scan_noise(raster) == pytest.approx(NOISE, rel=0.15)
    coarse = scan_noise(_sheets(1000.0, 7, noise=1.0))
    assert coarse == pytest.approx(1.0, rel=0.15)


def test_scan_noise_of_a_scan_with_each_point_twice_is_the_sensor_noise():
    """Each point twice (a merged file; or a copy 1 um off): the copy, a neighbour with the
    point's own noise, pulled the quadric onto the point (0.007 mm for 0.02 mm; the old
    quadrics 0.017 mm); two passes over the same places with their own noise read theirs."""
    rng = np.random.default_rng(8)
    one = _sheets(1000.0, 9)
    for twice in (np.vstack([one, one]), np.vstack([one, one + rng.normal(0, 1e-3, one.shape)]),
                  np.vstack([one, one + rng.normal(0, NOISE, len(one))[:, None] * _R[:, 2]])):
        est = scan_noise(twice[rng.permutation(len(twice))])
        assert est == pytest.approx(NOISE, rel=0.15), est
