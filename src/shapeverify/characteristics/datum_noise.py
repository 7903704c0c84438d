"""The datum features' own noise carried into a located characteristic's uncertainty.

A characteristic measured in a datum reference frame (:mod:`.drf`) reads its points where the
frame puts them; the frame rests on the datum features' scan points and moves with their
noise.  A tangent plane on small pads (NIST FTC 10's datum D: three 7 mm pads, 104 points at
1 mm) rests on its three highest points and turns by milliradians; a hole 20 mm above its
datum axes then reads ~0.15 mm of position on a perfect part.

Method (a parametric bootstrap of the DRF, then a linear propagation)
--------------------------------------------------------------------
1. :func:`frame_motions`: every datum feature's points are put on their CAD feet (exact
   closest points, once per datum) and given fresh Gaussian noise of the scan's sigma along
   the CAD normal (a point datum: fresh deviations; replicate r's noise is the same in every
   DRF naming the datum); each datum is fitted on them with its own association criterion
   (:func:`.drf._fit`) :data:`REPLICATES` times, and one pass of the DRF's lexicographic
   solution (:func:`.drf.one_pass`) linearised at the nominal datums turns the fits into the
   frame's correction.  As the simulated datums are nominal, that correction *is* the
   fit's error: a small rigid motion ``xi_r = (omega, t)``.  Their mean (a tangent plane's
   outward offset) and covariance describe where the noise puts the frame.  A datum's fit
   depends only on its own points and the datums before it, so it is made once per
   (datums up to it, replicate) and shared by the DRFs that start with them (D, D|B, D|B|C).
   Against the full iterated :func:`.drf.fit_drf` on the same simulated datums (FTC 10):
   the motions' standard deviations agree within a few % (D|B|C, A|B|C, A|B; D|E-F-G's
   pattern +10 %); what one linearised pass leaves out is second order in the frame's turn
   (e.g. a secondary tangent plane that may not follow the primary's tilt).
   Seeded: deterministic.  Cached per DRF.
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

Cost: one fit per (datums up to it, replicate), then a (samples x points) product per
characteristic on at most :data:`MAX_POINTS` points.  Whole plans, evaluate_plan CPU at the
true pose (benchmarks/bench_datum_noise.py, load 3-5 on 2 cores): FTC 10 (8 DRFs, 19 located)
11.8 -> 16.6 s (+40 %, mean of seeds 0-9), CTC 03 e2 22.6 -> 28.1 s (+24 %, seeds 1-2); the
first version (two passes of :func:`.drf.fit_drf` per replicate and DRF) took 30 and 45 s.
What is left is mostly scipy's linprog (its wrapper 3/4 of each small LP's time): FTC 10's
A|J (a midplane, 32 width fits) 1.1 s, D|B|C 0.8 s, D|E-F-G 0.8 s.

Check (benchmarks/bench_datum_noise.py: independent perfect scans of FTC 10, OCC
tessellation by area at 1 mm, 0.02 mm noise, seeds 0-9, the whole plan): (characteristic,
seed) with value > U 36/280 (12.9 %) -> 16/280 (5.7 %), of which 10 are GT10 (a profile that
reads 3.5 mm on every perfect scan, with or without this module) and 3/190 of those with a
DRF; GT17/19/21 (positions to D|B|C) 17/30 -> 0/30; no verdict changed.  The first version
(two passes of :func:`.drf.fit_drf` per replicate and DRF, 20 scans) gave 45/380 -> 14/380.
"""
from __future__ import annotations

import zlib
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


def _feet(f, ctx):
    """(feet, CAD normals) of the datum feature ``f``'s points and of its ``points2`` (exact
    closest points; cached per datum)."""
    key = ("drf_noise_feet", f.name)
    if key not in ctx.cache:
        out = []
        for P in (f.points, f.points2):
            if P is None or not len(P):
                out.append((np.zeros((0, 3)), np.zeros((0, 3))))
                continue
            cl = ctx.prep.closest(np.asarray(P, float), exact=True)
            out.append((np.asarray(cl.points, float), np.asarray(cl.normals, float)))
        ctx.cache[key] = out
    return ctx.cache[key]


def _simulated(f, feet, sigma, r):
    """The datum feature ``f`` with its points on their CAD feet plus fresh noise: replicate
    ``r``'s, the same in every DRF that names the datum."""
    import dataclasses

    rng = np.random.default_rng([SEED, zlib.crc32(f.name.encode()), r])
    (P, N), (P2, N2) = feet
    new = {}
    if len(f.points):
        new["points"] = P + rng.normal(0.0, sigma, len(P))[:, None] * N
    if f.points2 is not None and len(f.points2):
        new["points2"] = P2 + rng.normal(0.0, sigma, len(P2))[:, None] * N2
    if f.deviations is not None:
        new["deviations"] = rng.normal(0.0, sigma, len(f.deviations))
    return dataclasses.replace(f, **new)


def _fit_at(g, SN):
    """(DatumFit, G, r) of the simulated datum ``g`` in the free motions ``SN``; an axis's rows
    taken at the middle of its points' height, where the converged fit holds it: a circle of
    a direction fixed by the datums before it is fitted on the points projected along that
    direction, which the frame's turn shears -- the inscribed (circumscribed) circle of the
    sheared projection is centred at the middle of the points' height range."""
    from .drf import _axis_rows, _fit
    from .gdt_zones import tangent_basis

    fit, G, r = _fit(g, g.points, SN)
    if g.kind == "axis" and len(g.points):
        d0 = np.asarray(g.direction, float) / np.linalg.norm(g.direction)
        h = (g.points - fit.point) @ fit.direction
        c = fit.point + 0.5 * (h.min() + h.max()) * fit.direction
        G, r = _axis_rows(fit.direction, c, d0, np.asarray(g.point, float), tangent_basis(d0))
    return fit, G, r


def frame_motions(names, ctx) -> np.ndarray:
    """(m, 6) motions ``(omega, t)`` of the DRF ``names`` fitted on simulated noisy nominal
    datum features (step 1 of the module docstring); cached in ``ctx.cache``.

    One pass of the DRF's fit (:func:`.drf.one_pass`), linearised at the nominal datums: each
    datum fitted in the degrees of freedom the datums before it leave free at their nominal
    geometry, its rows ``G`` those of its nominal (noise-free) fit, its right side ``r`` the
    noisy fit's -- the converged fit's structure (a primary plane's noisy normal, 1e-4 off,
    would let a secondary hole's axis turn, fitted as a cylinder where the converged fit takes
    a circle, and its turn rows would fix the rotation about the primary's normal that the
    tertiary fixes).  A datum's fit in replicate r
    depends only on its simulated points and the datums before it: it is made once per
    (datums up to it, r) and shared by every DRF that starts with them."""
    key = ("drf_noise", tuple(names))
    if key in ctx.cache:
        return ctx.cache[key]
    from .drf import one_pass
    from .gdt import datum_features

    feats = datum_features(names, ctx)
    feet = [_feet(f, ctx) for f in feats]
    sigma = float(ctx.S.noise)
    L = float(ctx.prep.model.size) or 1.0
    Sc = np.diag([1 / L] * 3 + [1.0] * 3)

    def nominal(i, f, SN):
        k = ("drf_noise_free", tuple(names[:i + 1]))
        if k not in ctx.cache:
            fit, G, r = _fit_at(_simulated(f, feet[i], 0.0, 0), SN)
            ctx.cache[k] = (SN, G)
        return None, ctx.cache[k][1], np.zeros(len(ctx.cache[k][1]))

    try:
        one_pass(feats, Sc, L, nominal)
    except ValueError:
        ctx.cache[key] = np.zeros((0, 6))
        return ctx.cache[key]
    out = []
    for r in range(REPLICATES):

        def fit_one(i, f, SN, r=r):
            k = ("drf_noise_fit", tuple(names[:i + 1]), r)
            if k not in ctx.cache:
                free, G = ctx.cache[("drf_noise_free", tuple(names[:i + 1]))]
                fit, _, rhs = _fit_at(_simulated(f, feet[i], sigma, r), free)
                ctx.cache[k] = (fit, G, rhs)
            return ctx.cache[k]

        try:
            xi = one_pass(feats, Sc, L, fit_one)[0]
        except ValueError:
            continue
        out.append(Sc @ xi)
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
