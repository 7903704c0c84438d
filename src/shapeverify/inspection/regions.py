"""Defect regions: connected clusters of out-of-tolerance scan points.

All neighbourhoods here are taken between *foot points* (the scan points projected onto the CAD
surface): a spike 1 mm off the surface still has its neighbours around it.
Out-of-tolerance points are linked when their foot points on the CAD surface are closer than
``radius = 2.5 x`` the scan's median point spacing and they deviate to the same side (above the
upper limit / below the lower limit); the connected components of that radius graph
(``scipy.spatial.cKDTree.query_pairs`` + ``scipy.sparse.csgraph.connected_components``) are the
candidate regions.

A cluster with fewer than ``min_points`` points (default 5) is *not* a defect but a group of
**measurement outliers**: a single spike (typically a point the registration gave weight ~ 0)
or a pair of them cannot be told apart from scanner noise, reflections or dust at the scan's
density.  Raise ``min_points`` for noisy scanners; lower it for sparse scans.

For each region:

* ``n``: number of points; ``area``: sum over its points of the local surface area per point,
  ``pi r^2 / (number of evaluated scan points within r)`` with ``r = 2 x spacing`` (mm^2);
* ``extreme``: the extreme signed deviation, estimated robustly: the point of largest
  neighbourhood-median |deviation| is located, then a quadratic ``d(x, y)`` is fitted by
  least squares (with 3-sigma spike rejection) to the deviations within ``4 x spacing`` in the
  tangent plane there and its extremum (or its value at the point) is taken.  This averages out scanner noise that would bias
  the single largest value outwards; ``extreme_raw`` is that single largest measured value;
* ``centroid``: mean of its foot points (model coordinates, mm); ``extreme_point``: where the
  extreme is, on the CAD surface's tangent plane; ``faces``: CAD faces it touches.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

logger = logging.getLogger(__name__)

__all__ = ["DefectRegion", "Outliers", "find_regions", "median_spacing", "MIN_POINTS",
           "LINK_FACTOR"]

#: Default smallest number of points of a defect region.
MIN_POINTS = 5
#: Link radius of the cluster graph in units of the median point spacing.
LINK_FACTOR = 2.5
#: Registration weight below which a point counts as rejected by the robust registration.
LOW_WEIGHT = 1e-3


@dataclass(frozen=True, eq=False)
class DefectRegion:
    """One connected out-of-tolerance region (mm, model coordinates)."""

    n: int
    area: float
    extreme: float
    extreme_raw: float
    centroid: np.ndarray
    extreme_point: np.ndarray
    faces: tuple
    side: str                 # 'above' (material added) or 'below' (material missing)
    indices: np.ndarray       # scan point indices

    def to_dict(self) -> dict:
        return {"n": self.n, "area": self.area, "extreme": self.extreme,
                "extreme_raw": self.extreme_raw, "centroid": [float(c) for c in self.centroid],
                "extreme_point": [float(c) for c in self.extreme_point],
                "faces": [int(f) for f in self.faces], "side": self.side}

    def __repr__(self) -> str:
        c = self.centroid
        return (f"DefectRegion(n={self.n}, area={self.area:.2f} mm², extreme={self.extreme:+.4f} mm, "
                f"centroid=({c[0]:.2f}, {c[1]:.2f}, {c[2]:.2f}), faces={self.faces}, side={self.side!r})")


@dataclass(frozen=True, eq=False)
class Outliers:
    """Out-of-tolerance points that belong to no defect region (measurement outliers)."""

    indices: np.ndarray       # scan point indices
    low_weight: np.ndarray    # (k,) bool: the registration gave the point weight ~ 0

    @property
    def n(self) -> int:
        return int(self.indices.shape[0])

    @property
    def n_low_weight(self) -> int:
        return int(np.count_nonzero(self.low_weight))

    def to_dict(self) -> dict:
        return {"n": self.n, "n_low_weight": self.n_low_weight}

    def __repr__(self) -> str:
        return f"Outliers(n={self.n}, low_weight={self.n_low_weight})"


def median_spacing(tree: cKDTree, points: np.ndarray, max_samples: int = 1500) -> float:
    """Median nearest-neighbour distance of ``points`` (evenly subsampled to ``max_samples``)."""
    if points.shape[0] < 2:
        return float("nan")
    step = max(1, points.shape[0] // max_samples)
    d, _ = tree.query(points[::step], k=2)
    d = d[:, 1]
    d = d[np.isfinite(d) & (d > 0)]
    return float(np.median(d)) if d.size else float("nan")


def find_regions(points: np.ndarray, values: np.ndarray, evaluated: np.ndarray,
                 within: np.ndarray, face: np.ndarray, normals: np.ndarray,
                 weights: np.ndarray | None = None, min_points: int = MIN_POINTS,
                 spacing: float | None = None):
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
    min_points : int
        Smallest cluster that counts as a defect region.
    spacing : float, optional
        Median point spacing (mm); estimated from the evaluated points if None.

    Returns
    -------
    regions : list of DefectRegion
        Sorted by |extreme|, largest first.
    outliers : Outliers
    spacing : float
        The point spacing used (NaN if it could not be estimated and was not needed).
    """
    out_idx = np.flatnonzero(evaluated & ~within)
    no_outliers = Outliers(np.zeros(0, np.int64), np.zeros(0, bool))
    if out_idx.size == 0:
        return [], no_outliers, (float("nan") if spacing is None else float(spacing))
    ev_idx = np.flatnonzero(evaluated)
    ev_pts = points[ev_idx]
    tree = cKDTree(ev_pts, balanced_tree=False, compact_nodes=False)   # faster to build
    if spacing is None:
        spacing = median_spacing(tree, ev_pts)
    if not np.isfinite(spacing) or spacing <= 0:
        # A single evaluated point (or all coincident): nothing can be connected.
        low = _low_weight(weights, out_idx)
        return [], Outliers(out_idx, low), float(spacing)

    radius = LINK_FACTOR * spacing
    p_out = points[out_idx]
    above = values[out_idx] > 0
    pairs = cKDTree(p_out).query_pairs(radius, output_type="ndarray")
    if pairs.size:
        pairs = pairs[above[pairs[:, 0]] == above[pairs[:, 1]]]
    m = out_idx.size
    graph = coo_matrix((np.ones(pairs.shape[0], np.int8), (pairs[:, 0], pairs[:, 1])), shape=(m, m))
    n_comp, labels = connected_components(graph, directed=False)
    sizes = np.bincount(labels, minlength=n_comp)

    small = sizes[labels] < min_points
    outliers = Outliers(out_idx[small], _low_weight(weights, out_idx[small]))

    regions = []
    r_area = 2.0 * spacing
    for comp in np.flatnonzero(sizes >= min_points):
        idx = out_idx[labels == comp]
        regions.append(_describe(idx, points, values, face, normals, tree, ev_idx, spacing, r_area))
    regions.sort(key=lambda r: -abs(r.extreme))
    logger.debug("regions: %d out-of-tolerance points -> %d regions, %d outliers (spacing %.3g mm)",
                 out_idx.size, len(regions), outliers.n, spacing)
    return regions, outliers, float(spacing)


def _low_weight(weights, idx):
    if weights is None:
        return np.zeros(idx.shape[0], bool)
    return np.asarray(weights)[idx] < LOW_WEIGHT


def _describe(idx, points, values, face, normals, tree, ev_idx, spacing, r_area) -> DefectRegion:
    """Size, area, robust extreme and position of one region (scan indices ``idx``)."""
    p = points[idx]
    v = values[idx]
    counts = tree.query_ball_point(p, r_area, return_length=True)
    area = float(np.sum(np.pi * r_area ** 2 / np.maximum(counts, 1)))
    k_raw = int(np.argmax(np.abs(v)))
    extreme_raw = float(v[k_raw])

    # Locate the extreme on neighbourhood medians (robust to spikes) among the most extreme points.
    cand = np.flatnonzero(np.abs(v) >= np.quantile(np.abs(v), 0.8))
    if cand.size > 400:
        cand = cand[np.argsort(-np.abs(v[cand]))[:400]]
    ev_values = values[ev_idx]
    nbrs = tree.query_ball_point(p[cand], 2.0 * spacing, return_sorted=False)
    med = np.array([np.median(ev_values[nb]) if len(nb) >= 5 else 0.0 for nb in nbrs])
    k = int(cand[np.argmax(np.abs(med))])
    extreme, at = _quadratic_peak(points[idx[k]], normals[idx[k]], tree, ev_idx, points, values,
                                  4.0 * spacing, float(med[np.argmax(np.abs(med))]))
    return DefectRegion(
        n=int(idx.size), area=area, extreme=extreme, extreme_raw=extreme_raw,
        centroid=p.mean(axis=0), extreme_point=at,
        faces=tuple(int(f) for f in np.unique(face[idx])),
        side="above" if extreme_raw > 0 else "below", indices=idx)


def _quadratic_peak(center, normal, tree, ev_idx, points, values, radius, fallback):
    """Extremum of a least-squares quadratic of the deviations around ``center``.

    Returns ``(value, position)``; falls back to ``(fallback, center)`` with too few neighbours.
    """
    nb = ev_idx[tree.query_ball_point(center, radius)]
    if nb.size < 12:
        return fallback, center.copy()
    n = normal / (np.linalg.norm(normal) or 1.0)
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(n, a)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    d = points[nb] - center
    x, y = d @ e1, d @ e2
    A = np.column_stack([np.ones_like(x), x, y, x * x, x * y, y * y])
    b = values[nb]
    keep = np.ones(b.size, bool)
    for _ in range(3):                     # drop spikes: residuals beyond 3 robust sigmas
        c, *_ = np.linalg.lstsq(A[keep], b[keep], rcond=None)
        res = b - A @ c
        scale = 1.4826 * np.median(np.abs(res[keep])) + 1e-12
        new = np.abs(res) <= 3.0 * scale
        if new.sum() < 12 or np.array_equal(new, keep):
            break
        keep = new
    H = np.array([[2 * c[3], c[4]], [c[4], 2 * c[5]]])
    value, xy = float(c[0]), np.zeros(2)
    det = np.linalg.det(H)
    if det > 0 and np.sign(H[0, 0]) == -np.sign(c[0]):      # an extremum of the dent's/bump's sign
        s = np.linalg.solve(H, -c[1:3])
        if np.hypot(*s) <= 0.5 * radius:
            xy = s
            value = float(c[0] + c[1] * s[0] + c[2] * s[1] + c[3] * s[0] ** 2
                          + c[4] * s[0] * s[1] + c[5] * s[1] ** 2)
    return value, center + xy[0] * e1 + xy[1] * e2
