"""Defects that reach beyond the evaluation distance: one region, measured to its true height.

A bump taller (or a dent deeper) than the evaluation distance leaves only its flank within reach:
the points between the limit and the evaluation distance are evaluated and out of tolerance,
the rest are *too far* and were not looked at.  The part failed, but the report showed one or two
"deviation" regions (the flank's ring, broken where it is thin) whose extreme was the evaluation
distance at most (a 3 mm bump read +0.87 mm) and whose area left out the top.

Here such a defect becomes **one region** holding its out-of-tolerance patch and the points beyond
the evaluation distance joined to it by a dense, smooth surface that replaces the part's surface
(all lengths in the scan's spacing ``s``, :func:`.regions.surface_spacing`):

1. candidates: too-far points *over* a face (their offset from the closest CAD point runs along
   the normal: :func:`.material.beside_surface` is False; points beside the CAD are
   :mod:`.material`'s), signed like a deviation (+ outside the material);
2. candidates closer than ``LINK_FACTOR x s`` in space, on the same side, are linked; a
   connected component *joins* a region when at least ``ATTACH_MIN`` of its points lie within the
   link of that region's out-of-tolerance points on the same side.  It must be a **surface**:
   at least ``min_points`` points, ``DEGREE_SHARE`` of them with 2 linked neighbours (not
   scattered outliers), thin (the median ratio of the smallest to the largest principal axis of
   its points' ``FLAT_K`` nearest neighbours at most ``MAX_THICKNESS``: a sheet, not a cloud), and
   it must **replace** the part's surface: at most ``SEEN_SHARE`` of its points have the
   in-tolerance evaluated surface around their foot point (at least ``SEEN_FULL`` of the points
   within ``SEEN_RADIUS x s`` that the surface's own points around the component have there).  A reflection, ghost or second view lies over good surface
   that is measured under it; a bump, a dent or an object lying on the part hides it (only the
   points at its rim, walls included, see a half disc);
3. the regions are found again (:func:`.regions.find_regions`, its rules for layers and
   outliers unchanged) with the joined components' points evaluated at their signed distance
   from the exact CAD: the flank and the top are one surface, so the flank's ring (broken where
   it is thin, or too thin to hold core points) and the top make one region.  A region holding
   such points replaces the regions and outliers it overlaps when it **rises from the part**:
   beside the part's in-tolerance points (within ``RISE_RADIUS x s`` of its foot points) its
   lowest points are out of tolerance by at most ``MAX_STEP`` of the way from the limit to the
   evaluation distance (median over those points).  A bump, a dent, an object whose walls are
   seen climb from the limit; a surface lifted off the part with a step at its rim (the
   project's simulator's reflection blobs, lifted 1-2 mm along the rays) does not, and stays as
   it was.  It is measured like any region (:func:`.regions._describe`): its ``extreme`` the
   fitted peak of the whole surface (never beyond the largest measured value by more than the
   fit's error, so where the scan has no point near the top it is the largest measured value),
   its ``area`` the out-of-tolerance area of the part's surface under it (the cells of the foot
   points), ``n_beyond`` and ``area_beyond`` the part of it beyond the evaluation distance.  Its
   too-far points stay out of the statistics (they are not evaluated) and out of the
   floating-surface notes, and a deep dent's floor is seen surface for :mod:`.missing`.

Measured (tests/test_tall_bump_one_region.py, /work/lead/tallbump.py): panel bumps 1.5-5 mm and
dents 3-4 mm, radius 2.5-6 mm, random by area at 0.5 and 1 mm: one region, extreme within 5 %,
area within 3 % (radius 2 mm at 0.7 mm, 10 points in all: -13 %, +14 %); a box lying on the part: its height within 4 %, but its area over the
footprint's by about the perimeter times a spacing (the slope that continues ``|d| - limit``
across a cell does not know the wall is a step).

A dense surface beyond the evaluation distance that touches no region (a reflection over the
part, a foreign object standing on its own) is left as it was: a note
(:func:`.material.floating_surfaces`).
"""

from __future__ import annotations

import numpy as np
from shapeverify._lazy import cKDTree

from .deviations import TOO_FAR
from .region_measures import on_a_wall
from .regions import (LINK_FACTOR, MIN_POINTS, WALL_MIN, Outliers, RegionSearch, find_regions,
                      linked_components, standing_wall, steep_points)

__all__ = ["join_beyond"]

#: Fewest points of a joined component within the link of the region they join.
ATTACH_MIN = 3
#: Share of a joined component's points with at least 2 linked neighbours.
DEGREE_SHARE = 0.8
#: Neighbours of the thickness test, and the largest median ratio of the smallest to the largest
#: principal axis among them (a flat sheet: noise / spacing; a cloud: about 1).
FLAT_K = 10
MAX_THICKNESS = 0.35
#: Most points of a component that the thickness and the seen-under tests look at.
SAMPLE = 256
#: The part's surface is seen under a point when the in-tolerance evaluated foot points within
#: ``SEEN_RADIUS`` spacings of its foot point number at least ``SEEN_FULL`` of a full disc's
#: (the median count around the in-tolerance points near the component, ``SEEN_RING``; a random
#: sample reaches 60 % of a full disc's 12.6 with probability 0.93, a point at the rim of a defect,
#: with a half disc of surface around it, 0.3); a component seen under more than ``SEEN_SHARE``
#: of its points lies over the part (a reflection), it does not replace it.
SEEN_RADIUS = 2.0
SEEN_FULL = 0.6
SEEN_SHARE = 0.5
#: A joined region rises from the part: at the median in-tolerance point beside it (within
#: ``RISE_RADIUS`` spacings of its foot points) its lowest neighbour in the region is out of
#: tolerance by at most ``MAX_STEP`` of the way from the limit to the evaluation distance.
RISE_RADIUS = 1.5
MAX_STEP = 0.5
#: The full disc's count is that of the in-tolerance points themselves between these distances
#: (spacings) from the component's foot points (the face as narrow there as under it).
SEEN_RING = (2.0, 6.0)


def join_beyond(dev, regions, outliers, spacing: float, limits, within, beside, weights=None,
                min_points: int = MIN_POINTS):
    """The regions of an inspection with the surface beyond the evaluation distance that
    continues them joined to them (module docstring).

    Parameters
    ----------
    dev : Deviations
    regions : list of DefectRegion
        :func:`.regions.find_regions`' regions (kind ``"deviation"``).
    outliers : Outliers
        Its measurement outliers.
    spacing : float
        The scan's spacing on the part (mm).
    limits : ((N,) float64, (N,) float64)
        Per-point lower and upper limits (mm).
    within : (N,) bool
        In tolerance (evaluated points).
    beside : ((N,) bool, (N,) float64)
        :func:`.material.beside_surface` of ``dev``.
    weights : (N,) float64, optional
        Registration weights (for :class:`.regions.Outliers`).
    min_points : int
        ``find_regions``' smallest region.

    Returns
    -------
    regions : list of DefectRegion
        The regions; those a surface beyond the evaluation distance continues replaced by one
        region each holding it (``n_beyond > 0``).
    outliers : Outliers
        Without the outliers now in such a region.
    joined : (k,) int64
        Scan indices of the too-far points now in a region.
    """
    none = (list(regions), outliers, np.zeros(0, np.int64))
    if not (np.isfinite(spacing) and spacing > 0):
        return none
    is_beside, dist = beside
    cand = np.flatnonzero((dev.reason == TOO_FAR) & ~is_beside & np.isfinite(dist))
    anchor = np.flatnonzero(dev.evaluated & ~within)
    if cand.size < ATTACH_MIN or anchor.size < ATTACH_MIN:
        return none
    P, feet = dev.points_model, dev.foot_points
    up = np.einsum("ij,ij->i", P[cand] - feet[cand], dev.normals[cand]) > 0
    link = LINK_FACTOR * spacing
    tree = cKDTree(P[cand])
    # the candidates touching an out-of-tolerance evaluated point on their side
    d, j = cKDTree(P[anchor]).query(P[cand], k=min(8, anchor.size), distance_upper_bound=link)
    d, j = d.reshape(cand.size, -1), j.reshape(cand.size, -1)
    a_up = dev.values[anchor[np.minimum(j, anchor.size - 1)]] > 0
    touches = np.any(np.isfinite(d) & (a_up == up[:, None]), axis=1)
    if np.count_nonzero(touches) < ATTACH_MIN:
        return none
    pairs = tree.query_pairs(link, output_type="ndarray")
    pairs = pairs[up[pairs[:, 0]] == up[pairs[:, 1]]]
    n_comp, labels = linked_components(cand.size, pairs)
    degree = np.bincount(pairs.ravel(), minlength=cand.size)
    n_touch = np.bincount(labels, weights=touches.astype(np.float64), minlength=n_comp)
    good_feet = np.flatnonzero(dev.evaluated & within)
    comps = [c for c in np.flatnonzero(n_touch >= ATTACH_MIN)
             if _replaces_surface(np.flatnonzero(labels == c), cand, P, feet, degree, good_feet,
                                  spacing, dev.normals)]
    if not comps:
        return none

    # the regions again, with the joined surface's points evaluated at their signed distance
    far = cand[np.isin(labels, comps)]
    values = np.array(dev.values, dtype=np.float64)
    values[far] = np.where(up, 1.0, -1.0)[np.isin(labels, comps)] * dist[far]
    ev = np.array(dev.evaluated, dtype=bool)
    ev[far] = True
    beyond = np.zeros(values.shape[0], bool)
    beyond[far] = True
    found, _, _ = find_regions(feet, values, ev, within & dev.evaluated, dev.face, dev.normals,
                               weights, limits=limits,
                               search=RegionSearch(min_points=min_points, spacing=spacing,
                                                   beyond=beyond))
    new = [r for r in found if r.n_beyond > 0 and
           _rises_from_the_part(r, feet, values, dev.evaluated & within, limits, spacing,
                                dev.evaluation_distance, dev.normals)]
    if not new:
        return none          # a layer over the part after all (find_regions' rules): as it was
    held = np.zeros(values.shape[0], bool)
    for r in new:
        held[r.indices] = True
    out = [r for r in regions if not held[r.indices].any()] + new
    out.sort(key=lambda r: (-r.severity, -abs(r.extreme)))
    o = np.asarray(outliers.indices, np.int64)
    keep = ~held[o]
    outliers = Outliers(o[keep], np.asarray(outliers.low_weight)[keep],
                        min(outliers.n_layer, int(keep.sum())))
    return out, outliers, np.flatnonzero(held & beyond)


def _replaces_surface(sel, cand, P, feet, degree, good_feet, spacing, normals=None) -> bool:
    """Is the component ``cand[sel]`` a dense thin sheet that replaces the part's surface (no
    in-tolerance surface measured under it)?  (module docstring, step 2)  Its points on a
    steep wall (:func:`.regions.steep_points`, ``normals`` given) stand *beside* the surface,
    their feet crowded onto the wall's foot line next to the part's in-tolerance points: they
    say nothing of the surface under the sheet and are left out of that test (an object's walls
    up to 3 mm made more than half of the sheet of its walls and top, and the object read as a
    reflection: the box on the panel at 0.5 mm seed 5).  A wall point is also one on the steep
    plane that the most of its neighbours lie on (:func:`.region_measures.on_a_wall`): at 1 mm
    the walls above the evaluation distance are two spacings tall, the plane of a point's 8
    nearest holds the top, and the box on a lattice-scanned panel read as a reflection."""
    if sel.size < ATTACH_MIN or np.mean(degree[sel] >= 2) < DEGREE_SHARE:
        return False
    idx = cand[sel]
    if normals is not None:
        flat = idx[~(steep_points(P[idx], normals[idx], spacing) |
                     on_a_wall(P[idx], normals[idx], spacing))]
        if flat.size == 0:
            return True                          # all wall: nothing lies over the surface
    else:
        flat = idx
    sample = flat[np.linspace(0, flat.size - 1, min(flat.size, SAMPLE)).astype(np.int64)]
    if idx.size >= FLAT_K + 2:
        t = cKDTree(P[idx])
        _, j = t.query(P[sample], k=FLAT_K)
        X = P[idx][j]
        X = X - X.mean(axis=1, keepdims=True)
        C = np.einsum("nki,nkj->nij", X, X) / FLAT_K
        lam = np.linalg.eigvalsh(C)
        thick = np.sqrt(np.maximum(lam[:, 0], 0.0) / np.maximum(lam[:, 2], 1e-300))
        if np.median(thick) > MAX_THICKNESS:
            return False                                   # a cloud, not a sheet
    if good_feet.size:
        f = feet[sample]
        r = SEEN_RADIUS * spacing
        reach = SEEN_RING[1] * spacing + r
        lo, hi = f.min(axis=0) - reach, f.max(axis=0) + reach
        g = feet[good_feet]
        g = g[np.all((g >= lo) & (g <= hi), axis=1)]
        if g.shape[0]:
            gtree = cKDTree(g)
            n_at = gtree.query_ball_point(f, r, return_length=True)
            # the reference: the surface's own points around the component (as narrow as the face
            # there: a blade's two edges cut the disc for both)
            dc, _ = cKDTree(feet[idx]).query(g, k=1, distance_upper_bound=SEEN_RING[1] * spacing)
            ring = g[np.isfinite(dc) & (dc >= SEEN_RING[0] * spacing)]
            if ring.shape[0] >= FLAT_K:
                ring = ring[np.linspace(0, ring.shape[0] - 1, min(ring.shape[0], SAMPLE)).astype(np.int64)]
                ref = float(np.median(gtree.query_ball_point(ring, r, return_length=True))) - 1.0
            else:
                ref = np.pi * SEEN_RADIUS ** 2          # a full disc at the scan's spacing
            if np.mean(n_at >= SEEN_FULL * ref) > SEEN_SHARE:
                return False                               # over measured surface: a reflection
    return True


def _rises_from_the_part(region, feet, values, good, limits, spacing, evaluation_distance,
                         normals=None) -> bool:
    """Does ``region`` (its too-far points evaluated at ``values``) rise from the part's
    in-tolerance surface (``good``) continuously, or stand on it with a step at its rim?

    A bump, a dent or an object whose walls are seen climbs from the limit: beside the part's
    in-tolerance points the region's points are just out of tolerance.  A surface lifted off the
    part with a step at its rim (a reflection blob pushed off along the rays: its rim as far from
    the CAD as the evaluation distance and the part's surface right beside it) has its lowest
    points beside the part near the evaluation distance (module docstring, step 3).  A region
    holding a steep wall linked down to the in-tolerance surface (:func:`.regions.standing_wall`,
    ``normals`` given) rises from it whatever its rim's lowest points (at 1 mm spacing an
    object's 3 mm walls have a few points within the evaluation distance, scattered in
    height)."""
    if not np.isfinite(evaluation_distance):
        return True
    idx = np.asarray(region.indices, np.int64)
    above = region.side == "above"
    if above and normals is not None and standing_wall(feet, values, normals, np.flatnonzero(good), idx,
                                             spacing, limits[1] if above else limits[0]) >= WALL_MIN:
        return True
    above = region.side == "above"
    lim = np.abs(limits[1][idx] if above else limits[0][idx])
    excess = np.abs(values[idx]) - lim
    r = RISE_RADIUS * spacing
    lo, hi = feet[idx].min(axis=0) - r, feet[idx].max(axis=0) + r
    g = np.flatnonzero(good)
    g = g[np.all((feet[g] >= lo) & (feet[g] <= hi), axis=1)]
    if g.size == 0:
        return True
    k = min(8, idx.size)
    d, j = cKDTree(feet[idx]).query(feet[g], k=k, distance_upper_bound=r)
    d, j = d.reshape(g.size, k), j.reshape(g.size, k)
    near = np.isfinite(d)
    rim = near.any(axis=1)
    if not rim.any():
        return True
    low = np.where(near, excess[np.minimum(j, idx.size - 1)], np.inf).min(axis=1)[rim]
    band = float(evaluation_distance) - float(np.median(lim))
    return bool(np.median(low) <= MAX_STEP * band)
