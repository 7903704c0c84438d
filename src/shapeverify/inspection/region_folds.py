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

Not exact: a point of face A a few spacings from the edge whose foot lies in the crowd that B's
folded band makes on A, and whose place on B lies in the gap that A's band left there, is moved
across too (a quarter of the moved points in the quarter space of
``tests/test_region_dent_on_a_convex_edge.py``: 24-49 of 136-159); it takes a place of the
band's, and the area comes out within 2-14 % of the truth there at 1/15 of the dent's radius.
"""
from __future__ import annotations

import numpy as np
from shapeverify._lazy import cKDTree

__all__ = ["unfolded", "FOLD_REACH", "FOLD_ANGLE", "FOLD_CROWD", "FOLD_EXCESS", "CROWD_RADIUS",
           "FOLD_DEPTH"]

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
    S = points[ev_idx] + values[ev_idx, None] * normals[ev_idx]
    Ne = normals[ev_idx] / np.maximum(np.linalg.norm(normals[ev_idx], axis=1), 1e-300)[:, None]
    o = np.argsort(ev_idx, kind="stable")
    at = np.minimum(np.searchsorted(ev_idx, idx, sorter=o), ev_idx.size - 1)
    k_idx = np.where(ev_idx[o[at]] == idx, o[at], -1)
    cos_a = np.cos(np.radians(FOLD_ANGLE))
    mean = Ne.sum(axis=0)
    mean /= max(float(np.linalg.norm(mean)), 1e-300)
    if np.all(Ne @ mean > np.cos(np.radians(FOLD_ANGLE / 2))):
        return points, normals, values, fold     # no two normals FOLD_ANGLE apart: no edge
    # the other face's tangent plane for each point of idx with one near
    P = np.full((idx.size, 3), np.nan)
    N = np.full((idx.size, 3), np.nan)
    T = np.full(idx.size, np.nan)
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
        # on the same side of both faces, and no deeper under the other face than the points
        # around lie under theirs (a point of this face far from the edge is deep under the
        # other face's plane: no dent pushed it there)
        vmax = np.max(np.where(np.isfinite(d), np.abs(values[ev_idx[j]]), 0.0), axis=1)
        ok = has & (t * values[idx[a]] > 0) & (np.abs(t) <= FOLD_DEPTH * vmax)
        a, ka, jj, t = a[ok], ka[ok], jj[ok], t[ok]
        P[a], N[a], T[a] = S[ka] - t[:, None] * Ne[jj], Ne[jj], t
    cand = np.flatnonzero(np.isfinite(T))
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
