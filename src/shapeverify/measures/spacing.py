"""A point cloud's spacing and the neighbourhood median of deviations.

A leaf (:mod:`shapeverify.measures`): the inspection's regions (:mod:`shapeverify.inspection.regions`,
which re-exports these names) and the characteristics' neighbourhood support
(:mod:`shapeverify.characteristics.support`) both use them.

* :func:`median_spacing` -- the median nearest-neighbour distance (a grid search,
  :func:`nearest_distances`, or a k-d tree's);
* :func:`neighbourhood_median` -- the median deviation of the nearest evaluated points;
* :func:`nanmedian_rows` -- ``np.nanmedian(a, axis=1)`` bit for bit, faster on short rows.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .._arrays import bounds
from ._grid_kernels import kernel_array, nearest_other

if TYPE_CHECKING:
    from scipy.spatial import cKDTree

__all__ = ["median_spacing", "nearest_distances", "neighbourhood_median", "nanmedian_rows",
           "neighbour_noise"]


def median_spacing(tree: cKDTree | None, points: np.ndarray, max_samples: int = 1500) -> float:
    """Median nearest-neighbour distance of ``points`` (evenly subsampled to ``max_samples``).

    ``tree``: a k-d tree of ``points``, or None: the distances are found on a grid
    (:func:`nearest_distances`, the same numbers without building a tree)."""
    if points.shape[0] < 2:
        return float("nan")
    step = max(1, points.shape[0] // max_samples)
    if tree is None:
        d = nearest_distances(points, np.arange(0, points.shape[0], step))
    else:
        d, _ = tree.query(points[::step], k=2)
        d = d[:, 1]
    d = d[np.isfinite(d) & (d > 0)]
    return float(np.median(d)) if d.size else float("nan")


def nearest_distances(points: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Distance (mm) from each ``points[idx]`` to its nearest other point of ``points`` (0 for a
    duplicate); ``points`` (N, 3) with N >= 2.  Equal to ``cKDTree(points).query(points[idx],
    k=2)[0][:, 1]``: a grid search (:func:`._grid_kernels.nearest_other`) whose cells start at
    three times the spacing a surface of the points' extent would have and grow fourfold for
    the points it leaves undecided (isolated points), until the grid is one cell."""
    pts = kernel_array(points)
    idx = kernel_array(idx, np.int64)
    out = np.empty(idx.shape[0])
    lo, hi = bounds(pts)
    ext = np.sort(hi - lo)
    diag = float(np.linalg.norm(ext))
    if not diag > 0:
        return np.zeros(idx.shape[0])
    area = ext[2] * ext[1] if ext[1] > 0 else ext[2] * ext[2]
    h = max(3.0 * float(np.sqrt(area / pts.shape[0])), 1e-9 * diag)
    todo = np.arange(idx.shape[0])
    while True:
        part = np.empty(todo.shape[0])
        nearest_other(pts, idx[todo], h, part)
        out[todo] = part
        todo = todo[part < 0]
        if todo.size == 0:
            return out
        h *= 4.0


def neighbourhood_median(tree, ev_idx, values, p, radius, k: int = 9) -> np.ndarray:
    """Median deviation of the (up to) ``k`` nearest evaluated points within ``radius`` of each
    row of ``p`` (itself included when ``p`` are evaluated foot points); the point's own nearest
    value when fewer than 3 neighbours are found."""
    kk = min(k, ev_idx.size)
    d, j = tree.query(p, k=kk, distance_upper_bound=radius)
    d = d.reshape(len(p), kk)
    j = j.reshape(len(p), kk)
    ok = np.isfinite(d)
    v = np.where(ok, values[ev_idx[np.minimum(j, ev_idx.size - 1)]], np.nan)
    return nanmedian_rows(np.where(ok.sum(axis=1, keepdims=True) >= 3, v, v[:, :1]))


def nanmedian_rows(a: np.ndarray) -> np.ndarray:
    """``np.nanmedian(a, axis=1)`` of a (m, k) array, bit for bit (the mean of the two middle
    values of each row's sorted non-NaN values, NaN for an all-NaN row), without the masked
    arrays numpy uses for short rows (ten times slower)."""
    srt = np.sort(a, axis=1)                       # NaN sorts last
    c = a.shape[1] - np.count_nonzero(np.isnan(a), axis=1)
    h = c // 2
    lo = np.where(c % 2 == 1, h, h - 1)
    rows = np.arange(a.shape[0])
    with np.errstate(invalid="ignore"):
        med = (srt[rows, np.maximum(lo, 0)] + srt[rows, np.minimum(h, a.shape[1] - 1)]) / 2.0
    med[c == 0] = np.nan
    return med


def neighbour_noise(p: np.ndarray, v: np.ndarray) -> float:
    """Noise sigma (mm) of values ``v`` at points ``p`` ((n, 3), n >= 2): ``1.4826 median
    |v_i - v_j| / sqrt 2`` over each point and its nearest neighbour (the form cancels in a
    neighbour's difference; a step between a few pairs does not move the median)."""
    from shapeverify._lazy import cKDTree

    _, j = cKDTree(p).query(p, k=2)
    return float(1.4826 * np.median(np.abs(v - v[j[:, 1]])) / np.sqrt(2.0))
