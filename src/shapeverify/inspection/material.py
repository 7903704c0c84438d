"""Unexplained material: measured surface where the CAD model has none.

A scan point farther than the evaluation distance from every CAD face is usually background, a
fixture or a gross outlier, and is not evaluated.  But when many such points form a **dense
surface attached to the measured part**, the part has material the model does not: a hole that
was never pierced, an extra flange, an edge left untrimmed.  Such a cluster is a region of
``kind="material"`` and fails the part.

The rule (all distances in mm, ``s`` = the scan's spacing on the part as area per point,
:func:`.regions.surface_spacing`):

1. candidates: points *too far* (farther than the evaluation distance from the CAD) that lie
   **beside** the CAD rather than above it: their offset from the closest CAD point runs along
   the surface (within ``MAX_NORMAL_SHARE`` of it along the normal, i.e. their closest CAD point
   is on an edge: past a hole's rim, past the outline), and points past a free edge within the
   evaluation distance (``on_boundary``), which bridge a hole's rim.  Points far *above* a face
   (offset along its normal) are not material the CAD lacks but a surface floating over the
   part -- a reflection, a foreign object, or a bump beyond the evaluation distance; one that
   rises from a region's out-of-tolerance flank joins that region (:mod:`.beyond`), the other
   dense such clusters are reported by :func:`floating_surfaces` as notes, and their points stay
   excluded;
2. candidates closer than ``LINK_FACTOR x s`` (in space) are linked; a connected component is a
   material region when it holds at least ``MIN_MATERIAL_POINTS`` too-far points, is **dense**
   (at least 80 % of its points have 2 linked neighbours, and its median area per point, from a
   smooth kernel within ``DENSE_RADIUS x s``, is at most ``SPARSE_AREA x s^2``: a surface sampled
   like the part, not scattered outliers), and
   **joins the part without a step**, attached along a rim (at least 3 and a tenth of its points
   within ``ATTACH_RADIUS x s`` of an evaluated scan point that is not a measurement outlier:
   a sheet beside an edge touching the part at a point or two is a reflection, and so is a
   sheet whose only neighbours are its own out-of-tolerance points that reach within the
   evaluation distance of a face: measurement outliers join nothing, except those above the
   part that rise from its in-tolerance surface (from the nearest in-tolerance point, at most
   ``MAX_RISE_SLOPE`` times as far along the normal as across) -- a ramp, not a reflection's
   points standing over the measured surface with a step); and it is no piece of a sheet
   floating over measured surface (linked in space through measurement outliers and too-far
   points over a face that have the face's in-tolerance surface under them: a reflection that
   reaches past an edge at one end, :func:`_piece_of_floating_sheet`); its points within ``LINK_FACTOR x s`` of an
   evaluated scan point continue that point's surface (median slope ``|offset along the CAD normal| / |offset
   along the surface|`` at most ``MAX_JOIN_SLOPE``, about 30 degrees).  Material that was never
   removed continues the part; a surface floating over it with a step at its rim -- a
   reflection, a foreign object, background -- is not material of the part (its points stay
   "too far" and are counted as excluded);
3. its ``extreme`` is the largest distance of its points from the CAD; ``centroid`` the mean of its
   too-far points (model coordinates: for a missing hole, where the hole should be); ``area`` from
   the local point density; ``severity`` the volume ``sum a_i (d_i - upper limit)``.

Points over a missing hole within the evaluation distance of the hole's rim are past a free
edge and so not evaluated either: a hole smaller than twice the evaluation distance leaves no
too-far points and cannot be found this way (lower the evaluation distance).
"""

from __future__ import annotations

import numpy as np
from shapeverify._lazy import cKDTree

from .deviations import ON_BOUNDARY, TOO_FAR
from .regions import LINK_FACTOR, SPARSE_AREA, DefectRegion, area_per_point, linked_components

__all__ = ["find_material", "floating_surfaces", "far_over_surface", "MIN_MATERIAL_POINTS"]

#: Fewest too-far points of a material region.
MIN_MATERIAL_POINTS = 10
#: Radius (in spacings) of the disc that measures a material cluster's density.
DENSE_RADIUS = 3.0
#: Largest median slope (normal / tangential offset) where material joins the part.
MAX_JOIN_SLOPE = 0.6
#: Material is attached along a rim: at least ``max(ATTACH_MIN, ATTACH_SHARE x its points)``
#: of its points lie within ``ATTACH_RADIUS`` spacings of an evaluated scan point.
ATTACH_RADIUS = 1.5
ATTACH_MIN = 3
ATTACH_SHARE = 0.1
#: Largest share of a candidate's offset from the CAD that may lie along the CAD normal.
MAX_NORMAL_SHARE = 0.5
#: A measurement outlier above the part carries material when it rises from the part's
#: in-tolerance surface: from the nearest in-tolerance scan point, its offset along the normal
#: at most this many times its offset across (about 63 degrees; a ramp up to a corner that the
#: CAD chamfers at 45 degrees reads about 1, a reflection's points over measured surface more).
MAX_RISE_SLOPE = 2.0
#: A sheet's too-far point over a face floats over measured surface when the in-tolerance foot
#: points within ``FLOAT_RADIUS`` spacings of its foot point number at least ``FLOAT_SEEN`` of a
#: full disc's at the scan's spacing (a thin wall's two sides count double; a random sample
#: reaches half with probability 0.98).
FLOAT_RADIUS = 2.0
FLOAT_SEEN = 0.5


def find_material(dev, spacing: float, upper_limit: float,
                  min_points: int = MIN_MATERIAL_POINTS, *, beside=None,
                  outliers=None) -> list[DefectRegion]:
    """Material regions of an inspection (see the module docstring).

    Parameters
    ----------
    dev : Deviations
    spacing : float
        Median scan point spacing on the part (mm).
    upper_limit : float
        The tolerance's upper limit (mm), for the severity.
    min_points : int
        Fewest too-far points of a region.
    beside : ((N,) bool, (N,) float64), optional
        :func:`beside_surface` of ``dev``, when the caller has it (it is computed otherwise).
    outliers : (k,) int, optional
        Scan indices of the evaluated points that are measurement outliers
        (:class:`.regions.Outliers` ``.indices``): material does not join the part through them,
        except through those above the part that rise from its in-tolerance surface without a
        step (:func:`_rising`: the ramp up to a corner the CAD chamfers and the part does not;
        a reflection's points lifted over measured surface do not).

    Returns
    -------
    list of DefectRegion
        ``kind="material"``, most severe first.
    """
    if not (np.isfinite(spacing) and spacing > 0):
        return []
    too_far = dev.reason == TOO_FAR
    if np.count_nonzero(too_far) < min_points or dev.n_evaluated == 0:
        return []
    beside, dist = beside_surface(dev) if beside is None else beside
    cand = np.flatnonzero((too_far & beside) | (dev.reason == ON_BOUNDARY))
    if cand.size < min_points:
        return []
    link = LINK_FACTOR * spacing
    p = dev.points_model[cand]
    tree = cKDTree(p)
    pairs = tree.query_pairs(link, output_type="ndarray")
    m = cand.size
    n_comp, labels = linked_components(m, pairs)
    degree = np.bincount(pairs.ravel(), minlength=m)
    is_far = (too_far & beside)[cand]
    n_far = np.bincount(labels, weights=is_far.astype(np.float64), minlength=n_comp)
    comps = np.flatnonzero(n_far >= min_points)
    if comps.size == 0:
        return []
    # the part's measured surface: evaluated points that are not measurement outliers (a
    # reflection's sheet reaching within the evaluation distance of a face is evaluated, out of
    # tolerance and outliers; its part beyond the evaluation distance is attached to that
    # part of itself, not to the part)
    part = dev.evaluated.copy()
    if outliers is not None:
        o = np.asarray(outliers, np.int64)
        part[o[~_rising(dev, o, upper_limit, spacing)]] = False
    ev_idx = np.flatnonzero(part)
    if ev_idx.size == 0:
        return []
    ev_tree = cKDTree(dev.points_model[ev_idx])
    r_area = 2.0 * spacing
    out = []
    sheets = None
    for c in comps:
        sel = np.flatnonzero(labels == c)
        if np.mean(degree[sel] >= 2) < 0.8:
            continue                                       # scattered: outliers, not a surface
        if np.median(area_per_point(tree, p[sel], DENSE_RADIUS * spacing)) > \
                SPARSE_AREA * spacing ** 2:
            continue                 # sparser than the scanned part: stray points, not a surface
        if not _joins_part(p[sel], ev_tree, ev_idx, dev, link, spacing):
            continue                                       # detached, or a step: not material
        if sheets is None:
            sheets = _floating_sheets(dev, cand, outliers, beside, dist, link, spacing,
                                      upper_limit)
        if _piece_of_floating_sheet(sheets, cand[sel], sel.size):
            continue           # the end of a reflection floating over measured surface
        far = sel[is_far[sel]]
        counts = tree.query_ball_point(p[far], r_area, return_length=True)
        a = np.pi * r_area ** 2 / np.maximum(counts, 1)
        idx = cand[far]
        d = dist[idx]
        k = int(np.argmax(d))
        out.append(DefectRegion(
            n=int(idx.size), area=float(a.sum()), extreme=float(d[k]), extreme_raw=float(d[k]),
            centroid=dev.points_model[idx].mean(axis=0), extreme_point=dev.points_model[idx[k]].copy(),
            faces=tuple(int(f) for f in np.unique(dev.face[idx]) if f >= 0), side="above",
            indices=idx, severity=float(np.sum(a * np.maximum(d - abs(upper_limit), 0.0))),
            kind="material"))
    out.sort(key=lambda r: -r.severity)
    return out


def beside_surface(dev):
    """``(beside (N,) bool, distance (N,) mm)`` of the *too-far* points: is the scan point's
    offset from its foot point mostly along the surface (at most :data:`MAX_NORMAL_SHARE` of
    it along the normal), and the offset's length; False and NaN for the other points (neither
    :func:`find_material` nor :func:`floating_surfaces`, which both use it, looks at them)."""
    n = dev.reason.shape[0]
    beside = np.zeros(n, bool)
    dist = np.full(n, np.nan)
    rows = np.flatnonzero(dev.reason == TOO_FAR)
    delta = dev.points_model[rows] - dev.foot_points[rows]
    with np.errstate(invalid="ignore"):
        d = np.linalg.norm(delta, axis=1)
        along_n = np.abs(np.einsum("ij,ij->i", delta, dev.normals[rows]))
        beside[rows] = np.isfinite(d) & (along_n <= MAX_NORMAL_SHARE * d)
    dist[rows] = d
    return beside, dist


def far_over_surface(dev, beside=None) -> np.ndarray:
    """(N,) float64: the signed distance (+ outside the material) of the too-far points over a
    face (their offset from the foot point mostly along the normal, :func:`beside_surface`
    False); NaN for every other point.  :class:`.regions.RegionSearch`'s ``far``."""
    beside, dist = beside_surface(dev) if beside is None else beside
    out = np.full(dev.reason.shape[0], np.nan)
    rows = np.flatnonzero((dev.reason == TOO_FAR) & ~beside & np.isfinite(dist))
    up = np.einsum("ij,ij->i", dev.points_model[rows] - dev.foot_points[rows],
                   dev.normals[rows]) > 0
    out[rows] = np.where(up, 1.0, -1.0) * dist[rows]
    return out


def floating_surfaces(dev, spacing: float, min_points: int = 3 * MIN_MATERIAL_POINTS, *,
                      beside=None, exclude=None) -> list[dict]:
    """Dense clusters of too-far points *above* the CAD faces (offset along the normal).

    Returns ``[{"n", "centroid", "faces", "height": [min, max]}]`` (mm, model frame), largest
    first: a reflection, a foreign object, or a deviation beyond the evaluation distance.
    ``beside``: :func:`beside_surface` of ``dev`` if the caller has it; ``exclude``: scan
    indices left out (the points a region holds, :func:`.beyond.join_beyond`).
    """
    if not (np.isfinite(spacing) and spacing > 0):
        return []
    beside, dist = beside_surface(dev) if beside is None else beside
    free = (dev.reason == TOO_FAR) & ~beside & np.isfinite(dist)
    if exclude is not None and len(exclude):
        free[np.asarray(exclude, np.int64)] = False
    idx = np.flatnonzero(free)
    if idx.size < min_points:
        return []
    p = dev.points_model[idx]
    pairs = cKDTree(p).query_pairs(LINK_FACTOR * spacing, output_type="ndarray")
    m = idx.size
    n_comp, labels = linked_components(m, pairs)
    sizes = np.bincount(labels, minlength=n_comp)
    out = []
    for c in np.argsort(-sizes, kind="stable"):
        if sizes[c] < min_points:
            break
        sel = idx[labels == c]
        out.append({"n": int(sel.size),
                    "centroid": [float(x) for x in dev.points_model[sel].mean(axis=0)],
                    "faces": [int(f) for f in np.unique(dev.face[sel]) if f >= 0],
                    "height": [float(dist[sel].min()), float(dist[sel].max())]})
    return out


def _rising(dev, idx, upper_limit: float, spacing: float) -> np.ndarray:
    """(k,) bool: does each evaluated point ``idx`` lie above the part and rise from its
    in-tolerance surface without a step?  From the nearest in-tolerance evaluated scan point
    (in space) to it, the offset along the CAD normal at its foot point is at most
    :data:`MAX_RISE_SLOPE` times the offset across (at least half a spacing): a surface rising at
    up to 63 degrees, not a point standing over measured surface.  (In space, not between foot
    points: past a convex edge the feet of a sharp corner the CAD chamfers crowd onto the edge,
    and a 45-degree ramp read a slope of 3 between them.)"""
    idx = np.asarray(idx, np.int64)
    out = np.zeros(idx.size, bool)
    v = dev.values[idx]
    up = np.flatnonzero(v > 0)
    good = np.flatnonzero(dev.evaluated & (np.abs(dev.values) <= abs(upper_limit)))
    if up.size == 0 or good.size == 0:
        return out
    P = dev.points_model
    _, j = cKDTree(P[good]).query(P[idx[up]], k=1)
    delta = P[idx[up]] - P[good[j]]
    along = np.abs(np.einsum("ij,ij->i", delta, dev.normals[idx[up]]))
    across = np.sqrt(np.maximum(np.einsum("ij,ij->i", delta, delta) - along * along, 0.0))
    out[up] = along <= MAX_RISE_SLOPE * np.maximum(across, 0.5 * spacing)
    return out


def _floating_sheets(dev, cand, outliers, beside, dist, link, spacing, upper_limit):
    """``(members, labels, floating)``: the material candidates ``cand``, the measurement
    outliers and the too-far points *over* a face linked in space (within ``link``) into
    sheets; ``floating`` (per member) marks the too-far points over a face with the part's
    in-tolerance surface measured under them (at least ``FLOAT_SEEN`` of the in-tolerance foot
    points that a disc of ``FLOAT_RADIUS`` spacings around their foot point holds at the
    scan's spacing, counting those whose CAD normal is within 60 degrees of theirs)."""
    over = np.flatnonzero((dev.reason == TOO_FAR) & ~beside & np.isfinite(dist))
    o = np.zeros(0, np.int64) if outliers is None else np.asarray(outliers, np.int64)
    members = np.unique(np.concatenate([cand, o, over]))
    pairs = cKDTree(dev.points_model[members]).query_pairs(link, output_type="ndarray")
    labels = linked_components(members.size, pairs)[1]
    floating = np.zeros(members.size, bool)
    at_over = np.flatnonzero(np.isin(members, over))
    with np.errstate(invalid="ignore"):
        good = np.flatnonzero(dev.evaluated & (np.abs(dev.values) <= abs(upper_limit)))
    if at_over.size and good.size:
        r = FLOAT_RADIUS * spacing
        q = members[at_over]
        lists = cKDTree(dev.foot_points[good]).query_ball_point(dev.foot_points[q], r)
        lens = np.fromiter((len(x) for x in lists), np.int64, q.size)
        if lens.sum():
            flat = good[np.concatenate([np.asarray(x, np.int64) for x in lists])]
            row = np.repeat(np.arange(q.size), lens)
            # the surface under it: facing its way (not an adjacent face, not a thin wall's
            # other side)
            same = np.einsum("ij,ij->i", dev.normals[flat], dev.normals[q][row]) > 0.5
            n = np.bincount(row, weights=same.astype(np.float64), minlength=q.size)
            floating[at_over] = n >= FLOAT_SEEN * np.pi * FLOAT_RADIUS ** 2
    return members, labels, floating


def _piece_of_floating_sheet(sheets, idx, size) -> bool:
    """Is the material component ``idx`` (scan indices, ``size`` points) a piece of a sheet
    (:func:`_floating_sheets`) that floats over measured surface -- with at least
    ``MIN_MATERIAL_POINTS`` and half as many points there as the component has?  A reflection
    reaches past an edge at one end (the impeller's: 39 points floating, 15 past the edge);
    material the CAD does not have continues the part, it does not float over it."""
    members, labels, floating = sheets
    at = np.isin(members, idx)
    mine = np.isin(labels, np.unique(labels[at]))
    return int(np.count_nonzero(floating & mine)) >= max(MIN_MATERIAL_POINTS, 0.5 * size)


def _joins_part(p, ev_tree, ev_idx, dev, link: float, spacing: float) -> bool:
    """True when the points ``p`` near the evaluated part continue its surface (no step)."""
    d, j = ev_tree.query(p, k=1, distance_upper_bound=link)
    near = np.isfinite(d)
    if not near.any():
        return False
    # attached along a rim, not touching at a point: material continues the part from an
    # edge (a sheet floating beside an edge, a reflection, touches it at one or two points)
    if np.count_nonzero(d <= ATTACH_RADIUS * spacing) < max(ATTACH_MIN, ATTACH_SHARE * p.shape[0]):
        return False
    k = ev_idx[j[near]]
    delta = p[near] - dev.points_model[k]
    dn = np.abs(np.einsum("ij,ij->i", delta, dev.normals[k]))
    dt = np.sqrt(np.maximum(np.einsum("ij,ij->i", delta, delta) - dn * dn, 0.0))
    slope = dn / np.maximum(dt, 0.5 * spacing)
    return bool(np.median(slope) <= MAX_JOIN_SLOPE)
