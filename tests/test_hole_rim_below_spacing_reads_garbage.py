"""A hole seen only at its rim is not measured when the scan does not resolve it.

FTC 10 (bundled) on an independent scan at 1.5 mm (OpenCASCADE's tessellation sampled by
area, 0.03 mm noise, seed 3), a perfect part, failed two diameters:

* its 2.5 mm holes (radius 0.83 mean point spacings, no wall points) read -1.7 mm (hole 32):
  the rim's gap model (the points stop ~ a spacing short of the edge) is fitted on holes of
  4.5-18 spacings and gives nonsense below ~1.5 (:data:`holes._MIN_RIM_RADIUS`);
* its countersunk 10 mm hole 44 had 26 wall points (30 needed for a wall fit) and 21 points on
  the cone inside its circle (30 were needed to call the loop a countersink's rim): its "rim"
  read 3.7 mm (:data:`holes._MIN_INSIDE`).

Both now say why they are not measured (the plan marks them undecided).  And the brute-force
side: on random plates with a hole of radius >= 1.5 spacings the rim's U still covers the
error in >= 85 % of 30 scans.
"""
from __future__ import annotations

import gzip
import shutil
from pathlib import Path

import numpy as np
import pytest

from shapeverify.characteristics.holes import _MIN_RIM_RADIUS, measure_hole

DATA = Path(__file__).parent / "data" / "nist_extra"


def _plate(r0, s, sigma, seed, L=40.0):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-L / 2, L / 2, (rng.poisson(L * L / s ** 2), 2))
    xy = xy[np.hypot(*xy.T) > r0]
    return np.c_[xy, rng.normal(0.0, sigma, len(xy))]


def _measure(P, r0):
    return measure_hole(P, np.zeros(3), np.array([0.0, 0.0, 1.0]), 2.0 * r0)


def test_rim_of_a_hole_smaller_than_the_spacing_is_not_measured():
    # radius 1.25 at 1.5 mm: 9 of 40 read off by more than U before (up to 137 mm)
    for seed in range(10):
        with pytest.raises(ValueError, match="do not\\s+resolve its diameter"):
            _measure(_plate(1.25, 1.5, 0.03, seed), 1.25)


@pytest.mark.parametrize("r0, s", [(1.6, 1.0), (2.0, 1.0), (3.0, 1.5)])
def test_rim_of_a_resolved_hole_keeps_its_U(r0, s):
    assert r0 / s >= _MIN_RIM_RADIUS
    errs, Us = [], []
    for seed in range(30):
        try:
            hm = _measure(_plate(r0, s, 0.03, seed), r0)
        except ValueError:
            continue
        errs.append(hm.diameter - 2 * r0)
        Us.append(2.0 * hm.u_diameter)
    errs, Us = np.array(errs), np.array(Us)
    assert len(errs) >= 22
    assert np.mean(np.abs(errs) <= Us) >= 0.85, (errs, Us)
    assert np.all(2 * r0 + errs > 0)


@pytest.mark.slow
def test_ftc10_perfect_holes_at_1_5mm_are_not_read_from_garbage(tmp_path):
    from independent_scans import file_tessellation, random_points
    from model_cache import cached_prepared

    from shapeverify.characteristics.features import model_features

    p = tmp_path / "nist_ftc_10_asme1_ap242-e2.stp"
    with gzip.open(DATA / (p.name + ".gz"), "rb") as src, open(p, "wb") as dst:
        shutil.copyfileobj(src, dst)
    # features and tessellation once per code version, shared with test_datum_hole_wall.py
    # (tests/model_cache.py: bitwise what model_features and tessellate give)
    prep = cached_prepared(p, features=True)
    feats = {f.id: f for f in model_features(prep.model)}
    V, T, _ = file_tessellation(p, 0.001)
    rng = np.random.default_rng(3)
    P, N = random_points(V, T, 1.5, rng)
    P = P + rng.normal(0.0, 0.03, len(P))[:, None] * N
    for hid, why in (("hole:44", "countersink"), ("hole:32", "resolve its diameter")):
        f = feats[hid]
        X = P[np.linalg.norm(P - f.center, axis=1) < 3 * f.diameter + 10]
        cl = prep.closest(X, exact=True)
        try:
            hm = measure_hole(X, f.center, f.axis, f.diameter, face=prep.model.faces[f.face],
                              deviations=np.asarray(cl.distances), normals=np.asarray(cl.normals))
        except ValueError as e:
            assert why in str(e).replace("\n", " ")
            continue
        # measured (another tessellation or sampler): then its error must be within its U
        assert abs(hm.diameter - f.diameter) <= 2.0 * hm.u_diameter, (hid, hm.diameter)
