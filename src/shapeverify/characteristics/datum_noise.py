"""The datum features' own noise carried into a located characteristic's uncertainty.

A characteristic measured in a datum reference frame (:mod:`.drf`) reads its points where the
frame puts them; the frame rests on the datum features' scan points and moves with their
noise.  A tangent plane on small pads (NIST FTC 10's datum D: three 7 mm pads, 104 points at
1 mm) rests on its three highest points and turns by milliradians; a hole 20 mm above its
datum axes then reads ~0.15 mm of position on a perfect part.

Method (a parametric bootstrap of the DRF, then a linear propagation)
--------------------------------------------------------------------
1. :func:`frame_motions`: every datum feature's points are put on their CAD feet (exact
   closest points) and given fresh Gaussian noise of the scan's sigma along the CAD normal
   (a point datum: fresh deviations); the DRF is fitted on them (:func:`.drf.fit_drf`, the
   same association criteria) :data:`REPLICATES` times.  As the simulated datums are nominal,
   each fit's correction ``T_r`` *is* that fit's error: a small rigid motion ``xi_r = (omega,
   t)``.  Their mean (a tangent plane's outward offset) and covariance describe where the
   noise puts the frame.  Seeded: deterministic.  Cached per DRF.
2. :func:`datum_u`: a characteristic gives the points its value is read from (``P``, DRF
   frame) and the unit directions its zone measures at each (``D``: a profile's normals, a
   position's two directions across the axis, a planes zone's normal).  A motion moves point
   ``p`` by ``omega x p + t``; the value (twice the largest offset from the true geometry)
   changes by at most ``2 max_i |D_i (omega x p_i + t)|``.  A zone free to float
   (orientation, a composite's lower segment) sees no translation and turns about the
   points' centroid.  :data:`SAMPLES` motions drawn from the Gaussian of step 1 give that
   change's distribution; the datum part of U is its ``p``-quantile, ``p = erf(k / sqrt 2)``
   (95.45 % for k = 2): a magnitude, so a quantile, not k standard deviations.
3. The characteristic combines it in quadrature with its own part.

Cost: two passes of the DRF fit per replicate and DRF (within 1e-6 of the converged fit on
nominal datums), then a (samples x points) product per characteristic on at most
:data:`MAX_POINTS` points.  Measured (load ~10 on 2 cores, located characteristics only, true
pose): FTC 10 (19 located, 8 DRFs) 4.1 -> 18.9 s CPU; CTC 03 (9 located, 5 DRFs, one with an
axis datum of free direction: mating cylinders by LP) 6.2 -> 29 s.

Check (20 independent perfect scans of FTC 10, OCC tessellation by area at 1 mm, 0.02 mm
noise): (characteristic, seed) with value > U 45/380 (11.8 %) -> 14/380 (3.7 %); GT17/19/21
(positions to D|B|C) 29/60 -> 5/60.
"""
from __future__ import annotations

from math import erf, sqrt

import numpy as np

__all__ = ["frame_motions", "datum_u", "REPLICATES", "SAMPLES"]

#: DRF fits on simulated noisy datums, per DRF
REPLICATES = 32
#: motions drawn from their Gaussian, per characteristic
SAMPLES = 2000
#: a characteristic's points used (an even subset, plus the extremes of each motion's lever)
MAX_POINTS = 1500
SEED = 20261207


def _simulated(f, feet, normals, sigma, rng):
    """The datum feature ``f`` with its points on their CAD feet plus fresh noise."""
    import dataclasses

    new = {}
    if len(f.points):
        new["points"] = feet[0] + rng.normal(0.0, sigma, len(feet[0]))[:, None] * normals[0]
    if f.points2 is not None and len(f.points2):
        new["points2"] = feet[1] + rng.normal(0.0, sigma, len(feet[1]))[:, None] * normals[1]
    if f.deviations is not None:
        new["deviations"] = rng.normal(0.0, sigma, len(f.deviations))
    return dataclasses.replace(f, **new)


def frame_motions(names, ctx) -> np.ndarray:
    """(m, 6) motions ``(omega, t)`` of the DRF ``names`` fitted on simulated noisy nominal
    datum features (step 1 of the module docstring); cached in ``ctx.cache``."""
    key = ("drf_noise", tuple(names))
    if key in ctx.cache:
        return ctx.cache[key]
    from .drf import fit_drf
    from .gdt import datum_features

    feats = datum_features(names, ctx)
    feet = []
    for f in feats:
        fs = []
        for P in (f.points, f.points2):
            if P is None or not len(P):
                fs.append((np.zeros((0, 3)), np.zeros((0, 3))))
                continue
            cl = ctx.prep.closest(np.asarray(P, float), exact=True)
            fs.append((np.asarray(cl.points, float), np.asarray(cl.normals, float)))
        feet.append(fs)
    sigma = float(ctx.S.noise)
    rng = np.random.default_rng(SEED)
    out = []
    for _ in range(REPLICATES):
        sim = [_simulated(f, (a[0], b[0]), (a[1], b[1]), sigma, rng)
               for f, (a, b) in zip(feats, feet)]
        try:
            # two passes: the simulated datums are nominal, the second pass is within 1e-6
            T = fit_drf(sim, size=float(ctx.prep.model.size), max_iterations=2).T
        except ValueError:
            continue
        R = T[:3, :3]
        w = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
        out.append(np.r_[w, T[:3, 3]])
    ctx.cache[key] = np.array(out).reshape(-1, 6)
    return ctx.cache[key]


def datum_u(drf, ctx, P, D, floating: bool = False) -> float:
    """Expanded (k) change of a value read at points ``P`` (m, 3; DRF frame) along directions
    ``D`` ((m, j, 3) or (j, 3) for all points; unit) from the datums' noise (step 2 of the
    module docstring); 0 without a DRF."""
    if drf is None:
        return 0.0
    xi = frame_motions(drf.names, ctx)
    P = np.asarray(P, float).reshape(-1, 3)
    if len(xi) < 3 or not len(P):
        return 0.0
    D = np.asarray(D, float)
    D = np.broadcast_to(D.reshape((1,) * (3 - D.ndim) + D.shape), (len(P),) + D.shape[-2:])
    if floating:
        P = P - P.mean(axis=0)
    # g[i, j] = (p_i x d_ij, d_ij): the change along d_ij is g[i, j] . xi
    G = np.concatenate([np.cross(P[:, None, :], D), D], axis=2)
    if floating:
        G[..., 3:] = 0.0
    if len(G) > MAX_POINTS:
        flat = G.reshape(len(G), -1)
        keep = set(np.linspace(0, len(G) - 1, MAX_POINTS).astype(int).tolist())
        keep |= set(np.argmax(flat, axis=0).tolist()) | set(np.argmin(flat, axis=0).tolist())
        G = G[sorted(keep)]
    # the covariance of m replicates, at its one-sigma upper bound (chi-square, m - 1 degrees
    # of freedom: x 1.33 for 32): a U read from few replicates must not come out low
    from scipy.stats import chi2

    mu, C = xi.mean(axis=0), np.cov(xi.T) * (len(xi) - 1) / chi2.ppf(0.16, len(xi) - 1)
    rng = np.random.default_rng(SEED + 1)
    S = rng.multivariate_normal(mu, C, SAMPLES, method="eigh")     # (s, 6)
    change = np.einsum("ijk,sk->sij", G, S)                         # (s, m, j)
    d = 2.0 * np.sqrt((change ** 2).sum(axis=2)).max(axis=1)
    p = erf(float(ctx.k) / sqrt(2.0))
    return float(np.quantile(d, p))
