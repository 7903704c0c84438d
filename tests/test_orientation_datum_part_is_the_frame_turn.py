"""Issue 28, "How good": NIST CTC 05's GT4 (perpendicularity 0.254 of a face 79 mm across, to
datum C, a 50.8 x 31.75 mm target area on an end face) read 0.289 +- 0.099 with the face
tilted 0.2 deg (true 0.277): undecided, most of U the datum part (0.08).  Was that part too
large?  Measured on 10 independent CTC 05 scans (benchmarks/check_datum_u_coverage.py,
results_plan.md): the fitted frame of C turns by 0.56 / 0.24 mrad (sd, about the two
constrained axes), the bootstrap (:func:`.datum_noise.frame_motions`) says 0.43 / 0.28 --
the same within the 10 scans' sampling error; the datum part is right and the case is
undecided because its margin (0.023 mm) is smaller than the face's own noise part.

This pins the property in small, brute force: a plane datum on a rectangle target area, a
face perpendicular to it tilted 0.2 deg; the datum fitted on many independent scans (fresh
points *and* fresh noise, where the bootstrap re-noises one scan's feet), the tilted face's
nominal points read in each fitted frame.  The datum part of U must cover ~95 % of the value's
changes and not be much larger than their 95.45 % quantile (a U twice the scatter would keep
near-limit parts undecided for nothing)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from shapeverify.characteristics.datum_noise import datum_u
from shapeverify.characteristics.drf import DatumFeature, fit_drf
from shapeverify.characteristics.gdt_zones import planes_zone

pytestmark = pytest.mark.slow     # 101 plane fits by LP: ~8 s alone, 25 s at load 7 on 2 cores

NOISE = 0.02
#: the datum: the plane x = 0 (material at x > 0), a target area |y| <= 25, |z| <= 16
HALF = (25.0, 16.0)
C_NORMAL = np.array([-1.0, 0.0, 0.0])
#: the toleranced face: y = 0 for x in 5..85, |z| <= 10, tilted 0.2 deg about z
N0 = np.array([0.0, 1.0, 0.0])


def _datum_points(rng, spacing=1.0):
    n = rng.poisson(4 * HALF[0] * HALF[1] / spacing ** 2)
    P = np.column_stack([np.zeros(n), rng.uniform(-HALF[0], HALF[0], n),
                         rng.uniform(-HALF[1], HALF[1], n)])
    return P + rng.normal(0.0, NOISE, n)[:, None] * C_NORMAL


def _face(rng, n=1600):
    x, z = rng.uniform(5.0, 85.0, n), rng.uniform(-10.0, 10.0, n)
    return np.column_stack([x, np.tan(np.radians(0.2)) * (x - 45.0), z])


def _value(X):
    """Perpendicularity to C: the planes zone normal to N0, free to turn about C's normal."""
    return planes_zone(X, N0, [np.cross(C_NORMAL, N0)])[0]


def _closest(P, exact=True):
    feet = np.asarray(P, float).copy()
    feet[:, 0] = 0.0
    return SimpleNamespace(points=feet, normals=np.tile(C_NORMAL, (len(feet), 1)))


def _fit(P):
    return fit_drf([DatumFeature("C", "plane", np.zeros(3), C_NORMAL, P)], size=100.0,
                   max_iterations=2)


def test_orientation_datum_part_is_the_frame_turn_scatter():
    rng = np.random.default_rng(28)
    X = _face(rng)
    true = _value(X)
    assert abs(true - 80 * np.tan(np.radians(0.2))) < 0.01
    # brute force: independent scans of the datum (new points, new noise)
    change = np.array([_value(_fit(_datum_points(rng)).apply(X)) - true for _ in range(100)])
    q = float(np.quantile(np.abs(change), 0.9545))
    # the evaluation's view: one scan, its frame, the bootstrap about it
    P = _datum_points(rng)
    drf = _fit(P)
    ctx = SimpleNamespace(cache={("drf_features", ("C",)): [
        DatumFeature("C", "plane", np.zeros(3), C_NORMAL, P)]}, k=2.0,
        S=SimpleNamespace(noise=NOISE),
        prep=SimpleNamespace(closest=_closest, model=SimpleNamespace(size=100.0)))
    U = datum_u(drf, ctx, drf.apply(X), N0[None], floating=True)
    # the frame's turn moves a tilted face's reading by hundredths of a mm
    assert q > 0.02, q
    # seed 28: U = 1.00 q, 95 % of the brute force (seeds 28, 1, 2 with 150 fits: 0.95-1.24 q)
    assert np.mean(np.abs(change) <= U) >= 0.9, (U, q)
    assert U <= 1.6 * q, (U, q)
