"""Missing material: CAD surface the scan sees through (a hole or cut-out the CAD does not have).

The mirror of :mod:`.material`, **opt-in** (``inspect(..., missing=True)``): an enclosed
unseen area is told from a scanner's dropout (a shiny or dark spot) by no more than the rules
below, and a hole drilled through a solid already fails the part without it, through the
deviations of its wall, which lies inside the CAD's material (tested).  Evidence seen *through*
the gap (the wall or the fixture behind it) would make it decisive: not used yet.

Where the CAD has surface and the scan has no point near it,
either the part has no material there (a hole that should not be there, a missing flange) or
the scanner did not look there (outside its view, shadowed, the edge of a partial scan).  The
first fails the part (a region of ``kind="missing"``); the second is only a coverage gap
(:mod:`.coverage`: ``incomplete`` when too little is seen overall).

**How the two are told apart** (the rule chosen; all lengths in mm, ``s`` = the scan's spacing
as area per point, :func:`.regions.surface_spacing`).  A scanner that stopped seeing leaves a gap
that runs out to where its view ended; a hole leaves a gap that the scan's points surround.  So
an unseen area is missing material only when all of these hold:

1. **Unseen**: the model points (an even subset of ``prep.points``, :func:`.coverage.model_samples`)
   with no evaluated foot point within ``SEEN_RADIUS x s`` (random sampling leaves such a spot
   with probability ``exp(-4 pi)``, 4e-6), linked into connected gaps like the coverage gaps;
2. **wider than sampling explains**: some point of the gap is farther than ``MIN_WIDTH x s``
   from every foot point (the gap is at least 5 spacings across; the largest empty disc among
   100,000 random points has a radius of about 1.9 spacings, so sparse or thinned sampling never
   makes one);
3. **enclosed by seen surface**: along the gap's border, seen surface and "no surface" are
   weighed: for each gap point, the model points within ``2.5`` model spacings that are seen
   (weight for "seen"), and the deficit of model points against a full disc (weight for "the
   model ends here": the CAD's outline, a free edge, a face that is not inspected).  The seen
   share must be at least ``MIN_ENCLOSED`` (90 %).  A gap that reaches the CAD's outline where
   no scan point is (the unseen half of a partial scan) is bordered by the outline and is not
   missing material: the scanner may simply have stopped there;
4. **the surrounding surface is in tolerance**: at least ``MIN_IN_TOLERANCE`` of the evaluated
   points within ``SEEN_RADIUS + BAND`` spacings of the gap are within tolerance: a gap beside a
   raised defect is its shadow, and the defect fails the part already;
5. **seen through, in the line of sight**: at least ``MIN_VISIBLE`` of the gap's points must be
   seen through: no scan point that was not evaluated (too far, past an edge) lies within the
   seen radius of their line of sight, on either side of the surface within 10 evaluation
   distances (a reflection pushed off the surface, a foreign object: the scanner saw something
   there, not through the surface); and, when the scan has a dominant view direction ``v`` (the
   mean CAD normal at the evaluated foot points has a length of at least ``DOMINANT_VIEW``), they
   must face the view (``n . v > 0.1``) and not be hidden behind other CAD surface along ``v`` (a
   shadow behind a rib or a wall is hidden).  Without a dominant direction (views from all
   around) the line of sight is each point's normal and the hiding test is skipped.  Points seen
   *behind* the surface through the gap are not used as evidence for a hole (they block it, like
   points in front, when they are that close: conservative).

A region's ``area`` is the gap's CAD area, grown back by what the seen radius ate from its rim
(``SEEN_RADIUS - RIM`` spacings: the last scan points lie a fraction of a spacing before the edge
of the material), measured on probes finer than the scan (:func:`_area`).  On random scans of a
Ø12 mm hole it read 1.02-1.08 of the hole's area at 0.5 and 1 mm spacing, 0.82-1.03 at 2 mm
(a gap only 3 spacings wide is cut smaller by its nearest rim points); ``extreme`` is NaN (nothing was measured there; the depth of the missing material
is unknown), ``n`` 0 and ``indices`` empty (no scan point belongs to it), ``side`` ``"below"``,
``severity`` the area times the tolerance's lower-limit magnitude (so a larger hole ranks first
among the missing regions; deviation regions' severities are volumes beyond the limit).

Limits: material missing *at the CAD's own edges* (an oversized hole, a short flange, a notch in
the outline) is bordered by the model's end and is not found by this rule: without points seen
behind the CAD surface, the part's ending and the scanner's stopping look alike there.  A
dropout of the scanner enclosed by seen surface (a shiny or dark spot) looks like a hole, and
the reason says so.  A scan whose lines are far apart across and dense along (spacing ratio over
about 20) can leave strips wider than ``MIN_WIDTH`` area-based spacings.
"""

from __future__ import annotations

import numpy as np
from shapeverify._lazy import cKDTree

from ._grid_kernels import any_within, kernel_array, mark_within
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


def find_missing(prep, dev, spacing: float, within: np.ndarray, tolerance=None, *,
                 faces=None) -> list[DefectRegion]:
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

    Returns
    -------
    list of DefectRegion
        ``kind="missing"``, largest first.
    """
    s = float(spacing)
    ev = dev.evaluated
    if not (np.isfinite(s) and s > 0) or np.count_nonzero(ev) < 10:
        return []
    pts, face, a_pt = model_samples(prep, faces, MAX_SAMPLES)
    if pts.shape[0] < 10:
        return []
    feet = kernel_array(dev.foot_points[ev])
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
    h = float(np.sqrt(a_pt))                         # the samples' spacing
    link = 2.5 * h
    n_comp, labels = linked_components(gap_idx.size,
                                       cKDTree(pts[gap_idx]).query_pairs(link, output_type="ndarray"))
    deep = np.bincount(labels, weights=(~near).astype(np.float64), minlength=n_comp)
    size = np.bincount(labels, minlength=n_comp)
    comps = [c for c in np.argsort(-size, kind="stable") if deep[c] > 0][:MAX_GAPS]
    if not comps:
        return []
    normals = _sample_normals(prep, faces, pts.shape[0])
    other = dev.points_model[~ev]                    # not evaluated: too far, past an edge, ...
    other = kernel_array(other[np.all(np.isfinite(other), axis=1)])
    view = _view_direction(dev)
    lower = abs(float(getattr(tolerance, "lower", 1.0))) or 1.0
    out = []
    for c in comps:
        g = gap_idx[labels == c]
        if _enclosed(pts, seen, g, h, a_pt) < MIN_ENCLOSED:
            continue
        if _in_tolerance(dev, within, pts[g], r_seen + BAND * s) < MIN_IN_TOLERANCE:
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
    """The seen share of the border of gap ``g`` (rule 3): for each gap point, the seen model
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
    """Share of in-tolerance points among the evaluated points whose foot point lies within
    ``band`` of the gap points ``gp`` (rule 4); 0 when there are none."""
    ev = np.flatnonzero(dev.evaluated)
    mark = np.zeros(ev.size, bool)
    mark_within(kernel_array(dev.foot_points[ev]), kernel_array(gp), float(band), mark)
    k = ev[mark]
    return float(np.mean(within[k])) if k.size else 0.0


def _visible(pts, normals, g, view, h, prep, other, r_seen, reach, most: int = 64) -> float:
    """Share of (up to ``most``) gap points seen through (rule 5): facing ``view`` and not hidden
    behind other model points along it (when there is a view direction), and with no scan
    point that was not evaluated within ``r_seen`` of their line of sight, on either side of
    the surface within ``reach`` (a reflection, a foreign object: the scanner saw something
    there, not through the surface)."""
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
            t = np.arange(-reach, reach + 0.5 * r_seen, 0.5 * r_seen)
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
