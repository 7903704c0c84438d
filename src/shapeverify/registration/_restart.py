"""Restarts about the model's near-symmetry axis for a pose flagged as a wrong minimum, and a
check of the global search's pose by spins about that axis.

Why: a part that is nearly a solid of revolution (an impeller, a fan, a gear, a wheel) fixes the
spin about its axis, and often the slide across it, with a small share of its points (an
impeller seen from above: 95 % of the scan on the hub -- a flat top and small chamfers -- which
leaves x, y and the spin free or nearly so, 5 % on the blade sides at the rim). From a start
whose slide is about half the feature pitch at the rim (12 mm on the bundled impeller, blade
pitch 24 mm at r = 42 mm), the closest points of those few points lie on the neighbouring
feature: every local method -- any loss, subset, scale or step tried -- converges into a wrong
minimum 16-18 deg / 14 mm off (robust scale 8 x the noise). The minimum is detected (the
rejected points hold more information than the kept ones, the robust scale is high, or the final
stage does not settle) but no local rule can leave it. The global search does not help either:
the principal axes of such a part leave the spin arbitrary, and its screening at two voxels (6
mm) cannot tell one spin from another (every spin fits the hub).

What: the model's own near-symmetry is found from the model (its principal moments: two within
:data:`SYMMETRY_RTOL` give an axis through the centroid). From the start and from the flagged
end, the pose is first shifted along the axis to where a subset of the scan fits best (the
spin-invariant bulk -- the hub -- fixes the height whatever the spin; outliers fit nowhere, so
they do not move it), the scan's centroid (of the points within :data:`CLEAN` fit distances of
the model there) is put on the axis -- a full view of a near-axisymmetric part has its centroid
on the axis -- the height searched again, and the pose is spun about the axis in
:data:`SPIN_STEPS` steps over the full turn (10 deg apart; on the impeller's scans most of the
36 (20-36) end on one of its 11 blade copies). Each hypothesis is refined by the global search's
short Huber ICP on a subset and scored by its fit at the sharp fit distance (three times the
smallest robust scale among them, :func:`.global_search._sharp_fits`). Near-symmetric copies fit
alike (the impeller: 11 blade copies within 1 %), so among the hypotheses within :data:`TIE` of
the best fit the one nearest the start is chosen (the start is the only information that tells
the copies apart), and of the hypotheses within :data:`COPY_DEG` of it (the same copy, e.g. a
thin-wall lock 1.31 deg off it) the best fit is returned. The caller refines it with the final
stage and keeps it only if it fits better than the flagged end, at the sharper of the two robust
scales (so nothing changes where there is no better minimum).

The flagged end is also spun where it is (no height search, no centring, which a partial
view's off-axis centroid would spoil).  Those spins alone (``in_place``) also check every
unflagged end of the global search on such a part: its hypotheses hold few spins, and a wrong one can fit the search's
subset well enough to pass every check (an impeller rendered from an oblique camera by Open3D:
31 deg off at 16 x the noise, converged, no warning; ``benchmarks/check_independent_scans.py``).
About 0.5 s of CPU.

Not used when the model has three distinct principal moments (no axis to spin about), or when
the data leave a direction undetermined (an exactly symmetric part, whose spin is free).

References
----------
Gelfand, Ikemoto, Rusinkiewicz, Levoy, "Geometrically stable sampling for the ICP
algorithm", 3DIM 2003 (pose directions resting on few points); Mitra, Guibas, Pauly,
"Partial and approximate symmetry detection for 3D geometry", SIGGRAPH 2006 (approximate
symmetries as a prior of registration).
"""
from __future__ import annotations

import logging
import weakref
from types import SimpleNamespace

import numpy as np

from . import _irls
from .rigid import make_transform, rodrigues, rotation_vector

logger = logging.getLogger(__name__)

#: two principal moments of the model within this relative difference: a near-symmetry axis
SYMMETRY_RTOL = 0.05
#: spin hypotheses over the full turn about that axis (10 deg apart)
SPIN_STEPS = 36
#: Huber ICP steps per hypothesis (the global search's refinement)
REFINE_STEPS = 12
#: scan points used by the refinement and the scoring
POINTS = 400
#: points farther than this many fit distances from the model (at the base pose) are left out
#: of the centroid (outliers, clutter)
CLEAN = 5.0
#: hypotheses closer than this (deg) to the chosen copy are the same copy: the best fit of
#: them is returned
COPY_DEG = 5.0
#: the height along the axis is searched this share of the model's size either way
AXIAL_REACH = 0.1
#: hypotheses whose fit is at least this share of the best are copies: the nearest the start wins
TIE = 0.97


def symmetry_axis(side):
    """(axis (3,), centre (3,)) of the model's near-symmetry, or None.

    ``side.axes_points`` (m, 3): model points (the global search's regular subset of about
    5,000).  Two principal moments within :data:`SYMMETRY_RTOL` (relative to the larger) make
    the third eigenvector an axis of near-rotational symmetry through the centroid.
    """
    M = np.asarray(side.axes_points, np.float64)
    c = M.mean(axis=0)
    lam, V = np.linalg.eigh(np.cov((M - c).T))
    if lam[2] > 0:
        if lam[2] - lam[1] <= SYMMETRY_RTOL * lam[2]:
            return V[:, 0].copy(), c
        if lam[1] - lam[0] <= SYMMETRY_RTOL * lam[1]:
            return V[:, 2].copy(), c
    return None


_AXES: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _model_axis(prep):
    """:func:`symmetry_axis` of the prepared model (the same regular subset of its points as
    the global search's), cached per Prepared object; None without model points."""
    try:
        return _AXES[prep]
    except (KeyError, TypeError):
        pass
    mp = _irls.model_points(prep)
    out = None
    if mp is not None and mp[0].shape[0] >= 10:
        M = mp[0]
        out = symmetry_axis(SimpleNamespace(axes_points=M[::max(1, M.shape[0] // 5000)]))
    try:
        _AXES[prep] = out
    except TypeError:   # not weak-referenceable
        pass
    return out


def _spin(axis, centre, phi) -> np.ndarray:
    """The model-frame rotation by phi (rad) about the axis through centre (4, 4)."""
    R = rodrigues(axis * phi)
    return make_transform(R, centre - R @ centre)


def _distance(T1, T2, c, radius) -> float:
    """How far apart two poses move the scan: rotation angle x radius + shift of its centroid."""
    ang = float(np.linalg.norm(rotation_vector(T1[:3, :3] @ T2[:3, :3].T)))
    shift = (T1[:3, :3] - T2[:3, :3]) @ c + T1[:3, 3] - T2[:3, 3]
    return ang * radius + float(np.linalg.norm(shift))


def _axial(S, prep, T, axis, tau, reach) -> np.ndarray:
    """T shifted along the axis to where the points S fit best (truncated fit at ``tau``,
    steps of tau / 2 within +-reach): the spin-invariant bulk of a near-axisymmetric part
    (a hub) fixes its height whatever the spin."""
    from .global_search import fit_score

    steps = np.arange(-int(np.ceil(reach / (0.5 * tau))), int(np.ceil(reach / (0.5 * tau))) + 1)
    best, best_T = -1.0, T
    for k in steps[np.argsort(np.abs(steps), kind="stable")]:
        Tk = T.copy()
        Tk[:3, 3] += 0.5 * tau * k * axis
        f = fit_score(prep, S, Tk, tau)
        if f > best:
            best, best_T = f, Tk
    return best_T


def restart(P, prep, T_start, T_end, radius: float, rng, in_place: bool = False):
    """A start (4, 4) in the basin the flagged end ``T_end`` missed, or None (module docstring).

    Parameters
    ----------
    P : (n, 3) scan points (mm); prep : the Prepared model;
    T_start, T_end : (4, 4) the registration's start and its flagged end;
    radius : RMS radius of the scan (mm); rng : Generator (the scored subset);
    in_place : spin only ``T_end`` where it is (no height search, no centring on the axis):
        the check of an unflagged end of the global search (a sixth of the cost).
    """
    from .global_search import _model_side, _sharp_fits, refine

    sym = _model_axis(prep)
    if sym is None:       # decided before the global search's model side is built (costly)
        return None
    axis, centre = sym
    side = _model_side(prep)
    probe = P if P.shape[0] <= POINTS else P[np.sort(rng.choice(P.shape[0], POINTS,
                                                                 replace=False))]
    reach = AXIAL_REACH * side.size
    bases, kept = [], np.zeros(P.shape[0], bool)
    for T in (() if in_place else (T_start, T_end)):
        B = _axial(probe, prep, T, axis, side.tau, reach)
        m = _irls.match(P, prep, B[:3, :3], B[:3, 3])
        near = m.valid & (np.abs(m.d) <= CLEAN * side.tau)
        if np.count_nonzero(near) < 6:
            continue
        kept |= near
        x = B[:3, :3] @ P[near].mean(axis=0) + B[:3, 3]
        off = (x - centre) - ((x - centre) @ axis) * axis     # onto the axis, same height
        B = B.copy()
        B[:3, 3] -= off
        bases.append(_axial(probe, prep, B, axis, side.tau, reach))
    # the end itself, spun where it is: a partial view's centroid is off the axis
    m = _irls.match(P, prep, T_end[:3, :3], T_end[:3, 3])
    near = m.valid & (np.abs(m.d) <= CLEAN * side.tau)
    if np.count_nonzero(near) >= 6:
        kept |= near
        bases.append(T_end)
    idx = np.flatnonzero(kept)
    if not bases or idx.shape[0] < 6:
        return None
    S = P[np.sort(rng.choice(idx, POINTS, replace=False))] if idx.shape[0] > POINTS else P[idx]
    hyps = [refine(S, side, _spin(axis, centre, 2.0 * np.pi * j / SPIN_STEPS) @ B, radius,
                   REFINE_STEPS)
            for B in bases for j in range(SPIN_STEPS)]
    fits, tau = _sharp_fits(side, S, hyps)
    best = max(fits)
    if not best > 0:
        return None
    c = P.mean(axis=0)
    ties = [i for i, f in enumerate(fits) if f >= TIE * best]
    near = min(ties, key=lambda i: (_distance(hyps[i], T_start, c, radius), i))
    # within that copy (poses less than COPY_DEG apart: e.g. a thin-wall lock 1.31 deg off),
    # the best fit
    same = [i for i in range(len(hyps))
            if np.degrees(np.linalg.norm(rotation_vector(hyps[i][:3, :3] @ hyps[near][:3, :3].T)))
            < COPY_DEG and _distance(hyps[i], hyps[near], c, radius) < COPY_DEG / 57.3 * radius
            + CLEAN * side.tau]
    pick = max(same, key=lambda i: (fits[i], -i))
    logger.info("restart: %d spin hypotheses about the model's near-symmetry axis, best fit "
                "%.3f at %.3g mm, %d within %.0f %% of it; the one nearest the start taken "
                "(fit %.3f)", len(hyps), best, tau, len(ties), 100 * TIE, fits[pick])
    return hyps[pick]
