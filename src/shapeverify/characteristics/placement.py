"""Where a fixture-like alignment (datums, RPS) starts: the placements of the scan on the part.

A datum or RPS alignment measures a few features and fits the pose to them, so it needs to know
which scan points belong to which feature: a start pose.  A start that is a wrong copy of the
part (a plate upside down: its top datum plane then fits the bottom face, the datum holes the
holes below them, "converged, rms 0.05") gives a wrong frame that looks right.  So the start is
the same global search a free inspection makes (:func:`shapeverify.registration.global_search.
global_alignment`: principal axes, FPFH + RANSAC, ...), with every pose of it that fits the scan
nearly as well as its best (a symmetric part's copies), and the caller's start when given.
Each is fitted the alignment's way and judged by the *whole fit* of the scan at the result
(:func:`whole_fit`: the share of a fixed subset of scan points within three noise sigmas of the
CAD, the global search's sharp truncated objective); the alignment then picks among the
placements that fit alike by its own feature fit, and warns when those fit alike too.
"""
from __future__ import annotations

import numpy as np

__all__ = ["placements", "whole_fit", "scan_noise_of", "ALIKE", "N_PLACEMENTS"]

#: two placements fit alike when the poorer whole fit is at least this share of the better
#: (the registration's runner-up rule, registration._pose_warnings.WARN_RUNNER_UP)
ALIKE = 0.97
#: the global search's poses tried at most (best first)
N_PLACEMENTS = 4
#: global poses whose fit is below this share of the best are not tried
TRY_SHARE = 0.6
#: scan points (an even subset) of the whole fit
FIT_POINTS = 3000


def scan_noise_of(P) -> float:
    """The scan's noise sigma (mm) about local quadrics (:mod:`shapeverify.registration._noise`)
    from an even subset of at most 50,000 points."""
    from ..registration._noise import scan_noise

    return float(scan_noise(P[::max(1, P.shape[0] // 50_000)]))


def _distinct(T1, T2, size) -> bool:
    D = T2 @ np.linalg.inv(T1)
    ang = np.degrees(np.arccos(np.clip((np.trace(D[:3, :3]) - 1) / 2, -1, 1)))
    return ang > 1.0 or np.linalg.norm(D[:3, 3]) > 0.01 * size


def placements(P, prep, init=None, rng=0, turns: bool = False) -> list:
    """``[(name, T_model_scan), ...]``: the caller's start (if any), the global search's best
    pose and its other poses within :data:`TRY_SHARE` of its fit (at most
    :data:`N_PLACEMENTS`), distinct (1 degree or 1 % of the model size apart); with ``turns``
    also the global pose turned half a turn about each of the model's principal axes."""
    from ..registration.global_search import global_alignment

    size = float(prep.model.size)
    out = [] if init is None else [("start", np.asarray(init, np.float64))]
    ga = global_alignment(P, prep, rng=rng)
    cands = [("global", ga.T_model_scan)] + [
        (f"global copy {i + 1}", T) for i, (f, T) in enumerate(ga.others)
        if f >= TRY_SHARE * ga.fit][:N_PLACEMENTS - 1]
    for name, T in cands:
        if all(_distinct(T, T2, size) for _, T2 in out):
            out.append((name, np.asarray(T, np.float64)))
    # the global pose turned 180 degrees about the model's principal axes: a near-symmetric
    # part's copies, which the search may not return (the chamfered plate: in 5 of 40 random
    # poses it gave only the copy turned about the plate's normal)
    for i, Tt in enumerate(_turns(prep, ga.T_model_scan) if turns else ()):
        if all(_distinct(Tt, T2, size) for _, T2 in out):
            out.append((f"global turned {i + 1}", Tt))
    return out


def _turns(prep, T) -> list:
    """``T`` followed by a half turn about each of the model's coordinate axes through the
    centre of its bounds (a CAD part's symmetry usually lies along them: exact for the
    chamfered plate) and about each principal axis of its points through their centroid."""
    from ..registration import _irls

    axes = []
    b = getattr(prep.model, "bounds", None)
    if b is not None:
        c = 0.5 * (np.asarray(b[0], np.float64) + np.asarray(b[1], np.float64))
        axes += [(c, a) for a in np.eye(3)]
    mp = _irls.model_points(prep)
    if mp is not None:
        M = np.asarray(mp[0], np.float64)
        c = M.mean(axis=0)
        _, V = np.linalg.eigh(np.cov((M - c).T))
        axes += [(c, V[:, k]) for k in range(3)]
    out = []
    for c, a in axes:
        R = 2.0 * np.outer(a, a) - np.eye(3)          # half turn about a
        H = np.eye(4)
        H[:3, :3], H[:3, 3] = R, c - R @ c
        out.append(H @ np.asarray(T, np.float64))
    return out


def whole_fit(P, prep, T, noise, rng=0, n: int = FIT_POINTS) -> float:
    """Share (truncated: ``mean max(0, 1 - (d / tau)^2)``) of an even subset of the scan's points
    within ``tau = max(3 noise, 1e-4 x size)`` of the CAD at the pose T (points past the model's
    free boundary count 0); ``n`` points at most (default :data:`FIT_POINTS`)."""
    from ..registration.global_search import fit_score

    S = P[np.linspace(0, P.shape[0] - 1, min(P.shape[0], int(n))).astype(np.int64)]
    tau = max(3.0 * float(noise) if np.isfinite(noise) else 0.0, 1e-4 * float(prep.model.size))
    return fit_score(prep, S, T, tau)
