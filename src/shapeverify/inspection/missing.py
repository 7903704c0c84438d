"""Missing material: CAD surface the scan sees through (a hole or cut-out the CAD does not have).

The mirror of :mod:`.material`, **on by default** (``inspect(..., missing=False)`` skips it).
Where the CAD has surface and the scan has no point near it, either the part has no material
there (a hole that should not be there, a missing flange) or the scanner did not look there
(outside its view, shadowed, a shiny or dark spot, the back of a one-sided scan).  The first
fails the part (a region of ``kind="missing"``); the second is only a coverage gap
(:mod:`.coverage`: ``incomplete`` when too little is seen overall).

**How the two are told apart: see-through evidence.**  A scanner that did not look leaves no
trace; a scanner that looked *through* the CAD surface measured what lies behind it -- the wall of
a hole drilled through a solid, the table or fixture behind a sheet.  So an unseen area is missing
material only when scan points are seen behind it.  The rules (all lengths in mm, ``s`` = the
scan's spacing as area per point, :func:`.regions.surface_spacing`):

1. **Seen behind** (the evidence, checked first): scan points *off the CAD surface* -- not
   evaluated (farther than the evaluation distance), or evaluated inside the material beyond the
   lower limit -- that lie deeper than the evaluation distance behind the gap against its CAD
   normal (inside a solid's material; for a sheet, on the side its normals turn away from) and
   within ``SEEN_RADIUS + BEHIND_LATERAL`` spacings of a gap point across it: at least
   ``MIN_BEHIND`` (10) of them and ``MIN_BEHIND_SHARE`` (10 %) of the points the gap's area would
   hold.  A good part's points all lie on its CAD surface, so a dropout, a shadow or the unseen
   back of a plate has none (the back face's points of a plate lie *on* the CAD, not off it);
2. **unseen**: the model points (an even subset of ``prep.points``, :func:`.coverage.model_samples`)
   with no evaluated foot point within ``SEEN_RADIUS x s`` (random sampling leaves such a spot
   with probability ``exp(-4 pi)``, 4e-6), linked into connected gaps like the coverage gaps;
3. **wider than sampling explains**: some point of the gap is farther than ``MIN_WIDTH x s``
   from every foot point (the largest empty disc among 100,000 random points has a radius of
   about 1.9 spacings), and farther than ``MIN_WIDTH`` spacings of the surface around the gap
   on its own side of the wall (``s`` counts neighbours in space, both sides of a wall thinner
   than a few spacings: 0.76 of the true spacing on the impeller's blades);
4. **enclosed by seen surface**: along the gap's border, seen surface and "no surface" (the
   CAD's outline, a free edge, a face not inspected) are weighed; the seen share must be at least
   ``MIN_ENCLOSED`` (90 %): a gap that runs out to where the CAD ends is the edge of the scan;
5. **not a shadow**: at least ``MIN_IN_TOLERANCE`` of the evaluated points within
   ``SEEN_RADIUS + BAND`` spacings of the gap are not raised beyond the upper limit (a raised
   defect's shadow; points below the lower limit, such as a hole's wall near its rim, are what a
   hole looks like and do not count against it);
6. **in the line of sight**: at least ``MIN_VISIBLE`` of the gap's points have no scan point in
   *front* of the surface within the seen radius of their line of sight (a reflection pushed off
   the surface, a foreign object: the scanner saw something there); and, when the scan has a
   dominant view direction ``v`` (the mean CAD normal at the evaluated foot points has a length of
   at least ``DOMINANT_VIEW``), they face the view (``n . v > 0.1``) and are not hidden behind
   other CAD surface along ``v``.  Without a dominant direction (views from all around, no sensor
   position) the line of sight is each point's normal and the hiding test is skipped: then rules
   1 and 4 (a gap in densely seen surface, with surface seen behind it) decide.

A region's ``area`` is the gap's CAD area, grown back by what the seen radius ate from its rim
(``SEEN_RADIUS - RIM`` spacings), measured on probes finer than the scan (:func:`_area`).  On
random scans of a Ø12 mm hole in the wavy panel it read 1.02-1.08 of the hole's area at 0.5 and
1 mm spacing; Ø12 and Ø16 mm holes through a 10 mm plate (tests/test_missing_see_through.py),
within 20 % on both faces.  ``extreme`` is NaN (the depth of the missing material is unknown),
``n`` 0 and ``indices`` empty (no scan point belongs to it), ``side`` ``"below"``, ``severity``
the area times the tolerance's lower-limit magnitude.

Limits: with nothing seen behind it (a hole in a sheet scanned against a black background, a cut
flange with nothing behind) missing material stays a coverage gap -- not seen, not judged.
Material missing *at the CAD's own edges* (an oversized hole, a short flange) is bordered by the
model's end and is not found by rule 4.  A deep dent (deeper than the evaluation distance) whose
floor is seen can look like missing material; its slopes fail the part anyway.
"""

from __future__ import annotations

import numpy as np
from shapeverify._lazy import cKDTree

from ..measures._grid_kernels import any_within, kernel_array, mark_within
from .coverage import model_samples
from .regions import DefectRegion, linked_components

__all__ = ["find_missing", "SEEN_RADIUS", "MIN_WIDTH", "MIN_ENCLOSED"]

#: Radius (scan spacings) within which a foot point makes a model point seen.
SEEN_RADIUS = 2.0
#: Least distance (scan spacings) from every foot point that some point of a hole reaches.
MIN_WIDTH = 2.5
#: Least share of a gap's border that is seen surface.
MIN_ENCLOSED = 0.9
#: Least share of in-tolerance points in the band around a gap.
MIN_IN_TOLERANCE = 0.9
#: Width (scan spacings) of the band around a gap whose points must be in tolerance.
BAND = 3.0
#: Least length of the mean normal of the seen surface for a view direction.
DOMINANT_VIEW = 0.5
#: Least share of a gap's points that face the view and are not hidden.
MIN_VISIBLE = 0.8
#: Where a scan's rim lies before the edge of the material (scan spacings; measured, above).
RIM = 0.3
#: Most model samples used (an even subset of the prepared model points).
MAX_SAMPLES = 200_000
#: Most gaps looked at closely (largest first).
MAX_GAPS = 50
#: Least number of scan points seen behind a gap (rule 1) ...
MIN_BEHIND = 10
#: ... and least share of the points the gap's area would hold at the scan's spacing.
MIN_BEHIND_SHARE = 0.1
#: How far across (scan spacings, beyond the seen radius) a point behind a gap may lie from it.
BEHIND_LATERAL = 1.5
#: The surface whose density gives a gap its local spacing: within this many scan spacings of it.
LOCAL_RING = 8.0


def find_missing(prep, dev, spacing: float, within: np.ndarray, tolerance=None, *,
                 faces=None, seen_also=None) -> list[DefectRegion]:
    """Missing-material regions of an inspection (see the module docstring).

    Parameters
    ----------
    prep : shapeverify.nearest.Prepared
    dev : Deviations
    spacing : float
        The scan's spacing on the part as area per point (mm).
    within : (N,) bool
        In tolerance, per scan point (ignored where not evaluated).
    tolerance : Tolerance, optional
        For the severity (its lower limit); 1 mm² of hole counts 1 mm³ without it.
    faces : sequence of int, optional
        The inspected faces (None: all).
    seen_also : (k,) int, optional
        Scan indices of points not evaluated whose foot points are seen surface all the same:
        the points of a region beyond the evaluation distance (:mod:`.beyond`: a deep dent's
        floor is the part's surface, displaced, not a view through it).

    Returns
    -------
    list of DefectRegion
        ``kind="missing"``, largest first.
    """
    s = float(spacing)
    ev = dev.evaluated
    if not (np.isfinite(s) and s > 0) or np.count_nonzero(ev) < 10:
        return []
    # the evidence first (cheap, and absent from almost every inspection): scan points off the
    # CAD surface -- not evaluated, or evaluated and inside the material beyond the tolerance
    off = ~ev | (~within & (dev.values < 0))
    off_pts = dev.points_model[off]
    off_pts = off_pts[np.all(np.isfinite(off_pts), axis=1)]
    if off_pts.shape[0] < MIN_BEHIND:
        return []                                    # nothing seen off the surface: no evidence
    pts, face, a_pt = model_samples(prep, faces, MAX_SAMPLES)
    if pts.shape[0] < 10:
        return []
    on_part = ev
    if seen_also is not None and len(seen_also):
        on_part = ev.copy()
        on_part[np.asarray(seen_also, np.int64)] = True
    feet = kernel_array(dev.foot_points[on_part])
    r_seen = SEEN_RADIUS * s
    seen = np.empty(pts.shape[0], bool)
    any_within(feet, pts, float(r_seen), seen)
    gap_idx = np.flatnonzero(~seen)
    if gap_idx.size == 0:
        return []
    near = np.empty(gap_idx.size, bool)
    any_within(feet, pts[gap_idx], float(MIN_WIDTH * s), near)
    if near.all():
        return []                                    # no spot wider than sampling explains
    normals = _sample_normals(prep, faces, pts.shape[0])
    if normals is None:
        return []                                    # no CAD normals: no "behind"
    h = float(np.sqrt(a_pt))                         # the samples' spacing
    link = 2.5 * h
    n_comp, labels = linked_components(gap_idx.size,
                                       cKDTree(pts[gap_idx]).query_pairs(link, output_type="ndarray"))
    deep = np.bincount(labels, weights=(~near).astype(np.float64), minlength=n_comp)
    size = np.bincount(labels, minlength=n_comp)
    comps = [c for c in np.argsort(-size, kind="stable") if deep[c] > 0][:MAX_GAPS]
    if not comps:
        return []
    ev_dist = float(dev.evaluation_distance)
    delta = ev_dist if np.isfinite(ev_dist) else 3.0 * s
    depth_max = float(getattr(getattr(prep, "model", None), "size", 0.0) or np.ptp(pts, axis=0).max())
    lower = abs(float(getattr(tolerance, "lower", 1.0))) or 1.0
    out, lazy = [], {}
    for c in comps:
        g = gap_idx[labels == c]
        if not _wider_than_local_sampling(pts, normals, g, dev, on_part, a_pt, s):
            continue
        if _seen_behind(pts, normals, g, off_pts, r_seen + BEHIND_LATERAL * s, delta, depth_max) \
                < max(MIN_BEHIND, MIN_BEHIND_SHARE * g.size * a_pt / (s * s)):
            continue
        if not lazy:                                 # what the other rules need, once
            other = dev.points_model[~ev]            # not evaluated: too far, past an edge, ...
            lazy["other"] = kernel_array(other[np.all(np.isfinite(other), axis=1)])
            lazy["view"] = _view_direction(dev)
            lazy["ok_band"] = within | (dev.values <= 0)   # only raised material casts a shadow
        other, view, ok_band = lazy["other"], lazy["view"], lazy["ok_band"]
        if _enclosed(pts, seen, g, h, a_pt) < MIN_ENCLOSED:
            continue
        if _in_tolerance(dev, ok_band, pts[g], r_seen + BAND * s) < MIN_IN_TOLERANCE:
            continue
        if _visible(pts, normals, g, view, h, prep, other, r_seen,
                    10.0 * float(dev.evaluation_distance)) < MIN_VISIBLE:
            continue
        area, centroid, grown = _area(pts, normals, g, feet, r_seen, r_seen - RIM * s, h, a_pt, s)
        out.append(DefectRegion(
            n=0, area=area, extreme=float("nan"), extreme_raw=float("nan"), centroid=centroid,
            extreme_point=centroid.copy(),
            faces=tuple(int(f) for f in np.unique(face[grown]) if f >= 0), side="below",
            indices=np.zeros(0, np.int64), severity=area * lower, kind="missing"))
    out.sort(key=lambda r: -r.area)
    return out


def _wider_than_local_sampling(pts, normals, g, dev, on_part, a_pt, s) -> bool:
    """Rule 3 at the gap's own density: is some point of the gap ``g`` farther than ``MIN_WIDTH``
    local spacings from every foot point?  The local spacing is the area per foot point of the
    surface around the gap (the model samples within ``LOCAL_RING`` scan spacings of it, outside
    it, facing its way: CAD normals within 60 degrees of its mean normal) counting the foot
    points that face its way.  The scan's spacing ``s`` (:func:`.regions.surface_spacing`,
    neighbours counted in space) counts both sides of a wall thinner than a few spacings: on the
    impeller's blades it reads 0.76 of the true spacing, and a random sampling hole of 1.9 true
    spacings -- the largest among 100,000 points -- read 2.6 of them (0.5 mm, seed 21 of a good
    part: a 'missing' region).  Never below ``s``."""
    gp = pts[g]
    nrm = normals[g].mean(axis=0)
    L = float(np.linalg.norm(nrm))
    if not L > 0:
        return True
    nrm /= L
    reach = LOCAL_RING * s
    lo, hi = gp.min(axis=0) - reach, gp.max(axis=0) + reach
    local = np.flatnonzero(np.all((pts >= lo) & (pts <= hi), axis=1))
    local = local[normals[local] @ nrm > 0.5]
    dg, _ = cKDTree(gp).query(pts[local], k=1, distance_upper_bound=reach)
    in_gap = np.isin(local, g)
    ring = local[np.isfinite(dg) & ~in_gap]
    if ring.size < 10:
        return True
    fi = np.flatnonzero(on_part)
    f = dev.foot_points[fi]
    box = np.all((f >= lo) & (f <= hi), axis=1) & (dev.normals[fi] @ nrm > 0.5)
    f = f[box]
    if f.shape[0] == 0:
        return True
    # each foot point counted at its nearest model sample (facing the gap's way)
    _, j = cKDTree(pts[local]).query(f, k=1)
    ring_mask = np.isfinite(dg) & ~in_gap
    n_feet = int(np.count_nonzero(ring_mask[j]))
    if n_feet < 10:
        return True
    s_loc = max(s, float(np.sqrt(ring.size * a_pt / n_feet)))
    d, _ = cKDTree(f).query(gp, k=1)
    return bool(np.max(d) > MIN_WIDTH * s_loc)


def _seen_behind(pts, normals, g, off_pts, rho, delta, depth_max) -> int:
    """How many scan points off the CAD surface lie *behind* the gap ``g`` (rule 1): deeper than
    ``delta`` against the CAD normal of their nearest gap point (inside a solid's material, or
    past a sheet on the side its normals turn away from) and within ``rho`` of it across."""
    gp = pts[g]
    lo, hi = gp.min(axis=0) - depth_max, gp.max(axis=0) + depth_max
    q = off_pts[np.all((off_pts >= lo) & (off_pts <= hi), axis=1)]
    if q.shape[0] == 0:
        return 0
    d, j = cKDTree(gp).query(q, distance_upper_bound=float(np.hypot(depth_max, rho)))
    ok = np.isfinite(d)
    q, j = q[ok], j[ok]
    rel = gp[j] - q
    depth = np.einsum("ij,ij->i", rel, normals[g][j])
    lateral2 = np.einsum("ij,ij->i", rel, rel) - depth * depth
    return int(np.count_nonzero((depth > delta) & (lateral2 <= rho * rho)))


def _sample_normals(prep, faces, n: int) -> np.ndarray:
    """The CAD normals of :func:`.coverage.model_samples` (the same subset of ``prep.points``),
    or None when the model points carry none."""
    mp = prep.points
    if getattr(mp, "normals", None) is None:
        return None
    nrm = np.asarray(mp.normals)
    if faces is not None:
        nrm = nrm[np.isin(np.asarray(mp.face), np.asarray(faces, dtype=np.int32))]
    step = max(1, int(np.ceil(nrm.shape[0] / MAX_SAMPLES)))
    nrm = nrm[::step]
    return nrm if nrm.shape[0] == n else None


def _view_direction(dev):
    """The unit mean CAD normal at the evaluated foot points, or None when it is shorter than
    :data:`DOMINANT_VIEW` (views from several sides: no one line of sight)."""
    nrm = dev.normals[dev.evaluated]
    m = np.nanmean(nrm, axis=0) if nrm.shape[0] else np.zeros(3)
    L = float(np.linalg.norm(m))
    return m / L if np.isfinite(L) and L >= DOMINANT_VIEW else None


def _enclosed(pts, seen, g, h, a_pt) -> float:
    """The seen share of the border of gap ``g`` (rule 4): for each gap point, the seen model
    points within ``2.5 h`` weigh for "seen", the deficit against a full disc for "the model
    ends here", each less a slack of a fifth of a full disc (the count's own scatter)."""
    rho = 2.5 * h
    lo, hi = pts[g].min(axis=0) - 2 * rho, pts[g].max(axis=0) + 2 * rho
    local = np.flatnonzero(np.all((pts >= lo) & (pts <= hi), axis=1))
    full = np.pi * rho * rho / a_pt
    slack = 0.2 * full
    n_all = cKDTree(pts[local]).query_ball_point(pts[g], rho, return_length=True)
    seen_local = local[seen[local]]
    n_seen = (cKDTree(pts[seen_local]).query_ball_point(pts[g], rho, return_length=True)
              if seen_local.size else np.zeros(g.size))
    w_seen = np.maximum(n_seen - slack, 0.0).sum()
    w_end = np.maximum(full - n_all - slack, 0.0).sum()
    return float(w_seen / (w_seen + w_end)) if w_seen + w_end > 0 else 0.0


def _in_tolerance(dev, within, gp, band) -> float:
    """Share of ``within`` (in tolerance or not raised) among the evaluated points whose foot point
    lies within ``band`` of the gap points ``gp`` (rule 5); 0 when there are none."""
    ev = np.flatnonzero(dev.evaluated)
    mark = np.zeros(ev.size, bool)
    mark_within(kernel_array(dev.foot_points[ev]), kernel_array(gp), float(band), mark)
    k = ev[mark]
    return float(np.mean(within[k])) if k.size else 0.0


def _visible(pts, normals, g, view, h, prep, other, r_seen, reach, most: int = 64) -> float:
    """Share of (up to ``most``) gap points in the line of sight (rule 6): facing ``view`` and not
    hidden behind other model points along it (when there is a view direction), and with no scan
    point that was not evaluated within ``r_seen`` of their line of sight *in front* of the
    surface within ``reach`` (a reflection, a foreign object: the scanner saw something there;
    points behind are the evidence of rule 1, :func:`_seen_behind`)."""
    gs = g[np.linspace(0, g.size - 1, min(most, g.size)).astype(np.int64)]
    ok = np.ones(gs.size, bool)
    if view is not None:
        if normals is not None:
            ok &= normals[gs] @ view > 0.1
        size = float(getattr(getattr(prep, "model", None), "size", 0.0) or np.ptp(pts, axis=0).max())
        t = np.arange(3.0 * h, size + h, h)
        ray = (pts[gs][:, None, :] + t[None, :, None] * view[None, None, :]).reshape(-1, 3)
        hit = np.empty(ray.shape[0], bool)
        any_within(kernel_array(pts), kernel_array(ray), float(1.5 * h), hit)
        ok &= ~hit.reshape(gs.size, t.size).any(axis=1)
    if other.shape[0]:
        d = np.broadcast_to(view, (gs.size, 3)) if view is not None else normals[gs] \
            if normals is not None else None
        if d is not None:
            t = np.arange(0.5 * r_seen, reach + 0.5 * r_seen, 0.5 * r_seen)  # the front side
            ray = (pts[gs][:, None, :] + t[None, :, None] * d[:, None, :]).reshape(-1, 3)
            hit = np.empty(ray.shape[0], bool)
            any_within(other, kernel_array(ray), float(r_seen), hit)
            ok &= ~hit.reshape(gs.size, t.size).any(axis=1)
    return float(np.mean(ok))


def _area(pts, normals, g, feet, r_seen, grow, h, a_pt, s):
    """``(area mm², centroid, sample indices)`` of the gap ``g`` grown back by ``grow``.

    Measured on probes ``k x k`` per model sample in its tangent plane (``k = ceil(2 h / s)``,
    at most 6) so that a model sampled coarser than the scan still gives the area to about half a
    scan spacing along the rim: the probes not seen within ``r_seen`` are grown by ``grow`` and
    counted, ``a_pt / k^2`` each.
    """
    reach = grow + 2.0 * h
    gp = pts[g]
    lo, hi = gp.min(axis=0) - reach, gp.max(axis=0) + reach
    local = np.flatnonzero(np.all((pts >= lo) & (pts <= hi), axis=1))
    k = int(np.clip(np.ceil(2.0 * h / s), 1, 6)) if normals is not None else 1
    off = (np.arange(k) + 0.5) / k - 0.5
    n = normals[local] if normals is not None else np.tile([0.0, 0.0, 1.0], (local.size, 1))
    a = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e1 = np.cross(n, a)
    e1 /= np.maximum(np.linalg.norm(e1, axis=1, keepdims=True), 1e-12)
    e2 = np.cross(n, e1)
    u, v = np.meshgrid(off * h, off * h, indexing="ij")
    probes = (pts[local][:, None, :] + u.reshape(1, -1, 1) * e1[:, None, :]
              + v.reshape(1, -1, 1) * e2[:, None, :]).reshape(-1, 3)
    seen = np.empty(probes.shape[0], bool)
    any_within(feet, kernel_array(probes), float(r_seen), seen)
    if seen.all():
        return float(g.size * a_pt), gp.mean(axis=0), g
    hole = np.zeros(probes.shape[0], bool)
    if grow > 0:
        mark_within(kernel_array(probes), kernel_array(probes[~seen]), float(grow), hole)
    hole |= ~seen
    in_local = hole.reshape(local.size, k * k).any(axis=1)
    return (float(np.count_nonzero(hole) * a_pt / (k * k)), probes[hole].mean(axis=0),
            local[in_local])
