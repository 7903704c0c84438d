"""Points folded over a convex edge: measured where they were sampled, not at their feet.

A dent on a sharp convex edge pushes each face's points in along that face's normal; a point of
face A pushed in by ``h`` at ``u < h`` from the edge lies nearer face B, reads ``-u`` against it,
and its foot jumps onto a curve of B.  The points of a band ``h`` wide along the edge thus
gather their feet on one curve: their cells among the feet (:func:`.region_measures.out_area`)
and their kernel density (:func:`.regions.area_per_point`) stand for almost no area, and the
cells of B's own points beside that curve shrink; the dent's area read 40-56 % low on the wavy
cube (at 1/5 of its radius too little core support: no region at all).

Such a point is moved back to where it was sampled: its scan position ``foot + d n`` projected
onto the tangent plane of the other face (at the foot of the nearest evaluated point, of its
``FOLD_K`` nearest within ``FOLD_REACH`` spacings in space, whose CAD normal is more than
``FOLD_ANGLE`` degrees from its own), with that plane's normal and its distance to it as its
deviation there (so ``foot + d n`` is still the scan position).  It is folded when its scan
position lies on the same side of both faces, no deeper under the other face's plane than
``FOLD_DEPTH`` times the largest deviation among those nearest points (the dent's deepest
points read ``min(h, u)``, 0.038 mm for a push of 0.05 on the wavy cube), and its foot lies in
a crowd that the place it moves to does not: more than ``FOLD_CROWD`` times as many feet (plus
``FOLD_EXCESS``) within ``CROWD_RADIUS`` spacings of its foot as of that place.  A point
beside an undented edge lies in no crowd; the wall of an object lying on the part crowds its
feet on the rim's line, but no CAD surface near it faces another way (a wall stands for no
area of the part: its foot line is the boundary); a point far from an edge has no other face
near.  Nothing changes for them.

At a coarser spacing (1/5 of the dent's radius) the band is a row or two and hardly crowds:
nothing moves.  There :func:`behind_other_face` marks the points that *may* be folded: in
tolerance against their own face, their scan position beyond the limit under the other face's
plane, where that face's own points read beyond half the limit.  They are no evidence of
in-tolerance surface on that side: they have no vote in the neighbourhood medians
(:func:`.regions.find_regions`) and are not the surface seen under a layer
(:func:`.region_measures.facing`, :func:`.region_measures.seen_under`).

Not exact: a point of face A a few spacings from the edge whose foot lies in the crowd that B's
folded band makes on A, and whose place on B lies in the gap that A's band left there, is moved
across too (a quarter of the moved points in the quarter space of
``tests/test_region_dent_on_a_convex_edge.py``: 24-49 of 136-159); it takes a place of the
band's, and the area comes out within 2-14 % of the truth there at 1/15 of the dent's radius.
"""
from __future__ import annotations

import numpy as np
from shapeverify._lazy import cKDTree

from ..measures._grid_kernels import any_within, count_within, kernel_array
from ..measures.spacing import nanmedian_rows, neighbour_noise

__all__ = ["unfolded", "behind_other_face", "may_be_folded", "FOLD_REACH", "FOLD_ANGLE",
           "FOLD_CROWD", "FOLD_EXCESS", "CROWD_RADIUS", "FOLD_DEPTH", "OTHER_K", "OTHER_SHARE",
           "OTHER_Z"]

#: The other face: an evaluated point within this many spacings (in space) of the scan position ...
FOLD_REACH = 5.0
#: ... whose CAD normal is more than this many degrees from the point's own.
FOLD_ANGLE = 45.0
#: ... and its scan position no farther under that plane than this many times the largest
#: deviation among those nearest points.
FOLD_DEPTH = 1.6
#: Feet within this radius (spacings) of a place count its crowd (about pi of a sampling) ...
CROWD_RADIUS = 1.5
#: ... a folded point's foot has more than ``FOLD_CROWD`` x the crowd of the place it moves
#: to, plus ``FOLD_EXCESS``.
FOLD_CROWD = 2.0
FOLD_EXCESS = 2.0
#: Nearest points searched for the other face's; points handled at once.
FOLD_K = 128
CHUNK = 5000
#: The other face's deviation near a point: the median of this many of its nearest points
#: (fewer: no sheet of it there), beyond this share of the limit (not deep in tolerance: half,
#: as everywhere here).
OTHER_K = 9
OTHER_SHARE = 0.5
#: ... by this many of that median's standard errors (the noise of the deviations around): on a
#: good part scanned with noise 0.75 x the tolerance a median of 9 points near an edge lay
#: beyond half the limit by chance (a false 3-point region on the wavy cube).  (3 missed a
#: folded row of the quarter space at 1/5 of the dent's radius: its other face read -0.0123
#: against a bound of 0.0129; the fold's own points, in tolerance, dilute that median.)
OTHER_Z = 2.0
#: Feet looked up around a point for the other face (``may_be_folded``), in spacings: its scan
#: position's reach in space plus as much again for the deviations.
FOLD_AROUND = 2.0 * FOLD_REACH


def _other_planes(points, values, normals, ev_idx, idx, spacing):
    """``(P, N, T, vmax, vother)`` for each point of ``idx`` (scan indices of evaluated points, all
    in ``ev_idx``): the other face's tangent plane near its scan position ``foot + d n`` (the
    foot ``P`` of the nearest of its ``FOLD_K`` nearest evaluated points within
    ``FOLD_REACH`` spacings in space whose normal is more than ``FOLD_ANGLE`` degrees from
    its own; ``N`` that normal; ``T`` the scan position's signed distance to that plane) and
    ``vmax``, the largest ``|d|`` among those nearest points; ``vother``, the median deviation
    of the ``OTHER_K`` nearest of them on the other face; NaN rows where no other face is
    near.  None when no two normals around are ``FOLD_ANGLE`` apart (no edge)."""
    S = points[ev_idx] + values[ev_idx, None] * normals[ev_idx]
    Ne = normals[ev_idx] / np.maximum(np.linalg.norm(normals[ev_idx], axis=1), 1e-300)[:, None]
    mean = Ne.sum(axis=0)
    mean /= max(float(np.linalg.norm(mean)), 1e-300)
    if np.all(Ne @ mean > np.cos(np.radians(FOLD_ANGLE / 2))):
        return None     # no two normals FOLD_ANGLE apart: no edge
    o = np.argsort(ev_idx, kind="stable")
    at = np.minimum(np.searchsorted(ev_idx, idx, sorter=o), ev_idx.size - 1)
    k_idx = np.where(ev_idx[o[at]] == idx, o[at], -1)
    cos_a = np.cos(np.radians(FOLD_ANGLE))
    P = np.full((idx.size, 3), np.nan)
    N = np.full((idx.size, 3), np.nan)
    T = np.full(idx.size, np.nan)
    V = np.full(idx.size, np.nan)
    VO = np.full(idx.size, np.nan)
    s_tree = cKDTree(S)
    k = min(FOLD_K, ev_idx.size)
    for lo in range(0, idx.size, CHUNK):
        a = np.arange(lo, min(lo + CHUNK, idx.size))
        a = a[k_idx[a] >= 0]
        if a.size == 0:
            continue
        ka = k_idx[a]
        d, j = s_tree.query(S[ka], k=k, distance_upper_bound=FOLD_REACH * spacing)
        d, j = d.reshape(a.size, k), np.minimum(j.reshape(a.size, k), ev_idx.size - 1)
        other = np.isfinite(d) & (np.abs(np.einsum("ikc,ic->ik", Ne[j], Ne[ka])) < cos_a)
        has = other.any(axis=1)
        jj = j[np.arange(a.size), np.argmax(other, axis=1)]     # the nearest (k-NN: sorted)
        t = np.einsum("ic,ic->i", S[ka] - points[ev_idx[jj]], Ne[jj])
        vmax = np.max(np.where(np.isfinite(d), np.abs(values[ev_idx[j]]), 0.0), axis=1)
        # the other face's own deviation there: the median of its OTHER_K nearest points
        # (a sheet of them, not a few strays: an outlier of the other face pushed in lies alone)
        first = other & (np.cumsum(other, axis=1) <= OTHER_K)
        vo = nanmedian_rows(np.where(first, values[ev_idx[j]], np.nan))
        vo[first.sum(axis=1) < OTHER_K] = np.nan
        a, ka, jj, t, vmax, vo = a[has], ka[has], jj[has], t[has], vmax[has], vo[has]
        P[a], N[a], T[a], V[a], VO[a] = S[ka] - t[:, None] * Ne[jj], Ne[jj], t, vmax, vo
    return P, N, T, V, VO


def unfolded(points, values, normals, ev_idx, idx, spacing):
    """``(points, normals, values, fold)``: copies of the foot points, CAD normals and
    deviations (scan-indexed) with each folded point of ``idx`` (scan indices of evaluated
    points; ``fold``: (len(idx),) bool) moved to where it was sampled (module docstring):
    its scan position projected onto the other face's tangent plane, that plane's normal,
    and its scan position's signed distance to that plane; the inputs themselves where no
    point is folded.  ``ev_idx``: the evaluated points around ``idx`` (scan indices)."""
    fold = np.zeros(idx.size, bool)
    if idx.size == 0 or ev_idx.size < 2:
        return points, normals, values, fold
    planes = _other_planes(points, values, normals, ev_idx, idx, spacing)
    if planes is None:
        return points, normals, values, fold
    P, N, T, vmax, _ = planes
    # on the same side of both faces, and no deeper under the other face than the points
    # around lie under theirs (a point of this face far from the edge is deep under the
    # other face's plane: no dent pushed it there)
    with np.errstate(invalid="ignore"):
        cand = np.flatnonzero((T * values[idx] > 0) & (np.abs(T) <= FOLD_DEPTH * vmax))
    if cand.size == 0:
        return points, normals, values, fold
    r = CROWD_RADIUS * spacing
    tree = cKDTree(points[ev_idx])
    here = tree.query_ball_point(points[idx[cand]], r, return_length=True) - 1.0
    there = tree.query_ball_point(P[cand], r, return_length=True)
    fold[cand[here > FOLD_CROWD * there + FOLD_EXCESS]] = True
    if not fold.any():
        return points, normals, values, fold
    i = idx[fold]
    points, normals, values = points.copy(), normals.copy(), values.copy()
    points[i], normals[i], values[i] = P[fold], N[fold], T[fold]
    return points, normals, values, fold


def behind_other_face(points, values, normals, ev_idx, idx, lims, spacing) -> np.ndarray:
    """(len(lims), len(idx)) bool: whether each point of ``idx`` (scan indices of evaluated
    points, all in ``ev_idx``, the evaluated points around) may be a point of another face
    pushed beyond a limit: its scan position lies under (or over, as the limit has it; ``lims``
    a sequence of (N,) limits, one side each) another face's tangent plane (``_other_planes``)
    by more than the limit and by no more than ``FOLD_DEPTH`` times the largest deviation
    around, and that face's own ``OTHER_K`` points nearest to it (in space) read beyond
    ``OTHER_SHARE`` of the limit by ``OTHER_Z`` standard errors of their median (that face
    is dented there, not deep in tolerance; beside a good part's edge, a blade's fillet or a
    stray outlier it is not: the good impeller's outliers, up to 1 mm, made every point within
    1.6 mm of an edge one).

    Such a point reads in tolerance against its own face only because that face is nearer:
    on a dented convex edge the other face's points sampled within the limit of the edge,
    pushed in by the dent, have their feet among the dented points of this face, in tolerance
    (the wavy cube at 1/5 of the dent's radius: one row of them, 3-6 points, read as the
    surface seen under a layer: :func:`.region_measures.seen_among`).  The crowd their feet
    make (``unfolded``) is too thin to tell at that spacing; the point is no evidence of
    in-tolerance surface on that side.  Of a face's own points under a layer, only those
    within ``FOLD_DEPTH`` x the layer's height of an edge can meet this."""
    idx = np.asarray(idx, np.int64)
    out = np.zeros((len(lims), idx.size), bool)
    if idx.size == 0 or ev_idx.size < 2:
        return out
    # first what is needed for that median: more than half of OTHER_K points beyond
    # OTHER_SHARE of the limit within FOLD_REACH of the scan position (any face; a grid count)
    need = OTHER_K // 2 + 1
    S_ev = kernel_array(points[ev_idx] + values[ev_idx, None] * normals[ev_idx])
    S_idx = kernel_array(points[idx] + values[idx, None] * normals[idx])
    v_ev = values[ev_idx]
    maybe = np.zeros((len(lims), idx.size), bool)
    for k, lim in enumerate(lims):
        with np.errstate(invalid="ignore"):
            half = (v_ev * lim[ev_idx] > 0) & (np.abs(v_ev) > OTHER_SHARE * np.abs(lim[ev_idx]))
        if np.count_nonzero(half) >= need:
            n = np.empty(idx.size, np.int64)
            count_within(kernel_array(S_ev[half]), S_idx, FOLD_REACH * spacing * (1.0 + 1e-9),
                         need, n)
            maybe[k] = n >= need
    sel = np.flatnonzero(maybe.any(axis=0))
    if sel.size == 0:
        return out
    planes = _other_planes(points, values, normals, ev_idx, idx[sel], spacing)
    if planes is None:
        return out
    _, _, T, vmax, vo = planes
    # the noise of the deviations around (nearest-neighbour differences: the form cancels)
    sigma = neighbour_noise(points[ev_idx], v_ev)
    # the standard error of a median of OTHER_K values: 1.2533 sigma / sqrt(OTHER_K)
    margin = OTHER_Z * 1.2533 * sigma / np.sqrt(OTHER_K)
    with np.errstate(invalid="ignore"):
        for k, lim in enumerate(lims):
            li = lim[idx[sel]]
            out[k, sel] = (maybe[k, sel] & (T * li > 0) & (np.abs(T) > np.abs(li))
                           & (np.abs(T) <= FOLD_DEPTH * vmax) & (vo * li > 0)
                           & (np.abs(vo) > OTHER_SHARE * np.abs(li) + margin))
    return out


def may_be_folded(tree, ev_idx, values, normals, points, idx, lims, spacing) -> np.ndarray:
    """:func:`behind_other_face` of the points ``idx`` with the evaluated points around them
    (feet within ``FOLD_AROUND`` spacings) looked up in ``tree`` (of ``points[ev_idx]``)."""
    idx = np.asarray(idx, np.int64)
    if idx.size == 0:
        return np.zeros((len(lims), 0), bool)
    near = np.empty(tree.data.shape[0], bool)
    any_within(kernel_array(points[idx]), kernel_array(tree.data),
               FOLD_AROUND * spacing * (1.0 + 1e-9), near)
    return behind_other_face(points, values, normals, ev_idx[near], idx, lims, spacing)
