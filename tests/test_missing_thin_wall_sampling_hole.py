"""A sampling hole on a thin wall is not missing material (issue 29: good parts pass).

0.5 mm, seed 21 of the good impeller (``test_material_impeller._scan``: 2 % outliers, 4
reflection clusters): a 'missing' region of 2.6 mm² on a blade.  ``find_missing`` calls a gap
wider than sampling explains when some point of it is farther than ``MIN_WIDTH`` (2.5) spacings
from every foot point; the spacing (:func:`.regions.surface_spacing`) counts neighbours in
space, and on a wall thinner than a few spacings it counts both sides: on the impeller it reads
0.38 mm for scans of 0.5 mm, so an ordinary hole of random sampling (1.99 of the blade's own
spacings, the largest among 100,000 points is about 1.9) read 2.6 -- and a reflection copied
into the blade was the 'seen behind' evidence.  The gap is now measured in the spacing of the
surface around it, on its own side of the wall (``missing._wider_than_local_sampling``).

Here: a plate 0.8 mm thick (both faces scanned at random, 0.5 mm), a hole in the top face's
scan, and a reflection's patch of points 1.6 mm under the plate below it (too far: the evidence
rule 1 asks for).
"""
from __future__ import annotations

import types

import numpy as np
import pytest

from shapeverify.inspection.missing import find_missing
from shapeverify.inspection.regions import surface_spacing

S, HALF, THICK, TOL, EV_DIST = 0.5, 15.0, 1.2, 0.15, 1.0


def _prep(h=0.25):
    """A stand-in prepared model: both faces of the plate sampled on a grid of ``h``."""
    g = np.arange(-HALF + h / 2, HALF, h)
    X, Y = np.meshgrid(g, g)
    top = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, THICK / 2)])
    bot = top * [1, 1, -1]
    pts = np.vstack([top, bot])
    normals = np.vstack([np.tile([0, 0, 1.0], (len(top), 1)), np.tile([0, 0, -1.0], (len(top), 1))])
    face = np.repeat(np.array([0, 1], np.int32), len(top))
    mp = types.SimpleNamespace(points=pts, normals=normals, face=face, spacing=h)
    return types.SimpleNamespace(points=mp, model=types.SimpleNamespace(size=2 * HALF * np.sqrt(2)))


def _dev(seed, hole_radius):
    """Deviations of a random scan of both faces with no top-face point within
    ``hole_radius`` of (3, 2), and 100 points 2 mm under the plate there."""
    rng = np.random.default_rng(seed)
    faces = []
    for sign in (1.0, -1.0):
        n = rng.poisson((2 * HALF) ** 2 / S ** 2)
        P = np.column_stack([rng.uniform(-HALF, HALF, (n, 2)),
                             sign * THICK / 2 + rng.normal(0, 0.02, n)])
        if sign > 0:
            P = P[np.hypot(P[:, 0] - 3.0, P[:, 1] - 2.0) >= hole_radius]
        faces.append(P)
    behind = np.column_stack([rng.uniform(-1.5, 1.5, (100, 2)) + [3.0, 2.0],
                              -THICK / 2 - 1.6 + rng.normal(0, 0.02, 100)])
    P = np.vstack(faces + [behind])
    top = np.arange(len(P)) < len(faces[0])
    zf = np.where(top | (P[:, 2] > 0), THICK / 2, -THICK / 2)
    nz = np.where(zf > 0, 1.0, -1.0)
    values = (P[:, 2] - zf) * nz
    ev = np.abs(values) <= EV_DIST
    return types.SimpleNamespace(
        values=np.where(ev, values, np.nan), evaluated=ev,
        reason=np.where(ev, 0, 1).astype(np.int8), face=np.where(nz > 0, 0, 1).astype(np.int32),
        foot_points=np.column_stack([P[:, :2], zf]), normals=np.column_stack(
            [np.zeros((len(P), 2)), nz]), points_model=P, evaluation_distance=EV_DIST,
        n_evaluated=int(ev.sum()))


def _missing(seed, hole_radius, prep):
    dev = _dev(seed, hole_radius)
    s = surface_spacing(dev.foot_points[dev.evaluated])
    within = dev.evaluated & (np.abs(dev.values) <= TOL)
    return find_missing(prep, dev, s, within), s


def test_a_sampling_hole_on_a_thin_wall_is_not_missing():
    """A hole of 1 mm radius (2 true spacings, as wide as the widest hole of random sampling on
    a large part) in the top face's scan: no region.  The scan's spacing reads under 0.8 of the
    true one (both faces counted), the hole 2.6-2.7 of those spacings: seeds 1, 2 and 4 had a
    'missing' region of 3.5-4.4 mm^2."""
    prep = _prep()
    for seed in range(6):
        regions, s = _missing(seed, 1.0, prep)
        assert s < 0.8 * S, s                  # the wall's two sides in the spacing
        assert regions == [], (seed, s, regions)


@pytest.mark.parametrize("radius", [1.6, 2.5])
def test_a_hole_in_a_thin_wall_is_still_missing(radius):
    """Holes of 1.6 and 2.5 mm radius (3.2 and 5 true spacings) with the same evidence behind:
    one 'missing' region on the top face, as before.  Its area reads 1.17-1.43 x pi r^2 (the
    hole in the scan is wider than the disc taken out: its rim runs through the nearest points
    around it) with this change and without it; checked loosely here."""
    prep = _prep()
    for seed in range(3):
        regions, _ = _missing(seed, radius, prep)
        assert len(regions) == 1, (seed, regions)
        assert regions[0].faces == (0,)
        assert 1.0 < regions[0].area / (np.pi * radius ** 2) < 1.5, regions[0].area
