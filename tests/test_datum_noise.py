"""The datums' own noise in a located characteristic's U (:mod:`.datum_noise`).

NIST FTC 10's GT17/19/21 (positions to D|B|C) read 0.13-0.17 mm on a perfect scan while their U
was 0.051: D is three small collinear pads, whose tangent plane turns by ~1 mrad under
0.02 mm noise, and the holes sit 15-23 mm above where B and C fix the frame.  The part here is
that geometry in small: its datum part of U must cover what the frame's noise does to the
value of a perfect hole, brute force: the DRF fitted on many independent noisy scans of the
datum features, the perfect hole's axis read in each fitted frame.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from shapeverify.characteristics.datum_noise import datum_u
from shapeverify.characteristics.drf import DatumFeature, fit_drf
from shapeverify.characteristics.gdt_zones import tangent_basis

NOISE = 0.02
PADS = (-20.0, 0.0, 20.0)         # pads of radius 3 on z = 0, centres on the x axis
HOLES = {"B": (-40.0, 20.0), "C": (40.0, 20.0)}   # radius 3, axis z, z in 0..6
ENDS = np.array([[0.0, -20.0, 15.0], [0.0, -20.0, 25.0]])   # the located hole's axis ends


def _nominal(rng, spacing=1.0, hole_spacing=2.0):
    """(feet, normals) of each datum feature's points (uniform by area at ``spacing``, the
    holes' at ``hole_spacing``: fewer points, faster mating circles)."""
    n = rng.poisson(np.pi * 9 / spacing ** 2, len(PADS))
    r, t = [3 * np.sqrt(rng.random(k)) for k in n], [rng.uniform(0, 2 * np.pi, k) for k in n]
    D = np.vstack([np.column_stack([x + ri * np.cos(ti), ri * np.sin(ti), np.zeros(len(ri))])
                   for x, ri, ti in zip(PADS, r, t)])
    out = {"D": (D, np.tile([0.0, 0.0, -1.0], (len(D), 1)))}
    for k, (x, y) in HOLES.items():
        m = rng.poisson(2 * np.pi * 3 * 6 / hole_spacing ** 2)
        th = rng.uniform(0, 2 * np.pi, m)
        nrm = -np.column_stack([np.cos(th), np.sin(th), np.zeros(m)])   # into the hole
        out[k] = (np.column_stack([x - 3 * nrm[:, 0], y - 3 * nrm[:, 1],
                                   rng.uniform(0, 6, m)]), nrm)
    return out


def _features(nominal, rng):
    def noisy(k):
        P, N = nominal[k]
        return P + rng.normal(0.0, NOISE, len(P))[:, None] * N
    return [DatumFeature("D", "plane", np.zeros(3), np.array([0, 0, -1.0]), noisy("D"))] + [
        DatumFeature(k, "axis", np.array([x, y, 0.0]), np.array([0, 0, 1.0]), noisy(k))
        for k, (x, y) in HOLES.items()]


def _closest(P, exact=True):
    """The nominal surfaces' closest points and normals (pads: z = 0; holes: radius 3)."""
    P = np.asarray(P, float)
    feet, nrm = P.copy(), np.zeros_like(P)
    pad = np.abs(P[:, 2]) < 0.2
    if np.all(pad):
        feet[:, 2], nrm[:, 2] = 0.0, -1.0
        return SimpleNamespace(points=feet, normals=nrm)
    (k,) = {min(HOLES, key=lambda h: np.hypot(*(p[:2] - HOLES[h]))) for p in P}
    q = P[:, :2] - HOLES[k]
    u = q / np.linalg.norm(q, axis=1)[:, None]
    feet[:, :2] = HOLES[k] + 3 * u
    nrm[:, :2] = -u
    return SimpleNamespace(points=feet, normals=nrm)


def _value(T):
    """Position (diameter zone) of the perfect hole read in the frame T."""
    E = ENDS @ T[:3, :3].T + T[:3, 3]
    return 2.0 * float(np.linalg.norm((E - ENDS[:, None, :].mean(0))[:, :2], axis=1).max())


@pytest.mark.slow           # ~6 s of CPU: 184 DRF fits (mating circles by LP)
def test_position_to_noisy_datums_u_covers_perfect_part():
    rng = np.random.default_rng(5)
    nominal = _nominal(rng)
    # (two passes of the DRF fit: within 1e-6 of the converged fit on these datums)
    brute = [_value(fit_drf(_features(nominal, rng), size=100.0, max_iterations=2).T)
             for _ in range(120)]
    q = float(np.quantile(brute, 0.9545))
    # the evaluation's view: one scan's datum features, the frame fitted on them
    feats = _features(nominal, rng)
    drf = fit_drf(feats, size=100.0)
    ctx = SimpleNamespace(cache={("drf_features", ("D", "B", "C")): feats}, k=2.0,
                          S=SimpleNamespace(noise=NOISE),
                          prep=SimpleNamespace(closest=_closest,
                                               model=SimpleNamespace(size=100.0)))
    U = datum_u(drf, ctx, drf.apply(ENDS), tangent_basis(np.array([0, 0, 1.0])))
    # the frame's noise alone reads tenths of a mm on a perfect hole (the bug: U was ~0.05)
    assert q > 0.08, q
    # about it: 32 replicates give the frame's covariance to ~13 % (one sd), taken at its
    # one-sigma upper bound; the first version (two passes of fit_drf per replicate) read
    # 0.87-1.47 q over the simulation's seeds on these datums (the Gaussian of the motions is
    # ~8 % short of the tangent plane's tails).  With the module's seed (one linearised pass,
    # each datum's fits shared): 1.11 q, 97 % of the brute force
    assert 0.8 * q <= U <= 1.6 * q, (U, q)
    assert np.mean(np.asarray(brute) <= U) >= 0.85
