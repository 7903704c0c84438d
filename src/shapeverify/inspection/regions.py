"""Regions: connected clusters of out-of-tolerance scan points, and measurement outliers.

All neighbourhoods here are taken between *foot points* (the scan points projected onto the CAD
surface): a spike 1 mm off the surface still has its neighbours around it.

**Spacing.**  Every length here is in units of the scan's spacing ``s`` taken as surface area
per point (:func:`surface_spacing`): the same for a grid, random sampling, scanner rows or
anisotropic rows of the same density, and not collapsed by a second exposure of the same surface
(two passes 0.02 mm apart once gave a "spacing" of 0.017 mm, and every point of a dent looked
isolated: the dented part passed).  Support is counted by surface area, not by points.  Only
neighbours on a point's own side of the part count (:func:`_same_side`): on a wall thinner
than a few spacings the other side's points are as near, and the spacing read 0.76 x the truth
on the impeller's blades.

**Defect or outlier.**  A defect is a place where the *surface* is out of tolerance, not a few
points.  Every evaluated point near an out-of-tolerance one gets the median deviation of its 9
nearest evaluated points within ``MEDIAN_RADIUS = 3 s``; a **core** point is one whose median is
beyond the limit (on that side; an in-tolerance point that may be another face's pushed beyond
that limit, at a dented convex edge, has no vote there: :func:`.region_folds.behind_other_face`).
Core points closer than ``LINK_FACTOR = 2.5 s`` on the same side are linked, their feet or
their measured points (a dent on a convex edge: the points pushed in from one face lie nearer
the other, their feet jump across the edge, the dented surface stays
whole: two lobes and no region once); a connected component is a defect region when its *dense* core points (each
standing for at most ``SPARSE_AREA = 3 s^2``: stray points beside the part or in a shadow stand
for no measured surface) number at least ``min_points`` and cover at least ``min_points x s^2``
(each core point's area measured along the surface: :func:`area_per_point`).
The region's points are the out-of-tolerance points on its side within the link distance of
its core points; every other out-of-tolerance point is a measurement outlier (counted, excluded
from the statistics, never failing the part).  Scattered bad points among good ones (uniform
outliers, dust, spikes, noise) are never core.  Nor is a dense layer *over* in-tolerance measured
surface a defect (a reflection, multipath ghost or misplaced second view of a good part: the
part's surface is seen under it, :func:`_over_measured_surface`; a real defect replaces the
surface): its points are outliers too (``Outliers.n_layer``).  The surface is seen under (or
over) a component when half of its core points or more lie inside ordinary triangles of the
deep-in-tolerance points around (:func:`.region_measures.seen_under`, an alpha shape: a sparse
reflection crossing a blade crowded into a 6-point "region" with the blade's good surface all
around and between its points), or when it is dense and two-layered (:func:`_over_measured_surface`),
or when half of its out-of-tolerance points have the in-tolerance surface around them as densely
as the surface's own points have it (:func:`.region_measures.seen_around`: a layer's core points
are those in the sampling holes of the surface under it, so the test takes all its points).
A layer's component sits where the surface under it happens to be sparse (0.4-0.6 of the scan's
density on the impeller), so two more tests do not ask for the surface's density: deep points
of the surface lie *among* its points (inside the hull of its points around them, at least
``AMONG_MIN`` and ``AMONG_SHARE`` of its points, :func:`.region_measures.seen_among`; a real
defect replaces the surface and holds none, only stray outliers), or the component is a piece
of a larger sheet -- its out-of-tolerance points linked in space (at the scan points, within
the link distance, on both sides of the part: a reflection crosses it) to out-of-tolerance points
outside it -- and the whole sheet is seen around (:func:`_sheet_seen`): the sheet's other
pieces lie over denser surface.  A real defect's sheet is its own points.  The sheet runs on
through the points beyond the evaluation distance over a face when the caller gives them
(``RegionSearch.far``; a reflection lifted 1.5-4 mm comes within the evaluation distance of a
blade only at one end: 8 points of a sheet of 86 on the good impeller, 0.7 mm seed 1); the
surface is seen under its far points as under its evaluated ones, and a bump taller than the
evaluation distance, which replaces the surface under its top, stays a region.

For each region:

* ``n``: number of its (out-of-tolerance) points; ``area``: the out-of-tolerance surface area
  (mm^2): of the cell each of its points and their in-tolerance neighbours stands for (its
  Voronoi cell in its tangent plane), the part where ``|d| - |limit|`` continued by its local
  slope is positive (:func:`.region_measures.out_area`: the same area for random, lattice,
  scanner-row and anisotropic sampling, the boundary interpolated between points in and out;
  points folded over a convex edge, whose feet crowd onto a curve of the other face, measured
  where they were sampled: :func:`.region_folds.unfolded`, for the core support too);
* ``extreme``: the signed deviation at the region's worst point, the fitted peak of the local
  surface (a sampled dent's deepest point is missed by up to the spacing): from the core point
  of largest neighbourhood-median |deviation|, a quadratic ``d(x, y)`` is fitted in the tangent
  plane and moved to its extremum (:func:`.region_measures.fitted_peak`); the neighbourhood
  median when the fit finds no extremum beyond the region's limit, the largest measured value
  when the fitted peak lies more than twice the fit's standard error beyond it (or beyond it
  at all when the quadratic does not fit to the local noise).  ``extreme`` therefore
  always lies outside the tolerance, on the region's side; ``extreme_uncertainty`` is its
  standard uncertainty (mm); ``extreme_raw`` the single largest measured value (same side);
* ``severity``: the out-of-tolerance volume ``sum_i a_i (|d_i| - |limit_i|)`` (mm^3) over the
  region's points (``a_i`` the area per point): large and far-out regions first.  Regions are
  returned most severe first, so a real dent comes before specks in a reflection;
* ``centroid``: mean of the foot points weighted by their out-of-tolerance area (model coordinates, mm);
  ``extreme_point``: where the extreme is, on the CAD surface's tangent plane; ``faces``: CAD
  faces it touches;
* ``kind``: ``"deviation"`` here; :mod:`.material` adds ``"material"`` regions, :mod:`.missing`
  (opt-in) ``"missing"`` ones.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from itertools import chain

import numpy as np
from shapeverify._lazy import cKDTree

from .._arrays import bounds
from .._renamed import grouped_keywords
from ..measures.components import linked_components
from ..measures._grid_kernels import (any_within, count_within, kernel_array, kernel_sums,
                                      kernel_sums_unfolded, mark_within, nearest_other)
from ..measures.spacing import (median_spacing, nanmedian_rows,  # noqa: F401 (re-exported)
                                nearest_distances, neighbourhood_median)
from .region_folds import may_be_folded, unfolded
from .region_measures import (CELL_BOUND, MAX_PEAK_RADIUS, facing, fitted_peak,
                              local_noise, out_area, seen_among, seen_around, seen_under)

logger = logging.getLogger(__name__)

__all__ = ["DefectRegion", "Outliers", "RegionSearch", "find_regions", "median_spacing", "surface_spacing", "MIN_POINTS",
           "standing_wall", "steep_points",
           "LINK_FACTOR", "neighbourhood_median"]

#: Default smallest number of points of a defect region.
MIN_POINTS = 5
#: Link radius of the cluster graph in units of the spacing.
LINK_FACTOR = 2.5
#: Radius of a point's neighbourhood median (at most 9 neighbours), in spacings.
MEDIAN_RADIUS = 3.0
#: A fitted extreme whose residuals exceed twice the local noise and that falls short of its
#: centre's neighbourhood median by more than this many of the median's standard errors is no
#: peak of the data: the median is the extreme.
MEDIAN_SHORT = 3.0
#: Radius of the disc that gives a core point its area, in spacings.
AREA_RADIUS = 5.0
#: Core points standing for more than this area (in spacings^2) lie where the scan is sparse.
SPARSE_AREA = 3.0
#: The neighbour whose distance measures the density (:func:`surface_spacing`).
K_DENSITY = 8
#: Neighbours count for the spacing when their normals are within this angle (120 degrees: the
#: other side of a thin wall, about 180 degrees away, does not; an edge, 90 degrees, does).
SAME_SIDE_ANGLE = 120.0
SAME_SIDE_COS = float(np.cos(np.radians(SAME_SIDE_ANGLE)))
#: ... and when their offset lies within this angle (degrees) of the point's tangent plane.
SAME_SHEET_ELEVATION = 20.0
#: Most points the density is estimated from.
DENSITY_SUBSET = 20000
#: A layer over measured surface: in-tolerance points within this radius (spacings) of its core
#: points make at least this share of the points there.
LAYER_RADIUS = 1.5
LAYER_SHARE = 0.25
#: ... and at least this many times as many points there as around the component (in-tolerance
#: points between these distances, in spacings, from its core points: the surface alone).
LAYER_DENSITY = 1.4
LAYER_RING = (3.0, 6.0)
#: ... or at least this share of its core points lie where the in-tolerance surface is seen
#: under (or over) them (:func:`.region_measures.seen_under`).
SEEN_SHARE = 0.5
#: ... or at least this many deep-in-tolerance points, and this share of its out-of-tolerance
#: points, lie among them (:func:`.region_measures.seen_among`; a real defect holds none of its
#: surface's deep points, only the scan's stray outliers: a few per cent of its points).
AMONG_MIN = 3
AMONG_SHARE = 0.1
#: A wall standing on the part (:func:`standing_wall`): at least this many out-of-tolerance
#: points on a local sheet (from its ``WALL_K`` nearest points in space, thickness at most
#: ``WALL_THICKNESS`` of its width) more than ``WALL_ANGLE`` degrees out of the tangent plane,
#: linked down to the in-tolerance surface: no layer over the part, whatever else it holds.
WALL_MIN = 5
WALL_K = 8
WALL_THICKNESS = 0.3
WALL_ANGLE = 60.0
#: ... its neighbourhood a patch, not a line (its narrower width at least this share of its
#: wider: pairs of a doubled exposure along a row made "walls" in a reflection blob) ...
WALL_LINE = 0.2
#: ... and its lowest point at most this many spacings beyond the limit (a wall rises from the
#: limit; a reflection lifted 1 mm with a step at its rim does not).
WALL_FOOT = 0.5
#: ... and the in-tolerance surface within ``WALL_SIDE_RADIUS`` spacings of its feet on one side
#: of its foot line: on the other, at most ``WALL_SIDE_SHARE`` as many points (for most of its
#: points).
WALL_SIDE_RADIUS = 2.0
WALL_SIDE_SHARE = 0.25
#: Registration weight below which a point counts as rejected by the robust registration.
LOW_WEIGHT = 1e-3
#: Widest neighbourhood of an out-of-tolerance point looked at, in spacings (the quadratic peak
#: reaches 1.5 x region_measures.MAX_PEAK_RADIUS).
NEIGHBOURHOOD = 9.0


@dataclass(frozen=True, eq=False)
class DefectRegion:
    """One connected region that fails the part (mm, model coordinates).

    ``kind`` is ``"deviation"`` (out-of-tolerance surface, this module), ``"material"``
    (scan surface where the CAD has none, :mod:`shapeverify.inspection.material`) or
    ``"missing"`` (CAD surface the scan sees through, :mod:`shapeverify.inspection.missing`;
    ``n`` 0, ``indices`` empty, ``extreme`` NaN).
    """

    n: int
    area: float
    extreme: float
    extreme_raw: float
    centroid: np.ndarray
    extreme_point: np.ndarray
    faces: tuple
    side: str                 # 'above' (material added) or 'below' (material missing)
    indices: np.ndarray       # scan point indices
    severity: float = 0.0     # out-of-tolerance volume, mm^3
    kind: str = "deviation"
    extreme_uncertainty: float = float("nan")   # standard uncertainty of ``extreme``, mm
    n_beyond: int = 0         # of its points, beyond the evaluation distance (:mod:`.beyond`)
    area_beyond: float = 0.0  # of its area, under those points, mm^2

    def to_dict(self) -> dict:
        return {"kind": self.kind, "n": self.n, "area": self.area, "extreme": self.extreme,
                "extreme_raw": self.extreme_raw,
                "extreme_uncertainty": self.extreme_uncertainty, "severity": self.severity,
                "centroid": [float(c) for c in self.centroid],
                "extreme_point": [float(c) for c in self.extreme_point],
                "faces": [int(f) for f in self.faces], "side": self.side,
                "n_beyond": self.n_beyond, "area_beyond": self.area_beyond}

    def describe(self) -> str:
        """One line for a reason or a label, e.g. 'dent: 120 points, 95.2 mm², -0.412 mm ...'
        (lengths, areas and the point in the unit that keeps three significant digits)."""
        from ..quantities import area_text, length_text, point_text

        at = point_text(self.centroid)
        faces = ", ".join(str(f) for f in self.faces[:5]) + (" ..." if len(self.faces) > 5 else "")
        if self.kind == "missing":
            return (f"material missing where the CAD has surface (a hole or cut-out the CAD does "
                    f"not have, or a dropout of the scanner): {area_text(self.area)} seen "
                    f"through, enclosed by seen surface, around {at}"
                    + (f" on face(s) {', '.join(str(f) for f in self.faces[:5])}" if self.faces else ""))
        what = ("material where the CAD has none" if self.kind == "material" else
                "material added" if self.side == "above" else "material missing")
        dist = (f"up to {length_text(self.extreme)} from the CAD surface"
                if self.kind == "material" else f"extreme {length_text(self.extreme, signed=True)}")
        beyond = (f"; {self.n_beyond} of its points ({area_text(self.area_beyond)}) beyond the "
                  "evaluation distance, measured to the CAD but not in the statistics"
                  if self.n_beyond else "")
        return (f"{what}: {self.n} points, {area_text(self.area)}, {dist} at {at}"
                + (f" on face(s) {faces}" if faces else "") + beyond)

    def __repr__(self) -> str:
        c = self.centroid
        return (f"DefectRegion(kind={self.kind!r}, n={self.n}, area={self.area:.2f} mm², "
                f"extreme={self.extreme:+.4f} mm, severity={self.severity:.3g} mm³, "
                f"centroid=({c[0]:.2f}, {c[1]:.2f}, {c[2]:.2f}), faces={self.faces}, side={self.side!r})")


@dataclass(frozen=True, eq=False)
class Outliers:
    """Out-of-tolerance points that belong to no defect region (measurement outliers)."""

    indices: np.ndarray       # scan point indices
    low_weight: np.ndarray    # (k,) bool: the registration gave the point weight ~ 0
    n_layer: int = 0          # of them, in dense layers over in-tolerance measured surface

    @property
    def n(self) -> int:
        return int(self.indices.shape[0])

    @property
    def n_low_weight(self) -> int:
        return int(np.count_nonzero(self.low_weight))

    def to_dict(self) -> dict:
        return {"n": self.n, "n_low_weight": self.n_low_weight, "n_layer": self.n_layer}

    def __repr__(self) -> str:
        return f"Outliers(n={self.n}, low_weight={self.n_low_weight}, layer={self.n_layer})"


def surface_spacing(points: np.ndarray, seed: int = 0, normals: np.ndarray | None = None) -> float:
    """Spacing (mm) of ``points`` as surface area per point: ``sqrt(area / points)``.

    Unlike the median nearest-neighbour distance (:func:`median_spacing`), this is the same
    number for a grid, random sampling or scanner rows of the same density, and a scan holding
    two exposures of one surface 0.02 mm apart has half the area per point (not 0.02 mm).
    Estimated in a random subset of at most ``DENSITY_SUBSET`` points (a random thinning makes
    any sampling pattern look Poisson to the estimator): a first guess from the distance to the
    ``K_DENSITY``-th nearest neighbour (density ``(k - 1/3) / (pi * median r_k^2)``), refined by
    the median number of points within four such spacings, scaled back to all points.  NaN for fewer than ``K_DENSITY + 1`` points or all coincident.

    ``normals`` ((N, 3), the CAD normals at ``points``): only neighbours on the same side of the
    part count (:func:`_same_side`: normals within ``SAME_SIDE_ANGLE``, offsets within
    ``SAME_SHEET_ELEVATION`` of the tangent plane): on a wall thinner than a few spacings the
    other side's points are as near as the own side's, and the spacing read 0.76 x the true one
    on the impeller's blades (0.95-0.98 x now at 0.5-1 mm).  A convex or concave edge (normals 90 degrees apart) still counts:
    a ball around a point on an edge meets both faces over a full disc.
    """
    n = points.shape[0]
    k = K_DENSITY
    if n <= 2 * k:
        return median_spacing(None, points) if n >= 2 else float("nan")
    m = min(DENSITY_SUBSET, max(k + 1, n // 2))
    rng = np.random.default_rng(seed)
    pick = np.sort(rng.choice(n, m, replace=False)) if m < n else np.arange(n)
    sub = points[pick]
    qi = np.linspace(0, m - 1, min(m, 2000)).astype(np.int64)
    q = sub[qi]
    tree = cKDTree(sub)
    if normals is None:
        d, _ = tree.query(q, k=k + 1)
        r2 = np.median(d[:, k] ** 2)
    else:
        nn = np.asarray(normals, np.float64)[pick]
        kk = min(m, 4 * (k + 1))
        d, j = tree.query(q, k=kk)
        jj = np.minimum(j, m - 1)
        same = _same_side(nn[jj], sub[jj] - q[:, None, :], nn[qi][:, None, :], d)
        rank = np.cumsum(same, axis=1)
        hit = same & (rank == k + 1)                 # the point itself is the first
        r2 = np.median(np.where(hit.any(axis=1), d[np.arange(len(q)), np.argmax(hit, axis=1)],
                                d[:, -1]) ** 2)
    if not r2 > 0:
        return float("nan")
    # refined by counting the points within 4 such spacings (about 50): pairs of points (two
    # exposures, repeated rows) bias the k-th neighbour's distance, not the count
    radius = 4.0 * np.sqrt(np.pi * r2 / (k - 1.0 / 3.0))
    if normals is None:
        c = tree.query_ball_point(q, radius, return_length=True)
    else:
        lists = tree.query_ball_point(q, radius)
        # flattened by C iterators (a generator expression took ~0.1 s for 2,000 lists)
        lens = np.fromiter(map(len, lists), np.int64, len(lists))
        j = np.fromiter(chain.from_iterable(lists), np.int64, int(lens.sum()))
        row = np.repeat(np.arange(len(lists)), lens)
        dj = sub[j] - q[row]
        same = _same_side(nn[j], dj, nn[qi][row], np.linalg.norm(dj, axis=-1))
        c = np.bincount(row, weights=same, minlength=len(lists))
    area_per_sub = np.pi * radius ** 2 / max(float(np.median(c)) - 1.0, 1.0)
    return float(np.sqrt(area_per_sub * m / n))


def _same_side(nj, dj, ni, r):
    """Neighbours ``j`` (normals ``nj``, offsets ``dj`` from point ``i``, distances ``r``) on
    point ``i``'s side of the part: normals within ``SAME_SIDE_ANGLE`` of ``ni`` (oriented
    models: the other side of a wall faces away) and the offset within ``SAME_SHEET_ELEVATION``
    of the plane square to the mean of the two normals, ``i``'s tangent plane on a flat face
    (a model whose faces are not oriented, as IGES surfaces often are:
    the impeller's blades, about 1.2-1.7 mm thick, have the same normal on both sides: their
    other side lies 20 degrees or more out of the plane within 3.3 mm)."""
    cos = np.sum(nj * ni, axis=-1)
    # the chord between two points of one smooth sheet is square to the mean of their normals
    # (exactly so on a circle): its elevation from the plane across that mean is the test, so
    # a curved surface keeps its points however far around they lie
    m = nj + ni
    up = np.abs(np.sum(dj * m, axis=-1))
    lim = np.sin(np.radians(SAME_SHEET_ELEVATION)) * r * np.linalg.norm(m, axis=-1)
    return (cos > SAME_SIDE_COS) & (up <= lim + 1e-12 * r)


@dataclass(frozen=True)
class RegionSearch:
    """How :func:`find_regions` searches (its ``search=``): the smallest region, and what the
    caller already knows of the scan's neighbourhoods.

    Attributes
    ----------
    min_points : int
        Smallest region, as a surface area of ``min_points`` points at the scan's spacing
        (``min_points x spacing^2``): a doubled exposure needs the same area, not twice the points.
    spacing : float, optional
        The scan's spacing as area per point (mm, :func:`surface_spacing`); estimated from the
        evaluated points if None.
    tree : scipy.spatial.cKDTree, optional
        A tree of ``points[evaluated]`` the caller already built.  Otherwise one is built of
        only the evaluated points near an out-of-tolerance point: every neighbourhood looked
        at lies there, so the answers are those of the whole tree.
    """

    min_points: int = MIN_POINTS
    spacing: float | None = None
    tree: cKDTree | None = None
    #: (N,) bool: points beyond the evaluation distance taken in as evaluated
    #: (:mod:`.beyond`): counted in the regions' ``n_beyond`` and ``area_beyond``
    beyond: np.ndarray | None = None
    #: (N,) float64: the signed distance of the points beyond the evaluation distance over a face
    #: (:func:`.material.beside_surface` False; NaN for every other point): the sheet a
    #: component is a piece of continues through them (a reflection lifted 1.5-4 mm off the
    #: part comes within the evaluation distance of a face only in a few places)
    far: np.ndarray | None = None


@grouped_keywords("search", RegionSearch)
def find_regions(points: np.ndarray, values: np.ndarray, evaluated: np.ndarray,
                 within: np.ndarray, face: np.ndarray, normals: np.ndarray,
                 weights: np.ndarray | None = None, limits=None,
                 search: RegionSearch = RegionSearch()):
    """Cluster out-of-tolerance points into defect regions and measurement outliers.

    Parameters
    ----------
    points : (N, 3) float64
        Foot points of the scan points on the CAD surface (model coordinates).
    values : (N,) float64
        Signed deviations (NaN where not evaluated).
    evaluated : (N,) bool
    within : (N,) bool
        Inside the tolerance zone (ignored where not evaluated).
    face : (N,) int
    normals : (N, 3) float64
        Outward CAD normals at the foot points.
    weights : (N,) float64, optional
        Registration weights; points with weight < 1e-3 are flagged in :class:`Outliers`.
    limits : ((N,) float64, (N,) float64), optional
        Per-point lower and upper limits (mm), e.g. from :meth:`Tolerance.limits`; they decide
        which points are core points and the severity. None: just inside the smallest
        out-of-tolerance deviation on each side.
    search : RegionSearch
        ``min_points``, ``spacing`` and ``tree`` (see :class:`RegionSearch`); the loose
        keywords of these names still work, with a DeprecationWarning.

    Returns
    -------
    regions : list of DefectRegion
        Most severe first (see the module docstring).
    outliers : Outliers
    spacing : float
        The point spacing used (NaN if it could not be estimated and was not needed).
    """
    min_points, spacing, tree = search.min_points, search.spacing, search.tree
    out_idx = np.flatnonzero(evaluated & ~within)
    no_outliers = Outliers(np.zeros(0, np.int64), np.zeros(0, bool))
    if out_idx.size == 0:
        return [], no_outliers, (float("nan") if spacing is None else float(spacing))
    ev_idx = np.flatnonzero(evaluated)
    ev_pts = points[ev_idx]
    if spacing is None:
        spacing = surface_spacing(ev_pts, normals=normals[ev_idx])
    if not np.isfinite(spacing) or spacing <= 0:
        # A single evaluated point (or all coincident): nothing can be connected.
        low = _low_weight(weights, out_idx)
        return [], Outliers(out_idx, low), float(spacing)
    link = LINK_FACTOR * spacing
    r_area = AREA_RADIUS * spacing
    if tree is None:
        ev_idx, tree = _neighbourhood_tree(points, out_idx, ev_idx, ev_pts,
                                           max(NEIGHBOURHOOD, MEDIAN_RADIUS + AREA_RADIUS) * spacing)
    if limits is None:           # the tightest limits consistent with ``within``
        v_out = values[out_idx]
        hi = v_out[v_out > 0].min(initial=np.inf)
        lo = v_out[v_out <= 0].max(initial=-np.inf)
        limits = (np.full(values.shape, np.nextafter(lo, 0.0)), np.full(values.shape, np.nextafter(hi, 0.0)))
    lo_lim, hi_lim = limits

    # The candidates: evaluated points within the median's radius of an out-of-tolerance point
    # (a point farther off has no out-of-tolerance neighbour: its median cannot be beyond).
    p_out = points[out_idx]
    uniform = _uniform_limits(values, ev_idx, out_idx, lo_lim, hi_lim)
    n_out = np.empty(tree.data.shape[0], np.int64)         # (a grid: no tree of p_out)
    count_within(kernel_array(p_out), kernel_array(tree.data), float(MEDIAN_RADIUS * spacing),
                 2 if uniform else 1, n_out)
    near = n_out >= 1
    if uniform and out_idx.size >= 2:
        # a median of 3 or more values lies beyond a limit only when 2 of them do: an
        # in-tolerance point with a single out-of-tolerance point around cannot be core (the same
        # answers without the medians of the points around isolated outliers)
        near &= (n_out >= 2) | ~within[ev_idx]
    cand = np.sort(ev_idx[near])
    # (points that may be another face's pushed beyond a limit have no vote on that side)
    v_lo, v_hi = _without_folded(tree, ev_idx, values, normals, points, cand, within,
                                 lo_lim, hi_lim, spacing)
    med_lo = neighbourhood_median(tree, ev_idx, v_lo, points[cand], MEDIAN_RADIUS * spacing)
    med_hi = med_lo if v_hi is v_lo else \
        neighbourhood_median(tree, ev_idx, v_hi, points[cand], MEDIAN_RADIUS * spacing)
    with np.errstate(invalid="ignore"):
        up = med_hi > hi_lim[cand]
        down = med_lo < lo_lim[cand]
        both = up & down                  # (only where the two differ: the farther beyond)
        up[both] = (med_hi - hi_lim[cand])[both] >= (lo_lim[cand] - med_lo)[both]
        down &= ~up
    med = np.where(up, med_hi, med_lo)
    core = cand[up | down]
    core_med = med[up | down]
    core_up = up[up | down]
    # the medians of all measured values around: the extreme's centre is the core point of
    # the largest, its fallback value that median where it lies beyond the limit (else the
    # core's own)
    meas_med = rank_med = core_med
    if not (v_lo is values and v_hi is values) and core.size:
        rank_med = neighbourhood_median(tree, ev_idx, values, points[core], MEDIAN_RADIUS * spacing)
        with np.errstate(invalid="ignore"):
            beyond = np.where(core_up, rank_med > hi_lim[core], rank_med < lo_lim[core])
        meas_med = np.where(beyond, rank_med, core_med)

    regions = []
    member = np.zeros(values.shape[0], bool)
    n_layer_comp = np.zeros(0, np.int64)
    if core.size:
        pc = points[core]
        # linked where their feet are near, and where the measured points are: a dent on a
        # convex edge pushes one face's points nearer the other face, their feet jump across
        # the edge, while the dented surface itself stays connected
        sc = pc + values[core, None] * normals[core]
        pairs = np.unique(np.concatenate([cKDTree(pc).query_pairs(link, output_type="ndarray"),
                                          cKDTree(sc).query_pairs(link, output_type="ndarray")]),
                          axis=0)
        if pairs.size:
            pairs = pairs[core_up[pairs[:, 0]] == core_up[pairs[:, 1]]]
        n_comp, labels = linked_components(core.size, pairs)
        # points folded over a convex edge stand for the area where they were sampled (the
        # points the kernel counts moved back: :mod:`.region_folds`)
        around = ev_idx[np.unique(np.concatenate(
            [np.asarray(x, np.int64) for x in tree.query_ball_point(pc, r_area)]))]
        # (measured along the surface: near a sharp edge a ball holds more than a disc of it)
        u_pts, u_nrm, _, fold = unfolded(points, values, normals, ev_idx, around, spacing)
        a = area_per_point(cKDTree(u_pts[ev_idx]) if fold.any() else tree, u_pts[core], r_area,
                           _unit(u_nrm[ev_idx]), _unit(u_nrm[core]))
        # a defect is measured surface: core points where the scan is sparse (stray points
        # beside the part, in a shadow) support nothing
        dense = a <= SPARSE_AREA * spacing ** 2
        comp_area = np.bincount(labels, weights=np.where(dense, a, 0.0), minlength=n_comp)
        comp_n = np.bincount(labels, weights=dense.astype(np.float64), minlength=n_comp)
        keep = np.flatnonzero((comp_area >= min_points * spacing ** 2) & (comp_n >= min_points))
        if keep.size:
            layer = _over_measured_surface(tree, ev_idx, values, normals, points, core,
                                           core_med, core_up, labels, keep, lo_lim, hi_lim,
                                           spacing)
            sheets = []
            for k, c in enumerate(keep):
                at = labels == c
                up_c = bool(core_up[at][0])
                # its out-of-tolerance points (those the region would hold)
                side = out_idx[(values[out_idx] > 0) == up_c]
                d, _ = cKDTree(pc[at]).query(points[side], k=1, distance_upper_bound=link)
                members = side[np.isfinite(d)]
                if up_c and standing_wall(points, values, normals, ev_idx[within[ev_idx]],
                                          members, spacing, hi_lim) >= WALL_MIN:
                    layer[k] = False     # a wall rising from the surface: material, no layer
                    continue
                if not layer[k]:
                    layer[k] = seen_under(tree, ev_idx, values, normals, points, core[at],
                                          up_c, lo_lim, hi_lim, spacing) >= SEEN_SHARE
                if not layer[k]:
                    layer[k] = seen_around(tree, ev_idx, values, normals, points, members, up_c,
                                           lo_lim, hi_lim, spacing) >= SEEN_SHARE
                if not layer[k]:
                    # the surface seen among its points, however sparse there
                    among = seen_among(tree, ev_idx, values, normals, points, members, up_c,
                                       lo_lim, hi_lim, spacing)
                    layer[k] = among >= max(AMONG_MIN, AMONG_SHARE * members.size)
                if not layer[k]:
                    # the sheet it is a piece of, judged whole (both sides of the part: a
                    # reflection crosses it)
                    if not sheets:
                        sheets.append(_sheets(points, values, normals, out_idx, link, search.far,
                                              evaluated))
                    sheet = _sheet_of(sheets[0][:2], members)
                    # a sheet reaching beyond the evaluation distance: judged with all
                    # evaluated points (its far points' feet lie outside the neighbourhoods)
                    s_tree, s_ev, s_values = sheets[0][2:] if sheets[0][2] is not None and \
                        not np.isin(sheet, out_idx).all() else (tree, ev_idx, values)
                    layer[k] = sheet.size > members.size and _sheet_seen(
                        s_tree, s_ev, s_values, normals, points, sheet, lo_lim, hi_lim,
                        spacing) >= SEEN_SHARE
            n_layer_comp = keep[layer]
            keep = keep[~layer]
        if keep.size:
            # out-of-tolerance points on the same side within the link of a kept core point
            # belong to its region; the others are measurement outliers
            kept = np.isin(labels, keep)
            side_out = values[out_idx] > 0
            owner = np.full(out_idx.size, -1, np.int64)
            for up_side in (True, False):
                ks = np.flatnonzero(kept & (core_up == up_side))
                os_ = np.flatnonzero(side_out == up_side)
                if ks.size == 0 or os_.size == 0:
                    continue
                d, j = cKDTree(pc[ks]).query(p_out[os_], k=1, distance_upper_bound=link)
                ok = np.isfinite(d)
                owner[os_[ok]] = labels[ks[j[ok]]]
            for comp in keep:
                idx = out_idx[owner == comp]
                if idx.size == 0:
                    continue
                sel = labels == comp
                member[idx] = True
                regions.append(_describe(idx, core[sel], meas_med[sel], points, values, face,
                                         normals, tree, ev_idx, spacing, lo_lim, hi_lim,
                                         within, beyond=search.beyond,
                                         above=bool(core_up[sel][0]), rank=rank_med[sel]))
    small = ~member[out_idx]
    outliers = Outliers(out_idx[small], _low_weight(weights, out_idx[small]),
                        _layer_points(points, out_idx[small], values, core, labels, n_layer_comp,
                                      LINK_FACTOR * spacing) if n_layer_comp.size else 0)
    regions.sort(key=lambda r: (-r.severity, -abs(r.extreme)))
    logger.debug("regions: %d out-of-tolerance points -> %d regions, %d outliers (spacing %.3g mm)",
                 out_idx.size, len(regions), outliers.n, spacing)
    return regions, outliers, float(spacing)


def _without_folded(tree, ev_idx, values, normals, points, cand, within, lo_lim, hi_lim,
                    spacing):
    """``(below, above)``: ``values`` with NaN (no vote in the neighbourhood medians on that
    side) at the in-tolerance points around ``cand`` that may be another face's points pushed
    beyond the lower (upper) limit (:func:`.region_folds.behind_other_face`): on a dented
    convex edge the other face's points sampled within the limit of the edge have their feet
    among this face's dented points, in tolerance, and outvoted them (the wavy cube at 1/5 of
    the dent's radius, anisotropic rows along the edge: each face's out-of-tolerance part one
    row wide, a row of such feet beside it, 1 core point).  ``values`` itself where there are
    none."""
    d, j = tree.query(points[cand], k=min(9, ev_idx.size),
                      distance_upper_bound=MEDIAN_RADIUS * spacing)
    nb = ev_idx[np.unique(j[np.isfinite(d)])]
    nb = nb[within[nb]]
    out = []
    for amb in may_be_folded(tree, ev_idx, values, normals, points, nb, (lo_lim, hi_lim), spacing):
        if amb.any():
            v = values.copy()
            v[nb[amb]] = np.nan
            out.append(v)
        else:
            out.append(values)
    return tuple(out)


def _uniform_limits(values, ev_idx, out_idx, lo_lim, hi_lim) -> bool:
    """Whether every evaluated point has the same limits and the out-of-tolerance points
    ``out_idx`` are exactly those beyond them."""
    lo, hi = lo_lim[ev_idx], hi_lim[ev_idx]
    if ev_idx.size == 0 or lo.min() != lo.max() or hi.min() != hi.max():
        return False
    v = values[ev_idx]
    beyond = np.flatnonzero((v > hi[0]) | (v < lo[0]))
    return beyond.size == out_idx.size and bool(np.array_equal(ev_idx[beyond], out_idx))


def _over_measured_surface(tree, ev_idx, values, normals, points, core, med, up, labels, comps,
                           lo_lim, hi_lim, spacing) -> np.ndarray:
    """(len(comps),) bool: is the component a layer over in-tolerance measured surface (a
    reflection, a ghost of multipath, a second view misplaced)?  At each core point count the
    evaluated points within ``LAYER_RADIUS`` spacings whose deviation is deep inside the
    tolerance (at most half the limit) and at least half the core's median away from it: the
    part's surface seen *under* the out-of-tolerance points.  A component is a layer when at
    its median core point they are at least 2 and ``LAYER_SHARE`` of the points there, and
    there are ``LAYER_DENSITY`` times as many points there as on the in-tolerance surface
    around it (two layers, not a small pit whose rim is within reach).  A real defect replaces
    the surface: inside it no such points are seen, and at its rim they lie on one side only.
    The points under count only on a surface facing the way the part does
    (:func:`.region_measures.facing`: not the sheet of a convex edge's dented neighbour face,
    whose feet crowd onto a curve of this face)."""
    pc, lo, hi = points[core], lo_lim[core], hi_lim[core]
    out = np.zeros(comps.size, bool)
    sel = np.flatnonzero(np.isin(labels, comps))
    if sel.size == 0:
        return out
    r = LAYER_RADIUS * spacing
    lists = tree.query_ball_point(pc[sel], r)
    lens = np.fromiter((len(x) for x in lists), np.int64, sel.size)
    flat = ev_idx[np.concatenate([np.asarray(x, np.int64) for x in lists])] if lens.sum() else \
        np.zeros(0, np.int64)
    row = np.repeat(np.arange(sel.size), lens)
    v = values[flat]
    m = med[sel][row]
    lim = np.where(up[sel], hi[sel], lo[sel])[row]
    lower = (np.abs(v) <= 0.5 * np.abs(lim)) & (np.abs(v - m) > 0.5 * np.abs(m))
    for side, lim_all in ((True, hi_lim), (False, lo_lim)):
        at = lower & (up[sel][row] == side)
        if at.any():
            cand, inv = np.unique(flat[at], return_inverse=True)
            lower[at] = facing(tree, ev_idx, values, normals, points, cand, lim_all,
                               spacing)[inv]
    n_lower = np.bincount(row, weights=lower.astype(np.float64), minlength=sel.size)
    # the share of the points there (the density of a thin part's two sides or of a ghost
    # over it is not the scan's spacing)
    share = n_lower / np.maximum(lens, 1)
    all_pts = tree.data
    for k, c in enumerate(comps):
        at = labels[sel] == c
        if not (np.median(share[at]) >= LAYER_SHARE and np.median(n_lower[at]) >= 2):
            continue
        # and two layers: denser there than the surface around (a small sharp pit has its
        # rim's good surface within reach of its core points too, but one layer)
        pc_c = pc[sel[at]]
        ring = np.flatnonzero(np.isfinite(cKDTree(pc_c).query(
            all_pts, k=1, distance_upper_bound=LAYER_RING[1] * spacing)[0]))
        if ring.size:
            dr, _ = cKDTree(pc_c).query(all_pts[ring], k=1)
            lim_c = np.abs(np.where(up[sel[at]], hi[sel[at]], lo[sel[at]])).min()
            ring = ring[(dr > LAYER_RING[0] * spacing) & (np.abs(values[ev_idx[ring]]) <= 0.5 * lim_c)]
        if ring.size < 3:
            continue
        base = tree.query_ball_point(all_pts[ring], r, return_length=True)
        out[k] = np.median(lens[at]) >= LAYER_DENSITY * np.median(base)
    return out


def steep_points(X: np.ndarray, normals: np.ndarray, spacing: float, sheet_normals=False):
    """(n,) bool: which of the points ``X`` (in space; ``normals`` the CAD normals at their
    foot points) lie on a thin local sheet more than ``WALL_ANGLE`` degrees out of the CAD's
    tangent plane -- a wall standing on the part, whose feet crowd onto its foot line.  The
    local sheet is the plane of the ``WALL_K`` nearest points (all within ``LINK_FACTOR x s``),
    its thickness at most ``WALL_THICKNESS`` of its width.  ``sheet_normals``: also return the
    local sheets' normals ((n, 3), zero where there is none)."""
    steep = np.zeros(X.shape[0], bool)
    v = np.zeros(X.shape)
    done = (lambda: (steep, v)) if sheet_normals else (lambda: steep)
    if X.shape[0] < WALL_K:
        return done()
    d, j = cKDTree(X).query(X, k=WALL_K)
    ok = np.flatnonzero(np.isfinite(d).all(axis=1) & (d[:, -1] <= LINK_FACTOR * spacing))
    if ok.size == 0:
        return done()
    Y = X[j[ok]]
    Y = Y - Y.mean(axis=1, keepdims=True)
    lam, vec = np.linalg.eigh(np.einsum("nki,nkj->nij", Y, Y) / WALL_K)
    thin = ((np.sqrt(np.maximum(lam[:, 0], 0.0) / np.maximum(lam[:, 1], 1e-300)) <= WALL_THICKNESS)
            & (np.sqrt(np.maximum(lam[:, 1], 0.0) / np.maximum(lam[:, 2], 1e-300)) >= WALL_LINE))
    tilt = np.abs(np.einsum("ij,ij->i", vec[:, :, 0], normals[ok]))
    steep[ok] = thin & (tilt <= np.cos(np.radians(WALL_ANGLE)))
    v[ok] = vec[:, :, 0]
    return done()


def standing_wall(points, values, normals, good, members, spacing, limit) -> int:
    """How many of a component's out-of-tolerance points ``members`` (scan indices, one side;
    ``points`` the foot points, ``values`` the signed deviations) lie on a steep wall that
    rises from the part's in-tolerance surface (``good``: scan indices of in-tolerance points
    around; ``limit``: (N,) the limit on the members' side).

    In space (at the scan points, ``foot + d x normal``) a wall standing on the part -- the side
    of an object lying on a panel, of a boss, of a rib -- is a thin sheet steeper than
    ``WALL_ANGLE`` degrees (:func:`steep_points`) whose foot is continuous with the part's
    measured surface: linked within ``LINK_FACTOR x s`` down to in-tolerance points, its lowest
    point at most ``WALL_FOOT x s`` beyond the limit.  Its feet
    crowd onto its foot line right beside the part's in-tolerance points, so the rules for
    layers read it as a layer *over* measured surface (the box on the panel at 0.5 mm seed 5:
    all four walls' points became outliers and the part passed).  A reflection, a ghost or a
    second view lies over the surface, about parallel to it, and floats above it without a
    wall down to it.  Only walls rising *from* the part count (the regions above it): a
    reflection crossing an impeller blade's tip read as a 13-point 'wall' 0.3 mm into it."""
    members = np.asarray(members, np.int64)
    good = np.asarray(good, np.int64)
    if members.size < WALL_MIN or good.size == 0:
        return 0
    X = points[members] + values[members, None] * normals[members]
    steep, v = steep_points(X, normals[members], spacing, sheet_normals=True)
    si = np.flatnonzero(steep)
    if si.size < WALL_MIN:
        return 0
    link = LINK_FACTOR * spacing
    G = points[good] + values[good, None] * normals[good]
    lo, hi = X[si].min(axis=0) - link, X[si].max(axis=0) + link
    box = np.all((G >= lo) & (G <= hi), axis=1)
    G, gf = G[box], points[good[box]]
    if G.shape[0] == 0:
        return 0
    dg, _ = cKDTree(G).query(X[si], k=1, distance_upper_bound=link)
    pairs = cKDTree(X[si]).query_pairs(link, output_type="ndarray")
    n_comp, lab = linked_components(si.size, pairs)
    foot = np.zeros(n_comp, bool)
    foot[lab[np.isfinite(dg)]] = True
    excess = np.abs(values[members[si]]) - np.abs(limit[members[si]])
    low = np.full(n_comp, np.inf)
    np.minimum.at(low, lab, excess)
    foot &= low <= WALL_FOOT * spacing
    # it stands on the part: the in-tolerance surface lies on one side of its foot line only
    # (an object hides the part under it); a reflection crossing the part (a blade's tip) has
    # the part's surface measured on both sides of where it crosses
    r = WALL_SIDE_RADIUS * spacing
    lists = cKDTree(gf).query_ball_point(points[members[si]], r)
    lens = np.fromiter((len(x) for x in lists), np.int64, si.size)
    if lens.sum():
        flat = np.concatenate([np.asarray(x, np.int64) for x in lists if len(x)])
        row = np.repeat(np.arange(si.size), lens)
        t = np.einsum("ij,ij->i", gf[flat] - points[members[si]][row], v[si][row])
        npos = np.bincount(row, weights=(t > 0.5 * spacing).astype(float), minlength=si.size)
        nneg = np.bincount(row, weights=(t < -0.5 * spacing).astype(float), minlength=si.size)
        two = np.minimum(npos, nneg) > WALL_SIDE_SHARE * np.maximum(npos, nneg)
        n_two = np.bincount(lab, weights=two.astype(float), minlength=n_comp)
        foot &= n_two <= 0.5 * np.bincount(lab, minlength=n_comp)
    return int(np.count_nonzero(foot[lab]))


def _sheets(points, values, normals, side, link, far=None, evaluated=None):
    """``(side, labels, tree, ev_idx, values)``: the out-of-tolerance points ``side`` (scan
    indices) and the points beyond the evaluation distance over a face (``far``: their signed
    distances, NaN elsewhere; :class:`RegionSearch`) linked in space -- at the scan points,
    ``foot + d x normal`` -- within ``link``.  With such points, ``tree`` and ``ev_idx`` are of
    all evaluated points (a sheet reaches farther than the out-of-tolerance points'
    neighbourhoods) and ``values`` holds the far points' distances; else None."""
    extra = None
    if far is not None:
        far = np.asarray(far, np.float64)
        fi = np.flatnonzero(np.isfinite(far))
        if fi.size:
            values = np.array(values, np.float64)
            values[fi] = far[fi]
            side = np.concatenate([side, fi])
            ev_all = np.flatnonzero(evaluated)
            extra = (cKDTree(points[ev_all]), ev_all, values)
    X = points[side] + values[side, None] * normals[side]
    pairs = cKDTree(X).query_pairs(link, output_type="ndarray")
    return (side, linked_components(side.size, pairs)[1]) + (extra or (None, None, None))


def _sheet_seen(tree, ev_idx, values, normals, points, sheet, lo_lim, hi_lim, spacing) -> float:
    """:func:`.region_measures.seen_around` of a sheet's out-of-tolerance points, each side of
    the part on its own, weighted by their numbers."""
    share, n = 0.0, 0
    for up in (True, False):
        part = sheet[(values[sheet] > 0) == up]
        if part.size:
            share += part.size * seen_around(tree, ev_idx, values, normals, points, part, up,
                                             lo_lim, hi_lim, spacing)
            n += part.size
    return share / max(n, 1)


def _sheet_of(sheets, members):
    """The out-of-tolerance points of the sheets (:func:`_sheets`) that hold ``members``."""
    side, labels = sheets
    at = np.isin(side, members)
    return side[np.isin(labels, np.unique(labels[at]))]


def _layer_points(points, idx, values, core, labels, comps, link) -> int:
    """How many of the out-of-tolerance points ``idx`` lie within ``link`` of a core point of
    the layer components ``comps``."""
    sel = np.isin(labels, comps)
    if not sel.any() or idx.size == 0:
        return 0
    d, _ = cKDTree(points[core[sel]]).query(points[idx], k=1, distance_upper_bound=link)
    return int(np.count_nonzero(np.isfinite(d)))


def area_per_point(tree: cKDTree, p: np.ndarray, radius: float, tree_normals=None,
                   p_normals=None) -> np.ndarray:
    """Surface area (mm^2) each of the points ``p`` stands for among the points of ``tree``.

    The density is a smooth kernel sum, ``w(d) = (1 - d^2/R^2)^2`` over the points within ``R``
    (whose integral over the disc is ``pi R^2 / 3``): a hard count in a disc of a few spacings
    jumps by a ring of lattice points as ``R`` or the lattice shifts (the area of one dent read
    300-390 mm^2 on the same scan written once, twice, or twice 0.02 mm apart).  The point
    itself counts half (a lattice point has itself in its disc, a random sample one more).

    With the CAD normals (``tree_normals`` (len(tree.data), 3) and ``p_normals`` (len(p), 3),
    unit) ``d`` is measured along the surface (:func:`..measures._grid_kernels.kernel_sums_unfolded`:
    the two tangent planes unfolded about the line where they meet), so the disc is a disc of
    the surface: near a sharp edge a ball of radius ``R`` also holds the other face's points
    within ``R`` in space, ``sqrt(u^2 + v^2)`` (``u``, ``v`` their distances from the edge)
    instead of ``u + v`` along the surface, and a point ``R/2`` from a 90 degree edge stood for
    0.7-0.8 of its area (a dent on the wavy cube's edge at 1/5 of its radius: too little
    support, no region).  On a smooth surface the two differ by ``O(d^4 / rho^2)``; points whose
    normals are more than ``SAME_SIDE_ANGLE`` apart (the other side of a thin wall) keep the
    distance in space, as without normals.
    """
    s = np.empty(p.shape[0])
    if p.shape[0] and tree_normals is not None:
        kernel_sums_unfolded(kernel_array(tree.data), kernel_array(tree_normals), kernel_array(p),
                             kernel_array(p_normals), float(radius), SAME_SIDE_COS, s)
    elif p.shape[0]:
        kernel_sums(kernel_array(tree.data), kernel_array(p), float(radius), s)
    s -= 0.5
    return (np.pi * radius ** 2 / 3.0) / np.maximum(s, 0.5)


def _unit(v):
    """Rows of ``v`` scaled to unit length (zero rows stay zero)."""
    v = np.asarray(v, np.float64)
    return v / np.maximum(np.linalg.norm(v, axis=1), 1e-300)[:, None]


def _neighbourhood_tree(points, out_idx, ev_idx, ev_pts, reach):
    """``(ev_idx[near], tree of ev_pts[near])``: the evaluated points within ``reach`` of an
    out-of-tolerance point (a little more: the grid test is strict, the ball queries are not)."""
    near = np.empty(ev_pts.shape[0], bool)
    ev_k, out_k = kernel_array(ev_pts), kernel_array(points[out_idx])
    r = float(reach) * (1.0 + 1e-6)
    lo, hi = bounds(ev_k)
    o_lo, o_hi = bounds(out_k)
    box = np.prod(np.maximum(hi - lo, r)) if ev_k.shape[0] else 0.0
    if np.prod(np.maximum(np.minimum(o_hi + r, hi) - np.maximum(o_lo - r, lo), r)) < 0.25 * box:
        # out-of-tolerance points in a corner of the scan (a dent): a grid of them asked by
        # every evaluated point, without sorting all evaluated points into a grid
        any_within(out_k, ev_k, r, near)
    else:             # spread over the scan (outliers): each marks the evaluated points around it
        mark_within(ev_k, out_k, r, near)
    keep = np.flatnonzero(near)
    return ev_idx[keep], cKDTree(ev_pts[keep], balanced_tree=False, compact_nodes=False)


_nanmedian_rows = nanmedian_rows      # its earlier name (tests/test_inspect_fast_paths.py)


def _low_weight(weights, idx):
    if weights is None:
        return np.zeros(idx.shape[0], bool)
    return np.asarray(weights)[idx] < LOW_WEIGHT


def _describe(idx, core, med, points, values, face, normals, tree, ev_idx, spacing,
              lo_lim, hi_lim, within, beyond=None, above=None, rank=None) -> DefectRegion:
    """Size, area, severity, extreme and position of one region: its out-of-tolerance points
    (scan indices ``idx``) and its core points ``core`` with their neighbourhood medians
    ``med`` (:mod:`.region_measures` measures the area and the extreme).  ``beyond`` ((N,)
    bool): the points beyond the evaluation distance (:mod:`.beyond`), counted in ``n_beyond``
    and ``area_beyond``; ``above``: the region's side (None: the sign of ``med[0]``);
    ``rank``: the medians that choose the extreme's centre (None: ``med``)."""
    above = bool(med[0] > 0) if above is None else bool(above)
    v = values[idx]
    r_area = AREA_RADIUS * spacing
    sparse = SPARSE_AREA * spacing ** 2
    a = area_per_point(tree, points[idx], r_area)
    a = np.where(a <= sparse, a, 0.0)     # stray points stand for no area
    severity = float(np.sum(a * np.maximum(np.abs(v) - np.abs(hi_lim[idx] if above else lo_lim[idx]),
                                            0.0)))
    extreme_raw = float(v[int(np.argmax(np.abs(v)))])
    limit = hi_lim[core] if above else lo_lim[core]

    # the area: the out-of-tolerance part of the cells of the region's points and of their
    # in-tolerance neighbours (the boundary runs between them)
    nb = tree.query_ball_point(points[idx], 2.0 * CELL_BOUND * spacing)
    nb = np.unique(ev_idx[np.concatenate([np.asarray(x, np.int64) for x in nb])])
    q = np.union1d(idx, nb[within[nb]])
    g = np.full(values.shape[0], np.nan)
    g[ev_idx] = (values[ev_idx] - hi_lim[ev_idx]) if above else (lo_lim[ev_idx] - values[ev_idx])
    # points folded over a convex edge (their feet gather on a curve of the other face) are
    # measured where they were sampled (:mod:`.region_folds`)
    u_pts, u_nrm, u_val, fold = unfolded(points, values, normals, ev_idx, q, spacing)
    u_tree = cKDTree(u_pts[ev_idx]) if fold.any() else tree
    part, cell = out_area(u_tree, ev_idx, u_pts, u_nrm, g, q, spacing, values=u_val, above=above)
    part = np.where(cell <= 2.0 * sparse, part, 0.0)    # a point in a gap stands for no area
    area = float(np.sum(part))

    # the extreme: the fitted peak of the local surface around the worst core point
    k = int(np.argmax(np.abs(med if rank is None else rank)))
    extreme, uncertainty, at = float(med[k]), float("nan"), points[core[k]].copy()
    # the region's half-width there: the nearest in-tolerance point (a groove's is its
    # half-width, a round dent's its radius; the fit's window is a third of it)
    near = np.asarray(tree.query_ball_point(points[core[k]], np.sqrt(area / np.pi) + spacing),
                      np.int64)
    near = near[within[ev_idx[near]]]
    half = float(np.min(np.linalg.norm(tree.data[near] - points[core[k]], axis=1))) \
        if near.size else np.sqrt(area / np.pi)
    peak = fitted_peak(points[core[k]], normals[core[k]], tree, ev_idx, points, values, spacing,
                       area, half_width=half)
    if peak is not None and (peak[0] > limit[k] if above else peak[0] < limit[k]):
        extreme, uncertainty, at, se, sigma = peak
        noise = local_noise(tree, ev_idx, values, points[core[k]],
                            MAX_PEAK_RADIUS * spacing)
        if abs(extreme) > abs(extreme_raw) + (2.0 * se if sigma <= 2.0 * noise else 0.0):
            # the data do not support a peak so far beyond every measured value
            uncertainty = abs(extreme) - abs(extreme_raw)
            extreme, at = extreme_raw, points[idx[int(np.argmax(np.abs(v)))]].copy()
        elif sigma > 2.0 * noise and abs(extreme) < abs(med[k]) - MEDIAN_SHORT * \
                _median_uncertainty(tree, ev_idx, values, points[core[k]], spacing):
            # nor, when it does not fit the data, so far short of the median of the measured
            # values around its centre (a quadratic fitted over an object's flat top and its
            # walls next to it dipped to 1.87 mm for a 3 mm box: its worst core point, anywhere
            # on the top, lay near a corner): the median is a measured lower bound of the
            # extreme.  (A fit that does fit stays: the largest of many medians of a smooth
            # dent's floor is biased by their noise, +2..4 % at 1/50 of the dent's radius.)
            extreme, uncertainty, at = float(med[k]), float("nan"), points[core[k]].copy()
    if not np.isfinite(uncertainty):        # the neighbourhood median: its standard error
        uncertainty = _median_uncertainty(tree, ev_idx, values, points[core[k]], spacing)
    w = part if part.sum() > 0 else np.ones_like(part)
    centroid = (w[:, None] * points[q]).sum(axis=0) / w.sum()
    return DefectRegion(
        n=int(idx.size), area=area, extreme=float(extreme), extreme_raw=extreme_raw,
        centroid=centroid, extreme_point=at,
        faces=tuple(int(f) for f in np.unique(face[idx])),
        side="above" if above else "below", indices=idx, severity=severity,
        extreme_uncertainty=float(uncertainty),
        n_beyond=0 if beyond is None else int(np.count_nonzero(beyond[idx])),
        area_beyond=0.0 if beyond is None else float(np.sum(part[beyond[q]])))


def _median_uncertainty(tree, ev_idx, values, p, spacing) -> float:
    """Standard error of a neighbourhood median (:func:`neighbourhood_median`) at ``p``:
    ``1.2533 x`` the robust sigma of its values over the root of their number."""
    d, j = tree.query(p, k=min(9, ev_idx.size), distance_upper_bound=MEDIAN_RADIUS * spacing)
    j = np.atleast_1d(j)[np.isfinite(np.atleast_1d(d))]
    if j.size < 3:
        return float("nan")
    x = values[ev_idx[j]]
    return float(1.2533 * 1.4826 * np.median(np.abs(x - np.median(x))) / np.sqrt(j.size))
