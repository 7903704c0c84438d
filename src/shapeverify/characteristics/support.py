"""Which scan points a characteristic may use: the neighbourhood-support rule for outliers.

A characteristic's value is a measurement of the points it keeps, so the points it leaves out
must be left out for a reason that is not their distance against the limit (a cut-off at the
limit makes the value the cut-off: ``2 x 0.05 = 0.099998`` for a profile whose points reach
0.1 mm).  The rule is the inspection's own (:mod:`shapeverify.inspection.regions`): a deviation
counts when its neighbourhood supports it.  For every evaluated point ``i`` let ``med_i`` be the
median deviation of its (up to) 9 nearest evaluated foot points within 3 median spacings
(itself included, as the inspection's core-point test takes it).  A point is **unsupported**
(a measurement outlier: dust, a spike, a stray reflection) when its deviation departs both from
``med_i`` and from the median of the whole scan by more than ``z sigma``:

* ``sigma`` is the scan's noise, from the differences of the deviations of nearest neighbours
  (``1.4826 median |d_i - d_j| / sqrt 2`` on an even subset of up to 4,000 points): the form of
  the part cancels in a neighbour's difference, so a dented part has the noise of a good one;
* ``z = Phi^-1(1 - alpha / (2 n))`` with ``n`` the evaluated points and ``alpha = 0.01``: Gaussian
  noise of that sigma leaves out no point of a clean scan in 99 % of scans (the threshold is
  relative to the neighbourhood and the noise, never a distance against a tolerance).

A real defect is a surface: its points support each other and stay.  An isolated point (fewer
than 3 neighbours) is its own neighbourhood and stays too.

:func:`extreme_quantile` gives the other half of an honest extreme value: the noise part of a
value taken from the largest of ``n`` deviations (a profile's ``2 max |d|``, a flatness zone) is
not ``k sigma`` but the ``k``-level quantile of the largest of ``n`` absolute normal deviates
(about 5 sigma for 10^5 points).
"""
from __future__ import annotations

import numpy as np

__all__ = ["Support", "neighbourhood_support", "extreme_quantile", "ALPHA", "SAMPLE"]

#: probability that a clean scan (Gaussian noise) loses a point to the rule
ALPHA = 0.01
#: evaluated points (an even subset) that give the noise
SAMPLE = 4000
#: neighbours of the median, and the neighbourhood radius in median spacings (as regions.py)
NEIGHBOURS = 9
RADIUS = 3.0


class Support:
    """Result of :func:`neighbourhood_support`.

    Attributes
    ----------
    unsupported : (N,) bool
        Evaluated points whose deviation their neighbourhood does not support.
    noise : float
        The scan's noise sigma (mm) from neighbour differences (NaN with too few points).
    threshold : float
        ``z sigma`` (mm): the departure from the neighbourhood median that makes a point
        unsupported.
    spacing : float
        Median spacing of the evaluated foot points (mm).
    """

    def __init__(self, unsupported, noise, threshold, spacing, z):
        self.unsupported = unsupported
        self.noise = float(noise)
        self.threshold = float(threshold)
        self.spacing = float(spacing)
        self.z = float(z)

    def to_dict(self) -> dict:
        return {"rule": "neighbourhood support", "noise": self.noise,
                "threshold": self.threshold, "z": self.z, "spacing": self.spacing,
                "n_unsupported": int(np.count_nonzero(self.unsupported))}


def _z(n: int, alpha: float = ALPHA) -> float:
    from scipy.stats import norm

    return float(norm.isf(alpha / (2.0 * max(int(n), 1))))


def extreme_quantile(n: int, k: float = 2.0) -> float:
    """The ``k``-level quantile (normal coverage of ``k``: 95.45 % for 2) of the largest of
    ``n`` absolute standard normal deviates: ``Phi^-1(1 - (1 - p^(1/n)) / 2)``, ``p = 2 Phi(k)
    - 1``.  Equal to ``k`` for ``n = 1``.

    >>> round(extreme_quantile(1), 6), round(extreme_quantile(100_000), 2)
    (2.0, 5.04)
    """
    from scipy.stats import norm

    n = max(int(n), 1)
    p = 1.0 - 2.0 * float(norm.sf(k))
    tail = -np.expm1(np.log(p) / n) / 2.0          # 1 - p^(1/n), halved: both signs
    return float(norm.isf(tail))


def neighbourhood_support(feet, d, ok, alpha: float = ALPHA) -> Support:
    """The neighbourhood-support rule (module docstring) on the evaluated points ``ok``.

    Parameters
    ----------
    feet : (N, 3) float64
        Foot points on the CAD (model frame, mm).
    d : (N,) float64
        Signed deviations (any value where not ``ok``).
    ok : (N,) bool
        The evaluated points.

    Returns
    -------
    Support
    """
    from ..measures._grid_kernels import kernel_array, mark_within
    from ..measures.spacing import median_spacing, neighbourhood_median
    from scipy.spatial import cKDTree

    n = d.shape[0]
    ev = np.flatnonzero(ok)
    none = np.zeros(n, bool)
    if ev.size < 10:
        return Support(none, float("nan"), float("inf"), float("nan"), float("nan"))
    ev_pts = np.ascontiguousarray(feet[ev])
    spacing = median_spacing(None, ev_pts)
    if not np.isfinite(spacing) or spacing <= 0:
        return Support(none, float("nan"), float("inf"), spacing, float("nan"))
    dv = d[ev]
    radius = RADIUS * spacing
    sample = np.arange(0, ev.size, max(1, ev.size // SAMPLE))
    m0 = float(np.median(dv))
    # the noise from neighbour differences on the sample (a tree of the points around it)
    near = np.empty(ev.size, bool)
    mark_within(kernel_array(ev_pts), kernel_array(ev_pts[sample]), 2.0 * radius, near)
    loc = np.flatnonzero(near)
    dist, j = cKDTree(ev_pts[loc]).query(ev_pts[sample], k=2, distance_upper_bound=radius)
    pair = np.isfinite(dist[:, 1])
    if np.count_nonzero(pair) < 10:
        return Support(none, float("nan"), float("inf"), spacing, float("nan"))
    diff = dv[sample[pair]] - dv[loc[j[pair, 1]]]
    noise = 1.4826 * float(np.median(np.abs(diff))) / np.sqrt(2.0)
    z = _z(ev.size, alpha)
    thr = z * noise
    if not thr > 0:
        return Support(none, noise, thr, spacing, z)
    cand = np.flatnonzero(np.abs(dv - m0) > thr)          # within z sigma of the bulk: kept
    out = none.copy()
    if cand.size:
        near = np.empty(ev.size, bool)
        mark_within(kernel_array(ev_pts), kernel_array(ev_pts[cand]), radius * (1 + 1e-6), near)
        keep = np.flatnonzero(near)
        tree = cKDTree(ev_pts[keep], balanced_tree=False, compact_nodes=False)
        med = neighbourhood_median(tree, keep, dv, ev_pts[cand], radius, k=NEIGHBOURS)
        out[ev[cand[np.abs(dv[cand] - med) > thr]]] = True
    return Support(out, noise, thr, spacing, z)
